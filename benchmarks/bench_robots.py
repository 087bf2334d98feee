"""Every arm of example-robot-data: FK against pinocchio, IK against TRAC-IK, same targets, same run.

Method (docs/robots.md): each arm of `optik.catalog.robots.ARMS` is loaded by optik
(`optik.catalog.robot`), by pinocchio (``buildModelFromUrdf`` on the same file) and by TRAC-IK
(``pytracik``, Speed mode, the same base and tip links).

* **FK**: the largest entry of ``|T_optik(q) - T_pinocchio(q)|`` (tip pose in the base link)
  over ``--fk`` random joint vectors within the limits.
* **IK**: ``--n`` joint vectors drawn within the limits (`optik.Mechanism.random_q`, seeded;
  continuous joints in ``[-pi, pi]``), their FK poses (pinocchio's) as targets. Every solver
  starts from the mid-limit seed with the same time limit (``--time-limit``) and tolerance
  (``--tol``; TRAC-IK's ``eps`` is half of it, as in `optik.harness.peers.tracik_peer`); optik
  runs its default method for the arm (named in the table; ``--method`` picks one). The solvers
  run interleaved target by target after one untimed warm-up call each (optik's C code built and
  loaded); every call is timed around the public call, failures included. **Success is one check for both**:
  pinocchio's FK of the returned ``q`` within ``--tol`` of the target (position in m, geodesic
  angle in rad) and the URDF limits satisfied exactly (TRAC-IK's own flag is shown next to it,
  and its answers that fail only by a limit overshoot of at most `OVERSHOOT` are counted).
  ``pytracik`` reads the limits of a joint that has a ``<safety_controller>`` as ``[0, 0]``;
  such limits are replaced by the URDF's (``set_joint_limits``) so that both solvers search the
  same box.

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
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik import native, spatial  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.catalog.robots import ARMS, robot, robot_names, robot_urdf  # noqa: E402

OVERSHOOT = 1e-6
"""Largest joint-limit overshoot (rad or m) counted apart: ``pytracik`` keeps the limits in single
precision, so an answer on a limit can exceed the URDF's value by a few 1e-8."""

Pose = Callable[[np.ndarray], np.ndarray]
"""``q -> 4x4`` pose of the tip link in the base link."""


def pinocchio_fk(m: optik.Mechanism, urdf: Path, base: str, tip: str) -> Pose:
    """The tip pose in the base link computed by pinocchio from the same URDF, as a function of
    optik's coordinates (matched by joint name; continuous joints set through ``cos, sin``)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    slots = []
    for name in m.coordinate_names:
        joint = model.joints[model.getJointId(name)]
        slots.append((joint.idx_q, joint.nq))
    base_id, tip_id = (model.getFrameId(link, pin.FrameType.BODY) for link in (base, tip))
    q_pin = pin.neutral(model)

    def pose(q: np.ndarray) -> np.ndarray:
        for (i, nq), v in zip(slots, q, strict=True):
            if nq == 1:
                q_pin[i] = v
            else:  # continuous joint: (cos, sin)
                q_pin[i], q_pin[i + 1] = np.cos(v), np.sin(v)
        pin.framesForwardKinematics(model, data, q_pin)
        return (data.oMf[base_id].inverse() * data.oMf[tip_id]).homogeneous

    return pose


def pose_errors(pose: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """Position error (m) and geodesic orientation error (rad)."""
    pos = float(np.linalg.norm(pose[:3, 3] - target[:3, 3]))
    return pos, float(spatial.angle_between(pose[:3, :3], target[:3, :3]))


@dataclass
class Row:
    """One solver on one arm."""

    times: list[float] = field(default_factory=list)
    success: list[bool] = field(default_factory=list)
    own: list[bool] = field(default_factory=list)
    overshoot: list[bool] = field(default_factory=list)
    """Failed only by a joint-limit overshoot of at most `OVERSHOOT` (pose within tolerance)."""

    def rate(self) -> float:
        return 100.0 * float(np.mean(self.success)) if self.success else float("nan")

    def mean_ms(self) -> float:
        return 1e3 * float(np.mean(self.times)) if self.times else float("nan")


@dataclass
class ArmRun:
    """Everything measured on one arm."""

    name: str
    n_q: int
    method: str
    fk_gap: float
    optik: Row
    tracik: Row | None
    note: str = ""


def _tracik(m: optik.Mechanism, urdf: Path, base: str, tip: str, limit: float, eps: float):
    """A TRAC-IK solve function ``(q0, target) -> (q, own success)``, or a reason it cannot run."""
    try:
        import pytracik
    except ImportError:
        return 'pytracik not installed (pip install "optik[peers]")'
    from scipy.spatial.transform import Rotation

    solver = pytracik.TRAC_IK(
        base, tip, urdf.read_text(encoding="utf-8"), limit, eps, pytracik.SolveType.Speed
    )
    n = pytracik.get_num_joints(solver)
    if n != m.n_q:
        return f"TRAC-IK sees {n} joints in {base} -> {tip}, optik {m.n_q}"
    # pytracik reads the limits of a joint with a <safety_controller> as [0, 0] (TRAC-IK would use
    # the soft limits): give it the URDF's limits, as optik and pinocchio read them
    lo = np.asarray(pytracik.get_joint_lower_bounds(solver), dtype=float)
    hi = np.asarray(pytracik.get_joint_upper_bounds(solver), dtype=float)
    finite = np.isfinite(m.lower) & np.isfinite(m.upper)
    if np.any(np.abs(np.where(finite, m.lower - lo, 0)) + np.abs(np.where(finite, m.upper - hi, 0)) > 1e-6):
        pytracik.set_joint_limits(solver, np.where(finite, m.lower, lo), np.where(finite, m.upper, hi))

    def solve(q0: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, bool]:
        qx, qy, qz, qw = Rotation.from_matrix(target[:3, :3]).as_quat()
        out = np.asarray(pytracik.ik(solver, q0, *target[:3, 3], qx, qy, qz, qw))
        return (out[1:], True) if out[0] > 0 else (q0, False)

    return solve


def run_arm(
    name: str, n: int, n_fk: int, limit: float, tol: float, seed: int, method: str | None = None
) -> ArmRun:
    """Load one arm, compare its FK with pinocchio's, solve ``n`` FK targets with both solvers."""
    arm = ARMS[name]
    urdf = robot_urdf(name)
    m = robot(name)
    ref = pinocchio_fk(m, urdf, arm.base_link, arm.tip_link)
    gap = max(float(np.max(np.abs(m.fk(q) - ref(q)))) for q in m.random_q(n_fk, seed=seed + 1))
    q0 = m.mid_q()
    targets = [ref(q) for q in m.random_q(n, seed=seed)]
    tracik = _tracik(m, urdf, arm.base_link, arm.tip_link, limit, 0.5 * tol)
    note = tracik if isinstance(tracik, str) else ""
    trac = None if isinstance(tracik, str) else tracik

    methods: set[str] = set()

    def optik_solve(target: np.ndarray) -> tuple[np.ndarray, bool]:
        res = optik.solve_ik(m, target, q0, method=method, time_limit=limit, tol=tol)
        methods.add(res.method)
        return res.q, res.success

    def judged(q: np.ndarray, target: np.ndarray) -> tuple[bool, bool]:
        """(success, failed only by a limit overshoot <= OVERSHOOT)."""
        pos, ori = pose_errors(ref(q), target)
        close = pos <= tol and ori <= tol
        inside = m.within_limits(q)
        return close and inside, close and not inside and m.within_limits(q, OVERSHOOT)

    optik_solve(targets[0])  # warm-up: build, compile, load
    if trac is not None:
        trac(q0, targets[0])
    native.wait()
    rows = (Row(), Row())
    for target in targets:
        for row, solve in ((rows[0], optik_solve), (rows[1], None if trac is None else trac)):
            if solve is None:
                continue
            t0 = time.perf_counter()
            q, own = solve(target) if solve is optik_solve else solve(q0, target)
            row.times.append(time.perf_counter() - t0)
            ok, overshoot = judged(np.asarray(q, dtype=float), target)
            row.success.append(ok)
            row.overshoot.append(overshoot)
            row.own.append(bool(own))
    method = "+".join(sorted(methods))
    return ArmRun(name, m.n_q, method, gap, rows[0], rows[1] if trac is not None else None, note)


HEADER = (
    "| robot | DOF | FK vs pinocchio | optik method | optik success % | optik mean ms "
    "| TRAC-IK success % (own) | TRAC-IK limit overshoots | TRAC-IK mean ms | mean / TRAC-IK mean |\n"
    "|---|--:|--:|---|--:|--:|--:|--:|--:|--:|"
)


def row_text(r: ArmRun) -> str:
    """One markdown table row."""
    if r.tracik is None:
        trac, ratio = f"- ({r.note}) | - | -", "-"
    else:
        own = 100.0 * float(np.mean(r.tracik.own))
        over = int(np.sum(r.tracik.overshoot))
        trac = f"{r.tracik.rate():.1f} ({own:.1f}) | {over} | {r.tracik.mean_ms():.3f}"
        ratio = f"{r.optik.mean_ms() / r.tracik.mean_ms():.2f}"
    optik_cells = f"{r.optik.rate():.1f} | {r.optik.mean_ms():.3f}"
    return f"| {r.name} | {r.n_q} | {r.fk_gap:.1e} | {r.method} | {optik_cells} | {trac} | {ratio} |"


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
        f"{args.time_limit * 1e3:g} ms, tol {args.tol:g}; success by pinocchio's FK and the limits\n"
    )
    print(HEADER)
    runs = []
    for name in names:
        r = run_arm(name, args.n, args.fk, args.time_limit, args.tol, args.seed, args.method)
        runs.append(r)
        print(row_text(r), flush=True)
    both = [r for r in runs if r.tracik is not None]
    if both:
        o = np.concatenate([r.optik.times for r in both])
        t = np.concatenate([r.tracik.times for r in both])
        so = np.mean(np.concatenate([r.optik.success for r in both])) * 100
        st = np.mean(np.concatenate([r.tracik.success for r in both])) * 100
        gap = max(r.fk_gap for r in runs)
        print(
            f"| all {len(both)} arms | | {gap:.1e} | | {so:.1f} | {1e3 * o.mean():.3f} | "
            f"{st:.1f} | {sum(int(np.sum(r.tracik.overshoot)) for r in both)} | {1e3 * t.mean():.3f} | "
            f"{o.mean() / t.mean():.2f} |"
        )
    return 0 if all(r.fk_gap <= 1e-12 for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
