"""QP differential IK past an obstacle: the Panda's hand follows a straight line that grazes a ball,
optik with and without its velocity dampers (``optik.diffik.collision``) and Pink with and without
its collision barrier, in the same run.

Method: `optik.diffik.scenarios.ball_pass` (the Panda of example-robot-data, ``panda_link0`` to
``panda_hand_tcp``, its SRDF): the tool point moves ``--length`` m along y at a fixed orientation
in ``--steps`` samples of 0.01 s, a ball of radius ``--radius`` at the middle, its surface
``--offset`` m beside the line. optik: ``optik.diffik.track`` (method ``qp``, the default backend),
the dampers with ``world=W, margin=--margin`` (influence 5 cm, gain ``gamma`` 0.5).

Pink (pin-pink): the same frame task (position and orientation cost 1, gain 1) and its default
limits (configuration and velocity limits, as optik's), ``pink.solve_ik`` with the same QP backend
(``daqp`` when installed), then ``integrate_inplace`` (which updates Pinocchio's kinematics and,
with a collision model, every pair's distance): both are timed. Its model is Pinocchio's own of
the URDF with the finger joints locked at 0 (``buildReducedModel``), collision meshes as their
convex hulls (as optik queries them), ``addAllCollisionPairs`` minus the SRDF's, the ball a
geometry on the universe joint (so paired with every moving link). The barrier is
``pink.barriers.SelfCollisionBarrier`` over every pair of that model with ``d_min = --margin`` and
gain ``gamma / dt`` (its rows ``-J dq / dt <= gain (d - d_min)`` are then optik's damper rows
``-J dq <= gamma (d - d_s)``), its default safe-displacement gain (1).

Reported per run: the smallest exact distance along the path (``optik.collision.check_many`` at
every configuration, robot against the ball and itself: one judge for all), steps below the
margin, the largest position error (FK of each answer against its sample) and QP failures; then
the step time (mean / median / p95 over ``--repeats`` repetitions), the median CPU time of the
process per step (``time.process_time``: what the step computes, whatever else the machine runs)
and the ratios of the medians, wall / CPU, to optik's plain step and to the same library's plain
step, twice: with the four runs interleaved sample by sample (they see the same load, but every
step starts with caches the other runs' steps have filled) and with whole tracks one after the
other (each run's steps back to back, warm, as in a control loop that does nothing else). Medians:
on a loaded machine a step that the scheduler preempts takes a few milliseconds, which moves the
means of the longer steps most. optik's C code is built (and waited for) before the timed runs.

Run: ``optik benchmark collision_qp [--steps 200] [--margin 0.01] [--repeats 3] [--no-pink]``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

import optik
from optik import native
from optik.benchmarks import benchmark_parser
from optik.diffik.collision import DAMPER_GAIN
from optik.diffik.scenarios import Scenario, ball_pass
from optik.diffik.track import tracking_task
from optik.harness.tally import timing_ms

Stepper = Callable[[int], np.ndarray]
"""``k -> q``: one step towards sample ``k`` of the path from the stepper's own state."""


def optik_stepper(sc: Scenario, **kw: object) -> Callable[[], Stepper]:
    """A fresh optik run (``optik.diffik.step`` with the tracking task, gain 1, as ``track`` does)."""

    def make() -> Stepper:
        task = tracking_task(sc.m)
        state = {"q": sc.q0.copy(), "v": np.zeros(sc.m.n_q)}

        def do_step(k: int) -> np.ndarray:
            task.set_target(sc.path[k])
            res = optik.diffik.step(sc.m, state["q"], [task], sc.dt, v_prev=state["v"], **kw)
            state["q"], state["v"] = res.q, res.v
            return res.q

        return do_step

    return make


def pink_stepper(sc: Scenario, margin: float, barrier: bool) -> Callable[[], Stepper]:
    """A fresh Pink run on the same path (module docstring), with or without its barrier."""
    import coal
    import pink
    import pinocchio as pin
    import qpsolvers

    from optik.catalog.robots import robots_dir

    d = robots_dir() / "panda_description"
    urdf, srdf = str(d / "urdf" / "panda.urdf"), str(d / "srdf" / "panda.srdf")
    full = pin.buildModelFromUrdf(urdf)
    full_geom = pin.buildGeomFromUrdf(
        full, urdf, pin.GeometryType.COLLISION, package_dirs=[str(d.parents[2])]
    )
    fingers = [full.getJointId(n) for n in ("panda_finger_joint1", "panda_finger_joint2")]
    model, geom = pin.buildReducedModel(full, full_geom, fingers, pin.neutral(full))
    for go in geom.geometryObjects:
        if isinstance(go.geometry, coal.BVHModelBase):
            go.geometry.buildConvexHull(True, "Qt")
            go.geometry = go.geometry.convex
    for o in sc.world.snapshot():
        for k, (g, offset) in enumerate(optik.collision.shapes.coal_objects(o.shape)):
            t = o.pose @ offset
            geom.addGeometryObject(pin.GeometryObject(f"{o.name}_{k}", 0, pin.SE3(t[:3, :3], t[:3, 3]), g))
    geom.addAllCollisionPairs()
    pin.removeCollisionPairs(model, geom, srdf)
    solver = "daqp" if "daqp" in qpsolvers.available_solvers else "osqp"
    task = pink.tasks.FrameTask("panda_hand_tcp", position_cost=1.0, orientation_cost=1.0)
    n_pairs = len(geom.collisionPairs)

    def make() -> Stepper:
        data = model.createData()
        if barrier:
            conf = pink.Configuration(model, data, sc.q0.copy(), collision_model=geom)
            barriers = [pink.barriers.SelfCollisionBarrier(n_pairs, gain=DAMPER_GAIN / sc.dt, d_min=margin)]
        else:
            conf, barriers = pink.Configuration(model, data, sc.q0.copy()), []

        def do_step(k: int) -> np.ndarray:
            t = sc.path[k]
            task.set_target(pin.SE3(t[:3, :3].copy(), t[:3, 3].copy()))
            try:
                v = pink.solve_ik(conf, [task], sc.dt, solver=solver, barriers=barriers, safety_break=False)
            except pink.exceptions.NoSolutionFound:
                v = None
            if v is not None:
                conf.integrate_inplace(v, sc.dt)
            return np.array(conf.q) if v is not None else np.full(sc.m.n_q, np.nan)

        return do_step

    return make


@dataclass
class Timed:
    """Per run: the wall and CPU time of every step (s) and the configurations of the last repetition."""

    wall: dict[str, list[float]]
    cpu: dict[str, list[float]]
    q: dict[str, np.ndarray]


def _timed(
    runs: dict[str, tuple[str, Callable[[], Stepper]]], steps: int, repeats: int, by_sample: bool
) -> Timed:
    """Every run ``repeats`` times from a fresh state, interleaved sample by sample (``by_sample``)
    or whole track after whole track."""
    out = Timed({name: [] for name in runs}, {name: [] for name in runs}, {})
    for _ in range(max(1, repeats)):
        steppers = {name: make() for name, (_, make) in runs.items()}
        qs: dict[str, list[np.ndarray]] = {name: [] for name in runs}
        order = (
            [(k, name) for k in range(steps) for name in runs]
            if by_sample
            else [(k, name) for name in runs for k in range(steps)]
        )
        for k, name in order:
            t0, c0 = time.perf_counter(), time.process_time()
            qs[name].append(steppers[name](k))
            out.wall[name].append(time.perf_counter() - t0)
            out.cpu[name].append(time.process_time() - c0)
        out.q = {name: np.array(v) for name, v in qs.items()}
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the tracks and print a markdown table; returns 0."""
    ap = benchmark_parser("collision_qp", __doc__)
    ap.add_argument("--steps", type=int, default=200, help="path samples (one QP step each)")
    ap.add_argument("--length", type=float, default=0.5, help="path length (m)")
    ap.add_argument("--radius", type=float, default=0.05, help="ball radius (m)")
    ap.add_argument("--offset", type=float, default=0.0, help="ball surface beside the line, along x (m)")
    ap.add_argument("--margin", type=float, default=0.01, help="clearance kept by the dampers (m)")
    ap.add_argument("--repeats", type=int, default=3, help="repetitions of every run (timing)")
    ap.add_argument("--no-pink", action="store_true", help="skip the Pink runs")
    args = ap.parse_args(argv)
    if args.steps < 2 or not args.length > 0 or not args.radius > 0 or args.margin < 0:
        ap.error("--steps >= 2, --length and --radius > 0, --margin >= 0")
    try:
        sc = ball_pass(args.steps, args.length, args.radius, args.offset)
        optik.collision.robot_geometry(sc.m)
    except (ImportError, optik.OptikError) as exc:
        print(f"needs coal and example-robot-data (extras 'collision', 'robots'): {exc}")
        return 0
    runs: dict[str, tuple[str, Callable[[], Stepper]]] = {
        "optik qp": ("optik qp", optik_stepper(sc)),
        "optik qp + dampers": ("optik qp", optik_stepper(sc, world=sc.world, margin=args.margin)),
    }
    if not args.no_pink:
        try:
            runs["Pink"] = ("Pink", pink_stepper(sc, args.margin, barrier=False))
            runs["Pink + SelfCollisionBarrier"] = ("Pink", pink_stepper(sc, args.margin, barrier=True))
        except ImportError as exc:
            print(f"pin-pink is not installed (pip install 'optik[peers]'): Pink rows skipped ({exc})")
    for _, make in runs.values():  # warm-up: optik builds its C code (waited for), Pink its model
        stepper = make()
        for k in range(5):
            stepper(k)
    native.wait()
    interleaved = _timed(runs, args.steps, args.repeats, by_sample=True)
    tracks = _timed(runs, args.steps, args.repeats, by_sample=False)
    print(
        f"Panda hand along {args.length:g} m past a ball of radius {args.radius:g} m "
        f"(its surface {args.offset:g} m beside the line), {args.steps} steps, dt {sc.dt:g} s, "
        f"margin {args.margin:g} m"
    )
    print("\n| run | min distance mm | steps below margin | max position error mm | QP failures |")
    print("|---|---:|---:|---:|---:|")
    for name, q in interleaved.q.items():
        solved = np.flatnonzero(~np.isnan(q).any(axis=1))
        dist = optik.collision.check_many(sc.m, q[solved], sc.world).min_distance
        err = max(np.linalg.norm(sc.m.fk(q[k])[:3, 3] - sc.path[k, :3, 3]) for k in solved)
        below, failures = int((dist < args.margin).sum()), args.steps - len(solved)
        print(f"| {name} | {dist.min() * 1e3:.1f} | {below} | {err * 1e3:.2f} | {failures} |")
    for title, timed in (
        (
            "Step time, the four runs interleaved sample by sample (each step after the other runs' steps)",
            interleaved,
        ),
        ("Step time, whole tracks one after the other (each run's steps back to back)", tracks),
    ):
        print(f"\n{title}:\n")
        print(
            "| run | mean ms | median ms | p95 ms | CPU median ms | median / optik qp (wall / CPU) "
            "| median / same library's plain (wall / CPU) |"
        )
        print("|---|---:|---:|---:|---:|---:|---:|")
        med = {name: timing_ms(t)[1] for name, t in timed.wall.items()}
        cpu = {name: timing_ms(t)[1] for name, t in timed.cpu.items()}
        for name, (plain, _) in runs.items():
            mean, median, p95 = timing_ms(timed.wall[name])
            print(
                f"| {name} | {mean:.3f} | {median:.3f} | {p95:.3f} | {cpu[name]:.3f} "
                f"| {median / med['optik qp']:.2f} / {cpu[name] / cpu['optik qp']:.2f} "
                f"| {median / med[plain]:.2f} / {cpu[name] / cpu[plain]:.2f} |"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
