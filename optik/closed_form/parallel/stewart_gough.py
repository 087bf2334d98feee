"""Stewart-Gough closed forms: IK (1 branch) and FK, every real posture (at most 40) by homotopy
continuation in Study's coordinates."""

from __future__ import annotations

import functools
import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

from optik import spatial
from optik.closed_form import homotopy, parameter_homotopy
from optik.closed_form.parallel import stewart_parameter
from optik.closed_form.parallel.common import QUADRATIC_STOP, assemble, newton_step
from optik.closed_form.parallel.study import leg_constants, quat_left, quat_to_rot, stewart_quadrics
from optik.closed_form.registry import register
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism


def _sg_residual(b: np.ndarray, p: np.ndarray, rho: np.ndarray, r: np.ndarray, t: np.ndarray):
    """Leg residuals ``f (K, 6)`` and their Jacobians ``(K, 6, 6)`` in ``(t, w)`` of the
    postures ``r (K, 3, 3)``, ``t (K, 3)``."""
    rp = p @ np.swapaxes(r, -1, -2)
    v = rp + t[:, None, :] - b
    f = np.sum(v * v, axis=-1) - rho * rho
    jac = 2 * np.concatenate([v, np.cross(rp, v)], axis=-1)
    return f, jac


def polish_stewart(
    b: np.ndarray, p: np.ndarray, rho: np.ndarray, r: np.ndarray, t: np.ndarray, iters: int = 8
) -> tuple[np.ndarray, np.ndarray, float]:
    """Newton on the six leg equations in ``(t, w)`` with ``R <- exp([w]x) R``.

    Returns ``(R, t, max leg-length error)``.
    """
    rs, ts, err = polish_stewart_many(b, p, rho, np.asarray(r)[None], np.asarray(t)[None], iters)
    return rs[0], ts[0], float(err[0])


def polish_stewart_many(
    b: np.ndarray, p: np.ndarray, rho: np.ndarray, r: np.ndarray, t: np.ndarray, iters: int = 8
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`polish_stewart` of the postures ``r (K, 3, 3)``, ``t (K, 3)`` at once, each with its own
    stopping rule (a posture stops when its legs are met to ``1e-15 (1 + max rho^2)`` or its step
    falls below the quadratic stop).

    Returns ``(R (K, 3, 3), t (K, 3), max leg-length error (K,))``.
    """
    r, t = np.array(r, dtype=float), np.array(t, dtype=float)
    todo = np.arange(len(r))
    exact = 1e-15 * (1 + np.max(rho) ** 2)
    for _ in range(iters):
        if not len(todo):
            break
        f, jac = _sg_residual(b, p, rho, r[todo], t[todo])
        off = np.max(np.abs(f), axis=1) > exact  # the others are exact already
        todo, f, jac = todo[off], f[off], jac[off]
        if not len(todo):
            break
        try:
            step = np.linalg.solve(jac, f[..., None])[..., 0]
        except np.linalg.LinAlgError:  # a singular Jacobian: each posture its own step
            step = np.stack([newton_step(j, e) for j, e in zip(jac, f, strict=True)])
        t[todo] -= step[:, :3]
        r[todo] = spatial.so3_exp(-step[:, 3:]) @ r[todo]
        moving = np.max(np.abs(step), axis=1) >= QUADRATIC_STOP * (1 + np.max(np.abs(t[todo]), axis=1))
        todo = todo[moving]
    v = p @ np.swapaxes(r, -1, -2) + t[:, None, :] - b
    return r, t, np.max(np.abs(np.linalg.norm(v, axis=-1) - rho), axis=1)


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
        complex_solutions: distinct complex solutions found (40 for a general 6-6).
        paths: number of tracked homotopy paths (40 per parameter-homotopy attempt, 128 per
            total-degree round).
        rounds: total-degree rounds used (0 when the parameter homotopy was complete).
        complete: the count check passed (40 distinct nonsingular solutions merged over every
            parameter-homotopy attempt and total-degree round: 40 bounds the isolated ones, and
            singular end points are not counted), or a total-degree round accounted for every
            path with no two paths at the same end point. Two total-degree rounds that agree end
            the search but do not make the set complete.
        solve_time: wall time (s).
        method: ``"parameter"`` (40 paths), ``"total"`` (128 paths per round) or
            ``"parameter+total"`` (the count check failed and the total method completed the set).
        solutions: with ``keep_complex=True``, the distinct complex solutions in Study's
            coordinates ``(e, g)`` of the unscaled geometry (``g = t e / 2``), each scaled so that
            its largest ``|e_k|`` is 1; else None.
    """

    poses: list[tuple[np.ndarray, np.ndarray]]
    complex_solutions: int
    paths: int
    rounds: int
    complete: bool
    solve_time: float
    method: str = "total"
    solutions: np.ndarray | None = None


GENERAL_STEWART_SOLUTIONS = 40
"""Number of complex assembly modes of a general 6-6 Stewart-Gough platform (Raghavan 1993;
Ronga and Vust; Lazard; Mourrain; Husty 1996): an upper bound on the isolated solutions."""

PARAMETER_ATTEMPTS = 2
"""Parameter-homotopy attempts (fresh gamma and patch, solutions merged) before the count check
gives way to the total-degree method."""

RETRY_STOPPED = 4
"""A failed count check is retried (all paths, fresh gamma and patch) when at least one and at
most this many paths stopped (failed, or abandoned as heading for the degenerate set). A general
platform loses a path rarely and singly (4 of 1000 random platforms lost one: a failed path, or
one abandoned near the degenerate set for that gamma; the retry finds all 40); a special
geometry loses many, every attempt (the tests' planar hexagons 12 paths, 6-4 platform 7-8, 3-3
platform 11-12), so a retry there only delays the total-degree method.
Retracking only the stopped paths is not enough: for the new gamma they ended at solutions found
already on 3 of those 4 platforms."""

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


def _merge(mats: stewart_parameter.Quadrics, sols: np.ndarray, new: np.ndarray) -> np.ndarray:
    """``sols`` followed by the rows of ``new`` that are new solutions of ``mats``
    (`optik.closed_form.parallel.stewart_parameter.distinct`)."""
    both = np.concatenate([sols, new])
    return both[stewart_parameter.distinct(mats, both)]


def _total_round(
    mats: np.ndarray, rng: np.random.Generator, time_limit: float
) -> tuple[np.ndarray, np.ndarray, bool]:
    """One 128-path total-degree round: (distinct candidate end points, which of them are
    nonsingular, clean).

    Candidates solve the system and have ``|e| / |z| > DEGENERATE_E``; a candidate is
    *nonsingular* when its condition number (`optik.closed_form.parameter_homotopy.condition_numbers`,
    the parameter homotopy's) is below `optik.closed_form.parallel.stewart_parameter.SINGULAR_CONDITION`.
    The round is *clean* when every path is a candidate or ended on the degenerate set, and no
    two well-conditioned paths share an end point (which would reveal path jumping).
    """
    with np.errstate(invalid="ignore", over="ignore"):  # diverging paths of special geometries
        res = homotopy.track(mats, rng, time_limit=time_limit, abandon=_entered_degenerate_set)
    z = homotopy.refine(mats, res.z)
    e_part = _e_part(z)
    candidate = (e_part > DEGENERATE_E) & (stewart_parameter.relative_residual(mats, z) < 1e-8)
    sharp = (res.converged & (res.condition < 1e8))[candidate]
    z = z[candidate]
    same = stewart_parameter.same_points(mats, z)
    keep = stewart_parameter.first_of_groups(same)
    np.fill_diagonal(same, False)
    jumped = bool(np.any(same[sharp]))  # a well-conditioned end point reached by two paths
    nonsingular = _nonsingular(mats, z[keep])
    return z[keep], nonsingular, not jumped and bool(np.all(candidate | (e_part <= DEGENERATE_E)))


def _nonsingular(mats: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Solutions ``z`` of the quadrics ``mats`` whose condition number is below
    `optik.closed_form.parallel.stewart_parameter.SINGULAR_CONDITION`: isolated simple solutions,
    the only ones the count check may count (a singular end point may be a multiple solution or
    a point of a positive-dimensional solution set, of which any number of distinct points exist)."""
    return parameter_homotopy.condition_numbers(mats, z) < stewart_parameter.SINGULAR_CONDITION


def stewart_poses(
    b: np.ndarray,
    p: np.ndarray,
    rho: np.ndarray,
    *,
    seed: int | np.random.Generator = 0,
    time_limit: float = 5.0,
    max_rounds: int = 3,
    tol: float = 1e-9,
    method: str = "auto",
    keep_complex: bool = False,
) -> StewartFK:
    """Every real posture of a Stewart-Gough platform by homotopy continuation (all 40 complex).

    The leg equations in Study's coordinates (`study_matrices`) are 7 quadrics in ``P^7``.

    * ``method="parameter"``: the 40-path parameter homotopy from the shipped generic start
      instance (`optik.closed_form.parallel.stewart_parameter`; compiled tracker with a Cauchy
      endgame). The count check: 40 distinct nonsingular solutions prove completeness (40 bounds
      the isolated solutions). When the check fails because a few paths stopped (failed, or
      were abandoned as heading for the degenerate set: at most `RETRY_STOPPED`), all paths are
      tracked once more with a fresh gamma and patch, the solutions merged.
    * ``method="total"``: `optik.closed_form.homotopy.track` follows all ``2^7 = 128`` paths from a
      total-degree start system (gamma trick). With probability one every isolated nonsingular
      solution ends a path; the other paths end on the degenerate set ``e = 0`` (where all leg
      quadrics reduce to ``|g|^2 = 0``). A round is *complete* when every path is accounted for
      and no two paths share an end point (a shared end point reveals path jumping), or when 40
      distinct nonsingular solutions are found (`_nonsingular`; singular end points are never
      counted: on a positive-dimensional solution set any number of them exist). Otherwise a
      new round (fresh gamma and patch) is tracked and the solutions merged, up to
      ``max_rounds``; two rounds that agree also end the search,
      with ``complete`` False (agreement is no proof: a solution both rounds merged with a
      neighbour stays missing).
    * ``method="auto"`` (default): the parameter homotopy, and the total method (solutions
      merged) when its count check fails: special geometries (planar base and platform, 6-4,
      3-3 platforms) have fewer than 40 isolated solutions. Without a C compiler: the total
      method.

    Real solutions are those that are the same solution as their complex conjugate by the rule
    that tells solutions apart (`optik.closed_form.parallel.stewart_parameter.self_conjugate`:
    the distance of ``z`` to ``conj(z)`` explained by the error of ``z``), so a near-real
    conjugate pair is two complex solutions and the real count of a complete general set is
    even. Their real parts are polished by Newton on the real leg equations and kept when every
    leg length is met to ``tol`` (relative to the platform size).

    Raises:
        InvalidArgumentError: unknown ``method``.
    """
    start = time.perf_counter()
    if method not in ("auto", "parameter", "total"):
        raise InvalidArgumentError(
            "method", f"unknown Stewart-Gough FK method {method!r}; use 'auto', 'parameter' or 'total'"
        )
    rng = np.random.default_rng(seed) if not isinstance(seed, np.random.Generator) else seed
    size = float(max(np.max(np.linalg.norm(b, axis=1)), np.max(np.linalg.norm(p, axis=1)), np.max(rho)))
    bs, ps, rs = b / size, p / size, rho / size
    mats = functools.cache(lambda: stewart_quadrics(bs, ps, rs))  # built when first needed
    sols = np.zeros((0, 8), dtype=complex)
    sharp = sols  # the distinct nonsingular solutions: what the count check counts
    complete, rounds, paths, used = False, 0, 0, []
    if method != "total" and parameter_homotopy.available():
        used.append("parameter")
        for _ in range(PARAMETER_ATTEMPTS):
            remaining = time_limit - (time.perf_counter() - start)
            if remaining <= 0:
                break
            res = stewart_parameter.solve(bs, ps, leg_constants(bs, ps, rs), rng, remaining)
            paths += len(res.status)
            nonsingular = res.condition < stewart_parameter.SINGULAR_CONDITION
            # singular end points: possible (double) real postures, never on the set e = 0
            keep = nonsingular | (_e_part(res.solutions) > DEGENERATE_E)
            sols = _merge(mats, sols, res.solutions[keep])
            sharp = _merge(mats, sharp, res.solutions[nonsingular])
            complete = len(sharp) >= GENERAL_STEWART_SOLUTIONS
            stopped = np.count_nonzero((res.status == "failed") | (res.status == "abandoned"))
            if complete or not 0 < stopped <= RETRY_STOPPED:
                break  # none stopped: retrying cannot add a solution; many: a special geometry
    if not complete and method != "parameter":
        used.append("total")
        while rounds < max_rounds and not complete:
            remaining = time_limit - (time.perf_counter() - start)
            if remaining <= 0:
                break
            rounds += 1
            before = len(sols)
            ends, nonsingular, clean = _total_round(mats(), rng, remaining)
            paths += 128
            sols = _merge(mats, sols, ends)
            sharp = _merge(mats, sharp, ends[nonsingular])
            complete = len(sharp) >= GENERAL_STEWART_SOLUTIONS or clean
            if rounds > 1 and len(sols) == before:
                break  # two rounds agree: a further round is unlikely to add a solution (no proof)
    poses = _real_poses(mats, sols, b, p, rho, size, tol)
    kept = _unscaled(sols, size) if keep_complex else None
    return StewartFK(
        poses, len(sols), paths, rounds, complete, time.perf_counter() - start, "+".join(used), kept
    )


def _unscaled(z: np.ndarray, size: float) -> np.ndarray:
    """Study coordinates of the unscaled geometry (``g`` times ``size``), largest ``|e_k|`` = 1."""
    w = z / z[np.arange(len(z)), np.argmax(np.abs(z[:, :4]), axis=1)][:, None]
    w[:, 4:] *= size
    return w


def _real_poses(
    mats: stewart_parameter.Quadrics,
    sols: np.ndarray,
    b: np.ndarray,
    p: np.ndarray,
    rho: np.ndarray,
    size: float,
    tol: float,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The real solutions of the (scaled) quadrics ``mats`` among ``sols`` as polished, distinct
    postures ``(R, t)`` (see `stewart_poses`)."""
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    if len(sols) == 0:
        return poses
    w = sols / sols[np.arange(len(sols)), np.argmax(np.abs(sols[:, :4]), axis=1)][:, None]
    v = w[stewart_parameter.self_conjugate(mats, sols)].real
    if not len(v):
        return poses
    e, g = v[:, :4], v[:, 4:]
    e_conj = e * np.array([1.0, -1.0, -1.0, -1.0])
    left = np.moveaxis(quat_left(g.T), -1, 0)  # (K, 4, 4)
    t0 = 2 * np.einsum("kij,kj->ki", left, e_conj)[:, 1:] / np.sum(e * e, axis=1)[:, None]
    r0 = quat_to_rot(e)
    rs, ts, err = polish_stewart_many(b, p, rho, r0, t0 * size)  # every real candidate at once
    ok = np.flatnonzero(err <= tol * max(size, 1.0))
    rs, ts = rs[ok], ts[ok]
    # pairwise: translation gap, and the rotation angle of R_i^T R_j (spatial.angle_between) of the
    # pairs whose translations are that close
    same = np.linalg.norm(ts[:, None] - ts[None], axis=-1) <= 1e-7 * size
    i, j = np.nonzero(same)
    same[i, j] = spatial.rotation_angle(np.swapaxes(rs[i], -1, -2) @ rs[j]) <= 1e-7
    # first come: a posture the same as a kept one is left out
    return [(rs[i], ts[i]) for i in stewart_parameter.first_of_groups(same)]


def stewart_gough_fk(m: Mechanism, actuated: np.ndarray, time_limit: float = 5.0) -> list[np.ndarray]:
    """Stewart-Gough FK: every real posture (`stewart_poses`, within ``time_limit`` seconds) as a
    full ``q``.

    Warns (``RuntimeWarning``) when the homotopy could not certify completeness within its
    time limit, so that a possibly missing posture never goes unnoticed.
    """
    rho = np.asarray(actuated, dtype=float)
    fk = stewart_poses(m.params["base"], m.params["platform"], rho, time_limit=time_limit)
    if not fk.complete:
        warnings.warn(
            f"Stewart-Gough FK: completeness not certified after {fk.rounds} homotopy round(s) "
            f"({fk.complex_solutions} complex solutions found); a real posture may be missing",
            RuntimeWarning,
            stacklevel=2,
        )
    return [_stewart_q(m, r, t) for r, t in fk.poses]


register("stewart_gough", ik=stewart_gough_ik, fk=stewart_gough_fk)
