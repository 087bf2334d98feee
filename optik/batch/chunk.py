"""One chunk of a batch: what every chunk shares (`ChunkSpec`) and `solve_chunk`, the unit of
work of the local thread pool and of a Dask task."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optik import spatial
from optik.batch.result import BatchResult
from optik.mechanism import Mechanism
from optik.solvers import solve_ik
from optik.solvers.base import Tolerances, make_request
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
    if k.library is not None:
        k.library.wait()  # a batch is worth the C build (the Python loop is far slower per target)
    rows = target_rows(targets)
    out = k.run(rows, q0, seeds, settings.conf(m))
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
                errors[i] = k.final_errors(row, rows[i])
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
        keep = todo & (lo <= q[:, k]) & (q[:, k] <= hi)  # as m.wrap: within the limits already
        w[keep, k] = q[keep, k]
        todo &= ~keep
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
