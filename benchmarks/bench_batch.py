"""Batch IK on the Franka Panda: ``solve_ik_batch`` on W threads against TRAC-IK on 1 and on W processes.

Method: the Panda chain is loaded from the shipped URDF (``panda_link0`` -> ``panda_link8``) by
optik and by the TRAC-IK peer of `optik.harness.peers` (``pytracik``, Speed mode). ``--n`` joint
vectors are drawn uniformly within the limits (seeded), the targets are their FK poses, and each
target gets a random start (also seeded), the same for every solver; tolerance ``--tol`` (1e-5)
and time limit ``--time-limit`` (5 ms) per target. The targets are processed in blocks of
``--block``; every block is solved by ``optik.solve_ik_batch(..., workers=W)`` (``--workers``
threads), by TRAC-IK in a loop on one thread, and by TRAC-IK in a pool of W processes (the same
core count as optik: each process has its own solver and takes a contiguous share of the block),
in a rotating order so that load changes of a shared machine hit all of them; each solver's
throughput is its targets over the sum of its blocks' wall times (the batch call's validation,
thread pool and result assembly included; the pool's pickling and dispatch included). Every
solver is held to the rules of `optik.harness.peers.rules`: asked for half the tolerance
(TRAC-IK: ``eps = tol / 2`` per twist component), warmed up untimed (optik builds its kernel,
every pool process builds its solver and solves once), every answer clipped into the limits (the
raw overshoot is reported), and success judged for all by one referee (Pinocchio's FK on the same
URDF where installed): position error and geodesic orientation error <= ``--tol`` and the joint
limits satisfied exactly. The table gives the IK/s, the IK/s per core (throughput over the
threads or processes used) and the mean / median / p95 over the blocks of the wall time per
target. Equality: on ``--n-check`` sampled targets,
``optik.solve_ik(m, T[i], q0[i], method="lm", seed=res.seed[i])`` must return exactly the
batch's ``q`` (bitwise) and iteration count, where neither hit the time limit. Dask: the first
``--n-dask`` targets on a ``LocalCluster`` of one and of two worker processes (one thread
each), timed after a warm-up that ships the mechanism and builds each worker's kernel, both
clusters up at once and used in alternating blocks (``--dask-blocks``); the answers are
compared with the local run. The load average (``/proc/loadavg``) is printed before and after:
on a shared machine the numbers are depressed.

Run: ``optik benchmark batch [--n 100000] [--block 5000] [--tol 1e-5] [--time-limit 0.005]
[--workers 2] [--n-check 1000] [--n-dask 20000] [--dask-blocks 6] [--seed 0]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import itertools  # noqa: E402
import logging  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik.batch.fk import default_workers  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.catalog.arms import URDF_CHAINS, urdf_path  # noqa: E402
from optik.harness.peers import PeerUnavailable, TracIK  # noqa: E402
from optik.harness.peers.rules import Referee, warm_up  # noqa: E402
from optik.harness.tally import timing_ms  # noqa: E402
from optik.solvers.lm_kernel import target_seeds  # noqa: E402


def load_average() -> str:
    """The 1, 5 and 15 minute load averages (``/proc/loadavg``), or ``"n/a"``."""
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "n/a"


OPTIK, TRACIK_1, TRACIK_POOL = (
    "optik solve_ik_batch",
    "TRAC-IK (Speed), 1 thread",
    "TRAC-IK (Speed), process pool",
)

_WORKER: dict[str, object] = {}
"""The TRAC-IK solver of a pool process (built by `_pool_init`)."""


def _pool_init(chain: tuple[str, str, str], time_limit: float, tol: optik.Tolerances) -> None:
    path, base, tip = chain
    m = optik.Mechanism.from_urdf(path, base, tip)
    _WORKER.update(peer=TracIK(m, Path(path), base, tip), limit=time_limit, tol=tol)


def _pool_part(targets: np.ndarray, q0: np.ndarray) -> list[np.ndarray]:
    peer, limit, tol = _WORKER["peer"], _WORKER["limit"], _WORKER["tol"]
    return [peer.attempt(s, t, limit, tol)[0] for s, t in zip(q0, targets, strict=True)]  # type: ignore[attr-defined]


def _pool_solve(
    pool: ProcessPoolExecutor | None, targets: np.ndarray, q0: np.ndarray, workers: int
) -> list[np.ndarray]:
    """TRAC-IK on the pool's processes, each taking a contiguous share of the targets."""
    assert pool is not None
    cuts = np.linspace(0, len(targets), workers + 1).astype(int)
    futures = [pool.submit(_pool_part, targets[a:b], q0[a:b]) for a, b in itertools.pairwise(cuts)]
    return [q for f in futures for q in f.result()]


def compare(a: optik.BatchResult, b: optik.BatchResult) -> str:
    """How two runs of the same targets and seeds agree: bitwise ``q`` and iterations where
    neither hit the time limit (there the clock decides)."""
    timed = (a.status == "time_limit") | (b.status == "time_limit")
    same = (a.q == b.q).all(axis=1) & (a.iterations == b.iterations)
    differ = int((~same & ~timed).sum())
    return f"{int(same.sum())} identical, {differ} differ, {int(timed.sum())} time-limited in either run"


def dask_runs(
    m: optik.Mechanism,
    targets: np.ndarray,
    q0: np.ndarray,
    seeds: np.ndarray,
    local: optik.BatchResult,
    opts: dict,
    blocks: int,
) -> list[str]:
    """Throughput on LocalClusters of one and of two worker processes (one thread each), both
    up at once and used in alternation block by block, and agreement with the local run."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        return ['Dask: dask.distributed is not installed (pip install "optik[dist]"): skipped']
    logging.getLogger("distributed").setLevel(logging.ERROR)
    clusters = {
        w: LocalCluster(
            n_workers=w, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
        )
        for w in (1, 2)
    }
    clients = {w: Client(c) for w, c in clusters.items()}
    try:
        for c in clients.values():  # warm-up: ship the mechanism, build every worker's kernel
            optik.solve_ik_batch(m, targets[:400], q0[:400], scheduler=c, **opts)
        wall = {1: 0.0, 2: 0.0}
        parts: dict[int, list[optik.BatchResult]] = {1: [], 2: []}
        bounds = np.linspace(0, len(targets), blocks + 1).astype(int)
        for k, (a, b) in enumerate(itertools.pairwise(bounds)):
            for w in (1, 2) if k % 2 == 0 else (2, 1):
                res = optik.solve_ik_batch(
                    m, targets[a:b], q0[a:b], scheduler=clients[w], **opts, seed=seeds[a:b]
                )
                wall[w] += res.wall_time
                parts[w].append(res)
    finally:
        for w in clients:
            clients[w].close()
            clusters[w].close()
    lines = []
    for w in (1, 2):
        res = optik.BatchResult.concatenate(parts[w])
        lines.append(
            f"| Dask LocalCluster, {w} worker(s) | {len(res)} | {100 * res.success_rate:.2f} | "
            f"{wall[w]:.2f} | {len(res) / wall[w]:,.0f} | {compare(res, local)} |"
        )
    lines.append(f"\nDask 2 workers / 1 worker throughput (alternating blocks): {wall[1] / wall[2]:.2f}x")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point (also called by ``optik benchmark batch``)."""
    p = benchmark_parser("batch", __doc__)
    p.add_argument("--n", type=int, default=100_000, help="number of targets")
    p.add_argument("--block", type=int, default=5000, help="targets per alternating block")
    p.add_argument("--tol", type=float, default=1e-5, help="position / orientation tolerance")
    p.add_argument("--time-limit", type=float, default=0.005, help="time limit per target (s)")
    p.add_argument("--workers", type=int, default=default_workers(), help="threads of solve_ik_batch")
    p.add_argument("--n-check", type=int, default=1000, help="targets compared with solve_ik")
    p.add_argument("--n-dask", type=int, default=20_000, help="targets of the Dask runs (0: skip)")
    p.add_argument("--dask-blocks", type=int, default=6, help="alternating blocks of the Dask runs")
    p.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    args = p.parse_args(argv)
    print(f"load average before: {load_average()}  (cores: {os.cpu_count()})")
    path, (base, tip) = str(urdf_path("panda")), URDF_CHAINS["panda"]
    m = optik.Mechanism.from_urdf(path, base, tip)
    targets = optik.fk_batch(m, m.random_q(args.n, seed=args.seed))
    q0 = m.random_q(args.n, seed=args.seed + 1)
    opts = {"tol": args.tol, "time_limit": args.time_limit}
    seeds = target_seeds(args.seed, 0, args.n)  # the seeds of one batch of all targets, block by block
    tolerances = optik.Tolerances(position=args.tol, orientation=args.tol)
    chain = (path, base, tip)
    warm_up([lambda: optik.solve_ik_batch(m, targets[:10], q0[:10], workers=args.workers, **opts)])
    try:
        tracik: TracIK | None = TracIK(m, Path(path), base, tip)
    except PeerUnavailable as exc:
        tracik = None
        print(f"TRAC-IK skipped: {exc}")
    pool = None
    if tracik is not None:
        pool = ProcessPoolExecutor(
            args.workers, initializer=_pool_init, initargs=(chain, opts["time_limit"], tolerances)
        )
        warm_up(
            [
                lambda: tracik.attempt(q0[0], targets[0], args.time_limit, tolerances),
                lambda: _pool_solve(pool, targets[:40], q0[:40], args.workers),
            ]
        )
    parts: list[optik.BatchResult] = []
    walls: dict[str, list[float]] = {OPTIK: [], TRACIK_1: [], TRACIK_POOL: []}
    answers: dict[str, list[np.ndarray]] = {TRACIK_1: [], TRACIK_POOL: []}
    blocks = [(a, min(a + args.block, args.n)) for a in range(0, args.n, args.block)]
    for k, (a, b) in enumerate(blocks):

        def run_optik(a: int = a, b: int = b) -> None:
            t0 = time.perf_counter()
            parts.append(
                optik.solve_ik_batch(m, targets[a:b], q0[a:b], workers=args.workers, **opts, seed=seeds[a:b])
            )
            walls[OPTIK].append(time.perf_counter() - t0)

        def run_tracik(a: int = a, b: int = b) -> None:
            assert tracik is not None
            t0 = time.perf_counter()
            qs = [tracik.attempt(q0[i], targets[i], args.time_limit, tolerances)[0] for i in range(a, b)]
            walls[TRACIK_1].append(time.perf_counter() - t0)
            answers[TRACIK_1] += qs

        def run_pool(a: int = a, b: int = b) -> None:
            t0 = time.perf_counter()
            qs = _pool_solve(pool, targets[a:b], q0[a:b], args.workers)
            walls[TRACIK_POOL].append(time.perf_counter() - t0)
            answers[TRACIK_POOL] += qs

        runs = [run_optik] if tracik is None else [run_optik, run_tracik, run_pool]
        for i in range(len(runs)):
            runs[(i + k) % len(runs)]()
    if pool is not None:
        pool.shutdown()
    res = optik.BatchResult.concatenate(parts, wall_time=sum(walls[OPTIK]), workers=args.workers)
    referee = Referee(m, path, base, tip)
    answers[OPTIK] = list(res.q)
    print(
        f"\nPanda (URDF), {args.n} FK targets, random starts, tol {args.tol:g} (every solver asked for "
        f"tol / 2), time limit {args.time_limit * 1e3:g} ms, blocks of {args.block} in rotating order; "
        f"answers clipped into the limits, success by {referee.source}'s FK and the exact limits\n"
    )
    print(
        "| solver | cores | targets | success % | max overshoot | wall s | IK/s | IK/s per core "
        "| us per target, per block: mean / median / p95 | IK/s / TRAC-IK on as many cores |\n"
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|"
    )
    cores = {OPTIK: args.workers, TRACIK_1: 1, TRACIK_POOL: args.workers}
    rate = {name: args.n / sum(w) for name, w in walls.items() if w}
    same_cores = {
        OPTIK: TRACIK_POOL if args.workers > 1 else TRACIK_1,
        TRACIK_1: TRACIK_1,
        TRACIK_POOL: TRACIK_POOL,
    }
    for name in (TRACIK_1, TRACIK_POOL, OPTIK):
        if name not in rate:
            continue
        verdicts = [referee.judge(q, t, tolerances) for q, t in zip(answers[name], targets, strict=True)]
        ok = 100.0 * float(np.mean([v.success for v in verdicts]))
        over = max(v.overshoot for v in verdicts)
        per_target = np.asarray(walls[name]) / np.asarray([b - a for a, b in blocks])  # s
        mean, median, p95 = (1e3 * ms for ms in timing_ms(per_target))  # us
        peer = same_cores[name]
        ratio = f"{rate[name] / rate[peer]:.2f}" if peer in rate else "-"
        print(
            f"| {name} | {cores[name]} | {args.n} | {ok:.2f} | {over:.1e} | {sum(walls[name]):.2f} "
            f"| {rate[name]:,.0f} | {rate[name] / cores[name]:,.0f} "
            f"| {mean:.1f} / {median:.1f} / {p95:.1f} | {ratio} |"
        )
    names, counts = np.unique(res.status, return_counts=True)
    counts_text = ", ".join(f"{k} {int(v):,}" for k, v in zip(names, counts, strict=True))
    print(f"\noptik status counts: {counts_text}")
    rng = np.random.default_rng(args.seed)
    sample = rng.choice(args.n, size=min(args.n_check, args.n), replace=False)
    equal = timed_out = 0
    for i in sample:
        one = optik.solve_ik(
            m, targets[i], q0[i], method="lm", tol=args.tol, time_limit=args.time_limit, seed=int(res.seed[i])
        )
        if "time_limit" in (res.status[i], one.status):
            timed_out += 1
        else:
            equal += bool(np.array_equal(one.q, res.q[i]) and one.iterations == res.iterations[i])
    print(
        f"equal to solve_ik(seed=res.seed[i]) on {len(sample)} sampled targets: {equal} of the "
        f"{len(sample) - timed_out} where neither call hit the time limit ({timed_out} did: there the "
        "clock decides)"
    )
    if args.n_dask:
        nd = min(args.n_dask, args.n)
        local = optik.solve_ik_batch(m, targets[:nd], q0[:nd], workers=args.workers, **opts, seed=seeds[:nd])
        print("\n| run | targets | success % | wall s | IK/s | answers |\n|---|--:|--:|--:|--:|---|")
        print(
            f"| local threads, {args.workers} | {nd} | {100 * local.success_rate:.2f} | "
            f"{local.wall_time:.2f} | {local.throughput:,.0f} | - |"
        )
        for line in dask_runs(m, targets[:nd], q0[:nd], seeds[:nd], local, opts, args.dask_blocks):
            print(line)
    print(f"\nload average after: {load_average()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
