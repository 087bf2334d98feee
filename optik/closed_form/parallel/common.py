"""Helpers shared by the closed forms of the closed-chain catalog: coordinate vectors by name,
planar rotations and 2R chains, circle intersections, a guarded Newton step."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from optik.mechanism import Mechanism

QUADRATIC_STOP = 1e-9
"""Newton polishing stops after a step below this (relative): with quadratic convergence the
error left after a step of size ``d`` is ``O(d^2)``, at the level of rounding."""

CIRCLE_TOL = 1e-12
"""Relative tolerance under which a circle/circle or law-of-cosines discriminant counts as zero."""


def assemble(m: Mechanism, values: Mapping[str, float]) -> np.ndarray:
    """A coordinate vector from ``{coordinate name: value}`` (every coordinate must be given)."""
    return np.array([values[name] for name in m.coordinate_names], dtype=float)


def angle(v: np.ndarray) -> float:
    return float(np.arctan2(v[1], v[0]))


def rot2(phi: float) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])


def direction(phi: float) -> np.ndarray:
    return np.array([np.cos(phi), np.sin(phi)])


def two_link_ik(origin: np.ndarray, a: float, b: float, point: np.ndarray) -> list[tuple[float, float]]:
    """Both solutions of a planar 2R chain from ``origin`` with links ``a``, ``b`` reaching ``point``.

    ``point = origin + a u(theta) + b u(theta + psi)``: ``psi = atan2(+-sqrt(S), d^2 - a^2 - b^2)``
    with ``S = (a + b - d)(a + b + d)(d - a + b)(d + a - b) = (2 a b sin psi)^2`` (the product form
    keeps ``sin psi`` accurate where ``cos psi`` is near +-1, unlike ``acos``),
    ``theta = atan2(d) - atan2(b sin psi, a + b cos psi)``. Returns ``[(theta, psi), ...]``: two
    solutions, one at a boundary of the workspace (``S = 0``), none outside.
    """
    (ox, oy), (px, py) = np.asarray(origin, dtype=float).tolist(), np.asarray(point, dtype=float).tolist()
    return two_link_one(ox, oy, a, b, px, py)


def two_link_one(ox: float, oy: float, a: float, b: float, px: float, py: float) -> list[tuple[float, float]]:
    """`two_link_ik` on floats (one target: cheaper than numpy on 2-vectors)."""
    dx, dy = px - ox, py - oy
    d = math.hypot(dx, dy)
    s2 = (a + b - d) * (a + b + d) * (d - a + b) * (d + a - b)
    scale = 4 * a * a * b * b
    if s2 < -2 * CIRCLE_TOL * scale:
        return []
    cos_part = dx * dx + dy * dy - a * a - b * b  # 2 a b cos psi
    sin_part = math.sqrt(max(s2, 0.0))  # 2 a b |sin psi|
    psis = [math.atan2(sin_part, cos_part)]
    if s2 > 2 * CIRCLE_TOL * scale:
        psis.append(-psis[0])
    angle = math.atan2(dy, dx)
    return [(angle - math.atan2(b * math.sin(p), a + b * math.cos(p)), p) for p in psis]


def coordinate_row(m: Mechanism, values: Mapping[str, float]) -> list[float]:
    """`assemble` as a list of floats (what the registry works on)."""
    return [values[name] for name in m.coordinate_names]


def circle_intersections(c1: np.ndarray, r1: float, c2: np.ndarray, r2: float) -> list[np.ndarray]:
    """Intersection points of two circles (two, one when tangent, none when apart or concentric)."""
    (x1, y1), (x2, y2) = np.asarray(c1, dtype=float).tolist(), np.asarray(c2, dtype=float).tolist()
    return [np.array(pt) for pt in circle_points(x1, y1, float(r1), x2, y2, float(r2))]


def circle_points(
    x1: float, y1: float, r1: float, x2: float, y2: float, r2: float
) -> list[tuple[float, float]]:
    """`circle_intersections` on floats: along the centre line at ``a = (d^2 + r1^2 - r2^2) / 2d``
    from ``c1``, then ``+-h`` across it with ``h^2 = (r1 - a)(r1 + a)``."""
    dx, dy = x2 - x1, y2 - y1
    d = math.hypot(dx, dy)
    if d < CIRCLE_TOL * max(r1, r2, 1.0):
        return []
    a = (d * d + r1 * r1 - r2 * r2) / (2 * d)
    h2 = (r1 - a) * (r1 + a)
    if h2 < -CIRCLE_TOL * max(r1 * r1, 1.0):
        return []
    ux, uy = dx / d, dy / d
    bx, by = x1 + a * ux, y1 + a * uy
    if h2 <= CIRCLE_TOL * max(r1 * r1, 1.0):
        return [(bx, by)]
    h = math.sqrt(h2)
    return [(bx - h * uy, by + h * ux), (bx + h * uy, by - h * ux)]


def newton_step(jac: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``J^{-1} f``, or the least-squares step when ``J`` is singular."""
    try:
        return np.linalg.solve(jac, f)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(jac, f, rcond=None)[0]
