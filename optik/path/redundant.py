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

import threading
from collections import OrderedDict

import casadi as ca
import numpy as np

from optik.closed_form.derived import DerivedIK, derive_locked
from optik.errors import SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.path.nodes import into_limits

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


def self_motion_solutions(
    m: Mechanism, poses: np.ndarray, index: int, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every solution of ``poses (P, 4, 4)`` with coordinate ``index`` at one of the ``values``:
    the solutions ``(K, n)``, the pose of each ``(K,)`` (ascending) and the index of its value
    ``(K,)`` (per pose in the order of the values). One vectorized closed-form call per value.

    Raises:
        SolverUnavailableError: locking that coordinate leaves no derived closed form.
    """
    free = [k for k in range(m.n_q) if k != index]
    angles = np.asarray(m.revolute_mask, dtype=bool)
    rows, pose, tag = [np.zeros((0, m.n_q))], [np.zeros(0, dtype=np.int64)], [np.zeros(0, dtype=np.int64)]
    for i, v in enumerate(values):
        solver = _locked(m, index, float(v))
        if solver is None:
            raise SolverUnavailableError(
                f"locking {m.coordinate_names[index]!r} of {m.name!r} at {v:g} leaves no derived closed form "
                "(lock another joint)"
            )
        q6, ok = solver.solve(poses)
        p, b = np.nonzero(ok)
        full = np.empty((len(p), m.n_q))
        full[:, free] = q6[p, b]
        full[:, index] = v
        full = into_limits(full, m.lower, m.upper, angles)
        fits = np.isfinite(full).all(axis=1)
        rows.append(full[fits])
        pose.append(p[fits])
        tag.append(np.full(int(fits.sum()), i))
    order = np.argsort(np.concatenate(pose), kind="stable")  # by pose, each in the order of the values
    return np.concatenate(rows)[order], np.concatenate(pose)[order], np.concatenate(tag)[order]


class _Refiner:
    """The refinement NLP of one (frame, path length, tolerance): the poses are parameters, so
    one build serves every path of that length; calls are serialized (one ipopt memory)."""

    def __init__(self, m: Mechanism, frame: str | None, n: int, tol: float) -> None:
        dof = m.n_q
        x = ca.MX.sym("q", dof, n)
        p = ca.MX.sym("poses", 12, n)  # per pose: the position, then the rotation column-major
        poses = m.fk_function(frame).map(n)(x)  # 4 x 4n
        rows = []
        for k in range(n):
            r = poses[:3, 4 * k : 4 * k + 3]
            s = ca.reshape(p[3:, k], 3, 3).T @ r
            rows += [
                poses[:3, 4 * k + 3] - p[:3, k],
                ca.vertcat(s[2, 1] - s[1, 2], s[0, 2] - s[2, 0], s[1, 0] - s[0, 1]),
            ]
        d = x[:, 1:] - x[:, :-1]
        nlp = {"x": ca.vec(x), "p": ca.vec(p), "f": ca.sumsqr(d), "g": ca.vertcat(*rows)}
        opts = {
            "ipopt.print_level": 0,
            "print_time": False,
            "ipopt.sb": "yes",
            "ipopt.max_iter": 200,
            "ipopt.tol": 1e-12,
            "ipopt.constr_viol_tol": 0.1 * tol,
            "ipopt.bound_relax_factor": 0.0,  # the limits are exact: no relaxed bounds
        }
        self.solver = ca.nlpsol("refine", "ipopt", nlp, opts)
        self.lbx, self.ubx = np.tile(m.lower, n), np.tile(m.upper, n)
        self.lock = threading.Lock()

    def __call__(self, q: np.ndarray, targets: np.ndarray) -> np.ndarray | None:
        p = np.concatenate([targets[:, :3, 3], targets[:, :3, :3].transpose(0, 2, 1).reshape(-1, 9)], axis=1)
        with self.lock:
            out = self.solver(x0=q.reshape(-1), p=p.reshape(-1), lbx=self.lbx, ubx=self.ubx, lbg=0.0, ubg=0.0)
            ok = bool(self.solver.stats().get("success", False))
        return np.asarray(out["x"]).reshape(q.shape) if ok else None


_REFINERS: PerMechanism[OrderedDict[tuple[str | None, int, float], _Refiner]] = PerMechanism()
_REFINERS_MAX = 8
"""Refinement NLPs kept per mechanism (the least recently used is dropped past it)."""
_REFINERS_LOCK = threading.Lock()


def refiner(m: Mechanism, frame: str | None, n: int, tol: float) -> _Refiner:
    """The cached refinement NLP of ``m`` for paths of ``n`` samples (built on first use)."""
    key = (frame, n, float(tol))
    with _REFINERS_LOCK:
        per = _REFINERS.setdefault(m, OrderedDict())
        found = per.get(key)
        if found is not None:
            per.move_to_end(key)
            return found
    built = _Refiner(m, frame, n, tol)  # outside the lock: a build takes a while
    with _REFINERS_LOCK:
        found = per.setdefault(key, built)
        per.move_to_end(key)
        while len(per) > _REFINERS_MAX:
            per.popitem(last=False)
        return found


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
    minimizers move at even joint-space speed along the same least-motion route). The NLP takes
    the poses as parameters and is cached per (mechanism, frame, ``N``, ``tol``) (`refiner`, at
    most `_REFINERS_MAX` per mechanism): planning again on a path of the same length builds
    nothing.
    """
    return refiner(m, frame, len(q), tol)(q, targets)
