"""Humanoid reach with balance: the Unitree G1 (example-robot-data, free-flyer base) reaches a
hand target with both feet held and its centre of mass over the support polygon, optik's NLP
with balance rows against Pink (frame tasks and its CoM task) on the same targets in the same run.

Method (docs/benchmarks.md): the standing configuration is every joint at 0 (clipped into the
limits), the base lifted so that the lower foot is on z = 0; the support polygon is the convex
hull of both soles, a box of x in [-0.05, 0.12] and y in [-0.03, 0.03] m around each
``*_ankle_roll_link``. A target is the pose of ``right_rubber_hand`` at the standing
configuration with the waist and arm joints drawn uniformly within their limits clipped to
+-1 rad (seeded); draws whose centre of mass is not inside the polygon by ``--margin`` are
redrawn, so every target is reachable with balance.

optik: ``optik.solve_ik(m, {hand: T}, q0=stand, contacts={feet: poses}, support=polygon,
com_margin=margin, time_limit=...)`` (method ``"nlp"``). Pink: ``pink.solve_ik`` iterated from
the standing configuration (``dt = 1``, daqp) with a ``FrameTask`` for the hand (cost 1), one
per foot (cost 100), a ``ComTask`` toward the standing centre of mass (``--pink-com-costs``,
one Pink run per cost, 0 for none; Pink has no polygon constraint, so its CoM task holds the
CoM near the middle of the feet, and pulls the hand off its target by a cost-weighted
compromise) and a
``PostureTask`` (1e-6), until the hand and feet are within the tolerance, the time limit or a
QP without solution.

Every answer is judged by Pinocchio, on its own model of the URDF: the hand and both feet
within ``--tol`` (position and geodesic angle, ``updateFramePlacements``), the centre of mass
(``centerOfMass``) inside the polygon by ``margin - 1e-9``, the joint limits. Calls are
interleaved target by target; each solver has one untimed warm-up call.

Run: ``optik benchmark balance [--n 50] [--time-limit 0.5] [--tol 1e-6] [--margin 0.01] [--seed 0]
[--pink-com-costs 1e-2,1e-4]``.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence

import numpy as np

import optik
from optik.benchmarks import benchmark_parser
from optik.solvers.balance import support_halfplanes

URDF = "g1_description/urdf/g1_29dof_rev_1_0.urdf"
HAND = "right_rubber_hand"
FEET = ("left_ankle_roll_link", "right_ankle_roll_link")
SOLE = ((-0.05, -0.03), (0.12, -0.03), (0.12, 0.03), (-0.05, 0.03))
Solver = Callable[[np.ndarray, float], np.ndarray]
"""``(hand target, time_limit) -> Pinocchio configuration``."""


class Humanoid:
    """The optik and Pinocchio models of the G1, its standing pose, feet and support polygon."""

    def __init__(self) -> None:
        import pinocchio as pin

        from optik.catalog.robots import robots_dir

        path = robots_dir() / URDF
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.m = optik.Mechanism.from_urdf(path, floating_base=True)
        self.pin = pin
        self.model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
        self.data = self.model.createData()
        m = self.m
        stand = np.clip(np.zeros(m.n_q), m.lower, m.upper)
        stand[2] = -min(m.fk(stand, f)[2, 3] for f in FEET)
        self.stand = stand
        self.feet = {f: m.fk(stand, f) for f in FEET}
        corners = np.array([self.feet[f][:2, 3] + c for f in FEET for c in SOLE])
        from scipy.spatial import ConvexHull

        self.polygon = corners[ConvexHull(corners).vertices]
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

    def ok(self, qp: np.ndarray, hand: np.ndarray, tol: float, margin: float) -> bool:
        """Pinocchio's verdict (see the module docstring)."""
        pin, model, data = self.pin, self.model, self.data
        lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
        if np.any(qp[7:] < lo) or np.any(qp[7:] > hi):
            return False
        pin.framesForwardKinematics(model, data, qp)
        for frame, want in ((HAND, hand), *self.feet.items()):
            got = data.oMf[model.getFrameId(frame, pin.FrameType.BODY)]
            if np.linalg.norm(got.translation - want[:3, 3]) > tol:
                return False
            if np.linalg.norm(pin.log3(want[:3, :3].T @ got.rotation)) > tol:
                return False
        return self.inside(pin.centerOfMass(model, data, qp)) >= margin - 1e-9

    def targets(self, n: int, seed: int, margin: float) -> list[np.ndarray]:
        m, rng, out = self.m, np.random.default_rng(seed), []
        moving = [
            i
            for i, c in enumerate(m.coordinate_names)
            if any(k in c for k in ("waist", "shoulder", "elbow", "wrist"))
        ]
        lo, hi = np.maximum(m.lower[moving], -1.0), np.minimum(m.upper[moving], 1.0)
        while len(out) < n:
            q = self.stand.copy()
            q[moving] = rng.uniform(lo, hi)
            if self.inside(m.com(q)) >= margin:
                out.append(m.fk(q, HAND))
        return out


def optik_solver(h: Humanoid, tol: float, margin: float) -> Solver:
    contacts = dict(h.feet)

    def solve(hand: np.ndarray, time_limit: float) -> np.ndarray:
        r = optik.solve_ik(
            h.m,
            {HAND: hand},
            q0=h.stand,
            contacts=contacts,
            support=h.polygon,
            com_margin=margin,
            time_limit=time_limit,
            tol=tol,
        )
        return h.to_pin(r.q)

    return solve


def pink_solver(h: Humanoid, tol: float, com_cost: float) -> Solver:
    """Pink's differential IK iterated to the targets (see the module docstring)."""
    import pink

    pin = h.pin
    hand_task = pink.tasks.FrameTask(HAND, position_cost=1.0, orientation_cost=1.0)
    foot_tasks = [pink.tasks.FrameTask(f, position_cost=100.0, orientation_cost=100.0) for f in FEET]
    com_task = pink.tasks.ComTask(cost=com_cost)
    posture = pink.tasks.PostureTask(cost=1e-6)
    q0 = h.to_pin(h.stand)
    data = h.model.createData()
    com0 = pin.centerOfMass(h.model, data, q0)
    tasks = [hand_task, *foot_tasks, posture] + ([com_task] if com_cost > 0 else [])
    for task, f in zip(foot_tasks, FEET, strict=True):
        task.set_target(pin.SE3(h.feet[f][:3, :3], h.feet[f][:3, 3]))
    com_task.set_target(com0)
    posture.set_target(q0.copy())

    def solve(hand: np.ndarray, time_limit: float) -> np.ndarray:
        deadline = time.perf_counter() + time_limit
        conf = pink.Configuration(h.model, data, q0.copy())
        goal = pin.SE3(hand[:3, :3], hand[:3, 3])
        hand_task.set_target(goal)
        goals = [(HAND, goal)] + [(f, pin.SE3(h.feet[f][:3, :3], h.feet[f][:3, 3])) for f in FEET]
        while time.perf_counter() < deadline:
            try:
                v = pink.solve_ik(conf, tasks, 1.0, solver="daqp", safety_break=False)
            except pink.exceptions.NoSolutionFound:
                break
            conf.integrate_inplace(v, 1.0)
            worst = 0.0
            for frame, g in goals:
                p = conf.get_transform_frame_to_world(frame)
                worst = max(worst, np.linalg.norm(p.translation - g.translation))
                worst = max(worst, np.linalg.norm(pin.log3(g.rotation.T @ p.rotation)))
            if worst < 0.5 * tol:
                break
        return conf.q.copy()

    return solve


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print a markdown table with the ratio to optik; returns 0."""
    ap = benchmark_parser("balance", __doc__)
    ap.add_argument("--n", type=int, default=50, help="hand targets")
    ap.add_argument("--time-limit", type=float, default=0.5, help="seconds per call")
    ap.add_argument("--tol", type=float, default=1e-6, help="position (m) and orientation (rad) tolerance")
    ap.add_argument("--margin", type=float, default=0.01, help="balance margin (m)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--no-pink", action="store_true", help="skip the Pink peer")
    ap.add_argument(
        "--pink-com-costs", default="1e-2,1e-4", help="costs of Pink's CoM task, one Pink run each (0: none)"
    )
    args = ap.parse_args(argv)
    if args.n < 1 or not args.time_limit > 0 or not args.tol > 0 or args.margin < 0:
        ap.error("--n must be >= 1, --time-limit and --tol > 0, --margin >= 0")
    try:
        h = Humanoid()
    except (ImportError, optik.OptikError) as exc:
        print(f"needs pinocchio and example-robot-data (extras 'peers', 'robots'): {exc}")
        return 0
    solvers: dict[str, Solver] = {"optik nlp + balance": optik_solver(h, args.tol, args.margin)}
    if not args.no_pink:
        try:
            for cost in (float(c) for c in args.pink_com_costs.split(",") if c):
                solvers[f"Pink + daqp, CoM task cost {cost:g}"] = pink_solver(h, args.tol, cost)
        except ImportError:
            print('pin-pink is not installed (pip install "optik[peers]"): Pink skipped')
    targets = h.targets(args.n, args.seed, args.margin)
    for solve in solvers.values():  # untimed warm-up
        solve(targets[0], args.time_limit)
    results: dict[str, tuple[list[float], int]] = {name: ([], 0) for name in solvers}
    for hand in targets:
        for name, solve in solvers.items():
            t0 = time.perf_counter()
            qp = solve(hand, args.time_limit)
            elapsed = time.perf_counter() - t0
            times, ok = results[name]
            times.append(elapsed)
            results[name] = (times, ok + h.ok(qp, hand, args.tol, args.margin))
    ref = np.mean(results["optik nlp + balance"][0])
    print(
        f"G1 (29 DOF + free base), {args.n} hand targets, both feet held, CoM margin {args.margin:g} m, "
        f"time limit {args.time_limit * 1e3:g} ms, tol {args.tol:g}, judged by Pinocchio"
    )
    print("| solver | success | mean ms | median ms | p95 ms | mean / optik |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, (times, ok) in results.items():
        t = np.array(times) * 1e3
        print(
            f"| {name} | {ok}/{args.n} | {t.mean():.2f} | {np.median(t):.2f} | {np.percentile(t, 95):.2f} "
            f"| {t.mean() / (ref * 1e3):.2f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
