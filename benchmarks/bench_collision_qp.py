"""QP differential IK past an obstacle: the Panda's hand follows a straight line that grazes a ball,
with and without the velocity dampers of ``optik.diffik.collision``, in the same run.

Method: the Panda of example-robot-data (``panda_link0`` to ``panda_hand_tcp``, its SRDF) starts
at ``q0``; the path moves the tool point ``--length`` m along y at a fixed orientation in
``--steps`` samples; a ball of radius ``--radius`` sits at its middle, its surface ``--offset``
m beside the line (along x), so that the hand meets it without dampers. Both runs call
``optik.diffik.track`` (method ``qp``, the default backend); the dampers run with
``world=W, margin=--margin`` (influence 5 cm, gain 0.5). Reported per run: the smallest exact
distance along the path (``optik.collision.check`` at every configuration, robot against the
world and itself), steps below the margin, the largest position error, and the step time
(mean / median / p95 over ``--repeats`` alternating repetitions of both runs) with the ratio to
the run without dampers. The step time of the dampers
includes the exact coal query of every step.

Run: ``optik benchmark collision_qp [--steps 200] [--margin 0.01]``. Pink with its collision
barrier is not compared yet.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

import optik
from optik import spatial
from optik.benchmarks import benchmark_parser
from optik.harness.tally import timing_ms


def main(argv: Sequence[str] | None = None) -> int:
    """Run both tracks and print a markdown table; returns 0."""
    ap = benchmark_parser("collision_qp", __doc__)
    ap.add_argument("--steps", type=int, default=200, help="path samples (one QP step each)")
    ap.add_argument("--length", type=float, default=0.5, help="path length (m)")
    ap.add_argument("--radius", type=float, default=0.05, help="ball radius (m)")
    ap.add_argument("--offset", type=float, default=0.0, help="ball surface beside the line, along x (m)")
    ap.add_argument("--margin", type=float, default=0.01, help="clearance kept by the dampers (m)")
    ap.add_argument("--dt", type=float, default=0.01, help="control period (s)")
    ap.add_argument("--repeats", type=int, default=3, help="alternating repetitions of both runs (timing)")
    args = ap.parse_args(argv)
    if args.steps < 2 or not args.length > 0 or not args.radius > 0 or args.margin < 0:
        ap.error("--steps >= 2, --length and --radius > 0, --margin >= 0")
    try:
        from optik.catalog.robots import robots_dir

        d = robots_dir() / "panda_description"
        urdf, srdf = d / "urdf" / "panda.urdf", d / "srdf" / "panda.srdf"
        m = optik.Mechanism.from_urdf(urdf, "panda_link0", "panda_hand_tcp", srdf=srdf)
        optik.collision.robot_geometry(m)
    except (ImportError, optik.OptikError) as exc:
        print(f"needs coal and example-robot-data (extras 'collision', 'robots'): {exc}")
        return 0
    q0 = np.array([0.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785])
    start = m.fk(q0)
    start[:3, 3] += (0.0, -args.length / 2, 0.0)
    res = optik.solve_ik(m, start, q0=q0)
    if not res.success:
        print(f"the start pose is not reachable: {res.message}")
        return 0
    path = np.repeat(start[None], args.steps, axis=0)
    path[:, 1, 3] += np.linspace(0.0, args.length, args.steps)
    world = optik.World()
    middle = path[args.steps // 2, :3, 3] + (args.offset + args.radius, 0.0, 0.0)
    world.add_sphere("ball", args.radius, spatial.translation(*middle))
    runs = {
        "qp": {},
        "qp + dampers": {"world": world, "margin": args.margin},
    }
    times: dict[str, list[float]] = {name: [] for name in runs}
    tracks = {}
    for kw in runs.values():
        optik.diffik.track(m, res.q, path[:5], args.dt, **kw)  # warm-up (code generation)
    for _ in range(max(1, args.repeats)):  # the runs alternate, so that both see the same machine load
        for name, kw in runs.items():
            tracks[name] = optik.diffik.track(m, res.q, path, args.dt, **kw)
            times[name] += list(tracks[name].solve_time)
    rows = []
    base_mean = None
    for name, out in tracks.items():
        dist = np.array([optik.collision.check(m, q, world).min_distance for q in out.q])
        mean, median, p95 = timing_ms(times[name])
        base_mean = mean if base_mean is None else base_mean
        rows.append(
            f"| {name} | {dist.min() * 1e3:.1f} | {int((dist < args.margin - 1e-9).sum())} | "
            f"{out.position_error.max() * 1e3:.2f} | {mean:.3f} | {median:.3f} | {p95:.3f} | "
            f"{mean / base_mean:.2f} |"
        )
    print(
        f"Panda hand along {args.length:g} m past a ball of radius {args.radius:g} m "
        f"(its surface {args.offset:g} m beside the line), {args.steps} steps, dt {args.dt:g} s, "
        f"margin {args.margin:g} m"
    )
    print(
        "| run | min distance mm | steps below margin | max position error mm "
        "| mean ms | median ms | p95 ms | mean / qp |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
