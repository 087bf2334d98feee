"""`solve_ik_batch`: many IK targets on every core, or on a Dask cluster.

The targets are cut into chunks. With method ``"lm"`` a chunk is one call of the compiled
kernel (`optik.solvers.lm_kernel`): the whole multi-start loop of every target runs in C and
the call releases the GIL, so a thread pool keeps every core busy. With ``"closed_form"`` on
an arm whose closed form is derived (UR, PUMA-like 6R arms) each target is one call of the
compiled driver and the answers are checked by one vectorized FK, in the calling thread;
other methods loop over `optik.solve_ik` per target. The build and compile before the first
chunk is timed apart (``BatchResult.compile_time``, not counted in its throughput). Target
``i`` is solved with seed ``target_seeds(seed)[i]`` and its own time limit, so the answers
depend neither on the chunking nor on the number of threads or Dask workers, and
``solve_ik(m, targets[i], q0[i], seed=result.seed[i], ...)`` gives the same answer
(``result.seed`` holds the seeds). With ``scheduler=`` a ``dask.distributed.Client``, the
chunks are Dask tasks (`optik.batch.distributed`).
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from typing import Any

import numpy as np

from optik.batch.chunk import ChunkSpec, chunk_bounds, prepare, solve_chunk
from optik.batch.fk import default_workers
from optik.batch.inputs import as_starts, as_targets, target_seed_array
from optik.batch.result import BatchResult
from optik.checks import as_bool
from optik.collision.world import World
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.progress import Progress
from optik.solvers.base import Tolerances, get_method, make_request, positive_int
from optik.solvers.lm import lm_settings


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
    seed: int | np.random.Generator | Sequence[int] | np.ndarray | None = None,
    workers: int | None = None,
    scheduler: Any = None,
    chunk_size: int | None = None,
    retries: int = 2,
    progress: bool = False,
    world: Any = None,
    self_collision: bool | None = None,
    margin: float = 0.0,
    contacts: Any = None,
    support: Any = None,
    com_margin: float = 0.0,
    **options: Any,
) -> BatchResult:
    """Inverse kinematics of many targets: every core, or a Dask cluster.

    Args:
        m: the mechanism.
        targets: ``(N, 4, 4)`` transforms, ``(N, 3)`` positions, or a sequence of
            `optik.Pose2D` / `optik.Position` / 4x4 transforms.
        q0: first start: None (mid-limit), one vector for all, or ``(N, n)``.
        method: IK method (``"lm"``: the compiled chunk kernel; ``"closed_form"`` on an arm with
            a derived closed form: its compiled driver, one thread; others loop over
            `optik.solve_ik`).
        task: task space (default from the targets and the mechanism).
        frame: task frame (default: the end effector).
        time_limit: seconds per target (default 0.1, as `optik.solve_ik`).
        tol: tolerances (float: position and orientation) or `optik.Tolerances`.
        seed: batch seed (None: 0) or a Generator (one draw); target ``i`` is solved with seed
            ``result.seed[i]``. Or one int per target (e.g. ``result.seed[rows]`` of an earlier
            batch, to solve some of its targets again with their own seeds).
        workers: threads of the local pool (default: the cores available); ignored with
            ``scheduler`` and by ``"closed_form"`` (one thread: its calls hold the GIL).
        scheduler: a ``dask.distributed.Client`` (or a scheduler address) to solve the chunks
            on a Dask cluster.
        chunk_size: targets per chunk (default: about eight chunks per worker, at most 512
            locally).
        retries: Dask retries of a chunk whose worker was lost.
        progress: draw a progress bar on stderr.
        world: obstacles ([`optik.World`][optik.World]); with it or ``self_collision=True`` every
            target is one collision-aware `optik.solve_ik` (``lm`` or ``nlp``, on the local
            threads): success needs the exact check at ``margin``, a reached pose that collides
            has status ``"in_collision"``.
        self_collision: keep the robot clear of itself (None: True when ``world`` is given).
        margin: the clearance (m).
        contacts, support, com_margin: frames held in the world and static balance, as for
            `optik.solve_ik` (the same for every target; methods ``"lm"``, ``"nlp"``, ``"qp"`` with
            ``support``): each target is one `optik.solve_ik` call on the thread pool (the
            compiled ``lm`` balance kernel releases the GIL), its balance checked as there.
        **options: method options (as for `optik.solve_ik`).

    Returns:
        A `optik.batch.BatchResult`, rows in input order.

    Raises:
        OptikError: malformed input (named argument), unknown option or method.
    """
    t0 = time.perf_counter()
    compile_time = 0.0
    transforms, implied = as_targets(m, targets)
    n = len(transforms)
    starts = as_starts(m, q0, n)
    seeds, seed0 = target_seed_array(seed, n)
    request = make_request(
        m,
        transforms[0] if n else np.eye(4),
        starts[0] if n else None,
        task or implied,
        frame,
        time_limit,
        tol,
        0,
        options,
    )
    spec = ChunkSpec(method, request.task, frame, request.time_limit, request.tol, dict(options))
    own = (world is not None) if self_collision is None else as_bool(self_collision, "self_collision")
    if world is not None or own:
        if world is not None and not isinstance(world, World):
            raise InvalidArgumentError(
                "world", f"expected an optik.World or None, got {type(world).__name__}"
            )
        if scheduler is not None:
            raise InvalidArgumentError(
                "scheduler", "a collision-aware batch runs on local threads (the World is not sent to Dask)"
            )
        spec.collisions.update(world=world, self_collision=own, margin=margin)
    spec.balance.update(
        (k, v)
        for k, v in (("contacts", contacts), ("support", support), ("com_margin", com_margin))
        if v is not None and not (k == "com_margin" and v == 0.0)
    )
    if spec.balance and n:  # validated (and its code built) by one solve of the first target
        prepare(m, spec, transforms[0], starts[0])
    elif method == "lm":
        lm_settings(request)  # unknown options and bad values raise here, not in a worker
    else:
        get_method(method)
    if workers is not None:
        workers = positive_int(workers, "workers")
    if chunk_size is not None:
        chunk_size = positive_int(chunk_size, "chunk_size")
    bar = Progress(1) if as_bool(progress, "progress") else None
    if bar is not None:
        bar.start(f"IK x{n}", n)
    if scheduler is not None:
        from optik.batch.distributed import solve_on_cluster

        parts, used = solve_on_cluster(
            scheduler, m, spec, transforms, starts, seeds, chunk_size, retries, bar.step if bar else None
        )
    else:
        # the compiled closed form holds the GIL for its microseconds: threads would only contend
        used = 1 if method == "closed_form" else workers or default_workers()
        if n:  # build and compile once, before the threads start
            t_build = time.perf_counter()
            prepare(m, spec, transforms[0], starts[0])
            compile_time = time.perf_counter() - t_build
        bounds = chunk_bounds(n, used, chunk_size)
        parts = _run_threads(m, spec, transforms, starts, seeds, bounds, used, bar.step if bar else None)
    if bar is not None:
        bar.finish()
    if not parts:  # no target
        parts = [solve_chunk(m, spec, transforms, starts, seeds)]
    return BatchResult.concatenate(
        parts,
        method=method,
        base_seed=seed0,
        wall_time=time.perf_counter() - t0,
        workers=used,
        compile_time=compile_time,
        coordinate_names=tuple(m.coordinate_names),
    )


@contextlib.contextmanager
def _deferred_sigint() -> Iterator[threading.Event]:
    """Hold Ctrl-C while the calling thread waits on the pool: an event set by SIGINT, which the
    waiting loop turns into ``KeyboardInterrupt`` between two waits (within 0.5 s).

    A ``KeyboardInterrupt`` raised inside ``concurrent.futures.wait`` can land between a
    condition's release and re-acquire (CPython's ``threading.Condition.wait``), and the wait
    then fails with ``RuntimeError: release unlocked lock`` instead of the interrupt. Only the
    main thread receives signals, and only Python's default handler is replaced (a caller's own
    handler is left alone); the previous handler is restored on exit.
    """
    interrupted = threading.Event()
    if threading.current_thread() is not threading.main_thread() or (
        signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield interrupted
        return
    previous = signal.signal(signal.SIGINT, lambda signum, frame: interrupted.set())
    try:
        yield interrupted
    finally:
        signal.signal(signal.SIGINT, previous)


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
        with _deferred_sigint() as interrupted:
            pending = {pool.submit(job, i) for i in range(len(bounds))}
            while pending:
                finished, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
                if interrupted.is_set():
                    raise KeyboardInterrupt
                for f in finished:
                    done = f.result()
                    if step:
                        step(done)
            if interrupted.is_set():  # Ctrl-C during the last wait: not dropped
                raise KeyboardInterrupt
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return [p for p in parts if p is not None]
