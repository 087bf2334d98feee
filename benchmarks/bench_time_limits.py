"""Time limits kept: how far past its ``time_limit`` each solver returns (median and max overrun).

For each solver and limit, ``--calls`` calls on targets that cannot be reached (so that every
call runs until its limit, the worst case for the promise), timed from outside with
``time.perf_counter`` around the public call: the overrun is that wall time minus the limit.
Each solver is warmed up first (its problem built and its C code compiled and loaded: setup is
excluded from time limits and reported apart), so the table measures the steady state. Cases:

* ``lm`` and ``nlp`` (IPOPT): ``solve_ik`` on the Panda, pose targets 2 m out of reach;
* ``nlp`` collision (IPOPT with the sphere and capsule constraints): ``solve_ik`` on the dual
  Panda, both hands 2 m out of reach, ``self_collision=True`` (one IPOPT iteration of its 15
  joints and 376 self rows takes milliseconds; skipped without the Panda meshes of
  example-robot-data), and on the Panda in the cluttered scene of ``optik benchmark collision``
  (8 boxes, its self pairs too), the pose 2 m out of reach;
* ``solve_ik_all`` general 6R: the certified solver on a 6R arm with no decomposable closed
  form (`optik.dh_chain`), a pose out of reach (it has no iteration to cut short: the overrun
  is its whole run past the limit);
* ``solve_ik_all`` multi-start: the Panda (7 joints: the numerical search for all branches).

Run: ``optik benchmark time_limits [--calls 1000]`` (about a minute at 1,000 calls). Prints a
markdown table: solver, limit, calls, median / p95 / max overrun (ms), and the largest overrun
as a multiple of the limit.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

import optik
from optik import native
from optik.benchmarks import benchmark_parser

GENERAL_6R = [
    (0.3, 0.2, 1.1),
    (0.1, 0.5, -0.7),
    (0.2, 0.4, 0.9),
    (0.15, 0.3, 1.3),
    (0.1, 0.2, -1.2),
    (0.05, 0.3, 0.8),
]
"""DH rows ``(a, d, alpha)`` of the general 6R arm (issue 18's reproducer, without its 7th joint)."""


def _far(m: optik.Mechanism, seed: int, frame: str | None = None) -> np.ndarray:
    """A pose of ``frame`` (None: the end effector) 2 m beyond the reach of ``m`` (a reachable
    pose moved out along x)."""
    t = m.fk(m.random_q(seed=seed), frame)
    t[0, 3] += 2.0
    return t


def _collision_case() -> dict[str, tuple[Callable[[float, int], object], tuple[float, ...]]]:
    """The collision-aware ``nlp`` case on the dual Panda (none without its meshes)."""
    duo = optik.catalog.dual_panda()
    if len(optik.collision.robot_geometry(duo).links) <= 4:  # no meshes: no collision geometry
        return {}
    hands = ("left_tool", "right_tool")
    far = [{f: _far(duo, s, f) for f in hands} for s in range(16)]

    def call(lim: float, i: int) -> object:
        return optik.solve_ik(
            duo, far[i % 16], method="nlp", self_collision=True, margin=0.01, time_limit=lim, seed=i
        )

    cases = {"nlp collision (dual Panda)": (call, (1e-2, 5e-2))}
    return {**cases, **_clutter_case()}


def _clutter_case() -> dict[str, tuple[Callable[[float, int], object], tuple[float, ...]]]:
    """The collision-aware ``nlp`` case of the Panda in the cluttered scene of ``optik benchmark
    collision`` (its SRDF, self-collision too; none without example-robot-data or coal)."""
    from optik.benchmarks.bench_collision import scene
    from optik.catalog.robots import robots_dir

    try:
        d = robots_dir() / "panda_description"
        m = optik.Mechanism.from_urdf(
            d / "urdf" / "panda.urdf", "panda_link0", "panda_hand_tcp", srdf=d / "srdf" / "panda.srdf"
        )
    except optik.OptikError:
        return {}
    if len(optik.collision.robot_geometry(m).links) <= 1:
        return {}
    w = scene()
    far = [_far(m, s) for s in range(16)]

    def call(lim: float, i: int) -> object:
        return optik.solve_ik(
            m, far[i % 16], method="nlp", world=w, self_collision=True, margin=0.01, time_limit=lim, seed=i
        )

    return {"nlp collision (Panda clutter)": (call, (1e-2, 5e-2))}


def cases() -> dict[str, tuple[Callable[[float, int], object], tuple[float, ...]]]:
    """``{solver: (call(limit, i), limits)}``."""
    panda = optik.catalog.panda()
    arm = optik.dh_chain(GENERAL_6R)
    far_panda = [_far(panda, s) for s in range(16)]
    far_arm = [_far(arm, s) for s in range(16)]
    return {
        "lm": (
            lambda lim, i: optik.solve_ik(panda, far_panda[i % 16], method="lm", time_limit=lim, seed=i),
            (1e-3, 1e-2),
        ),
        "nlp (ipopt)": (
            lambda lim, i: optik.solve_ik(panda, far_panda[i % 16], method="nlp", time_limit=lim, seed=i),
            (1e-3, 1e-2),
        ),
        "solve_ik_all general 6R": (
            lambda lim, i: optik.solve_ik_all(arm, far_arm[i % 16], time_limit=lim),
            (1e-4, 1e-2),
        ),
        "solve_ik_all multi-start": (
            lambda lim, i: optik.solve_ik_all(panda, far_panda[i % 16], time_limit=lim, seed=i),
            (1e-2,),
        ),
        **_collision_case(),
    }


def measure(call: Callable[[float, int], object], limit: float, calls: int) -> np.ndarray:
    """Overruns (s) of ``calls`` calls: wall time minus ``limit`` (negative: returned early)."""
    call(limit, 0)
    native.wait()
    call(limit, 0)  # warm: compiled code loaded, problems built
    out = np.empty(calls)
    for i in range(calls):
        start = time.perf_counter()
        call(limit, i)
        out[i] = time.perf_counter() - start - limit
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Measure and print the table."""
    ap = benchmark_parser("time_limits", __doc__)
    ap.add_argument("--calls", type=int, default=1000, help="calls per solver and limit")
    ap.add_argument("--only", default=None, help="run only the solvers whose name contains this")
    args = ap.parse_args(argv)
    if args.calls < 1:
        ap.error("--calls must be >= 1")
    print("| solver | time_limit (ms) | calls | median overrun (ms) | p95 (ms) | max (ms) | max / limit |")
    print("|---|---|---|---|---|---|---|")
    for name, (call, limits) in cases().items():
        if args.only and args.only not in name:
            continue
        for limit in limits:
            over = measure(call, limit, args.calls) * 1e3
            med, p95, top = np.median(over), np.percentile(over, 95), over.max()
            ratio = (top + limit * 1e3) / (limit * 1e3)
            cells = [name, f"{limit * 1e3:g}", str(args.calls), f"{med:.2f}", f"{p95:.2f}", f"{top:.2f}"]
            print("| " + " | ".join([*cells, f"{ratio:.1f}x"]) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
