"""Planar 3-RPR closed forms: IK (1 branch) and FK, every real root of a degree-6 polynomial."""

from __future__ import annotations

import math

import numpy as np

from optik import spatial
from optik.closed_form.parallel.common import (
    QUADRATIC_STOP,
    angle,
    assemble,
    coordinate_row,
    direction,
    newton_step,
    rot2,
)
from optik.closed_form.registry import register
from optik.mechanism import Mechanism

CONTINUUM_SAMPLES = 12
"""Representatives returned where the assembly modes form a continuum (architecture singularity)."""


def _rpr_q(m: Mechanism, pos: np.ndarray, phi: float) -> np.ndarray:
    b, p = m.params["base"], m.params["platform"]
    pts = pos + p @ rot2(phi).T
    legs = pts - b
    th = [angle(v) for v in legs]
    rho = np.linalg.norm(legs, axis=1)
    values = {"pin1": phi - th[0]}
    for i in range(3):
        values[f"theta{i + 1}"] = th[i]
        values[f"rho{i + 1}"] = float(rho[i])
    return assemble(m, values)


def planar_3rpr_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """3-RPR IK (one branch): ``rho_i = |t + R(phi) p_i - b_i|``, leg angles by atan2
    (`_rpr_q` on floats)."""
    return [np.array(row) for row in _planar_3rpr_rows(m, target)]


def _planar_3rpr_rows(m: Mechanism, target: np.ndarray) -> list[list[float]]:
    """`planar_3rpr_ik` as lists of floats (registered: the registry works on floats)."""
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
    return [coordinate_row(m, values)]


def _rpr_residual(b: np.ndarray, p: np.ndarray, rho: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, ...]:
    r = rot2(x[2])
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
    """`rpr_polynomial` and the magnitude ``max(|N|^2 + rho_1^2 D^2)`` of its two terms
    over the samples (to tell an identically vanishing ``F`` from a small one)."""
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
    w = d @ rot2(phi).T - e
    k = rho[1:] ** 2 - rho[0] ** 2 - np.sum(w * w, axis=1)
    i = int(np.argmax(np.linalg.norm(w, axis=1)))
    if np.linalg.norm(w[i]) <= 1e-12 * (1 + np.max(np.abs(e))):
        # W = 0: the platform is a translate of the base (congruent triangles at this heading);
        # every u on the circle |u| = rho_1 assembles when k = 0: representatives of the continuum
        if np.max(np.abs(k)) > 1e-9 * max(rho[0] ** 2, 1.0):
            return []
        return [
            b[0] + rho[0] * direction(a)
            for a in np.linspace(-np.pi, np.pi, CONTINUUM_SAMPLES, endpoint=False)
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
        step = newton_step(jac, f)
        x = x - step
        if np.max(np.abs(step)) < QUADRATIC_STOP * (1 + np.max(np.abs(x))):
            break
    v = x[:2] + p @ rot2(x[2]).T - b
    return x, float(np.max(np.abs(np.linalg.norm(v, axis=1) - rho)))


def planar_3rpr_poses(b: np.ndarray, p: np.ndarray, rho: np.ndarray, tol: float = 1e-9) -> list[np.ndarray]:
    """All real assembly modes ``(x, y, phi)`` of a 3-RPR for leg lengths ``rho`` (at most 6).

    Roots of `rpr_polynomial` in ``z = e^{i phi}`` near the unit circle give candidate
    headings (a double root may split off the circle by ``O(sqrt(eps))``, hence the loose
    filter; the centroids of root clusters are tried as well, see `_cluster_means`); each
    candidate is polished by Newton on the leg equations, kept when every leg
    length is met to ``tol`` and de-duplicated. Leading/trailing coefficients that vanish only
    remove roots at ``z = 0`` or infinity, which are never real headings.

    Architecture singularities, where the modes form a continuum, give
    `CONTINUUM_SAMPLES` representatives of it: ``F`` vanishing identically (every heading
    a root), or ``W = 0`` at a root (platform congruent to the base: every ``P_1`` on the circle
    ``|P_1 - b_1| = rho_1``).
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
        p1 = p[0] @ rot2(phi).T
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
    """3-RPR FK: every real assembly mode (see `planar_3rpr_poses`) as a full ``q``."""
    rho = np.asarray(actuated, dtype=float)
    poses = planar_3rpr_poses(m.params["base"], m.params["platform"], rho)
    return [_rpr_q(m, x[:2], float(x[2])) for x in poses]


register("planar_3rpr", ik=_planar_3rpr_rows, fk=planar_3rpr_fk)
