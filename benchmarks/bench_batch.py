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
clusters up at once and used in alternating blocks (``--dask-blocks``), beside a TRAC-IK process
pool of the same size (1 and 2 processes) in the same alternation; every row gives its cores, its
success by the referee, its IK/s per core and the ratio to the TRAC-IK pool of as many processes,
and the Dask answers are compared with the local run. PyRoki (``--pyroki DIR``, the folder of a
checkout; `optik.harness.peers.pyroki_peer`, skipped and said so without it) solves the first
``--n-pyroki`` targets in the same rotation, block by block, by its beam of ``--pyroki-seeds``
seeds compiled once for the block size (untimed warm-up); JAX uses every core, so its row compares
with the TRAC-IK pool when that has as many processes. The load average (``/proc/loadavg``) is
printed before and after: on a shared machine the numbers are depressed.

Run: ``optik benchmark batch [--n 100000] [--block 5000] [--tol 1e-5] [--time-limit 0.005]
[--workers 2] [--n-check 1000] [--n-dask 20000] [--dask-blocks 6] [--pyroki DIR] [--n-pyroki 2000]
[--pyroki-seeds 64] [--seed 0]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import itertools  # noqa: E402
import logging  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik.batch.fk import default_workers  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.catalog.arms import URDF_CHAINS, urdf_path  # noqa: E402
from optik.harness.peers import PeerUnavailable, TracIK  # noqa: E402
from optik.harness.peers.pyroki_peer import PyRokiBatch  # noqa: E402
from optik.harness.peers.rules import Referee, warm_up  # noqa: E402
from optik.harness.tally import timing_ms  # noqa: E402
from optik.solvers.lm_kernel import target_seeds  # noqa: E402


def load_average() -> str:
    """The 1, 5 and 15 minute load averages (``/proc/loadavg``), or ``"n/a"``."""
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "n/a"


OPTIK, TRACIK_1, TRACIK_POOL, PYROKI = (
    "optik solve_ik_batch",
    "TRAC-IK (Speed), 1 thread",
    "TRAC-IK (Speed), process pool",
    "PyRoki beam (JAX, CPU)",
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


def _pool(workers: int, chain: tuple[str, str, str], time_limit: float, tol: optik.Tolerances):
    """A pool of ``workers`` TRAC-IK processes (each builds its own solver)."""
    return ProcessPoolExecutor(workers, initializer=_pool_init, initargs=(chain, time_limit, tol))


def dask_runs(
    m: optik.Mechanism,
    targets: np.ndarray,
    q0: np.ndarray,
    seeds: np.ndarray,
    local: optik.BatchResult,
    opts: dict,
    blocks: int,
    judge: Callable[[Sequence[np.ndarray], np.ndarray], tuple[float, float]],
    chain: tuple[str, str, str] | None,
) -> list[str]:
    """Throughput on LocalClusters of one and of two worker processes (one thread each) and, beside
    each, a TRAC-IK pool of as many processes (``chain``; None: TRAC-IK is not installed), all up at
    once and used in alternation block by block; success by ``judge`` (the referee), agreement of
    the Dask answers with the local run, IK/s per core and the ratio to the pool of the same size."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        return ['Dask: dask.distributed is not installed (pip install "optik[dist]"): skipped']
    logging.getLogger("distributed").setLevel(logging.ERROR)
    sizes = (1, 2)
    clusters = {
        w: LocalCluster(
            n_workers=w, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
        )
        for w in sizes
    }
    clients = {w: Client(c) for w, c in clusters.items()}
    tol = optik.Tolerances(position=opts["tol"], orientation=opts["tol"])
    pools = {w: _pool(w, chain, opts["time_limit"], tol) for w in sizes} if chain is not None else {}
    wall = {(kind, w): 0.0 for kind in ("dask", "pool") for w in sizes}
    parts: dict[int, list[optik.BatchResult]] = {w: [] for w in sizes}
    pooled: dict[int, list[np.ndarray]] = {w: [] for w in sizes}
    try:
        for w in sizes:  # warm-up: ship the mechanism, build every worker's kernel / solver
            optik.solve_ik_batch(m, targets[:400], q0[:400], scheduler=clients[w], **opts)
            if w in pools:
                _pool_solve(pools[w], targets[:40], q0[:40], w)
        bounds = np.linspace(0, len(targets), blocks + 1).astype(int)
        for k, (a, b) in enumerate(itertools.pairwise(bounds)):
            order = [(kind, w) for w in sizes for kind in ("dask", "pool") if kind == "dask" or w in pools]
            for kind, w in order if k % 2 == 0 else order[::-1]:
                t0 = time.perf_counter()
                if kind == "dask":
                    res = optik.solve_ik_batch(
                        m, targets[a:b], q0[a:b], scheduler=clients[w], **opts, seed=seeds[a:b]
                    )
                    parts[w].append(res)
                    wall[kind, w] += res.wall_time
                else:
                    pooled[w] += _pool_solve(pools[w], targets[a:b], q0[a:b], w)
                    wall[kind, w] += time.perf_counter() - t0
    finally:
        for w in sizes:
            clients[w].close()
            clusters[w].close()
            if w in pools:
                pools[w].shutdown()
    lines = []
    n = len(targets)
    for w in sizes:
        res = optik.BatchResult.concatenate(parts[w])
        ok, _ = judge(list(res.q), targets)
        rate = n / wall["dask", w]
        pool_rate = n / wall["pool", w] if w in pools else float("nan")
        lines.append(
            f"| Dask LocalCluster, {w} worker(s) | {w} | {n} | {ok:.2f} | {wall['dask', w]:.2f} "
            f"| {rate:,.0f} | {rate / w:,.0f} | {compare(res, local)} | {rate / pool_rate:.2f} |"
        )
        if w in pools:
            ok, _ = judge(pooled[w], targets)
            lines.append(
                f"| {TRACIK_POOL} of {w} | {w} | {n} | {ok:.2f} | {wall['pool', w]:.2f} | {pool_rate:,.0f} "
                f"| {pool_rate / w:,.0f} | - | 1.00 |"
            )
    lines.append(
        "\nDask 2 workers / 1 worker throughput (alternating blocks): "
        f"{wall['dask', 1] / wall['dask', 2]:.2f}x"
    )
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
    p.add_argument("--pyroki", default=None, help="folder of a PyRoki checkout (the optional batch peer)")
    p.add_argument("--n-pyroki", type=int, default=2000, help="targets PyRoki solves (its first blocks)")
    p.add_argument("--pyroki-seeds", type=int, default=64, help="seeds of PyRoki's beam")
    p.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    args = p.parse_args(argv)
    if min(args.n, args.block, args.workers, args.n_pyroki, args.pyroki_seeds) < 1 or args.pyroki_seeds < 4:
        p.error("--n, --block, --workers, --n-pyroki must be >= 1, --pyroki-seeds >= 4")
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
        pool = _pool(args.workers, chain, args.time_limit, tolerances)
        warm_up(
            [
                lambda: tracik.attempt(q0[0], targets[0], args.time_limit, tolerances),
                lambda: _pool_solve(pool, targets[:40], q0[:40], args.workers),
            ]
        )
    pyroki: PyRokiBatch | None = None
    if args.pyroki is None:
        print("PyRoki skipped: no checkout given (--pyroki DIR)")
    else:
        try:
            pyroki = PyRokiBatch(args.pyroki, m, path, tip, batch=args.block, seeds=args.pyroki_seeds)
            t0 = time.perf_counter()
            warm_up([lambda: pyroki.solve(targets[:1], q0[:1])])  # compiles the beam for one block
            print(f"PyRoki: beam of {args.pyroki_seeds} seeds compiled in {time.perf_counter() - t0:.0f} s")
        except PeerUnavailable as exc:
            print(f"PyRoki skipped: {exc}")
    parts: list[optik.BatchResult] = []
    walls: dict[str, list[float]] = {OPTIK: [], TRACIK_1: [], TRACIK_POOL: [], PYROKI: []}
    solved: dict[str, list[int]] = {name: [] for name in walls}  # targets per timed block
    answers: dict[str, list[np.ndarray]] = {TRACIK_1: [], TRACIK_POOL: [], PYROKI: []}
    blocks = [(a, min(a + args.block, args.n)) for a in range(0, args.n, args.block)]

    def timed(name: str, a: int, b: int, solve: Callable[[], object]) -> None:
        t0 = time.perf_counter()
        out = solve()
        walls[name].append(time.perf_counter() - t0)
        solved[name].append(b - a)
        if name in answers:
            answers[name] += list(out)  # type: ignore[call-overload]
        else:
            parts.append(out)  # type: ignore[arg-type]

    for k, (a, b) in enumerate(blocks):
        runs: list[tuple[str, Callable[[], object]]] = [
            (
                OPTIK,
                lambda a=a, b=b: optik.solve_ik_batch(
                    m, targets[a:b], q0[a:b], workers=args.workers, **opts, seed=seeds[a:b]
                ),
            )
        ]
        if tracik is not None:
            runs += [
                (
                    TRACIK_1,
                    lambda a=a, b=b: [
                        tracik.attempt(q0[i], targets[i], args.time_limit, tolerances)[0] for i in range(a, b)
                    ],
                ),
                (TRACIK_POOL, lambda a=a, b=b: _pool_solve(pool, targets[a:b], q0[a:b], args.workers)),
            ]
        if pyroki is not None and a < args.n_pyroki:
            runs.append((PYROKI, lambda a=a, b=b: pyroki.solve(targets[a:b], q0[a:b])))
        for i in range(len(runs)):
            name, solve = runs[(i + k) % len(runs)]
            timed(name, a, b, solve)
    if pool is not None:
        pool.shutdown()
    res = optik.BatchResult.concatenate(parts, wall_time=sum(walls[OPTIK]), workers=args.workers)
    referee = Referee(m, path, base, tip)
    answers[OPTIK] = list(res.q)

    def judge(qs: Sequence[np.ndarray], goals: np.ndarray) -> tuple[float, float]:
        """Success % by the referee and the largest raw overshoot of ``qs`` on ``goals[:len(qs)]``."""
        verdicts = [referee.judge(q, t, tolerances) for q, t in zip(qs, goals[: len(qs)], strict=True)]
        return 100.0 * float(np.mean([v.success for v in verdicts])), max(v.overshoot for v in verdicts)

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
    cores = {OPTIK: args.workers, TRACIK_1: 1, TRACIK_POOL: args.workers, PYROKI: os.cpu_count() or 1}
    rate = {name: sum(solved[name]) / sum(w) for name, w in walls.items() if w}
    same_cores = {name: TRACIK_POOL if c > 1 else TRACIK_1 for name, c in cores.items()}
    for name in (TRACIK_1, TRACIK_POOL, PYROKI, OPTIK):
        if name not in rate:
            continue
        ok, over = judge(answers[name], targets)
        per_target = np.asarray(walls[name]) / np.asarray(solved[name])  # s
        mean, median, p95 = (1e3 * ms for ms in timing_ms(per_target))  # us
        peer = same_cores[name] if cores[same_cores[name]] == cores[name] else None
        ratio = f"{rate[name] / rate[peer]:.2f}" if peer in rate else "-"
        print(
            f"| {name} | {cores[name]} | {sum(solved[name])} | {ok:.2f} | {over:.1e} "
            f"| {sum(walls[name]):.2f} | {rate[name]:,.0f} | {rate[name] / cores[name]:,.0f} "
            f"| {mean:.1f} / {median:.1f} / {p95:.1f} | {ratio} |"
        )
    if pyroki is not None:
        print(
            f"\nPyRoki: {args.pyroki_seeds} seeds (the start above first), best 4 after 6 steps, 10 more "
            "steps, no time limit; XLA's CPU thread pool uses every core"
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
        ok, _ = judge(list(local.q), targets)
        print(
            "\n| run | cores | targets | success % | wall s | IK/s | IK/s per core | answers "
            "| IK/s / TRAC-IK pool of as many processes |\n|---|--:|--:|--:|--:|--:|--:|---|--:|"
        )
        print(
            f"| local threads, {args.workers} | {args.workers} | {nd} | {ok:.2f} | {local.wall_time:.2f} "
            f"| {local.throughput:,.0f} | {local.throughput / args.workers:,.0f} | - | - |"
        )
        dask_chain = chain if tracik is not None else None
        for line in dask_runs(
            m, targets[:nd], q0[:nd], seeds[:nd], local, opts, args.dask_blocks, judge, dask_chain
        ):
            print(line)
    print(f"\nload average after: {load_average()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
