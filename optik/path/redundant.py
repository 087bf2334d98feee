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

from optik.batch import fk_batch
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


END_TOL = 1e-9
"""FK agreement required of `end_turns` at each test configuration."""


def end_turns(m: Mechanism, index: int, values: np.ndarray, seed: int = 0) -> tuple[bool, np.ndarray] | None:
    """``(right, D)`` when coordinate ``index`` moves the tool by a fixed transform, whatever the
    other coordinates: ``fk(q | q_index = v) = fk(q | q_index = v_0) D_v`` for every ``q`` (the
    last joint of a chain; ``right``) or ``= D_v fk(q | q_index = v_0)`` (the first; not
    ``right``), ``v_0 = values[0]``; ``D (V, 4, 4)``, one per value. Checked by FK at three random
    configurations within the limits, else None."""
    rng = np.random.default_rng(seed)
    lo, hi = np.maximum(m.lower, -np.pi), np.minimum(m.upper, np.pi)
    q = np.repeat(rng.uniform(lo, hi, (3, 1, m.n_q)), len(values), axis=1)
    q[:, :, index] = values
    f = fk_batch(m, q.reshape(-1, m.n_q)).reshape(3, len(values), 4, 4)
    base = f[:, :1]
    for right in (True, False):
        d = np.linalg.inv(base) @ f if right else f @ np.linalg.inv(base)
        if np.abs(d - d[:1]).max() <= END_TOL:
            return right, d[0]
    return None


def self_motion_solutions(
    m: Mechanism, poses: np.ndarray, index: int, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every solution of ``poses (P, 4, 4)`` with coordinate ``index`` at one of the ``values``:
    the solutions ``(K, n)``, the pose of each ``(K,)`` (ascending) and the index of its value
    ``(K,)`` (per pose in the order of the values).

    When the coordinate moves the tool by a fixed transform (`end_turns`: the last or the first
    joint), the solutions with ``q_index = v`` of a pose ``T`` are those with ``q_index = v_0``
    of ``T D_v^-1`` (or ``D_v^-1 T``): one vectorized call of one locked closed form over every
    value and pose. Otherwise one call per value, each with its own locked closed form.

    Raises:
        SolverUnavailableError: locking that coordinate leaves no derived closed form.
    """
    free = [k for k in range(m.n_q) if k != index]
    angles = np.asarray(m.revolute_mask, dtype=bool)
    turns = end_turns(m, index, values) if len(values) > 1 else None
    if turns is None:
        calls = [(np.array([i]), float(v), poses) for i, v in enumerate(values)]
    else:
        right, d = turns
        inv = np.linalg.inv(d)[:, None]  # (V, 1, 4, 4)
        moved = poses[None] @ inv if right else inv @ poses[None]
        calls = [(np.arange(len(values)), float(values[0]), moved.reshape(-1, 4, 4))]
    rows, pose, tag = [np.zeros((0, m.n_q))], [np.zeros(0, dtype=np.int64)], [np.zeros(0, dtype=np.int64)]
    for which, v, targets in calls:
        solver = _locked(m, index, v)
        if solver is None:
            raise SolverUnavailableError(
                f"locking {m.coordinate_names[index]!r} of {m.name!r} at {v:g} leaves no derived closed form "
                "(lock another joint)"
            )
        q6, t = _every_solution(solver, targets)  # t: the target (value-major over the poses)
        value, p = which[t // len(poses)], t % len(poses)
        full = np.empty((len(t), m.n_q))
        full[:, free] = q6
        full[:, index] = values[value]
        full = into_limits(full, m.lower, m.upper, angles)
        fits = np.isfinite(full).all(axis=1)
        rows.append(full[fits])
        pose.append(p[fits])
        tag.append(value[fits])
    order = np.argsort(np.concatenate(pose), kind="stable")  # by pose, each in the order of the values
    return np.concatenate(rows)[order], np.concatenate(pose)[order], np.concatenate(tag)[order]


_UNLIMITED = (np.full(6, -np.inf), np.full(6, np.inf))
"""No limits for the compiled driver: `self_motion_solutions` fits the rows into the arm's."""


def _every_solution(solver: DerivedIK, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every solution of each of ``targets (M, 4, 4)`` by the locked closed form, wrapped to
    ``(-pi, pi]``, as rows ``(K, 6)`` target after target (in the candidate order) and the target
    of each ``(K,)``: through its compiled driver over every target in one call once it is
    loaded (`optik.closed_form.ik_all`; the targets it hands back, and every target before,
    by the numpy kernel `DerivedIK.solve`)."""
    driver = solver.driver()
    many = None if driver is None else driver.many
    got = None if many is None else many(np.ascontiguousarray(targets, dtype=float), None, *_UNLIMITED, False)
    if got is None:
        q6, ok = solver.solve(targets)
        t, b = np.nonzero(ok)
        return q6[t, b], t
    rows, _, counts, _, _, status = got
    t = np.repeat(np.arange(len(targets)), counts)
    back = np.flatnonzero(status)
    if back.size:  # answered by numpy, put in their place
        q6, ok = solver.solve(targets[back])
        tb, b = np.nonzero(ok)
        order = np.argsort(np.concatenate([t, back[tb]]), kind="stable")
        rows, t = np.concatenate([rows, q6[tb, b]])[order], np.concatenate([t, back[tb]])[order]
    return rows, t


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
