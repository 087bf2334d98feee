"""Redundant arms: the self-motion of a 7-DOF arm sampled by locking one joint, and the
continuous refinement of a planned path.

*Self-motion samples.* With joint ``j`` locked at a value ``v`` the remaining 6R chain of a
Panda or an iiwa has a derived closed form (`optik.closed_form.derived.derive_locked`), which
solves every pose of the path at once (vectorized). Each value ``v`` of the samples gives every
solution with ``q_j = v``; the values are the groups of a path sample's nodes, and the graph's
optimum is exact over the sampled values.

*Refinement.* The graph's answer moves ``q_j`` in steps of the sampling. `refine` optimizes the
whole path continuously (one NLP, ipopt, every pose an equality constraint and the joint limits
bounds), warm-started from that answer. The answer is kept only when it is shorter and passes
every check of `optik.path.plan`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optik.closed_form.derived import DerivedIK, derive_locked
from optik.errors import SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism

_LOCKED: PerMechanism[dict[tuple[int, float], DerivedIK | None]] = PerMechanism()
_LOCKED_MAX = 256
"""Locked closed forms kept per mechanism (all are dropped past it)."""


def _locked(m: Mechanism, index: int, value: float) -> DerivedIK | None:
    """The closed form of ``m`` with coordinate ``index`` locked at ``value`` (cached on ``m``)."""
    per = _LOCKED.setdefault(m, {})
    key = (index, value)
    found = per.get(key, per)  # the dict itself: a sentinel (the cached value may be None)
    if found is not per:
        return found
    if len(per) >= _LOCKED_MAX:
        per.clear()
    return per.setdefault(key, derive_locked(m, {index: value}))


def _into_limits(q: np.ndarray, m: Mechanism) -> np.ndarray:
    """Rows with each angle wrapped and shifted by whole turns into its limits (NaN rows where
    some coordinate cannot be)."""
    out = q.copy()
    angles = np.flatnonzero(np.asarray(m.revolute_mask, dtype=bool))
    w = np.remainder(q[:, angles] + np.pi, 2.0 * np.pi) - np.pi
    lo, hi = m.lower[angles], m.upper[angles]
    best = np.full_like(w, np.nan)
    for shift in 2.0 * np.pi * np.array([0.0, 1.0, -1.0, 2.0, -2.0]):
        fits = np.isnan(best) & (w + shift >= lo) & (w + shift <= hi)
        best[fits] = (w + shift)[fits]
    out[:, angles] = best
    inside = np.all((out >= m.lower) & (out <= m.upper), axis=1)
    out[~inside] = np.nan
    return out


def self_motion_solutions(
    m: Mechanism, poses: np.ndarray, index: int, values: np.ndarray
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per pose of ``poses (P, 4, 4)``, every solution with coordinate ``index`` at one of the
    ``values`` ``(K, n)`` and the index of that value ``(K,)``.

    Raises:
        SolverUnavailableError: locking that coordinate leaves no derived closed form.
    """
    free = [k for k in range(m.n_q) if k != index]
    rows: list[list[np.ndarray]] = [[] for _ in poses]
    tags: list[list[np.ndarray]] = [[] for _ in poses]
    for i, v in enumerate(values):
        solver = _locked(m, index, float(v))
        if solver is None:
            raise SolverUnavailableError(
                f"locking {m.coordinate_names[index]!r} of {m.name!r} at {v:g} leaves no derived closed form "
                "(lock another joint)"
            )
        q6, ok = solver.solve(poses)
        full = np.zeros((*q6.shape[:2], m.n_q))
        full[..., free] = q6
        full[..., index] = v
        flat = _into_limits(full.reshape(-1, m.n_q), m).reshape(full.shape)
        ok = ok & np.isfinite(flat).all(axis=-1)
        for p in range(len(poses)):
            rows[p].append(flat[p][ok[p]])
            tags[p].append(np.full(int(ok[p].sum()), i))
    return [np.concatenate(r) for r in rows], [np.concatenate(t) for t in tags]


def refine(
    m: Mechanism, q: np.ndarray, targets: np.ndarray, frame: str | None, tol: float
) -> np.ndarray | None:
    """The path ``q (N, n)`` refined by one NLP over the whole path (module docstring), or None
    when ipopt does not converge.

    ```
    min_q  sum_k |q_{k+1} - q_k|^2
    s.t.   p(q_k) = p*_k,   vee(R*_k^T R(q_k) - R(q_k)^T R*_k) / 2 = 0,   lower <= q_k <= upper
    ```

    warm-started from ``q``; the sum of squares is the smooth stand-in of the length (its
    minimizers move at even joint-space speed along the same least-motion route).
    """
    n, dof = q.shape
    fk = m.fk_function(frame).map(n)
    x = ca.MX.sym("q", dof, n)
    poses = fk(x)  # 4 x 4n
    pt = ca.DM(np.hstack([t[:3, 3][:, None] for t in targets]))
    rt = ca.DM(np.hstack([t[:3, :3] for t in targets]))  # 3 x 3n
    rows = []
    for k in range(n):
        r = poses[:3, 4 * k : 4 * k + 3]
        s = rt[:, 3 * k : 3 * k + 3].T @ r
        rows += [
            poses[:3, 4 * k + 3] - pt[:, k],
            ca.vertcat(s[2, 1] - s[1, 2], s[0, 2] - s[2, 0], s[1, 0] - s[0, 1]),
        ]
    g = ca.vertcat(*rows)
    d = x[:, 1:] - x[:, :-1]
    nlp = {"x": ca.vec(x), "f": ca.sumsqr(d), "g": g}
    opts = {
        "ipopt.print_level": 0,
        "print_time": False,
        "ipopt.sb": "yes",
        "ipopt.max_iter": 200,
        "ipopt.tol": 1e-12,
        "ipopt.constr_viol_tol": 0.1 * tol,
        "ipopt.bound_relax_factor": 0.0,  # the limits are exact: no relaxed bounds
    }
    solver = ca.nlpsol("refine", "ipopt", nlp, opts)
    lbx = np.tile(m.lower, n)
    ubx = np.tile(m.upper, n)
    out = solver(x0=q.reshape(-1), lbx=lbx, ubx=ubx, lbg=0.0, ubg=0.0)
    if not solver.stats().get("success", False):
        return None
    return np.asarray(out["x"]).reshape(n, dof)
