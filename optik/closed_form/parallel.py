"""Closed forms of the closed-chain catalog: five-bar, doggy, slider-crank, 3-RPR, Stewart-Gough.

Every solver returns **full** coordinate vectors (passive coordinates included, in the model's
coordinate order, found by coordinate name), one per branch, so that each answer can be checked
against ``m.fk`` and ``m.closure``. Geometry comes from ``m.params`` (see
[`optik.catalog.closed_chains`][optik.catalog.closed_chains]).

Branch counts: five-bar IK 4 working modes, FK 2 assembly modes; doggy IK 4 leg combinations,
FK 1; slider-crank IK 2, FK 2; 3-RPR IK 1, FK every real root of a degree-6 polynomial;
Stewart-Gough IK 1, FK every real posture (at most 40) by homotopy continuation.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from optik import spatial
from optik.closed_form import homotopy
from optik.closed_form.registry import register
from optik.mechanism import Mechanism

QUADRATIC_STOP = 1e-9
"""Newton polishing stops after a step below this (relative): with quadratic convergence the
error left after a step of size ``d`` is ``O(d^2)``, at the level of rounding."""

CONTINUUM_SAMPLES = 12
"""Representatives returned where the assembly modes form a continuum (architecture singularity)."""

CIRCLE_TOL = 1e-12
"""Relative tolerance under which a circle/circle or law-of-cosines discriminant counts as zero."""


# ----------------------------------------------------------------------------- shared helpers
def _assemble(m: Mechanism, values: Mapping[str, float]) -> np.ndarray:
    """A coordinate vector from ``{coordinate name: value}`` (every coordinate must be given)."""
    return np.array([values[name] for name in m.coordinate_names], dtype=float)


def _angle(v: np.ndarray) -> float:
    return float(np.arctan2(v[1], v[0]))


def _rot2(phi: float) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])


def _dir(phi: float) -> np.ndarray:
    return np.array([np.cos(phi), np.sin(phi)])


def two_link_ik(origin: np.ndarray, a: float, b: float, point: np.ndarray) -> list[tuple[float, float]]:
    """Both solutions of a planar 2R chain from ``origin`` with links ``a``, ``b`` reaching ``point``.

    ``point = origin + a u(theta) + b u(theta + psi)``: ``cos psi = (d^2 - a^2 - b^2) / (2 a b)``,
    ``theta = atan2(d) - atan2(b sin psi, a + b cos psi)``. Returns ``[(theta, psi), ...]``: two
    solutions, one at a boundary of the workspace (``|cos psi| = 1``), none outside.
    """
    d = np.asarray(point, dtype=float) - origin
    c = (d @ d - a * a - b * b) / (2 * a * b)
    if abs(c) > 1 + CIRCLE_TOL:
        return []
    c = float(np.clip(c, -1.0, 1.0))
    psis = [float(np.arccos(c))]
    if 1 - abs(c) > CIRCLE_TOL:
        psis.append(-psis[0])
    return [(_angle(d) - float(np.arctan2(b * np.sin(p), a + b * np.cos(p))), p) for p in psis]


def _two_link_one(
    ox: float, oy: float, a: float, b: float, px: float, py: float
) -> list[tuple[float, float]]:
    """[`two_link_ik`][optik.closed_form.parallel.two_link_ik] on floats (one target: cheaper than numpy on
    2-vectors)."""
    dx, dy = px - ox, py - oy
    c = (dx * dx + dy * dy - a * a - b * b) / (2 * a * b)
    if abs(c) > 1 + CIRCLE_TOL:
        return []
    c = min(max(c, -1.0), 1.0)
    psis = [math.acos(c)]
    if 1 - abs(c) > CIRCLE_TOL:
        psis.append(-psis[0])
    angle = math.atan2(dy, dx)
    return [(angle - math.atan2(b * math.sin(p), a + b * math.cos(p)), p) for p in psis]


def _row(m: Mechanism, values: Mapping[str, float]) -> list[float]:
    """`_assemble` as a list of floats (what the registry works on)."""
    return [values[name] for name in m.coordinate_names]


def circle_intersections(c1: np.ndarray, r1: float, c2: np.ndarray, r2: float) -> list[np.ndarray]:
    """Intersection points of two circles (two, one when tangent, none when apart or concentric)."""
    d_vec = np.asarray(c2, dtype=float) - c1
    d = float(np.linalg.norm(d_vec))
    if d < CIRCLE_TOL * max(r1, r2, 1.0):
        return []
    a = (d * d + r1 * r1 - r2 * r2) / (2 * d)
    h2 = r1 * r1 - a * a
    if h2 < -CIRCLE_TOL * max(r1 * r1, 1.0):
        return []
    u = d_vec / d
    base = c1 + a * u
    if h2 <= CIRCLE_TOL * max(r1 * r1, 1.0):
        return [base]
    h = np.sqrt(h2)
    perp = np.array([-u[1], u[0]])
    return [base + h * perp, base - h * perp]


def _newton_step(jac: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``J^{-1} f``, or the least-squares step when ``J`` is singular."""
    try:
        return np.linalg.solve(jac, f)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(jac, f, rcond=None)[0]


def _planar_pose(t: np.ndarray) -> tuple[np.ndarray, float]:
    return np.asarray(t[:2, 3], dtype=float), float(np.arctan2(t[1, 0], t[0, 0]))


# ----------------------------------------------------------------------------- five-bar
def five_bar_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """Five-bar IK: the 4 working modes for a tool position.

    Chain 1 is a 2R chain (``l1``, ``tool``) from ``A1`` to the tool point (2 solutions); it fixes
    ``P = B1 + l3 u(theta1 + psi1)``; chain 2 is a 2R chain (``l2``, ``l4``) from ``A2`` to ``P``
    (2 solutions).
    """
    return [np.array(row) for row in _five_bar_rows(m, target)]


def _five_bar_rows(m: Mechanism, target: np.ndarray) -> list[list[float]]:
    """[`five_bar_ik`][optik.closed_form.parallel.five_bar_ik] as lists of floats (registered: the registry
    works on floats)."""
    (a1x, a1y), (a2x, a2y) = m.params["base"].tolist()
    l1, l2, l3, l4 = m.params["lengths"]
    tool = m.params["tool"]
    out = []
    for th1, psi1 in _two_link_one(a1x, a1y, l1, tool, float(target[0, 3]), float(target[1, 3])):
        px = a1x + l1 * math.cos(th1) + l3 * math.cos(th1 + psi1)
        py = a1y + l1 * math.sin(th1) + l3 * math.sin(th1 + psi1)
        for th2, psi2 in _two_link_one(a2x, a2y, l2, l4, px, py):
            out.append(_row(m, {"theta1": th1, "theta2": th2, "psi1": psi1, "psi2": psi2}))
    return out


def five_bar_fk(m: Mechanism, actuated: np.ndarray) -> list[np.ndarray]:
    """Five-bar FK: the 2 assembly modes, ``P`` on both circles ``|P - B1| = l3``, ``|P - B2| = l4``."""
    b = m.params["base"]
    l1, l2, l3, l4 = m.params["lengths"]
    th1, th2 = (float(v) for v in actuated)
    b1, b2 = b[0] + l1 * _dir(th1), b[1] + l2 * _dir(th2)
    return [
        _assemble(
            m, {"theta1": th1, "theta2": th2, "psi1": _angle(p - b1) - th1, "psi2": _angle(p - b2) - th2}
        )
        for p in circle_intersections(b1, l3, b2, l4)
    ]


# ----------------------------------------------------------------------------- doggy
def _leg_end(foot: np.ndarray, legs: np.ndarray, th_a: float, th_b: float) -> np.ndarray:
    return foot + legs[0] * _dir(th_a) + legs[1] * _dir(th_a + th_b)


def doggy_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """Doggy IK from the body pose ``(xB, yB, phiB)``: hips ``A = B + R h_A``, ``C = B + R h_C``,
    then each leg is a 2R chain from its foot to its hip: 2 x 2 = 4 leg combinations."""
    return [np.array(row) for row in _doggy_rows(m, target)]


def _doggy_rows(m: Mechanism, target: np.ndarray) -> list[list[float]]:
    """[`doggy_ik`][optik.closed_form.parallel.doggy_ik] as lists of floats (registered: the registry works on
    floats)."""
    f, h, lg = m.params["feet"].tolist(), m.params["hips"].tolist(), m.params["legs"].tolist()
    bx, by = float(target[0, 3]), float(target[1, 3])
    phi = math.atan2(target[1, 0], target[0, 0])
    c, s = math.cos(phi), math.sin(phi)
    hips = [(bx + (c * hx - s * hy), by + (s * hx + c * hy)) for hx, hy in h]
    out = []
    leg2 = _two_link_one(*f[1], lg[1][0], lg[1][1], *hips[1])
    for th1, th2 in _two_link_one(*f[0], lg[0][0], lg[0][1], *hips[0]):
        for th3, th4 in leg2:
            values = {"theta1": th1, "theta2": th2, "hipA": phi - th1 - th2, "theta3": th3, "theta4": th4}
            out.append(_row(m, values))
    return out


def doggy_fk(m: Mechanism, actuated: np.ndarray, tol: float = 1e-9) -> list[np.ndarray]:
    """Doggy FK from the four leg angles: the legs place the hips ``A`` and ``C``; the body
    assembles when ``|C - A| = |h_C - h_A|`` (to ``tol``), with heading
    ``phiB = atan2(C - A) - atan2(h_C - h_A)``. Four inputs for a mobility-3 body: the inputs are
    consistent or the body does not assemble (``[]``)."""
    f, h, lg = m.params["feet"], m.params["hips"], m.params["legs"]
    th1, th2, th3, th4 = (float(v) for v in actuated)
    a = _leg_end(f[0], lg[0], th1, th2)
    c = _leg_end(f[1], lg[1], th3, th4)
    span = h[1] - h[0]
    if abs(np.linalg.norm(c - a) - np.linalg.norm(span)) > tol:
        return []
    phi = _angle(c - a) - _angle(span)
    return [
        _assemble(m, {"theta1": th1, "theta2": th2, "hipA": phi - th1 - th2, "theta3": th3, "theta4": th4})
    ]


# ----------------------------------------------------------------------------- slider-crank
def _slider_q(m: Mechanism, theta: float, alpha: float, x: float) -> np.ndarray:
    return _assemble(m, {"theta": theta, "phi": alpha - theta, "x": x})


def slider_crank_fk(m: Mechanism, actuated: np.ndarray) -> list[np.ndarray]:
    """Slider-crank FK (2 assembly modes): ``r sin(theta) + l sin(alpha) = e`` gives the rod's
    absolute angle ``alpha = asin((e - r sin theta) / l)`` or ``pi - asin(...)``, then
    ``x = r cos(theta) + l cos(alpha)``."""
    r, l, e = m.params["crank"], m.params["rod"], m.params["offset"]
    theta = float(actuated[0])
    s = (e - r * np.sin(theta)) / l
    if abs(s) > 1 + CIRCLE_TOL:
        return []
    a0 = float(np.arcsin(np.clip(s, -1.0, 1.0)))
    alphas = [a0] if 1 - abs(s) <= CIRCLE_TOL else [a0, np.pi - a0]
    return [_slider_q(m, theta, a, r * np.cos(theta) + l * np.cos(a)) for a in alphas]


def slider_crank_ik(m: Mechanism, target: np.ndarray, tol: float = 1e-9) -> list[np.ndarray]:
    """Slider-crank IK for a piston position ``(x, e)`` (2 branches): the crank pin lies on the
    circles ``|B| = r`` and ``|B - (x, e)| = l``. A target off the line ``y = e`` is unreachable."""
    r, l, e = m.params["crank"], m.params["rod"], m.params["offset"]
    x, y = float(target[0, 3]), float(target[1, 3])
    if abs(y - e) > tol:
        return []
    piston = np.array([x, e])
    return [
        _slider_q(m, _angle(b), _angle(piston - b), x)
        for b in circle_intersections(np.zeros(2), r, piston, l)
    ]


# ----------------------------------------------------------------------------- 3-RPR
def _rpr_q(m: Mechanism, pos: np.ndarray, phi: float) -> np.ndarray:
    b, p = m.params["base"], m.params["platform"]
    pts = pos + p @ _rot2(phi).T
    legs = pts - b
    th = [_angle(v) for v in legs]
    rho = np.linalg.norm(legs, axis=1)
    values = {"pin1": phi - th[0]}
    for i in range(3):
        values[f"theta{i + 1}"] = th[i]
        values[f"rho{i + 1}"] = float(rho[i])
    return _assemble(m, values)


def planar_3rpr_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """3-RPR IK (one branch): ``rho_i = |t + R(phi) p_i - b_i|``, leg angles by atan2
    (`_rpr_q` on floats)."""
    return [np.array(row) for row in _planar_3rpr_rows(m, target)]


def _planar_3rpr_rows(m: Mechanism, target: np.ndarray) -> list[list[float]]:
    """[`planar_3rpr_ik`][optik.closed_form.parallel.planar_3rpr_ik] as lists of floats (registered: the
    registry works on floats)."""
    tx, ty = float(target[0, 3]), float(target[1, 3])
    phi = math.atan2(target[1, 0], target[0, 0])
    c, s = math.cos(phi), math.sin(phi)
    values = {}
    for i, ((bx, by), (px, py)) in enumerate(
        zip(m.params["base"].tolist(), m.params["platform"].tolist(), strict=True)
    ):
        lx, ly = tx + (px * c - py * s) - bx, ty + (px * s + py * c) - by
        values[f"theta{i + 1}"] = math.atan2(ly, lx)
        values[f"rho{i + 1}"] = math.sqrt(lx * lx + ly * ly)
    values["pin1"] = phi - values["theta1"]
    return [_row(m, values)]


def _rpr_residual(b: np.ndarray, p: np.ndarray, rho: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, ...]:
    r = _rot2(x[2])
    rp = p @ r.T
    v = x[:2] + rp - b
    f = np.sum(v * v, axis=1) - rho * rho
    jac = 2 * np.column_stack([v, _cross2(rp, v)])
    return f, jac


def _cross2(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v . (d/dphi R p) = v . (-(Rp)_y, (Rp)_x)`` row-wise."""
    return -v[:, 0] * a[:, 1] + v[:, 1] * a[:, 0]


def rpr_polynomial(b: np.ndarray, p: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Coefficients ``c_k`` (``k = -3..3``, ascending) of the trigonometric polynomial
    ``F(phi) = sum_k c_k e^{i k phi}`` whose real roots are the 3-RPR assembly modes.

    With ``u = P_1 - b_1`` (``P_i`` the platform points in the world), ``d_i = p_i - p_1``,
    ``e_i = b_i - b_1`` and ``w_i(phi) = R(phi) d_i - e_i``, the leg equations are
    ``|u|^2 = rho_1^2`` and ``2 w_i . u = rho_i^2 - rho_1^2 - |w_i|^2 =: k_i`` (``i = 2, 3``), linear
    in ``u``. Cramer's rule gives ``u = N(phi) / D(phi)`` with ``N = adj(W) k``, ``D = 2 det W``,
    and ``F = |N|^2 - rho_1^2 D^2``. ``F`` has degree 4 in ``(cos phi, sin phi)``, but its
    ``e^{+-4 i phi}`` terms cancel (the circular points), which leaves degree 3: ``e^{3 i phi} F``
    is the degree-6 polynomial in ``z = e^{i phi}``. The coefficients are read off exactly from
    16 samples by the FFT.
    """
    return _rpr_coefficients(b, p, rho)[0]


def _rpr_coefficients(b: np.ndarray, p: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, float]:
    """[`rpr_polynomial`][optik.closed_form.parallel.rpr_polynomial] and the magnitude ``max(|N|^2 + rho_1^2
    D^2)`` of its two terms over the samples (to tell an identically vanishing ``F`` from a small one)."""
    phis = 2 * np.pi * np.arange(16) / 16
    d, e = p[1:] - p[0], b[1:] - b[0]
    c, s = np.cos(phis), np.sin(phis)
    rd = np.stack(
        [c[:, None] * d[:, 0] - s[:, None] * d[:, 1], s[:, None] * d[:, 0] + c[:, None] * d[:, 1]], -1
    )
    w = rd - e  # (16, 2, 2): sample, leg, xy
    k = rho[1:] ** 2 - rho[0] ** 2 - np.sum(w * w, axis=2)
    det = w[:, 0, 0] * w[:, 1, 1] - w[:, 0, 1] * w[:, 1, 0]
    nx = w[:, 1, 1] * k[:, 0] - w[:, 0, 1] * k[:, 1]
    ny = -w[:, 1, 0] * k[:, 0] + w[:, 0, 0] * k[:, 1]
    f = nx * nx + ny * ny - rho[0] ** 2 * (2 * det) ** 2
    magnitude = float(np.max(nx * nx + ny * ny + rho[0] ** 2 * (2 * det) ** 2))
    coef = np.fft.fft(f) / 16  # coef[k % 16] multiplies e^{i k phi}
    return np.array([coef[k % 16] for k in range(-3, 4)]), magnitude


def _cluster_means(roots: np.ndarray, radius: float = 1e-3) -> np.ndarray:
    """Centroids of clusters of roots closer than ``radius``: a root of multiplicity ``k``
    splits by ``O(eps^(1/k))`` under rounding, but the centroid of the cluster stays accurate."""
    means = []
    for z in roots:
        near = roots[np.abs(roots - z) < radius]
        if len(near) > 1:
            mean = near.mean()
            if not any(abs(mean - w) < 1e-12 for w in means):
                means.append(mean)
    return np.array(means, dtype=complex)


def _rpr_candidates(b: np.ndarray, p: np.ndarray, rho: np.ndarray, phi: float) -> list[np.ndarray]:
    """Platform positions ``P_1`` for a heading: Cramer's rule; when ``W`` is singular the line
    ``2 w . u = k`` of the stronger row intersected with the circle ``|u| = rho_1``; when
    ``W = 0``, representatives of the circle."""
    d, e = p[1:] - p[0], b[1:] - b[0]
    w = d @ _rot2(phi).T - e
    k = rho[1:] ** 2 - rho[0] ** 2 - np.sum(w * w, axis=1)
    i = int(np.argmax(np.linalg.norm(w, axis=1)))
    if np.linalg.norm(w[i]) <= 1e-12 * (1 + np.max(np.abs(e))):
        # W = 0: the platform is a translate of the base (congruent triangles at this heading);
        # every u on the circle |u| = rho_1 assembles when k = 0: representatives of the continuum
        if np.max(np.abs(k)) > 1e-9 * max(rho[0] ** 2, 1.0):
            return []
        return [
            b[0] + rho[0] * _dir(a) for a in np.linspace(-np.pi, np.pi, CONTINUUM_SAMPLES, endpoint=False)
        ]
    det = w[0, 0] * w[1, 1] - w[0, 1] * w[1, 0]
    if abs(det) > 1e-9 * max(float(np.sum(w * w)), 1e-300):  # Cramer's rule on 2 W u = k
        return [
            b[0] + np.array([w[1, 1] * k[0] - w[0, 1] * k[1], w[0, 0] * k[1] - w[1, 0] * k[0]]) / (2 * det)
        ]
    n = w[i] / np.linalg.norm(w[i])
    dist = k[i] / (2 * np.linalg.norm(w[i]))
    h2 = rho[0] ** 2 - dist**2
    if h2 < 0:
        return []
    t = np.array([-n[1], n[0]])
    return [b[0] + dist * n + sgn * np.sqrt(h2) * t for sgn in (1.0, -1.0)]


def polish_planar_3rpr(
    b: np.ndarray, p: np.ndarray, rho: np.ndarray, x: np.ndarray, iters: int = 8
) -> tuple[np.ndarray, float]:
    """Newton on the leg equations ``|t + R p_i - b_i|^2 = rho_i^2`` in ``x = (t_x, t_y, phi)``.

    Returns the polished pose and the max leg-length error ``max_i | |t + R p_i - b_i| - rho_i |``.
    """
    for _ in range(iters):
        f, jac = _rpr_residual(b, p, rho, x)
        if np.max(np.abs(f)) <= 1e-15 * (1 + np.max(rho) ** 2):
            break  # already exact (also keeps points of a continuum, where J is singular)
        step = _newton_step(jac, f)
        x = x - step
        if np.max(np.abs(step)) < QUADRATIC_STOP * (1 + np.max(np.abs(x))):
            break
    v = x[:2] + p @ _rot2(x[2]).T - b
    return x, float(np.max(np.abs(np.linalg.norm(v, axis=1) - rho)))


def planar_3rpr_poses(b: np.ndarray, p: np.ndarray, rho: np.ndarray, tol: float = 1e-9) -> list[np.ndarray]:
    """All real assembly modes ``(x, y, phi)`` of a 3-RPR for leg lengths ``rho`` (at most 6).

    Roots of [`rpr_polynomial`][optik.closed_form.parallel.rpr_polynomial] in ``z = e^{i phi}`` near the unit
    circle give candidate headings (a double root may split off the circle by ``O(sqrt(eps))``, hence the
    loose filter; the centroids of root clusters are tried as well, see `_cluster_means`); each candidate is
    polished by Newton on the leg equations, kept when every leg length is met to ``tol`` and de-duplicated.
    Leading/trailing coefficients that vanish only remove roots at ``z = 0`` or infinity, which are never real
    headings.

    Architecture singularities, where the modes form a continuum, give
    [`CONTINUUM_SAMPLES`][optik.closed_form.parallel.CONTINUUM_SAMPLES] representatives of it: ``F`` vanishing
    identically (every heading a root), or ``W = 0`` at a root (platform congruent to the base: every ``P_1``
    on the circle ``|P_1 - b_1| = rho_1``).
    """
    coef, magnitude = _rpr_coefficients(b, p, rho)
    scale = np.max(np.abs(coef))
    if scale <= 1e-12 * magnitude:
        # F vanishes identically (architecture singularity): every heading is a root
        roots = np.exp(1j * np.linspace(-np.pi, np.pi, CONTINUUM_SAMPLES, endpoint=False))
    else:
        nz = np.flatnonzero(np.abs(coef) > 1e-13 * scale)
        trimmed = coef[nz[0] : nz[-1] + 1]
        roots = np.roots(trimmed[::-1]) if len(trimmed) > 1 else np.zeros(0)
        roots = np.concatenate([roots, _cluster_means(roots)])
    size = float(np.max(np.abs(b)) + np.max(np.abs(p)) + np.max(rho))
    poses: list[np.ndarray] = []
    for z in roots:
        if abs(np.log(abs(z))) > 1e-3:
            continue
        phi = float(np.angle(z))
        p1 = p[0] @ _rot2(phi).T
        for u in _rpr_candidates(b, p, rho, phi):
            x, err = polish_planar_3rpr(b, p, rho, np.array([*(u - p1), phi]))
            if err > tol * max(size, 1.0):
                continue
            x[2] = float(spatial.wrap_angle(x[2]))
            if all(
                np.linalg.norm(x[:2] - y[:2]) > 1e-7 * size or abs(spatial.wrap_angle(x[2] - y[2])) > 1e-7
                for y in poses
            ):
                poses.append(x)
    return poses


def planar_3rpr_fk(m: Mechanism, actuated: np.ndarray) -> list[np.ndarray]:
    """3-RPR FK: every real assembly mode (see
    [`planar_3rpr_poses`][optik.closed_form.parallel.planar_3rpr_poses]) as a full ``q``."""
    rho = np.asarray(actuated, dtype=float)
    poses = planar_3rpr_poses(m.params["base"], m.params["platform"], rho)
    return [_rpr_q(m, x[:2], float(x[2])) for x in poses]


# ----------------------------------------------------------------------------- Stewart-Gough
def quat_left(a: np.ndarray) -> np.ndarray:
    """``L(a)`` with ``a * b = L(a) b`` (Hamilton product, scalar first)."""
    a0, a1, a2, a3 = a
    return np.array([[a0, -a1, -a2, -a3], [a1, a0, -a3, a2], [a2, a3, a0, -a1], [a3, -a2, a1, a0]])


def quat_right(b: np.ndarray) -> np.ndarray:
    """``R(b)`` with ``a * b = R(b) a`` (Hamilton product, scalar first)."""
    b0, b1, b2, b3 = b
    return np.array([[b0, -b1, -b2, -b3], [b1, b0, b3, -b2], [b2, -b3, b0, b1], [b3, b2, -b1, b0]])


def quat_to_rot(e: np.ndarray) -> np.ndarray:
    """Rotation matrix of a (not necessarily unit) quaternion ``e = (e0, e1, e2, e3)``."""
    w, x, y, z = np.asarray(e, dtype=float) / np.linalg.norm(e)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def stewart_quadrics(b: np.ndarray, p: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """The Stewart-Gough FK as 7 homogeneous quadrics in Study's coordinates ``z = (e, g)``.

    The pose is ``R = R(e)``, ``t = 2 vec(g e*) / |e|^2`` (``g = t e / 2``). The Study quadric
    ``e . g = 0`` and, for each leg, ``|R p + t - b|^2 = rho^2`` times ``|e|^2``:

    ``(|p|^2 + |b|^2 - rho^2) |e|^2 - 2 <b e, e p> + 4 <e p - b e, g> + 4 |g|^2 = 0``

    (``b``, ``p`` as pure quaternions; ``<.,.>`` the Euclidean product of R^4). Each leg
    quadric is scaled to unit Frobenius norm.
    """
    mats = np.zeros((7, 8, 8))
    mats[0, :4, 4:] = mats[0, 4:, :4] = 0.5 * np.eye(4)
    for i in range(6):
        lb, rp = quat_left(np.r_[0.0, b[i]]), quat_right(np.r_[0.0, p[i]])
        a = lb.T @ rp
        c = p[i] @ p[i] + b[i] @ b[i] - rho[i] ** 2
        mt = np.zeros((8, 8))
        mt[:4, :4] = c * np.eye(4) - (a + a.T)
        mt[4:, :4] = 2 * (rp - lb)
        mt[:4, 4:] = mt[4:, :4].T
        mt[4:, 4:] = 4 * np.eye(4)
        mats[i + 1] = mt / np.linalg.norm(mt)
    return mats


def _sg_residual(b: np.ndarray, p: np.ndarray, rho: np.ndarray, r: np.ndarray, t: np.ndarray):
    rp = p @ r.T
    v = rp + t - b
    f = np.sum(v * v, axis=1) - rho * rho
    jac = 2 * np.hstack([v, np.cross(rp, v)])
    return f, jac


def polish_stewart(
    b: np.ndarray, p: np.ndarray, rho: np.ndarray, r: np.ndarray, t: np.ndarray, iters: int = 8
) -> tuple[np.ndarray, np.ndarray, float]:
    """Newton on the six leg equations in ``(t, w)`` with ``R <- exp([w]x) R``.

    Returns ``(R, t, max leg-length error)``.
    """
    for _ in range(iters):
        f, jac = _sg_residual(b, p, rho, r, t)
        if np.max(np.abs(f)) <= 1e-15 * (1 + np.max(rho) ** 2):
            break
        step = _newton_step(jac, f)
        t = t - step[:3]
        r = spatial.so3_exp(-step[3:]) @ r
        if np.max(np.abs(step)) < QUADRATIC_STOP * (1 + np.max(np.abs(t))):
            break
    v = p @ r.T + t - b
    return r, t, float(np.max(np.abs(np.linalg.norm(v, axis=1) - rho)))


def stewart_jacobian(b: np.ndarray, p: np.ndarray, r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The 6x6 inverse-kinematics Jacobian: row ``i`` is ``[n_i, (R p_i) x n_i]`` with ``n_i`` the
    unit leg direction (``d rho = J [dt; w]``); singular postures have ``det J = 0``."""
    rp = p @ r.T
    v = rp + t - b
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    return np.hstack([n, np.cross(rp, n)])


def _stewart_q(m: Mechanism, r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Full coordinates of a Stewart-Gough posture ``(R, t)``.

    Leg ``i``: ``rho_i = |v_i|``, ``v_i = R p_i + t - b_i``; the universal joint turns the leg's
    z axis onto ``n = v_i / rho_i``: ``Rx(a) Ry(c) e_z = (sin c, -sin a cos c, cos a cos c)``, so
    ``c = asin(n_x)`` in ``[-pi/2, pi/2]`` and ``a = atan2(-n_y, n_z)``. The spherical joint of
    leg 1 is the rotation vector ``log(R_u1^T R)`` (angle in ``[0, pi]``: every posture,
    half-turns included, has coordinates).
    """
    b, p = m.params["base"], m.params["platform"]
    values: dict[str, float] = {}
    r_u1 = np.eye(3)
    # per leg on floats (six legs: numpy on 3-vectors costs more than the arithmetic)
    for i, (vx, vy, vz) in enumerate((p @ r.T + t - b).tolist()):
        rho = math.sqrt(vx * vx + vy * vy + vz * vz)
        nx, ny, nz = vx / rho, vy / rho, vz / rho
        c = math.asin(min(max(nx, -1.0), 1.0))
        a = math.atan2(-ny, nz) if math.hypot(ny, nz) > 1e-15 else 0.0
        values[f"u{i + 1}[0]"], values[f"u{i + 1}[1]"], values[f"rho{i + 1}"] = a, c, rho
        if i == 0:  # Rot(x, a) Rot(y, c)
            ca, sa, cc, sc = math.cos(a), math.sin(a), math.cos(c), math.sin(c)
            r_u1 = np.array([[cc, 0.0, sc], [sa * sc, ca, -sa * cc], [-ca * sc, sa, ca * cc]])
    s1 = _so3_log_one((r_u1.T @ r).tolist())
    for k in range(3):
        values[f"s1[{k}]"] = float(s1[k])
    return _assemble(m, values)


def _so3_log_one(r: list[list[float]]) -> list[float]:
    """[`optik.spatial.so3_log`][optik.spatial.so3_log] of one rotation on floats (the same formulas; within
    1e-3 of a half-turn, where the axis comes from the symmetric part, it calls ``so3_log``)."""
    sx, sy, sz = r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]
    theta = math.atan2(
        0.5 * math.sqrt(sx * sx + sy * sy + sz * sz), 0.5 * (r[0][0] + r[1][1] + r[2][2] - 1.0)
    )
    if theta > np.pi - 1e-3:
        return spatial.so3_log(np.array(r)).tolist()
    coef = 0.5 * (1 + theta**2 / 6) if theta < 1e-6 else theta / (2 * math.sin(theta))
    return [2 * coef * (v / 2.0) for v in (sx, sy, sz)]


def stewart_gough_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """Stewart-Gough IK (one branch): leg lengths ``rho_i = |R p_i + t - b_i|`` and the passive
    joint angles of `_stewart_q`."""
    return [_stewart_q(m, target[:3, :3], target[:3, 3])]


@dataclass(frozen=True)
class StewartFK:
    """All real postures of a Stewart-Gough platform and how they were found.

    Attributes:
        poses: real postures ``(R, t)``, each polished to leg-length error <= ``tol``.
        complex_solutions: distinct nonsingular complex solutions found (40 for a general 6-6).
        paths: number of tracked homotopy paths (128 per round).
        rounds: tracking rounds used (a new round uses a fresh ``gamma`` and patch).
        complete: every path was accounted for (nonsingular end point or the degenerate set
            ``e = 0``) with no two paths at the same end point, or 40 solutions were found.
        solve_time: wall time (s).
    """

    poses: list[tuple[np.ndarray, np.ndarray]]
    complex_solutions: int
    paths: int
    rounds: int
    complete: bool
    solve_time: float


GENERAL_STEWART_SOLUTIONS = 40
"""Number of complex assembly modes of a general 6-6 Stewart-Gough platform (Raghavan 1993;
Ronga and Vust; Lazard; Mourrain; Husty 1996): an upper bound on the isolated solutions."""


DEGENERATE_E = 0.1
"""End points with ``|e| / |z|`` below this are not real postures: after scaling the geometry to
unit size (``|b_i|, |p_i|, rho_i <= 1``) a real posture has ``|t| <= 3`` and, with
``g = t e / 2``, ``|e| / |z| = 1 / sqrt(1 + |t|^2 / 4) >= 0.55``. Paths to the degenerate set
``e = 0`` end below it."""


def _e_part(z: np.ndarray) -> np.ndarray:
    return np.linalg.norm(z[:, :4], axis=1) / np.linalg.norm(z, axis=1)


def _entered_degenerate_set(z: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Paths with ``t < 1e-3`` and ``|e| / |z| < DEGENERATE_E / 2``: a path to a real posture
    (``|e| / |z| >= 0.55``) moves by ``O(t)`` near its nonsingular end and cannot be here."""
    return (t < 1e-3) & (_e_part(z) < DEGENERATE_E / 2)


def _projective_same(u: np.ndarray, v: np.ndarray, tol: float = 1e-7) -> bool:
    return bool(1 - abs(np.vdot(u, v)) / (np.linalg.norm(u) * np.linalg.norm(v)) < tol)


def stewart_poses(
    b: np.ndarray,
    p: np.ndarray,
    rho: np.ndarray,
    *,
    seed: int | np.random.Generator = 0,
    time_limit: float = 5.0,
    max_rounds: int = 3,
    tol: float = 1e-9,
) -> StewartFK:
    """Every real posture of a Stewart-Gough platform by homotopy continuation (all 40 complex).

    The leg equations in Study's coordinates
    ([`stewart_quadrics`][optik.closed_form.parallel.stewart_quadrics]) are 7 quadrics in ``P^7``;
    [`optik.closed_form.homotopy.track`][optik.closed_form.homotopy.track] follows all ``2^7 = 128`` paths
    from a total-degree start system (gamma trick). With probability one every isolated nonsingular solution
    ends a path; the other paths end on the degenerate set ``e = 0`` (where all leg quadrics reduce to ``|g|^2
    = 0``). A round is *complete* when every path is accounted for and no two paths share an end point (a
    shared end point reveals path jumping); finding 40 distinct solutions proves completeness outright, since
    40 bounds the isolated solutions. Otherwise a new round (fresh gamma and patch) is tracked and the
    solutions merged, up to ``max_rounds``. Real solutions (``max |Im|`` small after fixing the projective
    phase) are polished by Newton on the real leg equations and kept when every leg length is met to ``tol``
    (relative to the platform size).
    """
    start = time.perf_counter()
    rng = np.random.default_rng(seed) if not isinstance(seed, np.random.Generator) else seed
    size = float(max(np.max(np.linalg.norm(b, axis=1)), np.max(np.linalg.norm(p, axis=1)), np.max(rho)))
    mats = stewart_quadrics(b / size, p / size, rho / size)
    sols: list[np.ndarray] = []
    complete, rounds, paths = False, 0, 0
    while rounds < max_rounds and not complete:
        remaining = time_limit - (time.perf_counter() - start)
        if remaining <= 0:
            break
        rounds += 1
        res = homotopy.track(mats, rng, time_limit=remaining, abandon=_entered_degenerate_set)
        paths += len(res.z)
        z = homotopy.refine(mats, res.z)
        norm2 = np.sum(np.abs(z) ** 2, axis=1)
        val = np.abs(np.einsum("kij,pi,pj->pk", mats, z, z)).max(axis=1) / norm2
        e_part = _e_part(z)
        candidate = (e_part > DEGENERATE_E) & (val < 1e-8)
        well_conditioned = candidate & res.converged & (res.condition < 1e8)
        before = len(sols)
        ends: list[np.ndarray] = []
        jumped = False
        for v, sharp in zip(z[candidate], well_conditioned[candidate], strict=True):
            seen = any(_projective_same(v, u) for u in ends)
            jumped |= seen and bool(sharp)
            if not seen:
                ends.append(v)
        sols += [v for v in ends if not any(_projective_same(v, u) for u in sols)]
        clean = not jumped and bool(np.all(candidate | (e_part <= DEGENERATE_E)))
        agreed = rounds > 1 and len(sols) == before
        complete = len(sols) >= GENERAL_STEWART_SOLUTIONS or clean or agreed
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    for v in sols:
        w = v / v[int(np.argmax(np.abs(v[:4])))]
        if np.max(np.abs(w.imag)) > 1e-5 * np.max(np.abs(w)):
            continue
        e, g = w.real[:4], w.real[4:]
        e_conj = e * np.array([1.0, -1.0, -1.0, -1.0])
        t = 2 * (quat_left(g) @ e_conj)[1:] / (e @ e)
        r, t, err = polish_stewart(b, p, rho, quat_to_rot(e), t * size)
        if err > tol * max(size, 1.0):
            continue
        if all(
            np.linalg.norm(t - t2) > 1e-7 * size or spatial.angle_between(r, r2) > 1e-7 for r2, t2 in poses
        ):
            poses.append((r, t))
    return StewartFK(poses, len(sols), paths, rounds, complete, time.perf_counter() - start)


def stewart_gough_fk(m: Mechanism, actuated: np.ndarray) -> list[np.ndarray]:
    """Stewart-Gough FK: every real posture ([`stewart_poses`][optik.closed_form.parallel.stewart_poses]) as a
    full ``q``.

    Warns (``RuntimeWarning``) when the homotopy could not certify completeness within its
    time limit, so that a possibly missing posture never goes unnoticed.
    """
    fk = stewart_poses(m.params["base"], m.params["platform"], np.asarray(actuated, dtype=float))
    if not fk.complete:
        warnings.warn(
            f"Stewart-Gough FK: completeness not certified after {fk.rounds} homotopy round(s) "
            f"({fk.complex_solutions} complex solutions found); a real posture may be missing",
            RuntimeWarning,
            stacklevel=2,
        )
    return [_stewart_q(m, r, t) for r, t in fk.poses]


register("five_bar", ik=_five_bar_rows, fk=five_bar_fk)
register("doggy", ik=_doggy_rows, fk=doggy_fk)
register("slider_crank", ik=slider_crank_ik, fk=slider_crank_fk)
register("planar_3rpr", ik=_planar_3rpr_rows, fk=planar_3rpr_fk)
register("stewart_gough", ik=stewart_gough_ik, fk=stewart_gough_fk)
