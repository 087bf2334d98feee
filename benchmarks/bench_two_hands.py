"""Two-hand IK on a URDF tree: both tools of the dual Panda placed by one call, optik's methods
against Pink (pin-pink) with one frame task per hand, on the same targets in the same run.

Method (docs/benchmarks.md): joint vectors drawn uniformly within the limits of
`optik.catalog.dual_panda` (seeded); the targets are the full poses of ``left_tool`` and
``right_tool`` at each of them. Every solver starts from the mid-limit configuration and gets the
same time limit per call. optik: ``optik.solve_ik(m, {"left_tool": T1, "right_tool": T2},
method=...)`` with ``lm``, ``nlp``, ``dls`` and ``qp`` (their restarts included). Pink: its
differential IK iterated as position IK from the same start (``pink.solve_ik`` with two
``FrameTask``s of cost 1 and a ``PostureTask`` of cost 1e-6 toward the start, ``dt = 1``, its
default configuration and velocity limits, ``Configuration.integrate_inplace``) until both hands
are within the tolerance, the time limit, or a QP without solution (``NoSolutionFound``); no
restarts. Success is judged for every solver by
the same check on the returned configuration: each hand's position and geodesic orientation
errors from optik's FK (equal to pinocchio's on this URDF to 1e-15) within ``--tol``, and the
joint limits. Calls are interleaved target by target; each solver has one untimed warm-up call.

Run: ``optik benchmark two_hands [--n 200] [--time-limit 0.05] [--tol 1e-6] [--seed 0] [--no-pink]``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

import optik
from optik import spatial
from optik.benchmarks import benchmark_parser

HANDS = ("left_tool", "right_tool")
Solver = Callable[[dict[str, np.ndarray], float], np.ndarray]
"""``(targets, time_limit) -> q``."""


def _ok(m: optik.Mechanism, q: np.ndarray, targets: dict[str, np.ndarray], tol: float) -> bool:
    if not m.within_limits(q):
        return False
    for frame, target in targets.items():
        pose = m.fk(q, frame)
        if np.linalg.norm(pose[:3, 3] - target[:3, 3]) > tol:
            return False
        if float(spatial.angle_between(pose[:3, :3], target[:3, :3])) > tol:
            return False
    return True


def optik_solver(m: optik.Mechanism, method: str, tol: float) -> Solver:
    def solve(targets: dict[str, np.ndarray], time_limit: float) -> np.ndarray:
        return optik.solve_ik(m, targets, method=method, time_limit=time_limit, tol=tol).q

    return solve


def pink_solver(m: optik.Mechanism, tol: float) -> Solver:
    """Pink's differential IK iterated to both targets (see the module docstring)."""
    import pink
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(optik.catalog.urdf_path("dual_panda")))
    data = model.createData()
    hands = [pink.tasks.FrameTask(f, position_cost=1.0, orientation_cost=1.0) for f in HANDS]
    posture = pink.tasks.PostureTask(cost=1e-6)
    tasks = [*hands, posture]
    q0 = m.mid_q()

    def solve(targets: dict[str, np.ndarray], time_limit: float) -> np.ndarray:
        deadline = time.perf_counter() + time_limit
        conf = pink.Configuration(model, data, q0.copy())
        goals = [pin.SE3(targets[f][:3, :3], targets[f][:3, 3]) for f in HANDS]
        for task, goal in zip(hands, goals, strict=True):
            task.set_target(goal)
        posture.set_target(q0.copy())
        while time.perf_counter() < deadline:
            try:
                v = pink.solve_ik(conf, tasks, 1.0, solver="daqp", safety_break=False)
            except pink.exceptions.NoSolutionFound:  # a failed QP ends the call (counted as is)
                break
            conf.integrate_inplace(v, 1.0)
            poses = [conf.get_transform_frame_to_world(f) for f in HANDS]
            errors = [
                (
                    np.linalg.norm(p.translation - g.translation),
                    np.linalg.norm(pin.log3(g.rotation.T @ p.rotation)),
                )
                for p, g in zip(poses, goals, strict=True)
            ]
            if max(max(e) for e in errors) < 0.5 * tol:
                break
        return conf.q.copy()

    return solve


def run(
    m: optik.Mechanism, solvers: dict[str, Solver], n: int, time_limit: float, tol: float, seed: int
) -> dict[str, tuple[list[float], int]]:
    """``{solver: (call times, successes)}`` over ``n`` targets, interleaved target by target."""
    qs = m.random_q(n, seed=seed)
    all_targets = [{f: m.fk(q, f) for f in HANDS} for q in qs]
    out: dict[str, tuple[list[float], int]] = {name: ([], 0) for name in solvers}
    for solve in solvers.values():  # untimed warm-up: builds and compiles what is built once
        solve(all_targets[0], time_limit)
    for targets in all_targets:
        for name, solve in solvers.items():
            t0 = time.perf_counter()
            q = solve(targets, time_limit)
            elapsed = time.perf_counter() - t0
            times, ok = out[name]
            times.append(elapsed)
            out[name] = (times, ok + _ok(m, q, targets, tol))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print a markdown table with the ratios to ``lm``; returns 0."""
    ap = benchmark_parser("two_hands", __doc__)
    ap.add_argument("--n", type=int, default=200, help="targets (pairs of hand poses)")
    ap.add_argument("--time-limit", type=float, default=0.05, help="seconds per call")
    ap.add_argument("--tol", type=float, default=1e-6, help="position (m) and orientation (rad) tolerance")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--methods", default="lm,nlp,dls,qp", help="optik methods (comma separated)")
    ap.add_argument("--no-pink", action="store_true", help="skip the Pink peer")
    args = ap.parse_args(argv)
    if args.n < 1 or not args.time_limit > 0 or not args.tol > 0:
        ap.error("--n must be >= 1, --time-limit and --tol > 0")
    m = optik.catalog.dual_panda()
    solvers: dict[str, Solver] = {
        f"optik {k}": optik_solver(m, k, args.tol) for k in args.methods.split(",") if k
    }
    if not args.no_pink:
        try:
            solvers["Pink + daqp"] = pink_solver(m, args.tol)
        except ImportError:
            print('pin-pink is not installed (pip install "optik[peers]"): Pink skipped')
    results = run(m, solvers, args.n, args.time_limit, args.tol, args.seed)
    ref = np.mean(results["optik lm"][0]) if "optik lm" in results else None
    print(
        f"dual_panda, {args.n} targets (both tool poses), time limit {args.time_limit * 1e3:g} ms, "
        f"tol {args.tol:g}, from the mid-limit start"
    )
    print("| solver | success | mean ms | median ms | p95 ms | mean / lm |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, (times, ok) in results.items():
        t = np.array(times) * 1e3
        ratio = f"{np.mean(t) / (ref * 1e3):.2f}" if ref else "-"
        print(
            f"| {name} | {100 * ok / args.n:.1f} % | {np.mean(t):.3f} | {np.median(t):.3f} | "
            f"{np.percentile(t, 95):.3f} | {ratio} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
