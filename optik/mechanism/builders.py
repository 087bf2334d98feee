"""Builders for serial chains: planar R/P chains and DH chains in three conventions.

DH conventions (``q_i`` enters ``theta_i`` for revolute joints, ``d_i`` for prismatic joints):

* ``"seed"`` (seed ``001_*.txt``): ``A_i = Rot(z, theta_i) Trans(x, d_i) Rot(x, alpha_i)``;
  here ``d_i`` is a shift *along x* (the seed's link length) and a prismatic joint slides along x.
* ``"standard"`` (Denavit-Hartenberg): ``A_i = Rot(z, theta_i) Trans(z, d_i) Trans(x, a_i) Rot(x, alpha_i)``.
* ``"modified"`` (Craig): ``A_i = Rot(x, alpha_{i-1}) Trans(x, a_{i-1}) Rot(z, theta_i) Trans(z, d_i)``.

Every builder returns a [`Mechanism`][optik.mechanism.mechanism.Mechanism] whose bodies are
``base, link1, ..., linkN`` and whose end effector ``ee`` sits at the end of the last A-matrix
(for the modified convention, at an optional flange transform).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from optik import spatial
from optik.checks import as_limits, as_name, as_transform, as_vector
from optik.errors import InvalidArgumentError
from optik.mechanism.joint import Joint
from optik.mechanism.mechanism import Mechanism

CONVENTIONS = ("seed", "standard", "modified")


def planar_chain(
    types: str,
    lengths: Sequence[float],
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
    name: str | None = None,
    task: str | None = None,
) -> Mechanism:
    """A planar serial chain of revolute (``R``) and prismatic (``P``) joints in the x-y plane.

    Joint ``i`` acts at the tip of link ``i - 1``. A revolute joint turns about z and is followed
    by a link of length ``lengths[i]`` along its x axis. A prismatic joint slides along the current
    x axis by ``q_i`` (its stroke), followed by a fixed offset ``lengths[i]`` (often 0).
    For ``RRR``: ``x = sum l_i cos(theta_1 + ... + theta_i)`` (seed 000, equation (1)).

    Args:
        types: one letter per joint, ``R`` or ``P``.
        lengths: one link length per joint (metres).
        lower, upper: coordinate limits (defaults: +-pi for R, [0, 2] m for P).
        name: label (default: ``"planar_" + types``).
        task: default task space (see [`Mechanism`][optik.Mechanism]).
    """
    types = as_name(types, "types").upper()
    if not types or set(types) - {"R", "P"}:
        raise InvalidArgumentError("types", f"expected letters R and P, got {types!r}")
    ls = as_vector(lengths, "lengths", len(types))
    if np.any(ls < 0):
        raise InvalidArgumentError("lengths", f"link lengths must be >= 0, got {ls}")
    n = len(types)
    lo = [-np.pi if t == "R" else 0.0 for t in types] if lower is None else list(as_limits(lower, "lower", n))
    hi = [np.pi if t == "R" else 2.0 for t in types] if upper is None else list(as_limits(upper, "upper", n))
    joints = []
    prev = "base"
    origin = np.eye(4)
    for i, t in enumerate(types):
        body = f"link{i + 1}"
        joints.append(
            Joint(
                f"q{i + 1}",
                "revolute" if t == "R" else "prismatic",
                prev,
                body,
                origin=origin,
                axis=[0, 0, 1] if t == "R" else [1, 0, 0],
                lower=lo[i],
                upper=hi[i],
            )
        )
        prev = body
        origin = spatial.translation(ls[i], 0.0, 0.0)
    frames = {"ee": (prev, origin)}
    return Mechanism(joints, "base", frames, "ee", name or f"planar_{types}", task)


def dh_chain(
    params: Sequence[Sequence[float]],
    convention: str = "standard",
    types: str | None = None,
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
    flange: Any = None,
    name: str = "dh_chain",
    task: str | None = None,
) -> Mechanism:
    """A serial chain from DH parameters.

    Args:
        params: one row per joint. ``"seed"``: ``(d, alpha)``; ``"standard"``: ``(d, a, alpha)``;
            ``"modified"``: ``(a_{i-1}, alpha_{i-1}, d_i)``. Angles in radians. For a prismatic
            joint the row's ``d`` is a constant offset added to the joint's stroke.
        convention: ``"seed"``, ``"standard"`` or ``"modified"`` (see module docstring).
        types: ``R``/``P`` per joint (default all ``R``). A ``"seed"`` prismatic joint slides
            along x (``Trans(x, q)`` replaces ``Rot(z, theta)``); in the other conventions along z.
        lower, upper: coordinate limits.
        flange: 4x4 transform from the last DH frame to the end effector (default identity).
        name: label.
        task: default task space.

    Returns:
        Mechanism with bodies ``link1..linkN`` (joint frames after each joint's motion), frames
        ``frame1..frameN`` (the DH frames, i.e. after each whole A-matrix) and ``ee``.
    """
    as_name(convention, "convention", CONVENTIONS)
    if isinstance(params, (str, bytes)) or not isinstance(params, Sequence | np.ndarray):
        raise InvalidArgumentError("params", f"expected a sequence of DH rows, got {params!r}")
    rows = [as_vector(r, f"params[{i}]") for i, r in enumerate(params)]
    width = {"seed": 2, "standard": 3, "modified": 3}[convention]
    for i, r in enumerate(rows):
        if r.shape[0] != width:
            raise InvalidArgumentError(
                f"params[{i}]", f"{convention} DH rows have {width} values, got {r.shape[0]}"
            )
    n = len(rows)
    types = ("R" * n if types is None else as_name(types, "types")).upper()
    if len(types) != n or set(types) - {"R", "P"}:
        raise InvalidArgumentError("types", f"expected {n} letters R/P, got {types!r}")
    lo = None if lower is None else as_limits(lower, "lower", n)
    hi = None if upper is None else as_limits(upper, "upper", n)
    joints: list[Joint] = []
    frames: dict[str, tuple[str, np.ndarray]] = {}
    prev, pending = "base", np.eye(4)
    for i, r in enumerate(rows):
        body = f"link{i + 1}"
        axis = [1.0, 0.0, 0.0] if convention == "seed" and types[i] == "P" else [0.0, 0.0, 1.0]
        if convention == "modified":
            a_prev, alpha_prev, d = r
            origin = (
                pending @ spatial.transform(spatial.rot_x(alpha_prev)) @ spatial.translation(a_prev, 0.0, d)
            )
            after = np.eye(4)
        elif convention == "seed":
            d, alpha = r
            origin, after = (
                pending,
                spatial.translation(d, 0.0, 0.0) @ spatial.transform(spatial.rot_x(alpha)),
            )
        else:
            d, a, alpha = r
            origin, after = pending, spatial.translation(a, 0.0, d) @ spatial.transform(spatial.rot_x(alpha))
        joints.append(
            Joint(
                f"q{i + 1}",
                "prismatic" if types[i] == "P" else "revolute",
                prev,
                body,
                origin=origin,
                axis=axis,
                lower=None if lo is None else lo[i],
                upper=None if hi is None else hi[i],
            )
        )
        frames[f"frame{i + 1}"] = (body, after)
        prev, pending = body, after
    flange_t = np.eye(4) if flange is None else as_transform(flange, "flange")
    frames["ee"] = (prev, pending @ flange_t)
    return Mechanism(joints, "base", frames, "ee", name, task)
