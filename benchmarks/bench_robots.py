"""Every arm of example-robot-data: FK against pinocchio, IK against TRAC-IK, same targets, same run.

Method (docs/robots.md): each arm of `optik.catalog.robots.ARMS` is loaded by optik
(`optik.catalog.robot`), by pinocchio (``buildModelFromUrdf`` on the same file) and by TRAC-IK
(``pytracik``, Speed mode, the same base and tip links).

* **FK**: the largest entry of ``|T_optik(q) - T_pinocchio(q)|`` (tip pose in the base link)
  over ``--fk`` random joint vectors within the limits.
* **IK**: ``--n`` joint vectors drawn within the limits (`optik.Mechanism.random_q`, seeded;
  continuous joints in ``[-pi, pi]``), their FK poses (pinocchio's) as targets. Every solver
  starts from the mid-limit seed with the same time limit (``--time-limit``) and tolerance
  (``--tol``); both are held to the rules of `optik.harness.peers.rules` (asked for half the
  tolerance: TRAC-IK's ``eps`` per twist component is ``tol / 2``; one untimed warm-up call each;
  every answer clipped into the limits, the raw overshoot reported). optik runs its default method
  for the arm (named in the table; ``--method`` picks one). The solvers run interleaved target by
  target; every call is timed around the public call, failures included. **Success is one check
  for both**: Pinocchio's FK of the clipped answer within ``--tol`` of the target (position in m,
  geodesic angle in rad) and the URDF limits satisfied exactly (TRAC-IK's own flag is shown next
  to it). ``pytracik`` reads the limits of a joint that has a ``<safety_controller>`` as ``[0,
  0]``; the adapter replaces them by the URDF's so that both solvers search the same box.

Run: ``optik benchmark robots [--n 200] [--time-limit 0.05] [--tol 1e-6] [--robots ur5,panda]
[--method lm]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik import native  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.catalog.robots import ARMS, robot, robot_names, robot_urdf  # noqa: E402
from optik.harness.peers import PeerUnavailable, TracIK  # noqa: E402
from optik.harness.peers.rules import Referee, warm_up  # noqa: E402
from optik.harness.tally import Tally  # noqa: E402


@dataclass
class ArmRun:
    """Everything measured on one arm."""

    name: str
    n_q: int
    method: str
    fk_gap: float
    optik: Tally
    tracik: Tally | None
    note: str = ""


def run_arm(
    name: str, n: int, n_fk: int, limit: float, tol: float, seed: int, method: str | None = None
) -> ArmRun:
    """Load one arm, compare its FK with Pinocchio's, solve ``n`` FK targets with both solvers."""
    arm = ARMS[name]
    urdf = robot_urdf(name)
    m = robot(name)
    referee = Referee(m, urdf, arm.base_link, arm.tip_link)
    gap = max(float(np.max(np.abs(m.fk(q) - referee.fk(q)))) for q in m.random_q(n_fk, seed=seed + 1))
    q0 = m.mid_q()
    targets = [referee.fk(q) for q in m.random_q(n, seed=seed)]
    tolerances = optik.Tolerances(position=tol, orientation=tol)
    try:
        peer: TracIK | None = TracIK(m, urdf, arm.base_link, arm.tip_link)
        note = ""
    except PeerUnavailable as exc:
        peer, note = None, str(exc)

    methods: set[str] = set()

    def optik_solve(target: np.ndarray) -> tuple[np.ndarray, bool]:
        res = optik.solve_ik(m, target, q0, method=method, time_limit=limit, tol=tol)
        methods.add(res.method)
        return res.q, res.success

    solvers: list[tuple[Tally, Callable[[np.ndarray], tuple[np.ndarray, bool]]]] = [
        (Tally("optik"), optik_solve)
    ]
    if peer is not None:
        solvers.append((Tally("TRAC-IK"), lambda target: peer.attempt(q0, target, limit, tolerances)))
    warm_up(lambda solve=solve: solve(targets[0]) for _, solve in solvers)
    native.wait()
    for target in targets:
        for tally, solve in solvers:
            t0 = time.perf_counter()
            q, own = solve(target)
            elapsed = time.perf_counter() - t0
            tally.add(elapsed, referee.judge(q, target, tolerances), own)
    trac = solvers[1][0] if peer is not None else None
    return ArmRun(name, m.n_q, "+".join(sorted(methods)), gap, solvers[0][0], trac, note)


HEADER = (
    "| robot | DOF | FK vs pinocchio | optik method | optik success % | optik mean / median / p95 ms "
    "| TRAC-IK success % (own) | TRAC-IK max overshoot | TRAC-IK mean / median / p95 ms "
    "| median / TRAC-IK median |\n"
    "|---|--:|--:|---|--:|--:|--:|--:|--:|--:|"
)


def _cells(t: Tally) -> str:
    mean, median, p95 = t.timing_ms()
    return f"{mean:.3f} / {median:.3f} / {p95:.3f}"


def row_text(r: ArmRun) -> str:
    """One markdown table row."""
    if r.tracik is None:
        trac, ratio = f"- ({r.note}) | - | -", "-"
    else:
        t = r.tracik
        trac = f"{t.success_pct():.1f} ({t.own_pct():.1f}) | {t.max_overshoot():.1e} | {_cells(t)}"
        ratio = f"{r.optik.timing_ms()[1] / r.tracik.timing_ms()[1]:.2f}"
    optik_cells = f"{r.optik.success_pct():.1f} | {_cells(r.optik)}"
    return f"| {r.name} | {r.n_q} | {r.fk_gap:.1e} | {r.method} | {optik_cells} | {trac} | {ratio} |"


def _pooled(name: str, tallies: list[Tally]) -> Tally:
    out = Tally(name)
    for t in tallies:
        out.times += t.times
        out.verdicts += t.verdicts
        out.own += t.own
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = benchmark_parser("robots", __doc__)
    ap.add_argument("--n", type=int, default=200, help="IK targets per arm (default 200)")
    ap.add_argument("--fk", type=int, default=100, help="FK comparisons per arm (default 100)")
    ap.add_argument("--time-limit", type=float, default=0.05, help="per call (s, default 0.05)")
    ap.add_argument("--tol", type=float, default=1e-6, help="position (m) and angle (rad) tolerance")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--robots", help="comma-separated names (default: every arm)")
    ap.add_argument("--method", help="optik's IK method (default: its default for each arm)")
    args = ap.parse_args(argv)
    names = args.robots.split(",") if args.robots else list(robot_names())
    print(
        f"example-robot-data arms: {args.n} FK targets each, mid-limit seed, time limit "
        f"{args.time_limit * 1e3:g} ms, tol {args.tol:g}; every solver asked for tol / 2, answers clipped "
        "into the limits, success by Pinocchio's FK and the exact limits\n"
    )
    runs = []
    for name in names:  # the libraries' own messages come first, then one table
        runs.append(run_arm(name, args.n, args.fk, args.time_limit, args.tol, args.seed, args.method))
        print(f"{name}: done", file=sys.stderr, flush=True)
    print(HEADER)
    for r in runs:
        print(row_text(r))
    both = [r for r in runs if r.tracik is not None]
    if both:
        total = ArmRun(
            f"all {len(both)} arms",
            0,
            "",
            max(r.fk_gap for r in runs),
            _pooled("optik", [r.optik for r in both]),
            _pooled("TRAC-IK", [r.tracik for r in both if r.tracik is not None]),
        )
        print(row_text(total).replace("| 0 |", "| |", 1))
    return 0 if all(r.fk_gap <= 1e-12 for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
