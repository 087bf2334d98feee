"""`solve_ik_batch`: many IK targets on every core, or on a Dask cluster.

The targets are cut into chunks. With method ``"lm"`` a chunk is one call of the compiled
kernel (`optik.solvers.lm_kernel`): the whole multi-start loop of every target runs in C and
the call releases the GIL, so a thread pool keeps every core busy; other methods loop over
`optik.solve_ik` per target. Target ``i`` is solved with seed ``target_seeds(seed)[i]`` and its
own time limit, so the answers depend neither on the chunking nor on the number of threads or
Dask workers, and ``solve_ik(m, targets[i], q0[i], seed=result.seed[i], ...)`` gives the same
answer (``result.seed`` holds the seeds). With ``scheduler=`` a ``dask.distributed.Client``,
the chunks are Dask tasks (`optik.batch.distributed`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optik import spatial
from optik.batch.inputs import as_starts, as_targets, base_seed
from optik.batch.result import BatchResult
from optik.bench.progress import Progress
from optik.mechanism import Mechanism
from optik.solvers import solve_ik
from optik.solvers.base import Tolerances, get_method, make_request, positive_int
from optik.solvers.evaluation import errors_against
from optik.solvers.lm import lm_settings
from optik.solvers.lm_kernel import STATUS, kernel, target_seeds

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
    """

    method: str
    task: str
    frame: str | None
    time_limit: float
    tol: Tolerances
    options: dict[str, Any] = field(default_factory=dict)


def solve_chunk(
    m: Mechanism, spec: ChunkSpec, targets: np.ndarray, q0: np.ndarray, seeds: np.ndarray
) -> BatchResult:
    """Solve one chunk: ``targets`` ``(k, 4, 4)``, starts ``(k, n)``, seeds ``(k,)`` (uint64)."""
    if spec.method != "lm" or not len(targets):
        return _solve_loop(m, spec, targets, q0, seeds)
    request = make_request(
        m, targets[0], q0[0], spec.task, spec.frame, spec.time_limit, spec.tol, 0, spec.options
    )
    settings, closure_weight, compile = lm_settings(request)
    k = kernel(m, spec.task, spec.frame, closure_weight, compile)
    out = k.run(target_rows(targets), q0, seeds, settings.conf(m))
    q, errors = out.q, out.errors
    # make_result's final step, vectorized: rows within the limits and in (-pi, pi) are kept,
    # others are wrapped and clipped, and their errors recomputed where that changed them
    inside = ((q >= m.lower) & (q <= m.upper)).all(axis=1)
    redo = np.flatnonzero(~(inside & (np.abs(q) < np.pi).all(axis=1)))
    if len(redo):
        fixed = np.clip(wrap_rows(m, q[redo]), m.lower, m.upper)
        inside[redo] = ((fixed >= m.lower) & (fixed <= m.upper)).all(axis=1)
        for i, row in zip(redo, fixed, strict=True):
            if not np.array_equal(row, q[i]):
                q[i] = row
                errors[i] = errors_against(m, spec.task, spec.frame, targets[i], compile)(row)
    tol = spec.tol
    success = (
        (errors[:, 0] <= tol.position)
        & (errors[:, 1] <= tol.orientation)
        & (errors[:, 2] <= tol.closure)
        & inside
    )
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


def target_rows(targets: np.ndarray) -> np.ndarray:
    """`optik.problem.target_parameters` of ``(N, 4, 4)`` transforms, one row each ``(N, 12)``."""
    rot = targets[:, :3, :3].transpose(0, 2, 1).reshape(len(targets), 9)  # column-major vec(R)
    return np.concatenate([rot, targets[:, :3, 3]], axis=1)


def wrap_rows(m: Mechanism, q: np.ndarray) -> np.ndarray:
    """``Mechanism.wrap`` of each row of ``q`` ``(k, n)``, vectorized (the same operations, so
    the same values); mechanisms with spherical joints go row by row."""
    if m.spherical_slices:
        return np.array([m.wrap(row) for row in q]).reshape(q.shape)
    w = q.copy()
    ang = m.revolute_mask
    w[:, ang] = spatial.wrap_angle(q[:, ang])
    for k in np.flatnonzero(ang):
        lo, hi = m.lower[k], m.upper[k]
        todo = ~((lo <= w[:, k]) & (w[:, k] <= hi))
        for shift in (2 * np.pi, -2 * np.pi, 4 * np.pi, -4 * np.pi):
            moved = w[:, k] + shift
            hit = todo & (lo <= moved) & (moved <= hi)
            w[hit, k] = moved[hit]
            todo &= ~hit
    return w


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


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def chunk_bounds(n: int, workers: int, chunk_size: int | None) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` covering ``range(n)``: ``chunk_size`` targets each (default:
    about eight chunks per worker, at most `MAX_CHUNK`)."""
    size = chunk_size or max(1, min(MAX_CHUNK, math.ceil(n / (8 * workers))))
    return [(a, min(a + size, n)) for a in range(0, n, size)]


def solve_ik_batch(
    m: Mechanism,
    targets: Any,
    q0: Any = None,
    *,
    method: str = "lm",
    task: str | None = None,
    frame: str | None = None,
    time_limit: float | None = None,
    tol: float | Tolerances | None = None,
    seed: int | np.random.Generator | None = None,
    workers: int | None = None,
    scheduler: Any = None,
    chunk_size: int | None = None,
    retries: int = 2,
    progress: bool = False,
    **options: Any,
) -> BatchResult:
    """Inverse kinematics of many targets: every core, or a Dask cluster.

    Args:
        m: the mechanism.
        targets: ``(N, 4, 4)`` transforms, ``(N, 3)`` positions, or a sequence of
            `optik.Pose2D` / `optik.Position` / 4x4 transforms.
        q0: first start: None (mid-limit), one vector for all, or ``(N, n)``.
        method: IK method (``"lm"``: the compiled chunk kernel; others loop over `optik.solve_ik`).
        task: task space (default from the targets and the mechanism).
        frame: task frame (default: the end effector).
        time_limit: seconds per target (default 0.1, as `optik.solve_ik`).
        tol: tolerances (float: position and orientation) or `optik.Tolerances`.
        seed: batch seed (None: 0) or a Generator (one draw); target ``i`` is solved with seed
            ``result.seed[i]``.
        workers: threads of the local pool (default: the cores available); ignored with
            ``scheduler``.
        scheduler: a ``dask.distributed.Client`` (or a scheduler address) to solve the chunks
            on a Dask cluster.
        chunk_size: targets per chunk (default: about eight chunks per worker, at most 512
            locally).
        retries: Dask retries of a chunk whose worker was lost.
        progress: draw a progress bar on stderr.
        **options: method options (as for `optik.solve_ik`).

    Returns:
        A `optik.batch.BatchResult`, rows in input order.

    Raises:
        OptikError: malformed input (named argument), unknown option or method.
    """
    t0 = time.perf_counter()
    transforms, implied = as_targets(m, targets)
    n = len(transforms)
    starts = as_starts(m, q0, n)
    seed0 = base_seed(seed)
    request = make_request(
        m,
        transforms[0] if n else np.eye(4),
        starts[0] if n else None,
        task or implied,
        frame,
        time_limit,
        tol,
        seed0,
        options,
    )
    spec = ChunkSpec(method, request.task, frame, request.time_limit, request.tol, dict(options))
    if method == "lm":
        lm_settings(request)  # unknown options and bad values raise here, not in a worker
    else:
        get_method(method)
    seeds = target_seeds(seed0, 0, n)
    if workers is not None:
        workers = positive_int(workers, "workers")
    if chunk_size is not None:
        chunk_size = positive_int(chunk_size, "chunk_size")
    bar = Progress(1) if progress else None
    if bar is not None:
        bar.start(f"IK x{n}", n)
    if scheduler is not None:
        from optik.batch.distributed import solve_on_cluster

        parts, used = solve_on_cluster(
            scheduler, m, spec, transforms, starts, seeds, chunk_size, retries, bar.step if bar else None
        )
    else:
        used = workers or default_workers()
        if method == "lm" and n:  # build and compile once, before the threads start
            solve_chunk(m, spec, transforms[:1], starts[:1], seeds[:1])
        bounds = chunk_bounds(n, used, chunk_size)
        parts = _run_threads(m, spec, transforms, starts, seeds, bounds, used, bar.step if bar else None)
    if bar is not None:
        bar.finish()
    if not parts:  # no target
        parts = [_solve_loop(m, spec, transforms, starts, seeds)]
    return BatchResult.concatenate(
        parts, method=method, base_seed=seed0, wall_time=time.perf_counter() - t0, workers=used
    )


def _run_threads(
    m: Mechanism,
    spec: ChunkSpec,
    targets: np.ndarray,
    starts: np.ndarray,
    seeds: np.ndarray,
    bounds: list[tuple[int, int]],
    workers: int,
    step: Callable[[int], None] | None,
) -> list[BatchResult]:
    """Solve the chunks on a thread pool; parts in input order. Ctrl-C cancels the chunks
    not started and re-raises."""
    parts: list[BatchResult | None] = [None] * len(bounds)

    def job(i: int) -> int:
        a, b = bounds[i]
        parts[i] = solve_chunk(m, spec, targets[a:b], starts[a:b], seeds[a:b])
        return b - a

    if workers == 1 or len(bounds) <= 1:
        for i in range(len(bounds)):
            done = job(i)
            if step:
                step(done)
        return [p for p in parts if p is not None]
    pool = ThreadPoolExecutor(max_workers=workers)
    try:
        pending = {pool.submit(job, i) for i in range(len(bounds))}
        while pending:
            finished, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
            for f in finished:
                done = f.result()
                if step:
                    step(done)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return [p for p in parts if p is not None]
