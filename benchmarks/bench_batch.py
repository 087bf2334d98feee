"""Batch IK on the Franka Panda: ``solve_ik_batch`` on every core against TRAC-IK's single-thread loop.

Method: the Panda chain is loaded from the shipped URDF (``panda_link0`` -> ``panda_link8``) by
optik and by TRAC-IK (``pytracik``, Speed mode). ``--n`` joint vectors are drawn uniformly
within the limits (seeded), the targets are their FK poses, and each target gets a random start
(also seeded), the same for both solvers; tolerance ``--tol`` (1e-5) and time limit
``--time-limit`` (5 ms) per target. The targets are processed in blocks of ``--block``;
every block is solved by ``optik.solve_ik_batch(..., workers=--workers)`` and by a Python loop
over ``TracIK.ik`` on one thread, alternating which goes first, so that load changes of a
shared machine hit both; each solver's throughput is its targets over the sum of its blocks'
wall times (the batch call's validation, thread pool and result assembly included). TRAC-IK
runs with ``epsilon = tol / 2`` (a bound per twist component), as the TRAC-IK peer of
``optik bench``. Success is judged for both by an independent forward kinematics (Pinocchio on
the same URDF; optik's own FK when Pinocchio is missing): position error and geodesic
orientation error <= ``--tol`` and the joint limits satisfied exactly (TRAC-IK's answers often
overshoot a limit by about 5e-9 rad, so its success is also shown with the answers clipped into
the limits). Equality: on ``--n-check`` sampled targets,
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
from collections.abc import Callable, Sequence  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik.batch.fk import default_workers  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.catalog.arms import URDF_CHAINS, urdf_path  # noqa: E402
from optik.solvers.lm_kernel import target_seeds  # noqa: E402


def load_average() -> str:
    """The 1, 5 and 15 minute load averages (``/proc/loadavg``), or ``"n/a"``."""
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "n/a"


def fk_checker(path: str, tip: str, m: optik.Mechanism) -> tuple[str, Callable[[np.ndarray], np.ndarray]]:
    """An FK ``q -> 4x4`` independent of optik (Pinocchio) when available, and its name."""
    try:
        import pinocchio as pin
    except ImportError:
        return "optik fk (Pinocchio missing)", m.fk
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    frame = model.getFrameId(tip)

    def fk(q: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(model, data, q)
        return data.oMf[frame].homogeneous

    return "Pinocchio", fk


def successes(
    m: optik.Mechanism, fk: Callable[[np.ndarray], np.ndarray], qs: list, targets: np.ndarray, tol: float
) -> np.ndarray:
    """Per target: within limits, position and geodesic orientation errors <= tol."""
    ok = np.zeros(len(targets), dtype=bool)
    for i, (q, t) in enumerate(zip(qs, targets, strict=True)):
        if q is None or not ((q >= m.lower) & (q <= m.upper)).all():
            continue
        pose = fk(q)
        pos = np.linalg.norm(pose[:3, 3] - t[:3, 3])
        r = pose[:3, :3].T @ t[:3, :3]
        skew = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
        ori = np.arctan2(0.5 * np.linalg.norm(skew), 0.5 * (np.trace(r) - 1.0))
        ok[i] = pos <= tol and ori <= tol
    return ok


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
    optik.solve_ik_batch(m, targets[:10], q0[:10], **opts)  # build and compile outside the timings
    tracik = None
    try:
        from trac_ik import TracIK

        # epsilon bounds each twist component: tol / 2 keeps the Euclidean errors within tol (as
        # the TRAC-IK peer of `optik bench`)
        eps = 0.5 * args.tol
        tracik = TracIK(base, tip, path, timeout=args.time_limit, epsilon=eps, solver_type="Speed")
    except ImportError:
        print('pytracik is not installed (pip install "optik[peers]"): TRAC-IK skipped')
    parts, t_optik, t_tracik, tracik_q = [], 0.0, 0.0, []
    for k, a in enumerate(range(0, args.n, args.block)):
        b = min(a + args.block, args.n)

        def run_optik(a: int = a, b: int = b) -> float:
            t0 = time.perf_counter()
            parts.append(
                optik.solve_ik_batch(m, targets[a:b], q0[a:b], workers=args.workers, **opts, seed=seeds[a:b])
            )
            return time.perf_counter() - t0

        def run_tracik(a: int = a, b: int = b) -> float:
            t0 = time.perf_counter()
            for i in range(a, b):
                tracik_q.append(tracik.ik(targets[i][:3, 3], targets[i][:3, :3], q0[i]))
            return time.perf_counter() - t0

        if tracik is None:
            t_optik += run_optik()
        elif k % 2 == 0:
            t_optik += run_optik()
            t_tracik += run_tracik()
        else:
            t_tracik += run_tracik()
            t_optik += run_optik()
    res = optik.BatchResult.concatenate(parts, wall_time=t_optik, workers=args.workers)
    checker, fk = fk_checker(path, tip, m)
    ok = successes(m, fk, list(res.q), targets, args.tol)
    print(
        f"\nPanda (URDF), {args.n} FK targets, random starts, tol {args.tol:g}, time limit "
        f"{args.time_limit * 1e3:g} ms, blocks of {args.block} alternating; success by {checker}\n"
    )
    print("| solver | targets | success % | wall s | IK/s | IK/s / TRAC-IK |\n|---|--:|--:|--:|--:|--:|")
    rate = args.n / t_optik
    ratio = ""
    if tracik is not None:
        tk_q = [None if q is None else np.asarray(q, dtype=float) for q in tracik_q]
        tk_ok = successes(m, fk, tk_q, targets, args.tol)
        clipped = [None if q is None else np.clip(q, m.lower, m.upper) for q in tk_q]
        tk_clipped = successes(m, fk, clipped, targets, args.tol)
        ratio = f"{rate / (args.n / t_tracik):.1f}"
        print(
            f"| TRAC-IK (Speed), 1 thread | {args.n} | {100 * tk_ok.mean():.2f} "
            f"({100 * tk_clipped.mean():.2f} clipped into the limits) | {t_tracik:.2f} | "
            f"{args.n / t_tracik:,.0f} | 1.0 |"
        )
    print(
        f"| optik solve_ik_batch, {args.workers} threads | {args.n} | {100 * ok.mean():.2f} | "
        f"{t_optik:.2f} | {rate:,.0f} | {ratio or '-'} |"
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
