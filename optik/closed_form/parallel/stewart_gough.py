"""Stewart-Gough closed forms: IK (1 branch) and FK, every real posture (at most 40) by homotopy
continuation in Study's coordinates."""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

from optik import spatial
from optik.closed_form import homotopy
from optik.closed_form.parallel.common import QUADRATIC_STOP, assemble, newton_step
from optik.closed_form.registry import register
from optik.mechanism import Mechanism


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
        step = newton_step(jac, f)
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
    ``c = asin(n_x)`` in ``[-pi/2, pi/2]`` and ``a = atan2(-n_y, n_z)`` in ``(-pi, pi]``: the one
    canonical pair of every direction, downward legs included (the catalog's limits; a zero-length
    leg, ``rho_i = 0``, gets ``a = c = 0``). The spherical joint of leg 1 is the rotation vector
    ``log(R_u1^T R)`` (angle in ``[0, pi]``: every posture, half-turns included, has coordinates).
    """
    b, p = m.params["base"], m.params["platform"]
    values: dict[str, float] = {}
    r_u1 = np.eye(3)
    # per leg on floats (six legs: numpy on 3-vectors costs more than the arithmetic)
    for i, (vx, vy, vz) in enumerate((p @ r.T + t - b).tolist()):
        rho = math.sqrt(vx * vx + vy * vy + vz * vz)
        # a zero-length leg has no direction: any angles place it; take the upright (0, 0)
        nx, ny, nz = (vx / rho, vy / rho, vz / rho) if rho > 0 else (0.0, 0.0, 1.0)
        c = math.asin(min(max(nx, -1.0), 1.0))
        a = math.atan2(-ny, nz) if math.hypot(ny, nz) > 1e-15 else 0.0
        values[f"u{i + 1}[0]"], values[f"u{i + 1}[1]"], values[f"rho{i + 1}"] = a, c, rho
        if i == 0:  # Rot(x, a) Rot(y, c)
            ca, sa, cc, sc = math.cos(a), math.sin(a), math.cos(c), math.sin(c)
            r_u1 = np.array([[cc, 0.0, sc], [sa * sc, ca, -sa * cc], [-ca * sc, sa, ca * cc]])
    s1 = _so3_log_one((r_u1.T @ r).tolist())
    for k in range(3):
        values[f"s1[{k}]"] = float(s1[k])
    return assemble(m, values)


def _so3_log_one(r: list[list[float]]) -> list[float]:
    """`optik.spatial.so3_log` of one rotation on floats (the same formulas; within 1e-3
    of a half-turn, where the axis comes from the symmetric part, it calls ``so3_log``)."""
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

    The leg equations in Study's coordinates (`stewart_quadrics`) are 7 quadrics in
    ``P^7``; `optik.closed_form.homotopy.track` follows all ``2^7 = 128`` paths from a
    total-degree start system (gamma trick). With probability one every isolated nonsingular
    solution ends a path; the other paths end on the degenerate set ``e = 0`` (where all leg
    quadrics reduce to ``|g|^2 = 0``). A round is *complete* when every path is accounted for
    and no two paths share an end point (a shared end point reveals path jumping); finding 40
    distinct solutions proves completeness outright, since 40 bounds the isolated solutions.
    Otherwise a new round (fresh gamma and patch) is tracked and the solutions merged, up to
    ``max_rounds``. Real solutions (``max |Im|`` small after fixing the projective phase) are
    polished by Newton on the real leg equations and kept when every leg length is met to
    ``tol`` (relative to the platform size).
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
    """Stewart-Gough FK: every real posture (`stewart_poses`) as a full ``q``.

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


register("stewart_gough", ik=stewart_gough_ik, fk=stewart_gough_fk)
