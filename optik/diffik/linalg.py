"""Pseudo-inverse methods of differential IK: ``pinv``, ``dls`` (fixed or adaptive damping,
joint weights, null-space projection of secondary tasks) and the strict ``priority`` hierarchy.

All work on a [`DiffIKProblem`][optik.diffik.problem.DiffIKProblem]: the stacked weighted task rows ask
``W J dq = -alpha W e``; loop closures ``J_c dq = -gain c`` form an extra top level solved
exactly. Limits are enforced by *saturation in the null space* (SNS): when the solution leaves
``[lb, ub]``, the most violating coordinate is fixed at its bound and the remaining coordinates
solve the hierarchy again (higher levels keep priority), until every bound holds.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from optik.checks import as_vector
from optik.diffik.problem import DiffIKProblem
from optik.errors import InvalidArgumentError

Level = tuple[np.ndarray, np.ndarray]
"""A hierarchy level: rows ``J`` and the target ``t`` of ``J dq = t``."""

RCOND = 1e-10
"""Singular values below ``RCOND * sigma_max`` count as zero in the exact pseudo-inverse."""


def pinv_pair(jac: np.ndarray, damping: float = 0.0, threshold: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Damped and exact pseudo-inverses of ``J`` from one SVD ``J = U diag(s) V^T``.

    The damped one is ``J# = V diag(s_i / (s_i^2 + lambda^2)) U^T`` with

    * ``threshold == 0``: fixed damping ``lambda = damping``;
    * ``threshold > 0``: adaptive (singular-value based) damping
      ``lambda^2 = damping^2 (1 - (s_min / threshold)^2)`` when ``s_min < threshold`` else 0:
      exact away from singularities, damped with ``lambda -> damping`` at one, where joint
      velocities stay below ``|t| / (2 lambda)`` along singular directions.

    The exact one is the Moore-Penrose inverse with singular values below ``RCOND * s_max``
    dropped (it defines the null-space projectors).

    Args:
        jac: ``m x n`` matrix.
        damping: ``lambda`` (fixed) or ``lambda_max`` (adaptive), ``>= 0``.
        threshold: singular-value threshold ``epsilon`` of the adaptive scheme (0: fixed).
    """
    if jac.shape[0] == 0 or jac.shape[1] == 0:
        zero = np.zeros((jac.shape[1], jac.shape[0]))
        return zero, zero
    u, s, vt = np.linalg.svd(jac, full_matrices=False)
    keep = s > RCOND * max(s[0], 1e-300)
    exact_inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    lam2 = damping**2
    if threshold > 0:
        s_min = s[-1] if jac.shape[0] <= jac.shape[1] else 0.0
        lam2 = damping**2 * (1 - (s_min / threshold) ** 2) if s_min < threshold else 0.0
    damped_inv = s / (s**2 + lam2) if lam2 > 0 else exact_inv
    vt_t = vt.T
    return (vt_t * damped_inv) @ u.T, (vt_t * exact_inv) @ u.T


def damped_pinv(jac: np.ndarray, damping: float = 0.0, threshold: float = 0.0) -> np.ndarray:
    """The damped pseudo-inverse of [`pinv_pair`][optik.diffik.linalg.pinv_pair] (``damping = 0``:
    Moore-Penrose)."""
    return pinv_pair(jac, damping, threshold)[0]


def solve_levels(
    levels: list[Level], n: int, damping: float = 0.0, threshold: float = 0.0, project_last: bool = False
) -> np.ndarray:
    """Solve a hierarchy ``J_1 dq = t_1 >> J_2 dq = t_2 >> ...`` without bounds.

    Recursive task priority (Siciliano and Slotine): ``dq_k = dq_{k-1} + (J_k N_{k-1})# (t_k -
    J_k dq_{k-1})``, ``N_k = N_{k-1} - (J_k N_{k-1})^+ (J_k N_{k-1})`` with ``N_0 = I``; ``#`` is the
    damped inverse of [`pinv_pair`][optik.diffik.linalg.pinv_pair] for every level but the first, which is
    exact (the closures), ``^+`` the exact one. With ``project_last`` the last level is solved on its own and
    projected, ``dq += N (J_last# t_last)`` (the classic gradient projection of a secondary task: it never
    disturbs the levels above, but it is not compensated for their motion).
    """
    dq = np.zeros(n)
    proj: np.ndarray | None = None
    for k, (jac, t) in enumerate(levels):
        if jac.shape[0] == 0:
            continue
        lam, eps = (0.0, 0.0) if k == 0 else (damping, threshold)
        if project_last and k == len(levels) - 1 and k > 0:
            inv, _ = pinv_pair(jac, lam, eps)
            step = inv @ t
            return dq + (step if proj is None else proj @ step)
        jn = jac if proj is None else jac @ proj
        inv, exact = pinv_pair(jn, lam, eps)
        dq = dq + inv @ (t - jac @ dq)
        if k < len(levels) - 1:
            proj = (np.eye(n) if proj is None else proj) - exact @ jn
    return dq


def _max_scale(base: np.ndarray, direction: np.ndarray, lb: np.ndarray, ub: np.ndarray, tol: float) -> float:
    """Largest ``s`` in ``[0, 1]`` with ``lb <= base + s direction <= ub`` (-1 if ``base`` violates)."""
    if np.any(base < lb - tol) or np.any(base > ub + tol):
        return -1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(direction > 0, (ub - base) / direction, np.inf)
        down = np.where(direction < 0, (lb - base) / direction, np.inf)
    return float(np.clip(min(1.0, up.min(), down.min()), 0.0, 1.0))


def saturate(
    levels: list[Level],
    lb: np.ndarray,
    ub: np.ndarray,
    solve: Callable[[list[Level], int], np.ndarray],
    tol: float = 1e-12,
) -> tuple[np.ndarray, int, float]:
    """Saturation in the null space with task scaling (after Flacco, De Luca and Khatib).

    Repeat: solve the hierarchy with the saturated coordinates fixed at their bounds; if every bound
    holds, done; else record the largest scale ``s`` of the targets of the lowest levels for which
    the solution fits the bounds (only the last level scaled if that suffices, else the last two,
    ...; level 0, the closures, is never scaled), and fix the most violating coordinate at its
    bound. If no set of saturated coordinates achieves the full targets, the candidate that scales
    the fewest levels, then the least, is returned: the motion keeps the tasks' direction at a
    reduced speed and the higher levels exact as long as they fit. Candidates
    that break level 0 (saturation leaving too few coordinates for the closures) are discarded;
    when none is left, the first (unsaturated) solution scaled into the bounds is returned, so that
    the closures still make progress.

    Returns:
        ``dq`` within ``[lb, ub]``, the number of saturated coordinates and the scale of the
        scaled levels (1 when the targets are met in full).
    """
    n = lb.shape[0]
    fixed = np.zeros(n, dtype=bool)
    dq_fixed = np.zeros(n)
    best: tuple[int, float, np.ndarray, int] = (0, -1.0, np.clip(np.zeros(n), lb, ub), 0)
    top_jac, top_t = levels[0]
    top_tol = 1e-9 + 1e-6 * (float(np.max(np.abs(top_t))) if top_t.size else 0.0)

    first: np.ndarray | None = None

    def top_ok(dq: np.ndarray) -> bool:
        """Level 0 (the closures) still met: saturating coordinates must not break the loops."""
        return not top_t.size or float(np.max(np.abs(top_jac @ dq - top_t))) <= top_tol

    for _ in range(n + 1):
        free = ~fixed
        n_free = int(free.sum())
        shift = [jac[:, fixed] @ dq_fixed[fixed] for jac, _ in levels]
        full = [(jac[:, free], t - d) for (jac, t), d in zip(levels, shift, strict=True)]
        dq = dq_fixed.copy()
        if n_free:
            dq[free] = solve(full, n_free)
        if first is None:
            first = dq
        over = np.maximum(dq - ub, lb - dq)
        over[fixed] = -np.inf
        k = int(np.argmax(over))
        if over[k] <= tol and top_ok(dq):
            return np.clip(dq, lb, ub), int(fixed.sum()), 1.0
        for j in range(len(levels) - 1, 0, -1):  # scale as few (lowest) levels as possible
            zero = [(jac, t if i < j else np.zeros_like(t)) for i, (jac, t) in enumerate(levels)]
            dq0 = dq_fixed.copy()
            trivial = not fixed.any() and not any(np.any(t) for _, t in zero)  # solution is 0
            if n_free and not trivial:
                reduced = [(jac[:, free], t - d) for (jac, t), d in zip(zero, shift, strict=True)]
                dq0[free] = solve(reduced, n_free)
            scale = _max_scale(dq0, dq - dq0, lb, ub, tol)
            candidate = np.clip(dq0 + scale * (dq - dq0), lb, ub)
            if scale >= 0 and top_ok(candidate):
                if (j, scale) > best[:2]:
                    best = (j, scale, candidate, int(fixed.sum()))
                break
        if over[k] <= tol:  # within the bounds but level 0 broken: no further saturation helps
            break
        fixed[k] = True
        dq_fixed[k] = np.clip(dq[k], lb[k], ub[k])
    _, scale, dq, n_fixed = best
    if scale < 0 and first is not None:  # no candidate keeps level 0: scale the whole first solution
        zero = np.zeros(n)
        s_all = _max_scale(zero, first, lb, ub, tol)
        return np.clip(max(s_all, 0.0) * first if s_all >= 0 else first, lb, ub), 0, max(s_all, 0.0)
    return dq, n_fixed, max(scale, 0.0)


def _weighted(
    problem: DiffIKProblem, levels: list[Level], joint_weights: Any
) -> tuple[list[Level], np.ndarray, np.ndarray, np.ndarray]:
    """Change of variables ``dq = M^{-1/2} y`` for the weighted pseudo-inverse
    ``J#_M = M^-1 J^T (J M^-1 J^T)^-1`` (minimises ``dq^T M dq`` among exact solutions)."""
    n = problem.n
    if joint_weights is None:
        return levels, problem.lb, problem.ub, np.ones(n)
    w = as_vector(joint_weights, "joint_weights", n)
    if np.any(w <= 0):
        raise InvalidArgumentError("joint_weights", f"must be > 0, got {w}")
    s = 1.0 / np.sqrt(w)
    return [(jac * s, t) for jac, t in levels], problem.lb / s, problem.ub / s, s


def _levels(problem: DiffIKProblem, split: str) -> list[Level]:
    """Closure level, then the task levels: every priority (``"all"``) or priority 0 and all the
    others stacked (``"two"``)."""
    jac, t = problem.jacobian, problem.target
    rows = problem.levels()
    if split == "two" and len(rows) > 2:
        rows = [rows[0], np.concatenate(rows[1:])]
    return [(problem.A, problem.b)] + [(jac[r], t[r]) for r in rows]


def solve_pseudo_inverse(
    problem: DiffIKProblem,
    damping: float = 0.0,
    threshold: float = 0.0,
    hierarchy: str = "projection",
    joint_weights: Any = None,
) -> tuple[np.ndarray, int, float]:
    """``dq`` by (damped) pseudo-inverses with saturation of the bounds.

    Args:
        problem: the step's problem.
        damping, threshold: see [`pinv_pair`][optik.diffik.linalg.pinv_pair] (applied to every task level; the
            closure level is always exact).
        hierarchy: ``"projection"``: priority-0 tasks primary, the others projected into their null
            space ([`solve_levels`][optik.diffik.linalg.solve_levels] with ``project_last``); ``"strict"``:
            every priority value a level of the recursive hierarchy.
        joint_weights: positive weight per coordinate ``M = diag(w)`` (weighted pseudo-inverse).

    Returns:
        ``(dq, number of saturated coordinates, task scale)`` (see
        [`saturate`][optik.diffik.linalg.saturate]).
    """
    levels = _levels(problem, "two" if hierarchy == "projection" else "all")
    levels, lb, ub, scale = _weighted(problem, levels, joint_weights)
    project = hierarchy == "projection" and len(levels) > 2

    def solve(lv: list[Level], n: int) -> np.ndarray:
        return solve_levels(lv, n, damping, threshold, project)

    y, n_sat, task_scale = saturate(levels, lb, ub, solve)
    return y * scale, n_sat, task_scale
