"""Differential-IK step on the Panda: optik's QP step against Pink (pin-pink), same URDF, same tasks.

Method (docs/benchmarks.md): the same goals for every solver in the same run. Goals are flange poses of
random joint vectors drawn within the limits (seeded); every solver starts at the mid-limit
posture and runs closed-loop steps ``q <- q + v dt`` with a frame task on the flange (position
and orientation cost 1, gain 1), a posture task to the mid-limit posture (cost 1e-3), the joint
position limits and the URDF's joint velocity limits. Every step call is timed (Pink:
``solve_ik`` plus ``Configuration.integrate_inplace``, which updates the kinematics; optik:
``optik.diffik.step``, which evaluates the tasks, solves and integrates). A goal counts as
converged when the flange is within ``--tol`` (m and rad, measured by optik's FK, which equals
pinocchio's on this URDF) after at most ``--steps`` steps. Joint-limit violations of every
visited configuration are counted for every solver.

Pink's fastest installed solver is picked the way a new user would: each installed qpsolvers
backend runs the first goal and the fastest median step wins. The solvers then run interleaved,
goal by goal.

Run: ``optik benchmark diffik [--goals 20] [--steps 300] [--dt 0.01]``.
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

import optik
from optik import diffik, native, spatial
from optik.benchmarks import benchmark_parser
from optik.harness.tally import timing_ms

Stepper = Callable[[np.ndarray, np.ndarray], Callable[[], np.ndarray]]
"""``(q0, goal) -> step()``: prepares a run to one goal; each ``step()`` returns the new ``q``."""


@dataclass
class Row:
    """Timings and outcomes of one solver over all goals."""

    name: str
    times: list[float] = field(default_factory=list)
    converged: int = 0
    violations: int = 0
    steps_to_goal: list[int] = field(default_factory=list)
    setup: float = 0.0


def _errors(m: optik.Mechanism, q: np.ndarray, goal: np.ndarray) -> tuple[float, float]:
    t = m.fk(q)
    return float(np.linalg.norm(t[:3, 3] - goal[:3, 3])), float(
        spatial.angle_between(t[:3, :3], goal[:3, :3])
    )


def run(
    configs: Sequence[tuple[str, Stepper]],
    m: optik.Mechanism,
    goals: Sequence[np.ndarray],
    steps: int,
    tol: float,
) -> list[Row]:
    """Run every solver on every goal from the mid-limit posture, interleaved goal by goal (load
    changes of a shared machine hit all solvers alike), after one untimed warm-up step per solver
    that builds what is built once (optik's compiled task stack, OSQP's workspace)."""
    rows = [Row(name) for name, _ in configs]
    for row, (_, make) in zip(rows, configs, strict=True):
        t0 = time.perf_counter()
        make(m.mid_q(), goals[0])()
        row.setup = time.perf_counter() - t0
    native.wait()  # the C library built in the background: time the compiled code
    for goal in goals:
        for row, (_, make) in zip(rows, configs, strict=True):
            do_step = make(m.mid_q(), goal)
            for k in range(steps):
                t0 = time.perf_counter()
                q = do_step()
                row.times.append(time.perf_counter() - t0)
                if np.any(q < m.lower) or np.any(q > m.upper):
                    row.violations += 1
                pos, ori = _errors(m, q, goal)
                if pos <= tol and ori <= tol:
                    row.converged += 1
                    row.steps_to_goal.append(k + 1)
                    break
    return rows


def optik_stepper(m: optik.Mechanism, dt: float, solver: str | None) -> Stepper:
    """optik's step with the benchmark's tasks (default limits: position and velocity)."""
    frame = diffik.FrameTask(position_cost=1.0, orientation_cost=1.0)
    posture = diffik.PostureTask(m.mid_q(), cost=1e-3)
    tasks = [frame, posture]

    def make(q0: np.ndarray, goal: np.ndarray) -> Callable[[], np.ndarray]:
        frame.set_target(goal)
        state = {"q": q0.copy()}

        def do_step() -> np.ndarray:
            state["q"] = diffik.step(m, state["q"], tasks, dt, "qp", solver).q
            return state["q"]

        return do_step

    return make


def pink_stepper(urdf: str, tip: str, dt: float, solver: str) -> Stepper:
    """Pink with the same tasks and limits (its defaults: configuration and velocity limits)."""
    import pink
    import pinocchio as pin

    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    frame = pink.tasks.FrameTask(tip, position_cost=1.0, orientation_cost=1.0)
    posture = pink.tasks.PostureTask(cost=1e-3)
    tasks = [frame, posture]

    def make(q0: np.ndarray, goal: np.ndarray) -> Callable[[], np.ndarray]:
        conf = pink.Configuration(model, data, q0.copy())
        frame.set_target(pin.SE3(goal[:3, :3], goal[:3, 3]))
        posture.set_target(q0.copy())

        def do_step() -> np.ndarray:
            v = pink.solve_ik(conf, tasks, dt, solver=solver, safety_break=False)
            conf.integrate_inplace(v, dt)
            return conf.q

        return do_step

    return make


def _stats(row: Row, n_goals: int, ref: float | None) -> str:
    mean, median, p95 = (1e3 * ms for ms in timing_ms(row.times))  # us
    ratio = f"{median / ref:6.2f}" if ref else "     -"
    steps = f"{np.mean(row.steps_to_goal):7.1f}" if row.steps_to_goal else "      -"
    return (
        f"| {row.name:<24} | {median:9.1f} | {mean:9.1f} | {p95:9.1f} "
        f"| {ratio} | "
        f"{row.converged:3d}/{n_goals:<3d} | {steps} | {row.violations:5d} | {row.setup * 1e3:8.1f} |"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print a markdown table; returns 0."""
    ap = benchmark_parser("diffik", __doc__)
    ap.add_argument("--goals", type=int, default=20, help="random goal poses")
    ap.add_argument("--steps", type=int, default=300, help="at most this many steps per goal")
    ap.add_argument("--dt", type=float, default=0.01, help="time step (s)")
    ap.add_argument("--tol", type=float, default=1e-4, help="convergence tolerance (m and rad)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--no-pink", action="store_true", help="skip the Pink peer")
    args = ap.parse_args(argv)
    logging.getLogger().setLevel(logging.ERROR)  # Pink logs every limit violation it sees
    warnings.simplefilter("ignore")  # qpsolvers' dense-to-sparse conversion notices

    m = optik.catalog.panda()
    urdf = str(optik.catalog.urdf_path("panda"))
    _, tip = optik.catalog.URDF_CHAINS["panda"]
    rng = np.random.default_rng(args.seed)
    goals = [m.fk(q) for q in m.random_q(args.goals, seed=rng)]

    configs: list[tuple[str, Stepper]] = [
        (f"optik qp (default: {diffik.default_solver()})", optik_stepper(m, args.dt, None)),
        ("optik qp osqp", optik_stepper(m, args.dt, "osqp")),
    ]
    pink_best = None
    if not args.no_pink:
        try:
            import qpsolvers
        except ImportError:
            qpsolvers = None
        try:
            import pink  # noqa: F401
        except ImportError:
            print('pin-pink is not installed (pip install "optik[peers]"): Pink rows skipped')
        else:
            if qpsolvers is not None:
                trial = {}
                for name in sorted(qpsolvers.available_solvers):
                    config = (name, pink_stepper(urdf, tip, args.dt, name))
                    (row,) = run([config], m, goals[:1], args.steps, args.tol)
                    trial[name] = float(np.median(row.times))
                    print(f"Pink + {name}: first goal, median step {trial[name] * 1e6:.1f} us")
                pink_best = min(trial, key=trial.get)
                configs.append((f"Pink + {pink_best} (fastest)", pink_stepper(urdf, tip, args.dt, pink_best)))
                if pink_best != "osqp" and "osqp" in trial:
                    configs.append(("Pink + osqp", pink_stepper(urdf, tip, args.dt, "osqp")))

    rows = run(configs, m, goals, args.steps, args.tol)
    ref = None
    if pink_best is not None:
        ref = float(np.median(rows[2].times) * 1e6)
    print(
        f"\nPanda, {args.goals} goals, dt = {args.dt} s, <= {args.steps} steps, tol {args.tol:g} m/rad; "
        f"step times in us; ratio = median / median of Pink's fastest; conv. = goals converged; steps = mean "
        f"steps to converge; viol. = visited configurations outside the joint limits; "
        f"setup = first (untimed) step\n"
    )
    print(
        "| solver                   |    median |      mean |       p95 |  ratio "
        "| conv.   | steps   | viol. | setup ms |"
    )
    print(
        "|--------------------------|-----------|-----------|-----------|--------|---------|---------|-------|----------|"
    )
    for row in rows:
        print(_stats(row, args.goals, ref))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
