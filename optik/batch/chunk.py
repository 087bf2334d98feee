"""One chunk of a batch: what every chunk shares (`ChunkSpec`), `prepare` (the build and
compile every chunk then reuses) and `solve_chunk`, the unit of work of the local thread pool
and of a Dask task."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optik import spatial
from optik.batch.fk import fk_batch
from optik.batch.result import PER_TARGET, BatchResult
from optik.mechanism import Mechanism
from optik.solvers import solve_ik
from optik.solvers.balance import wait_kernels
from optik.solvers.base import Tolerances, make_request
from optik.solvers.closed import binding_of, compile_closed_form
from optik.solvers.lm import lm_settings
from optik.solvers.lm_kernel import STATUS, kernel

MAX_CHUNK = 512
"""Largest chunk of the local thread pool (small enough for a smooth progress bar and a
prompt Ctrl-C)."""


@dataclass(frozen=True)
class ChunkSpec:
    """What every chunk of a batch shares (picklable: Dask ships it with each task).

    Attributes:
        method: IK method.
        task: task space.
        frame: task frame (None: end effector).
        time_limit: seconds per target.
        tol: success tolerances.
        options: method options.
        collisions: ``world``, ``self_collision`` and ``margin`` of a collision-aware batch
            (empty: none); each target is then one collision-aware `optik.solve_ik`.
        balance: ``contacts``, ``support`` and ``com_margin`` of a batch with contacts (empty:
            none); each target is then one `optik.solve_ik` with them.
    """

    method: str
    task: str
    frame: str | None
    time_limit: float
    tol: Tolerances
    options: dict[str, Any] = field(default_factory=dict)
    collisions: dict[str, Any] = field(default_factory=dict)
    balance: dict[str, Any] = field(default_factory=dict)


def prepare(m: Mechanism, spec: ChunkSpec, target: np.ndarray, q0: np.ndarray) -> None:
    """Build and compile, once and before the chunks run, the code every chunk of ``spec`` uses:
    the LM kernel (``"lm"``) or the compiled driver of a derived closed form (``"closed_form"``);
    ``target`` and ``q0`` are one row of the batch (for the request's settings)."""
    if spec.balance:
        opts = {**spec.options, **spec.balance}  # one solve of one target: validates, builds the code
        solve_ik(m, target, q0, spec.method, task=spec.task, frame=spec.frame, time_limit=1e-9, **opts)
        wait_kernels(m)  # the lm balance kernel: a batch is worth its C build
    elif spec.method == "lm":
        _lm_kernel(m, spec, target, q0)
    elif spec.method == "closed_form":
        compile_closed_form(m)


def _lm_kernel(m: Mechanism, spec: ChunkSpec, target: np.ndarray, q0: np.ndarray) -> tuple[Any, Any]:
    """The compiled LM kernel of ``spec`` (built and waited for) and its settings."""
    request = make_request(m, target, q0, spec.task, spec.frame, spec.time_limit, spec.tol, 0, spec.options)
    settings, closure_weight, compile = lm_settings(request)
    k = kernel(m, spec.task, spec.frame, closure_weight, compile)
    if k.library is not None:
        k.library.wait()  # a batch is worth the C build (the Python loop is far slower per target)
    return k, settings


def solve_chunk(
    m: Mechanism, spec: ChunkSpec, targets: np.ndarray, q0: np.ndarray, seeds: np.ndarray
) -> BatchResult:
    """Solve one chunk: ``targets`` ``(k, 4, 4)``, starts ``(k, n)``, seeds ``(k,)`` (uint64)."""
    if spec.method == "closed_form" and len(targets):
        return _solve_closed_form(m, spec, targets, q0, seeds)
    if spec.method != "lm" or spec.collisions or spec.balance or not len(targets):
        return _solve_loop(m, spec, targets, q0, seeds)
    k, settings = _lm_kernel(m, spec, targets[0], q0[0])
    rows = target_rows(targets)
    out = k.run(rows, q0, seeds, settings.conf(m))
    q, inside, redo = finish_rows(m, out.q)
    errors = out.errors
    for i in redo:
        errors[i] = k.final_errors(q[i], rows[i])
    success = _success(spec.tol, errors, inside)
    status = np.where(success, "solved", "not_converged").astype(object)
    for code, name in STATUS.items():
        if code:
            status[out.status == code] = name
    return BatchResult(
        q=q,
        success=success,
        position_error=errors[:, 0].copy(),
        orientation_error=errors[:, 1].copy(),
        closure_error=errors[:, 2].copy(),
        iterations=out.iterations,
        restarts=out.restarts,
        solve_time=out.solve_time,
        status=status,
        seed=seeds.astype(np.uint64),
    )


def finish_rows(m: Mechanism, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`optik.solvers.base.make_result`'s final step on the rows of ``q (k, n)``, vectorized
    (``q`` is changed in place): rows within the limits and in ``(-pi, pi)`` are kept, others
    are wrapped and clipped into the limits. Returns ``q``, which rows are within the limits and
    the indices of the rows that changed (their errors must be recomputed)."""
    inside = ((q >= m.lower) & (q <= m.upper)).all(axis=1)
    redo = np.flatnonzero(~(inside & (np.abs(q) < np.pi).all(axis=1)))
    changed = []
    if len(redo):
        fixed = q[redo]
        finite = np.isfinite(fixed).all(axis=1)  # a non-finite row stays as it is (it fails)
        fixed[finite] = m.wrap(fixed[finite])
        fixed = np.clip(fixed, m.lower, m.upper)
        inside[redo] = ((fixed >= m.lower) & (fixed <= m.upper)).all(axis=1)
        for i, row in zip(redo, fixed, strict=True):
            if not np.array_equal(row, q[i]):
                q[i] = row
                changed.append(i)
    return q, inside, np.asarray(changed, dtype=np.int64)


def _success(tol: Tolerances, errors: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Rows whose ``(position, orientation, closure)`` errors meet ``tol``, within the limits."""
    return (
        (errors[:, 0] <= tol.position)
        & (errors[:, 1] <= tol.orientation)
        & (errors[:, 2] <= tol.closure)
        & inside
    )


def _solve_closed_form(
    m: Mechanism, spec: ChunkSpec, targets: np.ndarray, q0: np.ndarray, seeds: np.ndarray
) -> BatchResult:
    """Method ``"closed_form"`` on a chunk: for an arm with a derived closed form (the pose task
    of its end effector, no options), one call of the compiled driver per target gives the
    solution within the limits nearest its start, as `optik.solve_ik` takes it; the FK check of
    every answer is then one vectorized `optik.fk_batch`. Targets the driver leaves to the
    general path (no solution within the limits, a candidate to polish, two close candidates)
    and every other mechanism go through `optik.solve_ik` one by one."""
    plain = spec.task == m.task == "pose" and spec.frame is None and not spec.options
    fast = binding_of(m) if plain else None
    if fast is None:
        return _solve_loop(m, spec, targets, q0, seeds)
    n = len(targets)
    q = np.zeros((n, m.n_q))
    hit = np.zeros(n, dtype=bool)
    solve_time = np.zeros(n)
    lower, upper = m.lower, m.upper
    clock = time.perf_counter
    for i in range(n):
        t0 = clock()
        got = fast(targets[i], q0[i], lower, upper, True)
        solve_time[i] = clock() - t0
        if got and len(got[0]):
            q[i] = got[0][0]
            hit[i] = True
    rows = np.flatnonzero(hit)
    t0 = clock()
    q_hit, inside, _ = finish_rows(m, q[rows])
    poses = fk_batch(m, q_hit, workers=1)
    want = targets[rows]
    errors = np.zeros((len(rows), 3))
    errors[:, 0] = np.linalg.norm(poses[:, :3, 3] - want[:, :3, 3], axis=1)
    errors[:, 1] = spatial.angle_between(poses[:, :3, :3], want[:, :3, :3])
    solve_time[rows] += (clock() - t0) / max(len(rows), 1)  # an equal share of the check
    success = _success(spec.tol, errors, inside)
    out = BatchResult(
        q=q,
        success=np.zeros(n, dtype=bool),
        position_error=np.zeros(n),
        orientation_error=np.zeros(n),
        closure_error=np.zeros(n),
        iterations=np.zeros(n, dtype=np.int64),
        restarts=np.zeros(n, dtype=np.int64),
        solve_time=solve_time,
        status=np.full(n, "solved", dtype=object),
        seed=seeds.astype(np.uint64),
    )
    out.q[rows] = q_hit
    out.success[rows] = success
    out.position_error[rows] = errors[:, 0]
    out.orientation_error[rows] = errors[:, 1]
    out.status[rows[~success]] = "not_converged"
    rest = np.flatnonzero(~hit)
    if len(rest):
        loop = _solve_loop(m, spec, targets[rest], q0[rest], seeds[rest])
        for name in PER_TARGET:
            getattr(out, name)[rest] = getattr(loop, name)
    return out


def target_rows(targets: np.ndarray) -> np.ndarray:
    """`optik.problem.target_parameters` of ``(N, 4, 4)`` transforms, one row each ``(N, 12)``."""
    rot = targets[:, :3, :3].transpose(0, 2, 1).reshape(len(targets), 9)  # column-major vec(R)
    return np.concatenate([rot, targets[:, :3, 3]], axis=1)


def _solve_loop(
    m: Mechanism, spec: ChunkSpec, targets: np.ndarray, q0: np.ndarray, seeds: np.ndarray
) -> BatchResult:
    """Any IK method: `optik.solve_ik` per target, with the target's seed."""
    rows = [
        solve_ik(
            m,
            t,
            s,
            spec.method,
            task=spec.task,
            frame=spec.frame,
            time_limit=spec.time_limit,
            tol=spec.tol,
            seed=int(sd),
            **spec.options,
            **spec.collisions,
            **spec.balance,
        )
        for t, s, sd in zip(targets, q0, seeds, strict=True)
    ]
    n = len(rows)
    return BatchResult(
        q=np.array([r.q for r in rows]).reshape(n, m.n_q),
        success=np.array([r.success for r in rows], dtype=bool),
        position_error=np.array([r.position_error for r in rows], dtype=float),
        orientation_error=np.array([r.orientation_error for r in rows], dtype=float),
        closure_error=np.array([r.closure_error for r in rows], dtype=float),
        iterations=np.array([r.iterations for r in rows], dtype=np.int64),
        restarts=np.array([r.restarts for r in rows], dtype=np.int64),
        solve_time=np.array([r.solve_time for r in rows], dtype=float),
        status=np.array([r.status for r in rows], dtype=object),
        seed=seeds.astype(np.uint64),
    )


def chunk_bounds(n: int, workers: int, chunk_size: int | None) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` covering ``range(n)``: ``chunk_size`` targets each (default:
    about eight chunks per worker, at most `MAX_CHUNK`)."""
    size = chunk_size or max(1, min(MAX_CHUNK, math.ceil(n / (8 * workers))))
    return [(a, min(a + size, n)) for a in range(0, n, size)]
