"""Collision-free IK of the Panda in a cluttered scene (table, shelf with two boards, three boxes):
optik's collision-aware ``lm`` against TRAC-IK with coal rejection, in the same run, every success
judged by an independent Pinocchio + coal query.

Method (docs/benchmarks.md): the Panda of example-robot-data from ``panda_link0`` to
``panda_hand_tcp`` (fingers held closed) with its SRDF; targets are FK poses of configurations
drawn uniformly within the limits (seeded) and kept when optik's exact check finds them clear by
``--margin`` (so every target is reachable collision-free). optik: ``optik.solve_ik(m, T,
world=W, margin=margin, time_limit=...)``. TRAC-IK (pytracik, solve type Speed): solve from the
mid-limit seed, wrap and clip the answer into the limits (`optik.harness.peers.rules.settle`, what
optik's answers get: TRAC-IK's float32 limits overshoot by ~5e-9), check it with
`optik.collision.check` (coal) at the margin, and while it collides solve again from a uniformly
random seed until the time limit (what MoveIt does); each retry takes the longest timeout of
`timeout_ladder` that fits in the time left, its solver built once before the timed calls (a
TRAC-IK solver's timeout is fixed at construction).

The judge is `optik.benchmarks.judge.PinocchioJudge`: Pinocchio's own model of the whole URDF
(finger joints at 0) and its collision geometry (``buildGeomFromUrdf``, meshes as their convex
hulls, as coal queries them), its self-collision pairs ``addAllCollisionPairs`` minus the SRDF's
(``removeCollisionPairs``; none is left that no arm joint moves apart), every geometry against
every obstacle, coal distances: every solver's answer is settled into the limits the same way
(`PinocchioJudge.accepts`), then a success needs the pose within ``--tol`` (Pinocchio's FK), the
limits, and every distance ``>= margin - 1e-9``. Calls are interleaved target by target; each
solver has one untimed warm-up call (optik builds its constrained code then; the C compiler may
still be running during the run: the kernel then answers through CasADi's evaluator, and the
table says whether it was compiled).

Run: ``optik benchmark collision [--n 1000] [--time-limit 0.01] [--margin 0.01] [--tol 1e-6] [--seed 0]
[--compile-wait 600]`` (the wait for optik's C builds, kernels and collision screens, is not timed). Robots
near their own bodies are ``optik benchmark collision_self``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

import optik
from optik import spatial
from optik.benchmarks import benchmark_parser
from optik.benchmarks.judge import PinocchioJudge
from optik.harness.peers.rules import settle
from optik.harness.tally import success_table

Solver = Callable[[np.ndarray, float, int], "np.ndarray | None"]
"""``(target, time_limit, seed) -> q or None``."""


def scene() -> optik.World:
    """Table, a shelf (two sides, two boards) in front of the robot, three boxes on the table."""
    w = optik.World()
    w.add_box("table", (1.4, 1.6, 0.04), spatial.translation(0.3, 0.0, -0.04))
    for side, y in (("left", 0.42), ("right", -0.42)):
        w.add_box(f"shelf_{side}", (0.3, 0.02, 0.9), spatial.translation(0.75, y, 0.43))
    w.add_box("shelf_board_low", (0.3, 0.84, 0.02), spatial.translation(0.75, 0.0, 0.35))
    w.add_box("shelf_board_high", (0.3, 0.84, 0.02), spatial.translation(0.75, 0.0, 0.7))
    w.add_box("box_a", (0.1, 0.1, 0.12), spatial.translation(0.35, 0.45, 0.04))
    w.add_box("box_b", (0.08, 0.15, 0.2), spatial.translation(0.3, -0.45, 0.08))
    w.add_box("box_c", (0.12, 0.12, 0.1), spatial.translation(-0.35, 0.35, 0.03))
    return w


def optik_solver(m: optik.Mechanism, w: optik.World, margin: float, tol: float) -> Solver:
    def solve(target: np.ndarray, time_limit: float, seed: int) -> np.ndarray | None:
        r = optik.solve_ik(m, target, world=w, margin=margin, time_limit=time_limit, tol=tol, seed=seed)
        return r.q if r.success else None

    return solve


def timeout_ladder(time_limit: float, shortest: float = 1e-4) -> np.ndarray:
    """Timeouts ``time_limit / 2**k`` down to ``shortest``, longest first.

    A TRAC-IK solver's timeout is fixed when it is constructed (which parses the URDF), so a retry
    with the time left takes the longest of these timeouts that fits: every solver is constructed
    once, untimed, instead of once per retry inside the timed call.
    """
    k = max(int(np.floor(np.log2(time_limit / shortest))), 0)
    return time_limit / 2.0 ** np.arange(k + 1)


def tracik_solver(
    m: optik.Mechanism, urdf, w: optik.World, margin: float, tol: float, time_limit: float
) -> Solver:
    from optik.harness.peers.tracik_peer import TracIK

    peer = TracIK(m, urdf, "panda_link0", "panda_hand_tcp")
    tolerances = optik.Tolerances(position=tol, orientation=tol)
    ladder = timeout_ladder(time_limit)
    for timeout in ladder:  # constructed here, outside the timed calls
        peer.attempt(m.mid_q(), m.fk(m.mid_q()), float(timeout), tolerances)

    def solve(target: np.ndarray, time_limit: float, seed: int) -> np.ndarray | None:
        start = time.perf_counter()
        rng = np.random.default_rng(seed)
        q0 = m.mid_q()
        while (left := time_limit - (time.perf_counter() - start)) > 1e-4:
            fits = ladder[ladder <= left]
            q, found = peer.attempt(q0, target, float(fits[0]) if fits.size else left, tolerances)
            q = settle(m, q)  # the wrap and clip optik's answers get (float32 limits overshoot)
            if found and not optik.collision.check(m, q, w, margin=margin).in_collision:
                return q
            q0 = m.random_q(seed=rng)
        return None

    return solve


def timed_in_turn(
    solvers: dict[str, Callable[[Any, float, int], np.ndarray | None]],
    targets: Sequence[Any],
    time_limit: float,
    compile_wait: float,
    accept: Callable[[np.ndarray | None, Any], bool],
) -> dict[str, tuple[list[float], int]]:
    """Each solver's wall times and accepted count, the solvers interleaved target by target.

    Every solver first solves ``targets[0]`` untimed (optik builds its constrained code there),
    then optik's background C builds (the kernels and the collision screens) get up to
    ``compile_wait`` seconds in all; ``accept(q, target)`` judges each answer (None: no answer).
    """
    from optik import native

    for solve in solvers.values():
        solve(targets[0], 60.0, 0)
    native.wait(compile_wait)
    results: dict[str, tuple[list[float], int]] = {name: ([], 0) for name in solvers}
    for i, target in enumerate(targets):
        for name, solve in solvers.items():
            t0 = time.perf_counter()
            q = solve(target, time_limit, i)
            elapsed = time.perf_counter() - t0
            times, ok = results[name]
            times.append(elapsed)
            results[name] = (times, ok + accept(q, target))
    return results


def judged_in_turn(
    optik_solve: Callable[[Any, float, int], np.ndarray | None],
    tracik: Callable[[], Callable[[Any, float, int], np.ndarray | None]],
    targets: Sequence[Any],
    judge: PinocchioJudge,
    args: argparse.Namespace,
) -> dict[str, tuple[list[float], int]]:
    """optik and TRAC-IK + coal rejection (``tracik()`` builds it; skipped, said so, when pytracik is
    missing) through `timed_in_turn` at ``args.time_limit`` and ``args.compile_wait``, every answer
    judged by ``judge.accepts`` (settled, then within ``args.tol``, clear by ``args.margin``)."""
    solvers = {"optik lm + collisions": optik_solve}
    try:
        solvers["TRAC-IK + coal rejection"] = tracik()
    except (ImportError, optik.OptikError) as exc:
        print(f"pytracik is not available ({exc}): TRAC-IK skipped")
    return timed_in_turn(
        solvers,
        targets,
        args.time_limit,
        args.compile_wait,
        lambda q, target: judge.accepts(q, target, args.tol, args.margin),
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print a markdown table with the ratio to optik; returns 0."""
    ap = benchmark_parser("collision", __doc__)
    ap.add_argument("--n", type=int, default=1000, help="targets (the issue's spec: 1,000)")
    ap.add_argument("--time-limit", type=float, default=0.01, help="seconds per call (the spec: 10 ms)")
    ap.add_argument("--margin", type=float, default=0.01, help="clearance (m)")
    ap.add_argument("--tol", type=float, default=1e-6, help="position (m) and orientation (rad) tolerance")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--compile-wait", type=float, default=600.0, help="seconds to wait for optik's C build")
    args = ap.parse_args(argv)
    if args.n < 1 or not args.time_limit > 0 or not args.tol > 0 or args.margin < 0:
        ap.error("--n must be >= 1, --time-limit and --tol > 0, --margin >= 0")
    try:
        from optik.catalog.robots import robots_dir

        d = robots_dir() / "panda_description"
        urdf, srdf = d / "urdf" / "panda.urdf", d / "srdf" / "panda.srdf"
        m = optik.Mechanism.from_urdf(urdf, "panda_link0", "panda_hand_tcp", srdf=srdf)
        w = scene()
        judge = PinocchioJudge(m, urdf, srdf, ["panda_hand_tcp"], d.parents[2], w)
    except (ImportError, optik.OptikError) as exc:
        print(f"needs coal, pinocchio and example-robot-data (extras 'collision', 'peers', 'robots'): {exc}")
        return 0
    rng = np.random.default_rng(args.seed)
    targets = []
    while len(targets) < args.n:
        q = m.random_q(seed=rng)
        if not optik.collision.check(m, q, w, margin=args.margin).in_collision:
            targets.append(m.fk(q))
    results = judged_in_turn(
        optik_solver(m, w, args.margin, args.tol),
        lambda: tracik_solver(m, urdf, w, args.margin, args.tol, args.time_limit),
        targets,
        judge,
        args,
    )
    from optik.solvers.collision_free import compiled_kernels

    print(
        f"Panda ({m.n_q} joints) in a cluttered scene ({len(w)} boxes), {args.n} targets by FK of "
        f"configurations clear by {args.margin:g} m, answers settled into the limits, "
        f"time limit {args.time_limit * 1e3:g} ms, "
        f"tol {args.tol:g}, judged by Pinocchio + coal; constrained kernel compiled: {compiled_kernels()}"
    )
    print(success_table(results, args.n, "optik lm + collisions"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
