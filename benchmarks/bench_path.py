"""Cartesian paths: `optik.plan_path` against brute force over EAIK, nearest stepping, `diffik.track`.

Method: per arm (the UR5 of example-robot-data, joint-limited URDF, and the PUMA 560 of the
catalog) and per workload (a 20 cm straight line, a 90 degree circular arc of radius 5 cm, a
zig-zag weld of 5 teeth of 1 cm along the line; ``--n`` poses each, the tool's orientation
fixed, times uniform, ``--dt`` s apart), in one process, interleaved workload by workload:

* ``optik``: ``optik.plan_path(m, poses, times, velocity=v)``, the whole call (every
  closed-form solution of every pose, the DP in C, the checks);
* ``brute force``: the exact reference computed here, independently of optik's planner: every
  solution of every pose from EAIK's compiled ``calculate_IK`` (the robot of
  ``peer_arms.eaik_robot``: EAIK's URDF parser for the UR5, its DH constructor for the PUMA),
  each FK-checked and shifted into the limits by ``m.wrap`` (``peer_arms.valid_solutions``),
  every ``2 pi`` copy within the limits added, then a plain numpy DP over the full
  ``K x K`` edge matrices of each layer with the same velocity-limit rule (an edge is kept when
  every ``|dq_j| <= v_j dt``);
* ``nearest``: from the first pose's solution nearest the middle of the limits (the first of
  ``solve_ik_all``), each pose's solution (every copy) nearest the current one (plain joint
  distance);
* ``diffik.track``: ``optik.diffik.track(m, q0, poses, dt)`` (QP steps with the joint limits)
  from the same first configuration.

Columns: joint-space length ``sum |q_{k+1} - q_k|`` (unit weights), its gap to the brute-force
optimum, velocity violations (segments with some ``|dq_j| / dt > v_j``), jumps (steps with some
``|dq_j| > 0.3`` rad: a branch change on a dense path), the largest tool error of the samples
(position, m; recomputed by ``m.fk``), limit violations and the wall time of the whole call
(median of ``--repeat`` runs, one run for the brute force and ``diffik.track``; every method
warmed up once before).

Panda (7-DOF): a spin of the tool by 1.6 rad about its axis at a fixed point from
``q7 = 1.5`` (``min(--n, 300)`` poses): ``plan_path`` over 39 self-motion values of ``q7``, with
and without ``smooth``, against ``diffik.track`` from the same start (one run each).

The timing goal of issue 24 (a 1,000-pose line, 8 solutions x 36 tool-axis samples per pose,
<= 50 ms) is measured on the UR5 line with ``free_axis="z"`` and ``axis_step = 10`` degrees:
the whole call, the nodes alone (`optik.path.samples.sample_solutions`: every solution of every
pose, the axis joint's turned copies) and the DP alone on the same graph
(`optik.path.graph.least_motion`), interleaved call by call, each as wall time and as this
process's CPU time (the two differ when other processes share the cores); the rest is the
whole call less the two.

Run: ``optik benchmark path [--n 1000] [--dt 0.01] [--repeat 3] [--out report.md]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import itertools  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik import plot  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.benchmarks.peer_arms import eaik_dh, eaik_robot, ur_arm, valid_solutions  # noqa: E402
from optik.mechanism import Mechanism  # noqa: E402
from optik.path import graph, samples  # noqa: E402
from optik.path.nodes import turn_copies, wrapping  # noqa: E402

JUMP = 0.3
"""A step moving some joint more than this (rad) is a jump."""
START = {
    "ur5": np.array([0.0, -1.3, 1.6, -1.9, -1.57, 0.0]),
    "puma560": np.array([-0.44, 1.29, -1.77, 0.34, -0.13, 0.14]),
}
"""First configuration of each arm's workloads (its FK is the first pose)."""


def workloads(m: Mechanism, n: int) -> dict[str, np.ndarray]:
    """The line, arc and zig-zag poses ``(n, 4, 4)`` from ``m.fk(START)``."""
    t0 = m.fk(START[m.name])
    s = np.linspace(0.0, 1.0, n)
    line = np.repeat(t0[None], n, axis=0)
    line[:, :3, 3] += s[:, None] * np.array([0.0, 0.2, 0.0])
    arc = np.repeat(t0[None], n, axis=0)  # about a vertical axis 5 cm away
    centre = t0[:3, 3] + np.array([0.0, 0.05, 0.0])
    rot = np.asarray(optik.spatial.rot_z(np.radians(90.0) * s))
    arc[:, :3, 3] = centre + (rot @ (t0[:3, 3] - centre))
    zig = line.copy()  # 5 teeth of 1 cm across the line
    zig[:, :3, 3] += (0.01 * (1.0 - 2.0 * np.abs(((5.0 * s) % 1.0) - 0.5)))[:, None] * np.array(
        [0.0, 0.0, 1.0]
    )
    return {"line": line, "arc": arc, "zig-zag": zig}


def velocity_of(m: Mechanism) -> np.ndarray:
    """The model's velocity limits, else pi rad/s per joint."""
    own = m.params.get("velocity_limits")
    return np.asarray(own, dtype=float) if own is not None else np.full(m.n_q, np.pi)


def eaik_layers(m: Mechanism, robot: object, x: np.ndarray, poses: np.ndarray) -> list[np.ndarray]:
    """Every valid EAIK solution of every pose, with every 2 pi copy within the limits."""
    out = []
    angles = np.asarray(m.revolute_mask, dtype=bool)
    for t in poses:
        got = valid_solutions(m, list(np.asarray(robot.calculate_IK(t @ x).Q)), t)
        q = np.array(got).reshape(-1, m.n_q)
        out.append(turn_copies(q, m.lower, m.upper, angles)[0])
    return out


def brute_force_dp(layers: list[np.ndarray], bound: np.ndarray) -> tuple[np.ndarray, float]:
    """The least joint-space length through ``layers`` by a plain DP over full edge matrices."""
    cost = np.zeros(len(layers[0]))
    back = []
    for a, b in itertools.pairwise(layers):
        d = b[None, :, :] - a[:, None, :]
        c = np.linalg.norm(d, axis=2)
        c[(np.abs(d) > bound).any(axis=2)] = np.inf
        total = cost[:, None] + c
        arg = np.argmin(total, axis=0)
        cost = total[arg, np.arange(len(b))]
        back.append(arg)
    idx = [int(np.argmin(cost))]
    for arg in reversed(back):
        idx.append(int(arg[idx[-1]]))
    idx.reverse()
    return np.stack([layer[i] for layer, i in zip(layers, idx, strict=True)]), float(cost.min())


def nearest_stepping(m: Mechanism, poses: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """From ``q0``, each pose's solution (every copy) nearest the current configuration."""
    angles = np.asarray(m.revolute_mask, dtype=bool)
    out = [q0]
    for t in poses[1:]:
        sols = turn_copies(optik.solve_ik_all(m, t).q, m.lower, m.upper, angles)[0]
        if not len(sols):
            break
        out.append(sols[np.argmin(np.linalg.norm(sols - out[-1], axis=1))])
    return np.array(out)


@dataclass
class Row:
    """One method on one workload."""

    arm: str
    workload: str
    method: str
    length: float
    gap: float
    violations: int
    jumps: int
    error: float
    outside: int
    seconds: float
    samples: int


def measure(m: Mechanism, q: np.ndarray, poses: np.ndarray, dt: float, v: np.ndarray) -> tuple:
    """Length, velocity violations, jumps, largest tool position error, limit violations."""
    steps = np.abs(np.diff(q, axis=0))
    tips = optik.fk_batch(m, q)[:, :3, 3]
    err = float(np.linalg.norm(tips - poses[: len(q), :3, 3], axis=1).max())
    outside = int(np.count_nonzero(np.any((q < m.lower) | (q > m.upper), axis=1)))
    length = float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())
    fast = int(np.count_nonzero((steps > v * dt).any(axis=1)))
    return length, fast, int(np.count_nonzero((steps > JUMP).any(axis=1))), err, outside


def timed(fn: Callable[[], object], repeat: int) -> tuple[object, float]:
    """``fn()`` once to warm up, then the median wall time of ``repeat`` calls and the last answer."""
    out, wall, _ = timed_cpu(fn, repeat)
    return out, wall


def timed_cpu(fn: Callable[[], object], repeat: int) -> tuple[object, float, float]:
    """``fn()`` once to warm up, then the last answer of ``repeat`` calls, their median wall time
    and their median CPU time of this process (``time.process_time``: on a shared machine the
    wall time also counts the time other processes held the cores)."""
    out, wall, cpu = interleaved([fn], repeat)
    return out[0], wall[0], cpu[0]


def interleaved(fns: Sequence[Callable[[], object]], repeat: int) -> tuple[list, list[float], list[float]]:
    """Each of ``fns`` once to warm up, then ``repeat`` rounds calling each in turn: per function
    its last answer, its median wall time and its median CPU time (`timed_cpu`)."""
    for fn in fns:
        fn()
    wall: list[list[float]] = [[] for _ in fns]
    cpu: list[list[float]] = [[] for _ in fns]
    out: list[object] = [None] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            t0, c0 = time.perf_counter(), time.process_time()
            out[i] = fn()
            wall[i].append(time.perf_counter() - t0)
            cpu[i].append(time.process_time() - c0)
    return out, [float(np.median(x)) for x in wall], [float(np.median(x)) for x in cpu]


def run_arm(m: Mechanism, n: int, dt: float, repeat: int) -> list[Row]:
    v = velocity_of(m)
    robot, x, _ = eaik_robot(m) if eaik_dh is not None else (None, np.eye(4), "")
    rows = []
    for name, poses in workloads(m, n).items():
        times = np.arange(n) * dt
        path, t_opt = timed(lambda p=poses, t=times: optik.plan_path(m, p, t, velocity=v), repeat)
        if not path.success:
            print(f"{m.name} {name}: optik failed: {path.message}", flush=True)
            continue
        ref_len = np.nan
        found: list[tuple[str, np.ndarray, float]] = [("optik plan_path", path.q, t_opt)]
        if robot is not None:
            (q_ref, ref_len), t_ref = timed(
                lambda p=poses: brute_force_dp(eaik_layers(m, robot, x, p), v * dt), 1
            )
            found.append(("brute-force DP over EAIK", q_ref, t_ref))
        q0 = optik.solve_ik_all(m, poses[0]).q[0]
        q_near, t_near = timed(lambda p=poses, q=q0: nearest_stepping(m, p, q), repeat)
        found.append(("nearest solution", q_near, t_near))
        tr, t_track = timed(lambda p=poses, q=q0: optik.diffik.track(m, q, p[1:], dt), 1)
        found.append(("diffik.track", tr.q, t_track))
        for method, q, sec in found:
            length, viol, jumps, err, outside = measure(m, q, poses, dt, v)
            rows.append(
                Row(m.name, name, method, length, length - ref_len, viol, jumps, err, outside, sec, len(q))
            )
        print(f"{m.name} {name}: done", flush=True)
    return rows


def goal(m: Mechanism, n: int, repeat: int) -> str:
    """The issue's timing goal on the UR5 line, the whole call and its stages (module docstring)."""
    poses = workloads(m, n)["line"]
    shortcut = samples.axis_joint(m, "z", None)
    sampled = lambda: samples.sample_poses(poses, "z", np.pi / 18, None)  # noqa: E731
    layers, _ = samples.sample_solutions(m, sampled(), None, shortcut)
    (path, _, _), wall, cpu = interleaved(
        [
            lambda: optik.plan_path(m, poses, free_axis="z", axis_step=np.pi / 18),
            lambda: samples.sample_solutions(m, sampled(), None, shortcut),
            lambda: graph.least_motion(layers, np.ones(m.n_q), None, wrapping(m)),
        ],
        repeat,
    )
    nodes = np.mean([len(x) for x in layers])
    ms = [f"{1e3 * w:.0f} ms wall / {1e3 * c:.0f} ms CPU" for w, c in zip(wall, cpu, strict=True)]
    w_rest, c_rest = wall[0] - wall[1] - wall[2], cpu[0] - cpu[1] - cpu[2]
    rest = f"{1e3 * w_rest:.0f} ms wall / {1e3 * c_rest:.0f} ms CPU"
    return (
        f"Goal (issue 24): {n} poses x 36 tool-axis samples on the {m.name} line, {nodes:.0f} nodes per "
        f"pose ({path.message}): whole call {ms[0]}; of it, the nodes (sampled poses, every solution "
        f"in one C call, the turned copies) {ms[1]}, the DP {ms[2]}, the rest (timing, checks, branch "
        f"count, tool deviation) {rest} (medians of {repeat}, the three interleaved; goal <= 50 ms)."
    )


PANDA_Q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 1.5])
"""Panda start of the spin workload: q7 = 1.5, 1.4 rad from its upper limit."""


def panda_spin(n: int, dt: float) -> list[str]:
    """The 7-DOF workload: a tool spin of 1.6 rad about its axis at a fixed point, ``n`` poses,
    ``plan_path`` over 39 self-motion values of q7 (with and without ``smooth``) against
    ``diffik.track`` from the same start; rows of a markdown table."""
    m = optik.catalog.panda()
    poses = np.repeat(m.fk(PANDA_Q0)[None], n, axis=0)
    poses[:, :3, :3] = poses[0, :3, :3] @ np.asarray(optik.spatial.rot_z(np.linspace(0.0, 1.6, n)))
    motion = ("q7", np.linspace(-2.85, 2.85, 39))
    out = []
    runs = [
        ("plan_path, 39 q7 samples", lambda: optik.plan_path(m, poses, self_motion=motion).q),
        ("plan_path + smooth", lambda: optik.plan_path(m, poses, self_motion=motion, smooth=True).q),
        ("diffik.track", lambda: optik.diffik.track(m, PANDA_Q0, poses[1:], dt).q),
    ]
    for name, fn in runs:
        t0 = time.perf_counter()
        q = fn()
        sec = time.perf_counter() - t0
        f = optik.fk_batch(m, q)
        pos = np.linalg.norm(f[:, :3, 3] - poses[: len(q), :3, 3], axis=1).max()
        ori = max(optik.spatial.angle_between(a[:3, :3], b[:3, :3]) for a, b in zip(f, poses, strict=False))
        outside = int(np.count_nonzero(np.any((q < m.lower) | (q > m.upper), axis=1)))
        length = float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())
        out.append(
            f"| {name} | {len(q)} | {length:.4f} | {pos:.1e} | {ori:.1e} | {outside} | {1e3 * sec:.0f} |"
        )
    return [
        f"Panda, tool spin of 1.6 rad from q7 = 1.5 ({n} poses):",
        "",
        "| method | samples | joint length (rad) | max position error (m) | max orientation error (rad) "
        "| outside limits | time (ms) |",
        "|---|---|---|---|---|---|---|",
        *out,
    ]


def report(rows: list[Row], notes: list[str], command: str) -> str:
    lines = [
        f"`{command}`",
        "",
        "| arm | path | method | samples | joint length (rad) | gap to optimum | velocity viol. | jumps "
        "| max tool error (m) | outside limits | time (ms) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        gap = "-" if np.isnan(r.gap) else f"{r.gap:+.1e}"
        lines.append(
            f"| {r.arm} | {r.workload} | {r.method} | {r.samples} | {r.length:.6f} | {gap} | {r.violations} "
            f"| {r.jumps} | {r.error:.1e} | {r.outside} | {1e3 * r.seconds:.1f} |"
        )
    return "\n".join([*lines, "", *notes])


def main(argv: Sequence[str] | None = None) -> int:
    parser = benchmark_parser("path", __doc__)
    parser.add_argument("--n", type=int, default=1000, help="poses per path")
    parser.add_argument("--dt", type=float, default=0.01, help="time between poses (s)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per method (median)")
    parser.add_argument("--out", type=Path, help="also write the report (markdown) to this file")
    args = parser.parse_args(argv)
    if args.n < 2 or args.dt <= 0 or args.repeat < 1:
        parser.error("--n must be >= 2, --dt > 0, --repeat >= 1")
    ur5, note = ur_arm("ur5")
    arms = [a for a in (ur5, optik.catalog.puma560()) if a is not None]
    notes = [note] if note else []
    if eaik_dh is None:
        notes.append('EAIK not installed (pip install "optik[peers]"): no brute-force reference')
    rows = [row for m in arms for row in run_arm(m, args.n, args.dt, args.repeat)]
    if ur5 is not None:
        notes.append(goal(ur5, args.n, args.repeat))
    notes += ["", *panda_spin(min(args.n, 300), args.dt)]
    text = report(rows, notes, ("optik benchmark path " + " ".join(argv or [])).strip())
    print(text)
    if args.out is not None:
        plot.write_atomic(args.out, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    best = [r for r in rows if r.method == "optik plan_path"]
    return 0 if all(abs(r.gap) <= 1e-9 or np.isnan(r.gap) for r in best) else 1


if __name__ == "__main__":
    raise SystemExit(main())
