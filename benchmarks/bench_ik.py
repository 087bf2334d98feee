"""IK on the Panda and the iiwa14: optik ``lm`` / ``nlp`` against TRAC-IK and the Robotics Toolbox ``ik_LM``.

Method (docs/benchmarks.md): each arm's chain is loaded from the shipped URDF
(``optik.catalog.arms.urdf_path``; Panda ``panda_link0 -> panda_link8``, iiwa14 ``iiwa_link_0 ->
iiwa_link_ee``) by optik and by the peers of `optik.harness.peers`: TRAC-IK (``pytracik``, Speed
mode) and the Robotics Toolbox (``ETS.ik_LM``, C++, joint limits on). ``--n`` joint vectors are
drawn uniformly within the limits (seeded), the targets are their FK poses, and every solver starts
from the mid-limit seed (``--starts random``: from a random configuration per target, the same for
every solver) with the time limit ``--time-limit`` (5 ms; ``ik_LM`` has no time limit,
its iteration caps bound it) and tolerance ``--tol`` (1e-5). Every solver is held to the rules of
`optik.harness.peers.rules`: asked for half the tolerance (TRAC-IK: ``eps = tol / 2`` per twist
component; ``ik_LM``: residual ``E <= (tol / 2)^2 / 2``), one untimed warm-up call each, every answer
clipped into the limits (the overshoot of the raw answer is reported), and success judged for every
solver by the same referee: Pinocchio's FK of the answer within ``--tol`` (position, geodesic angle)
and the limits satisfied exactly (each solver's own success flag is shown next to it). Every call is
timed with ``time.perf_counter`` around the public call, failures included. The NLP method runs
with its own budget ``--nlp-time-limit`` on the first ``--n-nlp`` targets, with IPOPT (``nlp``)
and with ``sqpmethod`` (``nlp-sqp``). The solvers run interleaved per target so that load changes
on a shared machine hit all of them alike; the table reports success rate, mean / median / p95
time and the ratio of each median time to the fastest peer's median. A note gives, for each solver that
failed, the most CPU time (``time.thread_time``) any of its failed calls used: a time-limited solve
that fails having used far less CPU than its limit was suspended by the scheduler past its deadline
(a loaded machine), not stopped by its own search.

Run: ``optik benchmark ik [--n 10000] [--robots panda,iiwa14] [--time-limit 0.005] [--tol 1e-5]
[--methods lm,nlp,nlp-sqp,trac_ik,rtb_lm] [--n-nlp 1000] [--nlp-time-limit 0.3] [--starts mid,random]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik import native  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.catalog.arms import URDF_CHAINS, urdf_path  # noqa: E402
from optik.harness.peers import ADAPTERS, PeerUnavailable  # noqa: E402
from optik.harness.peers.rules import Referee, warm_up  # noqa: E402
from optik.harness.tally import Tally  # noqa: E402

Solver = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray | None, bool]]
"""``(target 4x4, start q0) -> (raw q or None, the solver's own success flag)``."""

PEER_LABELS = {"trac_ik": "TRAC-IK (Speed)", "rtb_lm": "Robotics Toolbox ik_LM (C++)"}

HEADER = (
    "| robot | solver | n | success % | own success % | max overshoot | mean ms | median ms | p95 ms "
    "| median / fastest peer median |\n"
    "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|"
)


def _optik_solver(m: optik.Mechanism, method: str, limit: float, tol: float, **options: object) -> Solver:
    def solve(target: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray | None, bool]:
        res = optik.solve_ik(m, target, q0, method=method, time_limit=limit, tol=tol, **options)
        return res.q, res.success

    return solve


def _peer_solver(
    name: str,
    m: optik.Mechanism,
    chain: tuple[str, str, str],
    limit: float,
    tol: optik.Tolerances,
) -> Solver:
    peer = ADAPTERS[name](m, *chain)
    peer.check_fk()

    def solve(target: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray | None, bool]:
        return peer.attempt(q0, target, limit, tol)

    return solve


def run(
    robot: str = "panda",
    n: int = 10000,
    time_limit: float = 0.005,
    tol: float = 1e-5,
    methods: Sequence[str] = ("lm", "nlp", "nlp-sqp", "trac_ik", "rtb_lm"),
    n_nlp: int = 1000,
    nlp_time_limit: float = 0.3,
    seed: int = 0,
    starts: str = "mid",
) -> tuple[dict[str, Tally], list[str]]:
    """Run the benchmark on one arm; the tallies by solver label (peers' labels in
    `PEER_LABELS`) and notes on the solvers that could not run. ``starts``: ``"mid"`` (every
    solver starts from the mid-limit seed) or ``"random"`` (target ``i`` from the ``i``-th of
    ``n`` configurations drawn within the limits with seed ``seed + 1``, the same for every
    solver)."""
    path = str(urdf_path(robot))
    base, tip = URDF_CHAINS[robot]
    m = optik.Mechanism.from_urdf(path, base, tip)
    targets = m.fk(m.random_q(n, seed=seed))
    if starts not in ("mid", "random"):
        raise ValueError(f"starts: 'mid' or 'random', got {starts!r}")
    q0s = np.tile(m.mid_q(), (n, 1)) if starts == "mid" else m.random_q(n, seed=seed + 1)
    tolerances = optik.Tolerances(position=tol, orientation=tol)
    referee = Referee(m, path, base, tip)
    notes = [] if referee.source == "pinocchio" else ["pinocchio not installed: success judged by optik's FK"]
    solvers: dict[str, tuple[Solver, int]] = {}
    for name in methods:
        if name in ADAPTERS:
            try:
                solvers[PEER_LABELS.get(name, name)] = (
                    _peer_solver(name, m, (path, base, tip), time_limit, tolerances),
                    n,
                )
            except PeerUnavailable as exc:
                notes.append(f"skipped: {exc}")
        elif name in ("nlp", "nlp-sqp"):
            solver = "ipopt" if name == "nlp" else "sqpmethod"
            label = f"optik nlp {solver} ({nlp_time_limit * 1e3:g} ms)"
            nlp = _optik_solver(m, "nlp", nlp_time_limit, tol, solver=solver)
            solvers[label] = (nlp, min(n, n_nlp))
        else:
            solvers[f"optik {name}"] = (_optik_solver(m, name, time_limit, tol), n)
    warm_up(lambda s=s: s(targets[0], q0s[0]) for s, _ in solvers.values())
    native.wait()  # the C libraries built in the background: time the compiled code
    tallies = {label: Tally(label) for label in solvers}
    failed_cpu: dict[str, list[float]] = {label: [] for label in solvers}  # CPU time of each failure
    for i, target in enumerate(targets):
        for label, (solve, count) in solvers.items():
            if i >= count:
                continue
            t0, c0 = time.perf_counter(), time.thread_time()
            q, own = solve(target, q0s[i])
            elapsed, cpu = time.perf_counter() - t0, time.thread_time() - c0
            verdict = referee.judge(q, target, tolerances)
            tallies[label].add(elapsed, verdict, own)
            if not verdict.success:
                failed_cpu[label].append(cpu)
    for label, cpus in failed_cpu.items():
        if cpus:
            notes.append(
                f"{label}: its {len(cpus)} failures used at most {max(cpus) * 1e3:.3f} ms of CPU time each "
                f"(time.thread_time around the call; the time limit is {time_limit * 1e3:g} ms of wall time)"
            )
    return tallies, notes


def table_rows(robot: str, tallies: dict[str, Tally]) -> list[str]:
    """Markdown rows of one arm; ratios of median times to the fastest peer's median."""
    peers = [t for label, t in tallies.items() if label in PEER_LABELS.values()]
    ref = min((t.timing_ms()[1] for t in peers), default=None)
    rows = []
    for t in tallies.values():
        ratio = f"{t.timing_ms()[1] / ref:.2f}" if ref else "-"
        rows.append(
            f"| {robot} | {t.name} | {t.n} | {t.success_pct():.2f} | {t.own_pct():.2f} "
            f"| {t.max_overshoot():.1e} | {t.timing_cells()} | {ratio} |"
        )
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point (also called by the ``optik`` CLI)."""
    p = benchmark_parser("ik", __doc__)
    p.add_argument("--n", type=int, default=10000, help="number of targets per robot")
    p.add_argument("--robots", default="panda,iiwa14", help=f"comma list of {', '.join(URDF_CHAINS)}")
    p.add_argument("--time-limit", type=float, default=0.005, help="time limit per call (s)")
    p.add_argument("--tol", type=float, default=1e-5, help="position / orientation tolerance")
    p.add_argument(
        "--methods",
        default="lm,nlp,nlp-sqp,trac_ik,rtb_lm",
        help="comma list of lm, nlp (IPOPT), nlp-sqp (sqpmethod), the peers trac_ik and rtb_lm, "
        "and any registered method",
    )
    p.add_argument("--n-nlp", type=int, default=1000, help="targets for the (slower) nlp method")
    p.add_argument("--nlp-time-limit", type=float, default=0.3, help="time limit of nlp calls (s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    p.add_argument(
        "--starts",
        default="mid",
        help="comma list of mid (the mid-limit seed) and random (a random start per target, the same for "
        "every solver)",
    )
    args = p.parse_args(argv)
    starts = [s.strip() for s in args.starts.split(",") if s.strip()]
    for kind in starts:
        if kind not in ("mid", "random"):
            p.error(f"--starts: mid or random, got {kind!r}")
    methods = [s.strip() for s in args.methods.split(",") if s.strip()]
    robots = [s.strip() for s in args.robots.split(",") if s.strip()]
    print(
        f"{args.n} random targets within limits per arm (URDF), starts {'/'.join(starts)}, time limit "
        f"{args.time_limit * 1e3:g} ms, tol {args.tol:g}; every solver asked for tol / 2, its answer clipped "
        "into the limits, success by Pinocchio's FK and the exact limits\n"
    )
    print(HEADER)
    all_notes = []
    for robot in robots:
        for kind in starts:
            nlp = (args.n_nlp, args.nlp_time_limit)
            tallies, notes = run(robot, args.n, args.time_limit, args.tol, methods, *nlp, args.seed, kind)
            label = robot if kind == "mid" else f"{robot} (random starts)"
            print("\n".join(table_rows(label, tallies)), flush=True)
            all_notes += [f"{label}: {note}" for note in notes]
    for note in dict.fromkeys(all_notes):
        print(f"\n- {note}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
