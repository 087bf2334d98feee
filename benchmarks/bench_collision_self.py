"""Self-collision-free IK near the robot's own body, the dual Panda (both hands at once) and TALOS
(torso and left arm): optik's collision-aware ``lm`` against TRAC-IK with coal rejection, in the
same run, every success judged by an independent Pinocchio + coal query.

Method (docs/benchmarks.md): per robot, configurations drawn uniformly within the limits (seeded)
and kept when optik's exact check finds them clear of the robot itself by ``--margin`` and
closer than ``--near`` to it (a hand near the torso, the other arm, the legs); the targets are
the poses of the robot's frames there, so every target is reachable collision-free.

* ``dual_panda``: `optik.catalog.dual_panda` (15 joints), both tools at once:
  ``optik.solve_ik(m, {"left_tool": T1, "right_tool": T2}, self_collision=True, margin=...)``.
  TRAC-IK solves one chain, so it gets the tree chain by chain: the torso and left arm
  (``world`` to ``left_tool``), then the right arm (``right_panda_link0`` to ``right_tool``)
  for the right target seen from that arm's base where the first answer put it.
* ``talos``: TALOS of example-robot-data (``talos_reduced.urdf``, its SRDF), the chain
  ``base_link`` to ``gripper_left_base_link`` (9 joints: torso and left arm), the rest of the
  body held at zero and checked too: optik and TRAC-IK solve the same chain.

TRAC-IK (pytracik, solve type Speed) + coal rejection: solve from the mid-limit seed, wrap and
clip the whole answer into the limits (`optik.harness.peers.rules.settle`, what optik's answers
get: TRAC-IK's float32 limits overshoot by ~5e-9), check it with `optik.collision.check` at the
margin, and while it collides solve again from
a uniformly random seed until the time limit (what MoveIt does), each retry with the longest
timeout of `optik.benchmarks.bench_collision.timeout_ladder` that fits in the time left, every
solver constructed once before the timed calls.

The judge is `optik.benchmarks.judge.PinocchioJudge`, no world: Pinocchio's own model of the whole
URDF (joints outside the solved ones at zero) and its collision geometry (``buildGeomFromUrdf``,
meshes as their convex hulls, as coal queries them), its pairs ``addAllCollisionPairs`` minus the
SRDF's and minus those no solved joint moves apart (both geometries moved by the same solved
joints, as TALOS's torso and its right arm held at zero: a constant distance): a success needs
every target frame within ``--tol`` (Pinocchio's FK), the limits, and every pair's coal distance
``>= margin - 1e-9``. Calls are interleaved target by target; each solver has one untimed warm-up
call (optik builds its constrained code then; the wait for its C build is not timed).

Run: ``optik benchmark collision_self [--n 50] [--robots dual_panda,talos] [--time-limit 0.05]
[--margin 0.01] [--near 0.05] [--tol 1e-6] [--seed 0] [--compile-wait 600]``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import optik
from optik import spatial
from optik.benchmarks import benchmark_parser
from optik.benchmarks.bench_collision import judged_in_turn, timeout_ladder
from optik.benchmarks.judge import PinocchioJudge
from optik.harness.peers.rules import settle
from optik.harness.tally import success_table

Targets = dict[str, np.ndarray]
Solver = Callable[[Targets, float, int], "np.ndarray | None"]
"""``(targets by frame, time_limit, seed) -> q or None``."""


@dataclass(frozen=True)
class Workload:
    """One robot of the benchmark.

    Attributes:
        m: the mechanism optik solves.
        urdf, srdf: its files.
        frames: the target frames.
        chains: the ``(base_link, tip_link)`` chains TRAC-IK solves one after the other, the
            first from the root of ``m``; each tip is one of ``frames``.
    """

    m: optik.Mechanism
    urdf: Path
    srdf: Path
    frames: tuple[str, ...]
    chains: tuple[tuple[str, str], ...]


def workload(name: str) -> Workload:
    """The ``dual_panda`` or ``talos`` workload (see the module docstring)."""
    if name == "dual_panda":
        urdf = optik.catalog.urdf_path("dual_panda")
        m = optik.catalog.dual_panda()
        chains = (("world", "left_tool"), ("right_panda_link0", "right_tool"))
        return Workload(m, urdf, urdf.with_suffix(".srdf"), ("left_tool", "right_tool"), chains)
    from optik.catalog.robots import robots_dir

    d = robots_dir() / "talos_data"
    urdf, srdf = d / "robots" / "talos_reduced.urdf", d / "srdf" / "talos.srdf"
    m = optik.Mechanism.from_urdf(urdf, "base_link", "gripper_left_base_link", srdf=srdf)
    return Workload(m, urdf, srdf, ("gripper_left_base_link",), (("base_link", "gripper_left_base_link"),))


def optik_solver(w: Workload, margin: float, tol: float) -> Solver:
    def solve(targets: Targets, time_limit: float, seed: int) -> np.ndarray | None:
        goal = targets if len(targets) > 1 else next(iter(targets.values()))
        r = optik.solve_ik(
            w.m, goal, self_collision=True, margin=margin, time_limit=time_limit, tol=tol, seed=seed
        )
        return r.q if r.success else None

    return solve


def tracik_solver(w: Workload, margin: float, tol: float, time_limit: float) -> Solver:
    """TRAC-IK chain by chain, its answer checked by coal, retried from random seeds."""
    from optik.harness.peers.tracik_peer import TracIK

    m, tolerances, ladder = w.m, optik.Tolerances(position=tol, orientation=tol), timeout_ladder(time_limit)
    names = list(m.coordinate_names)
    chains = []
    for base, tip in w.chains:
        chain = optik.Mechanism.from_urdf(w.urdf, base, tip)
        peer = TracIK(chain, w.urdf, base, tip)
        for timeout in ladder:  # constructed here, outside the timed calls
            peer.attempt(chain.mid_q(), chain.fk(chain.mid_q()), float(timeout), tolerances)
        chains.append((peer, base, tip, [names.index(c) for c in chain.coordinate_names]))

    def solve(targets: Targets, time_limit: float, seed: int) -> np.ndarray | None:
        start = time.perf_counter()
        rng = np.random.default_rng(seed)
        q0 = m.mid_q()
        while (left := time_limit - (time.perf_counter() - start)) > 1e-4:
            q, found = q0.copy(), True
            for peer, base, tip, idx in chains:
                fits = ladder[ladder <= left]
                seen = targets[tip] if base == m.base else spatial.inv_transform(m.fk(q, base)) @ targets[tip]
                q[idx], found = peer.attempt(q0[idx], seen, float(fits[0]) if fits.size else left, tolerances)
                left = time_limit - (time.perf_counter() - start)
                if not found or left <= 0:
                    break
            q = settle(m, q)  # the wrap and clip optik's answers get (float32 limits overshoot)
            if found and not optik.collision.check(m, q, margin=margin).in_collision:
                return q
            q0 = m.random_q(seed=rng)
        return None

    return solve


def near_targets(w: Workload, n: int, margin: float, near: float, rng: np.random.Generator) -> list[Targets]:
    """``n`` target sets by FK of random configurations clear by ``margin`` and nearer than ``near``."""
    out: list[Targets] = []
    while len(out) < n:
        q = w.m.random_q(seed=rng)
        report = optik.collision.check(w.m, q, margin=margin)
        if not report.in_collision and report.min_distance < near:
            out.append({f: w.m.fk(q, f) for f in w.frames})
    return out


def run_robot(name: str, args) -> None:
    """Build, warm up and run one robot's workload, then print its caption and table."""
    try:
        w = workload(name)
        judge = PinocchioJudge(w.m, w.urdf, w.srdf, w.frames)
    except (ImportError, optik.OptikError) as exc:
        print(f"{name}: needs coal, pinocchio and example-robot-data (extras 'collision', 'robots'): {exc}")
        return
    rng = np.random.default_rng(args.seed)
    targets = near_targets(w, args.n, args.margin, args.near, rng)
    results = judged_in_turn(  # every answer settled into the limits, the same for every solver
        optik_solver(w, args.margin, args.tol),
        lambda: tracik_solver(w, args.margin, args.tol, args.time_limit),
        targets,
        judge,
        args,
    )
    from optik.solvers.collision_free import compiled_kernels

    print(
        f"{name} ({w.m.n_q} joints, frames {', '.join(w.frames)}; TRAC-IK chains "
        + ", then ".join(f"{a} to {b}" for a, b in w.chains)
        + f"), {args.n} targets by FK of configurations clear by {args.margin:g} m and closer than "
        f"{args.near:g} m to the robot's own body, time limit {args.time_limit * 1e3:g} ms, "
        f"tol {args.tol:g}, "
        f"judged by Pinocchio + coal; constrained kernel compiled: {compiled_kernels().get(w.m.name)}"
    )
    print()
    print(success_table(results, args.n, "optik lm + collisions"))
    print()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print one markdown table per robot with the ratio to optik; returns 0."""
    ap = benchmark_parser("collision_self", __doc__)
    ap.add_argument("--n", type=int, default=50, help="targets per robot")
    ap.add_argument("--robots", default="dual_panda,talos", help="comma list of dual_panda, talos")
    ap.add_argument("--time-limit", type=float, default=0.05, help="seconds per call")
    ap.add_argument("--margin", type=float, default=0.01, help="clearance (m)")
    ap.add_argument("--near", type=float, default=0.05, help="a target's self-distance is below this (m)")
    ap.add_argument("--tol", type=float, default=1e-6, help="position (m) and orientation (rad) tolerance")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--compile-wait", type=float, default=600.0, help="seconds to wait for optik's C build")
    args = ap.parse_args(argv)
    robots = [r.strip() for r in args.robots.split(",") if r.strip()]
    if set(robots) - {"dual_panda", "talos"} or not robots:
        ap.error(f"--robots: a comma list of dual_panda, talos, got {args.robots!r}")
    if args.n < 1 or not args.time_limit > 0 or not args.tol > 0 or args.margin < 0 or not args.near > 0:
        ap.error("--n must be >= 1, --time-limit, --tol and --near > 0, --margin >= 0")
    for name in robots:
        run_robot(name, args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
