"""Registry of closed-form solvers by catalog ``kind``.

A catalog mechanism carries ``m.kind`` and ``m.params``; the closed-form modules register, per
kind, an IK solver ``ik(m, T) -> list[q]`` (``T`` a 4x4 target) and/or an FK solver
``fk(m, actuated) -> list[q]`` returning full coordinate vectors, one per branch / assembly
mode (an empty list when unreachable or not assemblable). The functions here add validation,
the 2 pi shift of angles into the limits and the optional filtering by joint limits.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from optik.checks import as_vector
from optik.errors import SolverUnavailableError
from optik.mechanism import Mechanism
from optik.targets import target_transform

IKSolver = Callable[[Mechanism, np.ndarray], list[np.ndarray]]
FKSolver = Callable[[Mechanism, np.ndarray], list[np.ndarray]]

_IK: dict[str, IKSolver] = {}
_FK: dict[str, FKSolver] = {}


def register(kind: str, ik: IKSolver | None = None, fk: FKSolver | None = None) -> None:
    """Register the closed-form IK and/or FK of a catalog kind."""
    if ik is not None:
        _IK[kind] = ik
    if fk is not None:
        _FK[kind] = fk


def has_ik(m: Mechanism) -> bool:
    """True when a closed-form IK is registered for the mechanism's kind."""
    return m.kind in _IK


def has_fk(m: Mechanism) -> bool:
    """True when a closed-form FK (all assembly modes) is registered for the mechanism's kind."""
    return m.kind in _FK


def _finish(m: Mechanism, qs: list[np.ndarray], respect_limits: bool) -> list[np.ndarray]:
    out = []
    for q in qs:
        w = m.wrap(q)
        if respect_limits and not m.within_limits(w):
            continue
        out.append(w)
    return out


def ik(m: Mechanism, target: Any, respect_limits: bool = True) -> list[np.ndarray]:
    """All closed-form IK branches of a catalog mechanism.

    Args:
        m: a catalog mechanism with a registered closed form.
        target: 4x4 transform, :class:`~optik.Pose2D` or :class:`~optik.Position`.
        respect_limits: drop branches outside the joint limits (angles are first shifted by
            multiples of 2 pi into the limits where possible).

    Returns:
        One full coordinate vector per branch; ``[]`` when the target is unreachable.

    Raises:
        SolverUnavailableError: no closed form is registered for ``m.kind``.
    """
    if m.kind not in _IK:
        raise SolverUnavailableError(f"no closed-form IK for mechanism {m.name!r} (kind {m.kind!r})")
    return _finish(m, _IK[m.kind](m, target_transform(target)), respect_limits)


def fk(m: Mechanism, actuated: Any, respect_limits: bool = True) -> list[np.ndarray]:
    """All closed-form assembly modes for given actuated coordinates.

    Returns:
        One full coordinate vector per assembly mode; ``[]`` when the inputs cannot assemble.

    Raises:
        SolverUnavailableError: no closed-form FK is registered for ``m.kind``.
    """
    if m.kind not in _FK:
        raise SolverUnavailableError(f"no closed-form FK for mechanism {m.name!r} (kind {m.kind!r})")
    a = as_vector(actuated, "actuated", len(m.actuated_indices))
    return _finish(m, _FK[m.kind](m, a), respect_limits)
