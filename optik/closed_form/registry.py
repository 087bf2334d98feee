"""Registry of closed-form solvers by catalog ``kind``.

A catalog mechanism carries ``m.kind`` and ``m.params``; the closed-form modules register, per
kind, an IK solver ``ik(m, T) -> list[q]`` (``T`` a 4x4 target) and/or an FK solver
``fk(m, actuated) -> list[q]`` returning full coordinate vectors, one per branch / assembly
mode (an empty list when unreachable or not assemblable). The functions here add validation,
the 2 pi shift of angles into the limits and the optional filtering by joint limits.

The shift ([`wrap_rows`][optik.closed_form.registry.wrap_rows]) is
[`Mechanism.wrap`][optik.Mechanism.wrap] of all the branches at once; the limit filter
([`within_limits`][optik.closed_form.registry.within_limits]) works on the few branches of one target as plain
floats, with the same arithmetic as
[`Mechanism.within_limits`][optik.Mechanism.within_limits]; [`branches`][optik.closed_form.registry.branches]
is the unvalidated core that [`optik.solvers.closed`][optik.solvers.closed] calls with an already validated
target.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from optik.checks import as_bool, as_vector
from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.spatial import wrap_into
from optik.targets import target_transform

IKSolver = Callable[[Mechanism, np.ndarray], Sequence[Sequence[float]]]
FKSolver = Callable[[Mechanism, np.ndarray], Sequence[Sequence[float]]]

_IK: dict[str, IKSolver] = {}
_FK: dict[str, FKSolver] = {}
_GENERATION = [0]
"""Bumped by every registration: caches of what `ik_solver` answered compare it (`generation`)."""
_PREFER_EXACT_DERIVED: set[str] = set()
"""Kinds whose registered IK gives way to a derived one that is exact (``exact`` attribute)."""
_TIMED_FK: set[str] = set()
"""Kinds whose FK can run long (iterative: homotopy) and takes a ``time_limit`` keyword."""


def register(
    kind: str, ik: IKSolver | None = None, fk: FKSolver | None = None, prefer_exact_derived: bool = False
) -> None:
    """Register the closed-form IK and/or FK of a catalog kind. An FK solver that can run long
    declares a ``time_limit`` keyword (seconds); [`fk`][optik.closed_form.registry.fk] passes it on.
    With ``prefer_exact_derived``, a solver derived from the model (see
    [`register_deriver`][optik.closed_form.registry.register_deriver]) whose ``exact`` attribute is
    True answers for the kind instead of ``ik`` (the hand-written one then answers for the
    geometries the derived one only approximates)."""
    _GENERATION[0] += 1
    if ik is not None:
        _IK[kind] = ik
        if prefer_exact_derived:
            _PREFER_EXACT_DERIVED.add(kind)
    if fk is not None:
        _FK[kind] = fk
        if "time_limit" in inspect.signature(fk).parameters:
            _TIMED_FK.add(kind)


Deriver = Callable[[Mechanism], IKSolver | None]
_DERIVERS: list[Deriver] = []
_DERIVED: PerMechanism[tuple[int, IKSolver | None]] = PerMechanism()
"""``(registry generation, derived IK)`` per mechanism: stale once the generation changed."""


def register_deriver(deriver: Deriver) -> None:
    """Register a function that derives a closed-form IK from a mechanism's model (or returns
    None). Derivers are tried in registration order for mechanisms whose kind has no registered
    IK; the first answer is cached per mechanism."""
    _DERIVERS.append(deriver)
    _GENERATION[0] += 1


def generation() -> int:
    """A number that changes with every registration (of a kind's solvers or a deriver): what
    [`ik_solver`][optik.closed_form.registry.ik_solver] answers for a mechanism holds while it
    stays the same."""
    return _GENERATION[0]


def ik_solver(m: Mechanism) -> IKSolver | None:
    """The closed-form IK of ``m``: the one registered for its kind (unless the kind prefers an
    exact derived one and there is one), else the first derived one (see
    [`register_deriver`][optik.closed_form.registry.register_deriver]), else None."""
    own = _IK.get(m.kind) if m.kind is not None else None
    if own is not None and m.kind not in _PREFER_EXACT_DERIVED:
        return own
    cached = _DERIVED.get(m)
    if cached is not None and cached[0] == _GENERATION[0]:
        return cached[1]
    solver = None
    for deriver in _DERIVERS:
        solver = deriver(m)
        if solver is not None:
            break
    if own is not None and not getattr(solver, "exact", False):
        solver = own
    _DERIVED[m] = (_GENERATION[0], solver)
    return solver


def costly(m: Mechanism) -> bool:
    """True when ``m``'s closed-form IK declares itself costly (a ``costly`` attribute that is
    True: the general 6R solver, about five times ``lm``'s time per target), so that
    `optik.solve_ik` with ``method=None`` tries the numerical method first."""
    return getattr(ik_solver(m), "costly", False) is True


def has_ik(m: Mechanism) -> bool:
    """True when a closed-form IK is registered for the mechanism's kind or derived from its model."""
    return ik_solver(m) is not None


def has_fk(m: Mechanism) -> bool:
    """True when a closed-form FK (all assembly modes) is registered for the mechanism's kind."""
    return m.kind in _FK


_Coordinates = tuple[tuple[bool, ...], tuple[slice, ...], tuple[int, ...]]
_COORDS: PerMechanism[_Coordinates] = PerMechanism()

MAX_ACTUATED = 1e50
"""Largest actuated value (leg length, angle) the closed-form FK accepts: the assembly
polynomials raise them to powers up to 6, which overflows beyond (the 3-RPR and Stewart-Gough
solvers raised OverflowError, IndexError or LinAlgError there)."""


def _coordinates(m: Mechanism) -> _Coordinates:
    """``(m.revolute_mask as a tuple, m.spherical_slices, angle indices)``, cached per mechanism:
    the joints and topology of a [`Mechanism`][optik.Mechanism] never change (limits may; they are read on
    every call)."""
    try:
        return _COORDS[m]
    except KeyError:
        mask = tuple(bool(v) for v in m.revolute_mask)
        coords = (mask, m.spherical_slices, tuple(k for k, a in enumerate(mask) if a))
        _COORDS[m] = coords
        return coords


def angle_mask(m: Mechanism) -> tuple[bool, ...]:
    """``m.revolute_mask`` as a tuple (cached): the coordinates compared modulo 2 pi."""
    return _coordinates(m)[0]


def wrap_rows(m: Mechanism, rows: Sequence[Sequence[float]]) -> list[list[float]]:
    """[`Mechanism.wrap`][optik.Mechanism.wrap] of every row (branches of one target), as lists
    of floats (``[]`` for no rows).

    Plain floats through [`spatial.wrap_into`][optik.spatial.wrap_into] (the rule of ``m.wrap``,
    one angle at a time): on a few short rows numpy calls would cost several times the closed
    form itself. Mechanisms with spherical joints go through ``m.wrap``.

    Raises:
        OptikError: a row of the wrong length or not finite (from ``m.wrap``).
    """
    if not len(rows):
        return []
    mask, spherical, angles = _coordinates(m)
    out = [row.tolist() if isinstance(row, np.ndarray) else [float(v) for v in row] for row in rows]
    if spherical or not all(len(row) == len(mask) and math.isfinite(sum(row)) for row in out):
        return m.wrap(np.array(out, dtype=float)).tolist()  # rotation vectors; m.wrap raises on bad rows
    lo, hi, pi = m.lower.tolist(), m.upper.tolist(), math.pi
    for row in out:
        for k in angles:
            v = row[k]
            if not (-pi < v <= pi and lo[k] <= v <= hi[k]):
                row[k] = wrap_into(v, lo[k], hi[k])
    return out


LIMIT_TOL = 1e-9
"""A computed coordinate at most this far outside a joint limit (rad or m) is at the limit:
rounding of an answer on the boundary (e.g. the R-P arm's slide at its lower limit). It is
clipped onto the limit, and the FK check of the clipped row decides, as the success check of
every method does with its clipped answer (`optik.solvers.base.make_result`)."""


def clip_to_limits(m: Mechanism, row: list[float]) -> list[float] | None:
    """``row`` when ``lower <= q <= upper`` holds in every coordinate
    ([`Mechanism.within_limits`][optik.Mechanism.within_limits]); a copy clipped onto the
    limits when no coordinate is more than `LIMIT_TOL` outside; else None."""
    lo, hi = m.lower.tolist(), m.upper.tolist()
    if len(row) != len(lo):
        return None
    out = row
    for k, v in enumerate(row):
        if lo[k] <= v <= hi[k]:
            continue
        if not lo[k] - LIMIT_TOL <= v <= hi[k] + LIMIT_TOL:
            return None
        if out is row:
            out = list(row)
        out[k] = lo[k] if v < lo[k] else hi[k]
    return out


def within_limits(m: Mechanism, rows: list[list[float]]) -> list[list[float]]:
    """The rows within the joint limits, each by `clip_to_limits` (a row within `LIMIT_TOL`
    of a limit clipped onto it: a new list)."""
    clipped = (clip_to_limits(m, row) for row in rows)
    return [row for row in clipped if row is not None]


class CheckedRows(list):
    """Rows an IK solver returns together with the FK check it made of each: ``errors[i]`` is
    the ``(position, orientation)`` error of row ``i`` against the target (m, rad). The solvers
    layer then reports those errors instead of evaluating the FK of every row again."""

    def __init__(
        self, rows: Sequence[Sequence[float]], errors: Sequence[tuple[float, float]], wrapped: bool = False
    ) -> None:
        super().__init__(rows)
        self.errors = list(errors)
        self.wrapped = wrapped
        """True when every angle is already in ``(-pi, pi]``."""


class Uncertified(list):
    """Rows from an IK solver that checks each of them but does not certify that they are every
    solution (a sampled search, a count check that failed); ``reason`` says why. The rows pass
    through [`branches`][optik.closed_form.registry.branches] and [`ik`][optik.closed_form.registry.ik]
    with the flag, and `optik.solve_ik_all` reports it (``IKSolutions.certified``)."""

    def __init__(self, rows: Sequence[Any], reason: str) -> None:
        super().__init__(rows)
        self.reason = reason


def _flagged(rows: Any, out: list[Any]) -> list[Any]:
    """``out`` with the flag of ``rows`` when they are `Uncertified`."""
    return Uncertified(out, rows.reason) if isinstance(rows, Uncertified) else out


def branches(m: Mechanism, t: np.ndarray) -> list[list[float]]:
    """All closed-form IK branches for a validated 4x4 target ``t``, wrapped by
    [`wrap_rows`][optik.closed_form.registry.wrap_rows], without the limit filter (``[]`` when
    unreachable; `Uncertified` when the solver does not certify completeness).

    Raises:
        SolverUnavailableError: no closed form is registered for ``m.kind``.
    """
    solver = ik_solver(m)
    if solver is None:
        raise SolverUnavailableError(f"no closed-form IK for mechanism {m.name!r} (kind {m.kind!r})")
    rows = solver(m, t)
    if isinstance(rows, CheckedRows):
        if rows.wrapped and _covers_half_turns(m):  # wrap_rows would return the same numbers
            return rows
        return CheckedRows(wrap_rows(m, rows), rows.errors)
    return _flagged(rows, wrap_rows(m, rows))


def _covers_half_turns(m: Mechanism) -> bool:
    """Every angle coordinate of ``m`` has limits containing ``(-pi, pi]`` (so that
    [`wrap_rows`][optik.closed_form.registry.wrap_rows] leaves wrapped angles unchanged) and
    there are no spherical joints."""
    mask, spherical, angles = _coordinates(m)
    lo, hi = m.lower.tolist(), m.upper.tolist()
    return (
        len(angles) == len(mask) and not spherical and all(lo[k] <= -np.pi and hi[k] >= np.pi for k in angles)
    )


def _finish(m: Mechanism, rows: list[list[float]], respect_limits: bool) -> list[np.ndarray]:
    return _flagged(rows, [np.array(row) for row in (within_limits(m, rows) if respect_limits else rows)])


def ik(m: Mechanism, target: Any, respect_limits: bool = True) -> list[np.ndarray]:
    """All closed-form IK branches of a catalog mechanism.

    Args:
        m: a catalog mechanism with a registered closed form.
        target: 4x4 transform, [`Pose2D`][optik.Pose2D] or [`Position`][optik.Position].
        respect_limits: drop branches outside the joint limits (angles are first shifted by
            multiples of 2 pi into the limits where possible; a coordinate within `LIMIT_TOL`
            of a limit is clipped onto it); True or False only.

    Returns:
        One full coordinate vector per branch; ``[]`` when the target is unreachable; an
        `Uncertified` list (with its ``reason``) when the solver does not certify completeness.

    Raises:
        SolverUnavailableError: no closed form is registered for ``m.kind``.
        InvalidArgumentError: ``respect_limits`` is not a boolean.
    """
    respect_limits = as_bool(respect_limits, "respect_limits")
    if ik_solver(m) is None:
        raise SolverUnavailableError(f"no closed-form IK for mechanism {m.name!r} (kind {m.kind!r})")
    return _finish(m, branches(m, target_transform(target)), respect_limits)


def fk(
    m: Mechanism, actuated: Any, respect_limits: bool = True, time_limit: float | None = None
) -> list[np.ndarray]:
    """All closed-form assembly modes for given actuated coordinates.

    Args:
        m: a catalog mechanism with a registered closed-form FK.
        actuated: values of the actuated coordinates.
        respect_limits: drop modes outside the joint limits (`within_limits`); True or False.
        time_limit: wall-time budget (s) of the FK solvers that can run long (the Stewart-Gough
            homotopy, which warns when it could not certify completeness in time); None: their
            default. The algebraic closed forms finish in microseconds and need none.

    Returns:
        One full coordinate vector per assembly mode; ``[]`` when the inputs cannot assemble.

    Raises:
        SolverUnavailableError: no closed-form FK is registered for ``m.kind``.
        InvalidArgumentError: an actuated value beyond `MAX_ACTUATED` in magnitude.
    """
    respect_limits = as_bool(respect_limits, "respect_limits")
    if m.kind not in _FK:
        raise SolverUnavailableError(f"no closed-form FK for mechanism {m.name!r} (kind {m.kind!r})")
    a = as_vector(actuated, "actuated", len(m.actuated_indices))
    if a.size and not float(np.abs(a).max()) <= MAX_ACTUATED:
        raise InvalidArgumentError(
            "actuated", f"values beyond {MAX_ACTUATED:g} in magnitude overflow the closed forms, got {a}"
        )
    options = {"time_limit": time_limit} if time_limit is not None and m.kind in _TIMED_FK else {}
    return _finish(m, wrap_rows(m, _FK[m.kind](m, a, **options)), respect_limits)
