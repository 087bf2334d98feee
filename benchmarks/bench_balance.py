"""Whole-body IK with balance on the legged robots of `optik.catalog.legged`: the G1 humanoid
reaching a hand target, or the Go2 quadruped moving its base, with the feet held and the
centre of mass over the support polygon; optik against Pink (frame tasks and its CoM task) on
the same targets in the same run.

Method (docs/benchmarks.md): the robot's standing configuration (``m.params["standing"]``) and
support polygon (`optik.catalog.legged.support_polygon`: the hull of the G1's soles, of the
Go2's foot points). Targets (seeded): for ``g1``, the pose of ``right_rubber_hand`` at the
standing configuration with the waist and arm joints drawn uniformly within their limits
clipped to +-1 rad, redrawn until the centre of mass is inside the polygon by ``--margin`` (so
every target is reachable with balance); for ``go2``, the base pose moved by up to 3 cm in x
and y, -6 to +2 cm in z and a rotation vector of up to 0.1 rad per axis (small enough to be
reachable with the feet held; not certified).

optik: ``optik.solve_ik(m, {frame: T}, q0=standing, contacts=feet, support=polygon,
com_margin=margin, time_limit=..., method=...)`` for each of ``--methods`` (``lm``, the default: the
compiled kernel with the balance hinges; ``nlp``: IPOPT with the balance inequalities; flat feet
held as poses, point feet as positions). The C build of the ``lm`` kernel runs before the timed
calls and is not timed (``--compile-wait``). Pink: ``pink.solve_ik`` iterated from the standing
configuration (``dt = 1``, daqp) with a ``FrameTask`` for the target frame (cost 1), one per foot
(cost 100; orientation cost 0 for point feet), a ``ComTask`` toward the standing centre of mass
(``--pink-com-costs``, one Pink run per cost, 0 for none; Pink has no polygon constraint, so its CoM
task holds the CoM near the middle of the feet, and pulls the target frame off by a cost-weighted
compromise) and a ``PostureTask`` (1e-6), until the target and the feet are within the tolerance,
the time limit or a QP without solution.

Every answer is judged by Pinocchio, on its own model of the URDF: the target frame and the
feet within ``--tol`` (position and geodesic angle; position only for point feet;
``framesForwardKinematics``), the centre of mass (``centerOfMass``) inside the polygon by
``margin - 1e-9``, the joint limits. Calls are interleaved target by target; each solver has one
untimed warm-up call.

Run: ``optik benchmark balance [--robot g1] [--n 50] [--time-limit 0.5] [--tol 1e-6]
[--margin 0.01] [--seed 0] [--methods lm,nlp] [--pink-com-costs 1e-2,1e-4] [--compile-wait 600]``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

import optik
from optik.benchmarks import benchmark_parser
from optik.harness.tally import success_table
from optik.solvers.balance import BALANCE_METHODS, compiled_kernels, support_halfplanes

Solver = Callable[[np.ndarray, float], np.ndarray]
"""``(target pose, time_limit) -> Pinocchio configuration``."""


class Legged:
    """The optik (`optik.catalog.legged`) and Pinocchio models of a legged robot, its standing
    configuration, feet, support polygon and target frame."""

    def __init__(self, name: str) -> None:
        import pinocchio as pin

        from optik.catalog.legged import LEGGED, support_polygon
        from optik.catalog.robots import robots_dir

        self.m = m = optik.catalog.legged(name)
        self.name = name
        self.pin = pin
        self.model = pin.buildModelFromUrdf(str(robots_dir() / LEGGED[name].urdf), pin.JointModelFreeFlyer())
        self.data = self.model.createData()
        self.stand = m.params["standing"]
        self.flat = m.params["sole"] is not None
        self.frame = m.params["hands"][1] if m.params["hands"] else m.joints[0].child
        self.feet = {f: m.fk(self.stand, f) for f in m.params["feet"]}
        self.contacts = {f: t if self.flat else optik.Position(t[:3, 3]) for f, t in self.feet.items()}
        self.polygon = support_polygon(m, self.stand)
        self.normals, self.b = support_halfplanes(self.polygon)
        self.idx = [self.model.joints[self.model.getJointId(n)].idx_q for n in m.coordinate_names[6:]]

    def to_pin(self, q: np.ndarray) -> np.ndarray:
        qp = self.pin.neutral(self.model)
        qp[:3] = q[:3]
        qp[3:7] = self.pin.Quaternion(self.pin.exp3(q[3:6])).coeffs()
        qp[self.idx] = q[6:]
        return qp

    def inside(self, com: np.ndarray) -> float:
        return float(np.min(self.b - self.normals @ com[:2]))

    def ok(self, qp: np.ndarray, target: np.ndarray, tol: float, margin: float) -> bool:
        """Pinocchio's verdict (see the module docstring)."""
        pin, model, data = self.pin, self.model, self.data
        lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
        if np.any(qp[7:] < lo) or np.any(qp[7:] > hi):
            return False
        pin.framesForwardKinematics(model, data, qp)
        checks = [(self.frame, target, True)] + [(f, t, self.flat) for f, t in self.feet.items()]
        for frame, want, orientation in checks:
            got = data.oMf[model.getFrameId(frame, pin.FrameType.BODY)]
            if np.linalg.norm(got.translation - want[:3, 3]) > tol:
                return False
            if orientation and np.linalg.norm(pin.log3(want[:3, :3].T @ got.rotation)) > tol:
                return False
        return self.inside(pin.centerOfMass(model, data, qp)) >= margin - 1e-9

    def targets(self, n: int, seed: int, margin: float) -> list[np.ndarray]:
        m, rng, out = self.m, np.random.default_rng(seed), []
        if not m.params["hands"]:  # base poses
            for _ in range(n):
                t = m.fk(self.stand, self.frame)
                t[:3, 3] += rng.uniform([-0.03, -0.03, -0.06], [0.03, 0.03, 0.02])
                t[:3, :3] = optik.spatial.so3_exp(rng.uniform(-0.1, 0.1, 3)) @ t[:3, :3]
                out.append(t)
            return out
        names = ("waist", "shoulder", "elbow", "wrist")
        moving = [i for i, c in enumerate(m.coordinate_names) if any(k in c for k in names)]
        lo, hi = np.maximum(m.lower[moving], -1.0), np.minimum(m.upper[moving], 1.0)
        while len(out) < n:
            q = self.stand.copy()
            q[moving] = rng.uniform(lo, hi)
            if self.inside(m.com(q)) >= margin:
                out.append(m.fk(q, self.frame))
        return out


def optik_solver(h: Legged, tol: float, margin: float, method: str) -> Solver:
    def solve(target: np.ndarray, time_limit: float) -> np.ndarray:
        r = optik.solve_ik(
            h.m,
            {h.frame: target},
            q0=h.stand,
            method=method,
            contacts=h.contacts,
            support=h.polygon,
            com_margin=margin,
            time_limit=time_limit,
            tol=tol,
        )
        return h.to_pin(r.q)

    return solve


def pink_solver(h: Legged, tol: float, com_cost: float) -> Solver:
    """Pink's differential IK iterated to the targets (see the module docstring)."""
    import pink

    pin = h.pin
    main_task = pink.tasks.FrameTask(h.frame, position_cost=1.0, orientation_cost=1.0)
    foot_cost = 100.0 if h.flat else 0.0
    foot_tasks = [pink.tasks.FrameTask(f, position_cost=100.0, orientation_cost=foot_cost) for f in h.feet]
    com_task = pink.tasks.ComTask(cost=com_cost)
    posture = pink.tasks.PostureTask(cost=1e-6)
    q0 = h.to_pin(h.stand)
    data = h.model.createData()
    tasks = [main_task, *foot_tasks, posture] + ([com_task] if com_cost > 0 else [])
    feet = [(f, pin.SE3(t[:3, :3], t[:3, 3])) for f, t in h.feet.items()]
    for task, (_, goal) in zip(foot_tasks, feet, strict=True):
        task.set_target(goal)
    com_task.set_target(pin.centerOfMass(h.model, data, q0))
    posture.set_target(q0.copy())

    def solve(target: np.ndarray, time_limit: float) -> np.ndarray:
        deadline = time.perf_counter() + time_limit
        conf = pink.Configuration(h.model, data, q0.copy())
        goal = pin.SE3(target[:3, :3], target[:3, 3])
        main_task.set_target(goal)
        checks = [(h.frame, goal, True)] + [(f, g, h.flat) for f, g in feet]
        while time.perf_counter() < deadline:
            try:
                v = pink.solve_ik(conf, tasks, 1.0, solver="daqp", safety_break=False)
            except pink.exceptions.NoSolutionFound:
                break
            conf.integrate_inplace(v, 1.0)
            worst = 0.0
            for frame, g, orientation in checks:
                p = conf.get_transform_frame_to_world(frame)
                worst = max(worst, np.linalg.norm(p.translation - g.translation))
                if orientation:
                    worst = max(worst, np.linalg.norm(pin.log3(g.rotation.T @ p.rotation)))
            if worst < 0.5 * tol:
                break
        return conf.q.copy()

    return solve


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print a markdown table with the ratio to optik; returns 0."""
    ap = benchmark_parser("balance", __doc__)
    ap.add_argument("--robot", default="g1", choices=("g1", "go2"), help="g1: hand reach; go2: base pose")
    ap.add_argument("--n", type=int, default=50, help="targets")
    ap.add_argument("--time-limit", type=float, default=0.5, help="seconds per call")
    ap.add_argument("--tol", type=float, default=1e-6, help="position (m) and orientation (rad) tolerance")
    ap.add_argument("--margin", type=float, default=0.01, help="balance margin (m)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--methods", default="lm,nlp", help="optik methods, comma-separated (lm, nlp)")
    ap.add_argument("--compile-wait", type=float, default=600.0, help="seconds to wait for optik's C build")
    ap.add_argument("--no-pink", action="store_true", help="skip the Pink peer")
    ap.add_argument(
        "--pink-com-costs", default="1e-2,1e-4", help="costs of Pink's CoM task, one Pink run each (0: none)"
    )
    args = ap.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    if args.n < 1 or not args.time_limit > 0 or not args.tol > 0 or args.margin < 0:
        ap.error("--n must be >= 1, --time-limit and --tol > 0, --margin >= 0")
    if not methods or set(methods) - set(BALANCE_METHODS):
        ap.error(f"--methods: some of {', '.join(BALANCE_METHODS)}")
    try:
        h = Legged(args.robot)
    except (ImportError, optik.OptikError) as exc:
        print(f"needs pinocchio and example-robot-data (extras 'peers', 'robots'): {exc}")
        return 0
    solvers: dict[str, Solver] = {
        f"optik {method} + balance": optik_solver(h, args.tol, args.margin, method) for method in methods
    }
    if not args.no_pink:
        try:
            for cost in (float(c) for c in args.pink_com_costs.split(",") if c):
                solvers[f"Pink + daqp, CoM task cost {cost:g}"] = pink_solver(h, args.tol, cost)
        except ImportError:
            print('pin-pink is not installed (pip install "optik[peers]"): Pink skipped')
    targets = h.targets(args.n, args.seed, args.margin)
    for solve in solvers.values():  # untimed warm-up (optik starts the C build of its lm kernel)
        solve(targets[0], args.time_limit)
    waited = time.perf_counter()
    while not all(compiled_kernels(h.m)) and time.perf_counter() - waited < args.compile_wait:
        time.sleep(1.0)
    results: dict[str, tuple[list[float], int]] = {name: ([], 0) for name in solvers}
    for target in targets:
        for name, solve in solvers.items():
            t0 = time.perf_counter()
            qp = solve(target, args.time_limit)
            elapsed = time.perf_counter() - t0
            times, ok = results[name]
            times.append(elapsed)
            results[name] = (times, ok + h.ok(qp, target, args.tol, args.margin))
    print(
        f"{args.robot} ({h.m.n_q - 6} joints + free base), {args.n} targets of {h.frame}, "
        f"{len(h.feet)} feet held, CoM margin {args.margin:g} m, "
        f"time limit {args.time_limit * 1e3:g} ms, tol {args.tol:g}, judged by Pinocchio; "
        f"lm kernel compiled: {all(compiled_kernels(h.m))}"
    )
    print(success_table(results, args.n, f"optik {methods[0]} + balance"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
