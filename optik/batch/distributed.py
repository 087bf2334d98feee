"""Batch IK on a Dask cluster (``pip install optik[dist]``).

Each chunk of targets is one Dask task running `optik.batch.solve.solve_chunk` on a worker.
The mechanism is shipped once per cluster as the result of a small task (the definition only:
see ``Mechanism.__reduce__``), not as scattered data: the scheduler keeps the task, so when the
worker holding the mechanism dies Dask recomputes it elsewhere (scattered data would be lost
with its worker, and every chunk with it). Each worker fetches it once, unpickles it once and its compiled
kernel, built on the first chunk into the worker machine's cache
(``$OPTIK_CACHE_DIR`` or ``~/.cache/optik``), serves every later chunk. Results are gathered in
input order; a chunk whose worker dies is rerun by Dask on another worker (``retries``). The
answers are those of a local run: each target carries its own seed.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable
from typing import Any

import numpy as np

from optik.batch.chunk import ChunkSpec, chunk_bounds, solve_chunk
from optik.batch.result import BatchResult
from optik.errors import InvalidArgumentError, require_extra
from optik.mechanism import Mechanism
from optik.mechanism.memo import LRU, PerMechanism

_SHIPPED: PerMechanism[dict[str, Any]] = PerMechanism()
"""The future of each shipped mechanism per client id (ship a mechanism once per cluster)."""

WORKER_MECHANISMS = 16
"""How many shipped mechanisms a worker process keeps (with their built kernels), the least
recently used dropped past it: a worker serving many clients or mechanisms stays bounded."""

_ON_WORKER: LRU[str, Mechanism] = LRU(WORKER_MECHANISMS)
"""In a worker process: the first copy of each shipped mechanism by its key, so that every
later chunk (even one given another deserialized copy) reuses its built and compiled kernel
(at most `WORKER_MECHANISMS` of them)."""


def client_of(scheduler: Any) -> Any:
    """A ``dask.distributed.Client``: the one given, or one connected to a scheduler address.

    Raises:
        MissingExtraError: dask.distributed is not installed (``pip install "optik[dist]"``).
        InvalidArgumentError: ``scheduler`` is neither a Client nor the address of a scheduler
            that answers (``"tcp://host:port"`` or ``"host:port"``).
    """
    wrong = f"expected a dask.distributed.Client or an address, got {type(scheduler).__name__}"
    if not isinstance(scheduler, str) and type(scheduler).__name__ != "Client":
        raise InvalidArgumentError("scheduler", wrong)  # wrong whether Dask is installed or not
    distributed = require_extra("distributed", "dist", "solve_ik_batch(scheduler=...)")
    if isinstance(scheduler, distributed.Client):
        return scheduler
    if not isinstance(scheduler, str):
        raise InvalidArgumentError("scheduler", wrong)
    try:
        return distributed.Client(scheduler)
    except (ValueError, TypeError, OSError) as exc:  # OSError: TimeoutError, refused connections
        raise InvalidArgumentError(
            "scheduler",
            f"no Dask scheduler at {scheduler!r} ({exc or type(exc).__name__}); "
            "expected a Client or an address such as 'tcp://127.0.0.1:8786'",
        ) from None


def _ship(key: str, m: Mechanism) -> tuple[str, Mechanism]:
    return key, m


def shipped(client: Any, m: Mechanism) -> Any:
    """The future of ``(key, m)`` on ``client``'s cluster: a task's result, so Dask recomputes it
    when its worker is lost (made on first use; the key names this mechanism on the workers)."""
    per_client = _SHIPPED.setdefault(m, {})
    if client.id not in per_client:
        per_client[client.id] = client.submit(_ship, uuid.uuid4().hex, m, pure=False)
    return per_client[client.id]


def solve_shipped(
    shipped: tuple[str, Mechanism],
    spec: ChunkSpec,
    targets: np.ndarray,
    starts: np.ndarray,
    seeds: np.ndarray,
) -> BatchResult:
    """`solve_chunk` on a worker with the worker's one copy of the shipped mechanism."""
    key, m = shipped
    return solve_chunk(_ON_WORKER.setdefault(key, m), spec, targets, starts, seeds)


def solve_on_cluster(
    scheduler: Any,
    m: Mechanism,
    spec: ChunkSpec,
    targets: np.ndarray,
    starts: np.ndarray,
    seeds: np.ndarray,
    chunk_size: int | None,
    retries: int,
    step: Callable[[int], None] | None = None,
) -> tuple[list[BatchResult], int]:
    """Solve the chunks as Dask tasks; the parts in input order and the number of workers.

    Default chunks: about eight per worker thread, at most 4096 targets.
    """
    client = client_of(scheduler)
    from distributed import as_completed

    threads = sum(client.nthreads().values()) or 1
    workers = len(client.nthreads()) or 1
    n = len(targets)
    size = chunk_size or max(1, min(4096, -(-n // (8 * threads))))
    bounds = chunk_bounds(n, threads, size)
    mf = shipped(client, m)
    futures = [
        client.submit(
            solve_shipped, mf, spec, targets[a:b], starts[a:b], seeds[a:b], retries=retries, pure=False
        )
        for a, b in bounds
    ]
    sizes = {f.key: b - a for f, (a, b) in zip(futures, bounds, strict=True)}
    try:
        for f in as_completed(futures):
            if step:
                step(sizes[f.key])
        parts = client.gather(futures)
    except KeyboardInterrupt:
        client.cancel(futures)
        raise
    return list(parts), workers
