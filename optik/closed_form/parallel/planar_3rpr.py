"""Planar 3-RPR closed forms: IK (1 branch) and FK, every real root of a degree-6 polynomial.

The FK runs in C (``planar_3rpr.c``, compiled once per machine in the background by
`optik.native.CFunction`): the same coefficients, Cramer start, Newton polish, acceptance and
de-duplication as `planar_3rpr_poses`, with the real roots isolated on the unit circle by
certified bounds on ``F`` and ``F'`` instead of ``numpy.roots``. The C code hands the call back
to `planar_3rpr_poses` wherever the bounds cannot decide (two roots or a complex pair within
about 1e-3 rad of each other on the circle) and at the architecture singularities; without a C
compiler, or while the library builds, `planar_3rpr_poses` answers every call.
"""

from __future__ import annotations

import ctypes
import math
import threading
from pathlib import Path

import numpy as np

from optik import native
from optik.closed_form.parallel.common import (
    QUADRATIC_STOP,
    coordinate_row,
    direction,
    rot2,
)
from optik.closed_form.registry import register
from optik.mechanism import Mechanism
from optik.spatial import wrap_angle

CONTINUUM_SAMPLES = 12
"""Representatives returned where the assembly modes form a continuum (architecture singularity)."""

POSE_TOL = 1e-9
"""Relative leg-length tolerance under which a polished candidate is an assembly mode."""

SOURCE = Path(__file__).with_name("planar_3rpr.c")
"""The C kernel of the FK (`optik_rpr_fk`)."""

COORDINATES = ("theta1", "rho1", "pin1", "theta2", "rho2", "theta3", "rho3")
"""The order of the coordinates in the C kernel's rows (the catalog's)."""

_MAX_MODES = 12  # MAX_MODES of the C kernel


_KERNEL = native.CFunction(SOURCE, "optik_planar_3rpr", "optik_rpr_fk", [ctypes.c_void_p, ctypes.c_void_p])


class _Buffers(threading.local):
    """One thread's input and output buffers of the kernel, with their addresses."""

    def __init__(self) -> None:
        self.data = np.empty(16)
        self.out = np.empty(1 + 7 * _MAX_MODES)
        self.args = (self.data.ctypes.data, self.out.ctypes.data)


_BUFFERS = _Buffers()


def compiled_rows(b: np.ndarray, p: np.ndarray, rho: np.ndarray, tol: float = POSE_TOL) -> np.ndarray | None:
    """Every assembly mode as rows ``(theta1, rho1, pin1, theta2, rho2, theta3, rho3)`` (`_pose_row`
    of each pose of `planar_3rpr_poses`, ``pin1`` not wrapped), from the C kernel; None when it is
    not loaded or hands the call back (an undecided root interval, an architecture singularity)."""
    fn = _KERNEL.get()
    if fn is None:
        return None
    buffers = _BUFFERS
    data = buffers.data
    data[:6] = b.reshape(-1)
    data[6:12] = p.reshape(-1)
    data[12:15] = rho
    data[15] = tol
    if fn(*buffers.args) != 0:
        return None
    out = buffers.out
    return out[1 : 1 + 7 * int(out[0])].reshape(-1, 7).copy()


def planar_3rpr_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """3-RPR IK (one branch): ``rho_i = |t + R(phi) p_i - b_i|``, leg angles by atan2
    (`_rpr_q` on floats)."""
    return [np.array(row) for row in _planar_3rpr_rows(m, target)]


def _planar_3rpr_rows(m: Mechanism, target: np.ndarray) -> list[list[float]]:
    """`planar_3rpr_ik` as lists of floats (registered: the registry works on floats)."""
    phi = math.atan2(target[1, 0], target[0, 0])
    return [_pose_row(m, float(target[0, 3]), float(target[1, 3]), phi)]


def _pose_row(m: Mechanism, tx: float, ty: float, phi: float) -> list[float]:
    """Full coordinates (floats) of the platform pose ``(tx, ty, phi)``: leg vectors
    ``l_i = t + R(phi) p_i - b_i``, ``theta_i = atan2(l_i)``, ``rho_i = |l_i|``,
    ``pin1 = phi - theta1``."""
    c, s = math.cos(phi), math.sin(phi)
    values = {}
    for i, ((bx, by), (px, py)) in enumerate(
        zip(m.params["base"].tolist(), m.params["platform"].tolist(), strict=True)
    ):
        lx, ly = tx + (px * c - py * s) - bx, ty + (px * s + py * c) - by
        values[f"theta{i + 1}"] = math.atan2(ly, lx)
        values[f"rho{i + 1}"] = math.sqrt(lx * lx + ly * ly)
    values["pin1"] = phi - values["theta1"]
    return coordinate_row(m, values)


def rpr_polynomial(b: np.ndarray, p: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Coefficients ``c_k`` (``k = -3..3``, ascending) of the trigonometric polynomial
    ``F(phi) = sum_k c_k e^{i k phi}`` whose real roots are the 3-RPR assembly modes.

    With ``u = P_1 - b_1`` (``P_i`` the platform points in the world), ``d_i = p_i - p_1``,
    ``e_i = b_i - b_1`` and ``w_i(phi) = R(phi) d_i - e_i``, the leg equations are
    ``|u|^2 = rho_1^2`` and ``2 w_i . u = rho_i^2 - rho_1^2 - |w_i|^2 =: k_i`` (``i = 2, 3``), linear
    in ``u``. Cramer's rule gives ``u = N(phi) / D(phi)`` with ``N = adj(W) k``, ``D = 2 det W``,
    and ``F = |N|^2 - rho_1^2 D^2``. ``F`` has degree 4 in ``(cos phi, sin phi)``, but its
    ``e^{+-4 i phi}`` terms cancel (the circular points), which leaves degree 3: ``e^{3 i phi} F``
    is the degree-6 polynomial in ``z = e^{i phi}``. The coefficients are computed exactly by
    products of Laurent polynomials in ``z``.
    """
    return _rpr_coefficients(b, p, rho)[0]


def _rpr_coefficients(b: np.ndarray, p: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, float]:
    """`rpr_polynomial` and the magnitude of its two terms (the larger coefficient sum of
    ``|N|^2`` and ``rho_1^2 D^2``, to tell an identically vanishing ``F`` from a small one).

    Exact products of Laurent polynomials in ``z = e^{i phi}`` on floats (``cos phi =
    (z + 1/z) / 2``, ``sin phi = (z - 1/z) / 2i``): ``w_i`` and ``k_i`` have degree 1, ``det W``
    and ``N`` degree 2, ``F`` degree 4 before the cancellation of its outer terms.
    """
    (b0x, b0y), (p0x, p0y) = b[0].tolist(), p[0].tolist()
    r0 = float(rho[0])
    w, k = [], []
    for i in (1, 2):
        dx, dy = float(p[i][0]) - p0x, float(p[i][1]) - p0y
        ex, ey = float(b[i][0]) - b0x, float(b[i][1]) - b0y
        rdx = [0.5 * dx - 0.5j * dy, 0j, 0.5 * dx + 0.5j * dy]  # (R d)_x; powers -1, 0, 1
        rdy = [0.5 * dy + 0.5j * dx, 0j, 0.5 * dy - 0.5j * dx]  # (R d)_y
        w.append(([rdx[0], -ex, rdx[2]], [rdy[0], -ey, rdy[2]]))
        e_rd = 2 * (ex * rdx[0] + ey * rdy[0])  # 2 e . R d, power -1 (power 1: its conjugate)
        base = float(rho[i]) ** 2 - r0 * r0 - dx * dx - dy * dy - ex * ex - ey * ey
        k.append([e_rd, base + 0j, e_rd.conjugate()])
    (w1x, w1y), (w2x, w2y) = w
    det2 = [2 * (u - v) for u, v in zip(_mul(w1x, w2y), _mul(w1y, w2x), strict=True)]
    nx = [u - v for u, v in zip(_mul(w2y, k[0]), _mul(w1y, k[1]), strict=True)]
    ny = [u - v for u, v in zip(_mul(w1x, k[1]), _mul(w2x, k[0]), strict=True)]
    n2 = [u + v for u, v in zip(_mul(nx, nx), _mul(ny, ny), strict=True)]
    d2 = [r0 * r0 * v for v in _mul(det2, det2)]
    coef = np.array([u - v for u, v in zip(n2[1:8], d2[1:8], strict=True)])  # powers -3..3
    return coef, max(sum(abs(v) for v in n2), sum(abs(v) for v in d2))


def _mul(a: list[complex], b: list[complex]) -> list[complex]:
    """Product of two Laurent polynomials given by centred coefficient lists."""
    out = [0j] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


def _cluster_means(roots: np.ndarray, radius: float = 1e-3) -> np.ndarray:
    """Centroids of clusters of roots closer than ``radius``: a root of multiplicity ``k``
    splits by ``O(eps^(1/k))`` under rounding, but the centroid of the cluster stays accurate."""
    gaps = np.abs(roots[:, None] - roots[None, :]) + np.eye(len(roots)) * radius
    if len(roots) < 2 or np.min(gaps) >= radius:
        return np.zeros(0, dtype=complex)  # the usual case: simple, separated roots
    means = []
    for z in roots:
        near = roots[np.abs(roots - z) < radius]
        if len(near) > 1:
            mean = near.mean()
            if not any(abs(mean - w) < 1e-12 for w in means):
                means.append(mean)
    return np.array(means, dtype=complex)


def _cramer_one(bl: list, pl: list, rho: list, phi: float) -> tuple[float, float] | None:
    """``P_1`` for a heading by Cramer's rule on ``2 W u = k`` in floats (see `rpr_polynomial`);
    None when ``W`` vanishes or is (nearly) singular."""
    c, s = math.cos(phi), math.sin(phi)
    (b0x, b0y), (p0x, p0y) = bl[0], pl[0]
    w, k = [], []
    for i in (1, 2):
        dx, dy = pl[i][0] - p0x, pl[i][1] - p0y
        wx, wy = c * dx - s * dy - (bl[i][0] - b0x), s * dx + c * dy - (bl[i][1] - b0y)
        w.append((wx, wy))
        k.append(rho[i] * rho[i] - rho[0] * rho[0] - wx * wx - wy * wy)
    (w1x, w1y), (w2x, w2y) = w
    det = w1x * w2y - w1y * w2x
    w2 = w1x * w1x + w1y * w1y + w2x * w2x + w2y * w2y
    e_max = max(abs(v - o) for row in bl[1:] for v, o in zip(row, bl[0], strict=True))
    if w2 <= (1e-12 * (1 + e_max)) ** 2 or not abs(det) > 1e-9 * w2:
        return None  # W = 0 (a continuum) or singular: `_rpr_candidates` handles both
    return b0x + (w2y * k[0] - w1y * k[1]) / (2 * det), b0y + (w1x * k[1] - w2x * k[0]) / (2 * det)


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
    out = _polish_one(b.tolist(), p.tolist(), np.asarray(rho, dtype=float).tolist(), *map(float, x), iters)
    return np.array(out[:3]), out[3]


def _polish_one(
    bl: list, pl: list, rho: list, tx: float, ty: float, phi: float, iters: int = 8
) -> tuple[float, float, float, float]:
    """`polish_planar_3rpr` on floats: ``f_i = |v_i|^2 - rho_i^2``, ``v_i = t + R p_i - b_i``,
    rows ``2 [v_x, v_y, v . (d R p_i / d phi)]``, the 3x3 step by Cramer's rule (a singular
    Jacobian, e.g. at points of a continuum, ends the iteration)."""
    stop = 1e-15 * (1 + max(rho) ** 2)
    for _ in range(iters):
        c, s = math.cos(phi), math.sin(phi)
        rows, f = [], []
        for (bx, by), (px, py), r in zip(bl, pl, rho, strict=True):
            rx, ry = c * px - s * py, s * px + c * py
            vx, vy = tx + rx - bx, ty + ry - by
            f.append(vx * vx + vy * vy - r * r)
            rows.append((2 * vx, 2 * vy, 2 * (vy * rx - vx * ry)))
        if max(abs(v) for v in f) <= stop:
            break  # already exact (also keeps points of a continuum, where J is singular)
        (a1, a2, a3), (b1, b2, b3), (c1, c2, c3) = rows
        det = a1 * (b2 * c3 - b3 * c2) - a2 * (b1 * c3 - b3 * c1) + a3 * (b1 * c2 - b2 * c1)
        if det == 0.0 or not math.isfinite(det):
            break
        f1, f2, f3 = f
        dx = (f1 * (b2 * c3 - b3 * c2) - a2 * (f2 * c3 - b3 * f3) + a3 * (f2 * c2 - b2 * f3)) / det
        dy = (a1 * (f2 * c3 - b3 * f3) - f1 * (b1 * c3 - b3 * c1) + a3 * (b1 * f3 - f2 * c1)) / det
        dp = (a1 * (b2 * f3 - f2 * c2) - a2 * (b1 * f3 - f2 * c1) + f1 * (b1 * c2 - b2 * c1)) / det
        tx, ty, phi = tx - dx, ty - dy, phi - dp
        if max(abs(dx), abs(dy), abs(dp)) < QUADRATIC_STOP * (1 + max(abs(tx), abs(ty), abs(phi))):
            break
    c, s = math.cos(phi), math.sin(phi)
    err = max(
        abs(math.hypot(tx + c * px - s * py - bx, ty + s * px + c * py - by) - r)
        for (bx, by), (px, py), r in zip(bl, pl, rho, strict=True)
    )
    return tx, ty, phi, err


def planar_3rpr_poses(
    b: np.ndarray, p: np.ndarray, rho: np.ndarray, tol: float = POSE_TOL
) -> list[np.ndarray]:
    """All real assembly modes ``(x, y, phi)`` of a 3-RPR for leg lengths ``rho`` (at most 6).

    Roots of `rpr_polynomial` in ``z = e^{i phi}`` near the unit circle give candidate
    headings (a double root may split off the circle by ``O(sqrt(eps))``, hence the loose
    filter; the centroids of root clusters are tried as well, see `_cluster_means`); each
    candidate is polished by Newton on the leg equations, kept when every leg length is met to
    ``tol`` and de-duplicated; the modes come in increasing heading. Leading/trailing
    coefficients that vanish only remove roots at ``z = 0`` or infinity, which are never real
    headings.

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
    bl, pl, rl = b.tolist(), p.tolist(), np.asarray(rho, dtype=float).tolist()
    size = float(np.max(np.abs(b)) + np.max(np.abs(p)) + np.max(rho))
    accept = tol * max(size, 1.0)
    poses: list[tuple[float, float, float]] = []
    for z in roots.tolist():
        if abs(math.log(abs(z))) > 1e-3:
            continue
        phi = math.atan2(z.imag, z.real)
        u = _cramer_one(bl, pl, rl, phi)
        starts = [u] if u is not None else [tuple(v) for v in _rpr_candidates(b, p, rho, phi)]
        c, s = math.cos(phi), math.sin(phi)
        (p0x, p0y) = pl[0]
        for ux, uy in starts:
            tx, ty, ph, err = _polish_one(bl, pl, rl, ux - (c * p0x - s * p0y), uy - (s * p0x + c * p0y), phi)
            if err > accept:
                continue
            ph = wrap_angle(ph)
            if all(
                math.hypot(tx - x, ty - y) > 1e-7 * size or abs(wrap_angle(ph - a)) > 1e-7
                for x, y, a in poses
            ):
                poses.append((tx, ty, ph))
    return [np.array(x) for x in sorted(poses, key=lambda x: x[2])]


def planar_3rpr_fk(m: Mechanism, actuated: np.ndarray) -> list[list[float]]:
    """3-RPR FK: every real assembly mode (see `planar_3rpr_poses`) as a full ``q`` (floats), from
    the C kernel (`compiled_rows`) when it answers."""
    rho = np.asarray(actuated, dtype=float)
    b, p = m.params["base"], m.params["platform"]
    rows = compiled_rows(b, p, rho)
    if rows is not None:
        if m.coordinate_names == COORDINATES:
            return rows.tolist()
        return [coordinate_row(m, dict(zip(COORDINATES, row, strict=True))) for row in rows.tolist()]
    return [_pose_row(m, *x.tolist()) for x in planar_3rpr_poses(b, p, rho)]


register("planar_3rpr", ik=_planar_3rpr_rows, fk=planar_3rpr_fk)
