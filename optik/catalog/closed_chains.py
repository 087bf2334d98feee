"""Closed chains and parallel mechanisms: five-bar, doggy, slider-crank, 3-RPR, Stewart-Gough.

Each constructor lays out bodies and joints; the spanning tree and the cut joints follow from
[`optik.mechanism.topology`][optik.mechanism.topology], and the loop closures from the cut joints.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from optik import spatial
from optik.catalog.serial import _positive, _tag
from optik.checks import as_vector, real_array
from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError
from optik.mechanism import Joint, Mechanism


def _points(value: Any, name: str, n: int, dim: int) -> np.ndarray:
    a = real_array(value, name)
    if a.shape != (n, dim):
        raise ShapeError(name, f"expected {n} points of {dim} coordinates, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(name, "contains NaN or infinity")
    return a


def _at(xy: Sequence[float]) -> np.ndarray:
    return spatial.translation(float(xy[0]), float(xy[1]), 0.0)


def five_bar(
    base: Any = ((0.0, 0.0), (1.0, 0.0)),
    lengths: Sequence[float] = (1.0, 1.0, 1.2, 1.2),
    tool: float | None = None,
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
) -> Mechanism:
    """Planar five-bar linkage with actuated revolutes at the base pivots ``A1``, ``A2``.

    Proximal links ``l1`` (from ``A1``) and ``l2`` (from ``A2``); distal links ``l3`` and ``l4``
    meet at ``P``. The tool point lies on the distal link of the first chain at distance ``tool``
    from its proximal joint (default ``l3``: the tool is ``P``). The seed's variant (003,
    Example 4.3: both pivots at ``O``, tool on an extended link) is ``base=((0, 0), (0, 0))``
    with ``tool > l3``.

    Coordinates ``(theta1, theta2, psi1, psi2)``: absolute angles of the proximal links
    (actuated) and the distal links' angles relative to them (passive). Mobility 2.
    """
    b = _points(base, "base", 2, 2)
    l1, l2, l3, l4 = _positive(lengths, "lengths", 4)
    t = l3 if tool is None else float(as_vector(tool, "tool", 1)[0])
    lo = (-np.pi,) * 4 if lower is None else tuple(as_vector(lower, "lower", 4))
    hi = (np.pi,) * 4 if upper is None else tuple(as_vector(upper, "upper", 4))
    joints = [
        Joint("theta1", "revolute", "base", "proximal1", _at(b[0]), lower=lo[0], upper=hi[0]),
        Joint("theta2", "revolute", "base", "proximal2", _at(b[1]), lower=lo[1], upper=hi[1]),
        Joint(
            "psi1", "revolute", "proximal1", "distal1", _at((l1, 0)), lower=lo[2], upper=hi[2], actuated=False
        ),
        Joint(
            "psi2", "revolute", "proximal2", "distal2", _at((l2, 0)), lower=lo[3], upper=hi[3], actuated=False
        ),
        Joint("P", "revolute", "distal1", "distal2", _at((l3, 0)), actuated=False, child_offset=_at((l4, 0))),
    ]
    m = Mechanism(joints, "base", {"tool": ("distal1", _at((t, 0)))}, "tool", "five_bar", "position2d")
    return _tag(m, "five_bar", base=b, lengths=(l1, l2, l3, l4), tool=t)


def doggy(
    feet: Any = ((-0.6, 0.0), (0.6, 0.0)),
    hips: Any = ((-0.4, 0.0), (0.4, 0.0)),
    legs: Any = ((0.6, 0.6), (0.6, 0.6)),
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
) -> Mechanism:
    """The two-legged "doggy" of seed 003, Example 4.4.

    A rigid body with hip pivots ``A`` and ``C`` (``hips``, in the body frame ``B``) stands on two
    planar 2R legs whose feet are pinned to the ground at ``feet``. Leg 1: ``theta1`` at the
    foot (absolute), ``theta2`` at the knee (relative), shin and thigh lengths ``legs[0]``;
    leg 2 likewise with ``theta3``, ``theta4``. The hips are passive. The end effector is the body
    frame ``B``: IK takes ``(xB, yB, phiB)``, FK takes the four leg angles. Mobility 3.

    Coordinates ``(theta1, theta2, hipA, theta3, theta4)``; the hip at ``C`` closes the loop.
    """
    f = _points(feet, "feet", 2, 2)
    h = _points(hips, "hips", 2, 2)
    lg = _points(legs, "legs", 2, 2)
    if np.any(lg <= 0):
        raise InvalidArgumentError("legs", "leg link lengths must be > 0")
    lo = (0.0, -np.pi, -np.pi, 0.0, -np.pi) if lower is None else tuple(as_vector(lower, "lower", 5))
    hi = (np.pi, np.pi, np.pi, np.pi, np.pi) if upper is None else tuple(as_vector(upper, "upper", 5))
    joints = [
        Joint("theta1", "revolute", "base", "shin1", _at(f[0]), lower=lo[0], upper=hi[0]),
        Joint("theta2", "revolute", "shin1", "thigh1", _at((lg[0, 0], 0)), lower=lo[1], upper=hi[1]),
        Joint(
            "hipA",
            "revolute",
            "thigh1",
            "body",
            _at((lg[0, 1], 0)),
            lower=lo[2],
            upper=hi[2],
            actuated=False,
            child_offset=_at(h[0]),
        ),
        Joint("theta3", "revolute", "base", "shin2", _at(f[1]), lower=lo[3], upper=hi[3]),
        Joint("theta4", "revolute", "shin2", "thigh2", _at((lg[1, 0], 0)), lower=lo[4], upper=hi[4]),
        Joint(
            "hipC", "revolute", "thigh2", "body", _at((lg[1, 1], 0)), actuated=False, child_offset=_at(h[1])
        ),
    ]
    m = Mechanism(joints, "base", None, "body", "doggy", "pose2d")
    return _tag(m, "doggy", feet=f, hips=h, legs=lg)


def slider_crank(
    crank: float = 0.3,
    rod: float = 1.0,
    offset: float = 0.0,
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
) -> Mechanism:
    """Slider-crank (seed 004, Figure 3): crank ``r`` turning about the origin (actuated), rod
    ``l``, piston sliding along the line ``y = offset``. The end effector is the piston.

    Coordinates ``(theta, phi, x)``: crank angle, rod angle relative to the crank, piston
    position; the wrist pin closes the loop. Mobility 1 (n = 3, g = 4).
    """
    r, l = _positive((crank, rod), "crank/rod", 2)
    e = float(as_vector(offset, "offset", 1)[0])
    reach = r + l
    lo = (-np.pi, -np.pi, -reach) if lower is None else tuple(as_vector(lower, "lower", 3))
    hi = (np.pi, np.pi, reach) if upper is None else tuple(as_vector(upper, "upper", 3))
    joints = [
        Joint("theta", "revolute", "base", "crank", lower=lo[0], upper=hi[0]),
        Joint("phi", "revolute", "crank", "rod", _at((r, 0)), lower=lo[1], upper=hi[1], actuated=False),
        Joint(
            "x",
            "prismatic",
            "base",
            "piston",
            _at((0, e)),
            axis=[1, 0, 0],
            lower=lo[2],
            upper=hi[2],
            actuated=False,
        ),
        Joint("pin", "revolute", "rod", "piston", _at((l, 0)), actuated=False),
    ]
    m = Mechanism(joints, "base", None, "piston", "slider_crank", "position2d")
    return _tag(m, "slider_crank", crank=r, rod=l, offset=e)


def _leg_limits(leg_limits: Sequence[float]) -> tuple[float, float]:
    """Validated ``(min, max)`` length of the actuated legs of a parallel mechanism."""
    lo, hi = (float(v) for v in as_vector(leg_limits, "leg_limits", 2))
    if not 0 <= lo < hi:
        raise InvalidArgumentError("leg_limits", f"need 0 <= min < max, got {tuple(leg_limits)}")
    return lo, hi


def _actuated_leg(i: int, axis: Sequence[float], lo: float, hi: float) -> Joint:
    """The actuated prismatic joint ``rho<i+1>`` from ``cylinder<i+1>`` to ``rod<i+1>``."""
    return Joint(f"rho{i + 1}", "prismatic", f"cylinder{i + 1}", f"rod{i + 1}", axis=axis, lower=lo, upper=hi)


DEFAULT_3RPR_BASE = ((0.0, 0.0), (2.0, 0.0), (0.8, 1.8))
DEFAULT_3RPR_PLATFORM = ((-0.3, -0.15), (0.3, -0.15), (0.0, 0.3))


def planar_3rpr(
    base: Any = DEFAULT_3RPR_BASE,
    platform: Any = DEFAULT_3RPR_PLATFORM,
    leg_limits: tuple[float, float] = (0.3, 2.5),
) -> Mechanism:
    """Planar 3-RPR parallel manipulator (seed 004, Figure 6).

    Leg ``i`` turns about the base point ``base[i]`` (passive), extends by its actuated length
    ``rho_i`` and is pinned to the platform at ``platform[i]`` (platform frame). The end effector
    is the platform frame, pose ``(x, y, phi)``.

    Coordinates ``(theta1, rho1, pin1, theta2, rho2, theta3, rho3)``; the pins of legs 2 and 3
    close the loops. Mobility 3 (n = 7, g = 9).
    """
    b = _points(base, "base", 3, 2)
    p = _points(platform, "platform", 3, 2)
    lo, hi = _leg_limits(leg_limits)
    joints: list[Joint] = []
    for i in range(3):
        joints += [
            Joint(f"theta{i + 1}", "revolute", "base", f"cylinder{i + 1}", _at(b[i]), actuated=False),
            _actuated_leg(i, [1, 0, 0], lo, hi),
            Joint(
                f"pin{i + 1}", "revolute", f"rod{i + 1}", "platform", actuated=False, child_offset=_at(p[i])
            ),
        ]
    m = Mechanism(joints, "base", None, "platform", "planar_3rpr", "pose2d")
    return _tag(m, "planar_3rpr", base=b, platform=p, leg_limits=(lo, hi))


def _hexagon(radius: float, angles_deg: Sequence[float], z: float) -> np.ndarray:
    a = np.radians(np.asarray(angles_deg, dtype=float))
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), np.full(len(a), z)])


DEFAULT_SG_BASE = _hexagon(1.0, (-12, 12, 108, 132, 228, 252), 0.0)
DEFAULT_SG_PLATFORM = _hexagon(0.6, (-48, 48, 72, 168, 192, 288), 0.0)


def stewart_gough(
    base: Any = DEFAULT_SG_BASE,
    platform: Any = DEFAULT_SG_PLATFORM,
    leg_limits: tuple[float, float] = (0.5, 2.5),
) -> Mechanism:
    """Stewart-Gough platform, general 6-6 geometry (seed 004, Figure 7).

    Leg ``i`` is U-P-S: a universal joint at ``base[i]`` (passive, axes x then y, the first within
    ``[-pi, pi]``, the second within ``[-pi/2, pi/2]``: every leg direction, up or down, has
    exactly one pair of angles ``(a, c)``, ``Rx(a) Ry(c) e_z = n``), an actuated
    prismatic joint of length ``rho_i`` along the leg, a spherical joint at ``platform[i]``
    (platform frame). Leg ``i`` joins ``base[i]`` and ``R @ platform[i] + t``. The end effector is
    the platform frame.

    Coordinates: per leg the two universal angles and ``rho_i``, then the spherical joint of
    leg 1 as a rotation vector; spherical joints of legs 2-6 close the loops (15 equations).
    Mobility 6 (n = 13, g = 18, sum f = 36).
    """
    b = _points(base, "base", 6, 3)
    p = _points(platform, "platform", 6, 3)
    lo, hi = _leg_limits(leg_limits)
    half = np.pi / 2  # one canonical universal-joint pair per leg direction (up or down)
    joints: list[Joint] = []
    for i in range(6):
        joints += [
            Joint(
                f"u{i + 1}",
                "universal",
                "base",
                f"cylinder{i + 1}",
                spatial.translation(*b[i]),
                axis=[1, 0, 0],
                axis2=[0, 1, 0],
                lower=(-np.pi, -half),
                upper=(np.pi, half),
                actuated=False,
            ),
            _actuated_leg(i, [0, 0, 1], lo, hi),
            Joint(
                f"s{i + 1}",
                "spherical",
                f"rod{i + 1}",
                "platform",
                actuated=False,
                child_offset=spatial.translation(*p[i]),
            ),
        ]
    m = Mechanism(joints, "base", None, "platform", "stewart_gough", "pose")
    return _tag(m, "stewart_gough", base=b, platform=p, leg_limits=(lo, hi))
