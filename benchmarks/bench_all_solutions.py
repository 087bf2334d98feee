"""Every IK solution of 6-axis arms: optik's derived closed forms against EAIK and ik-geo, pose by pose.

Method (docs/benchmarks.md): per arm, ``--n`` joint vectors drawn uniformly within the limits (seeded),
targets by the mechanism's own FK (``m.fk``); then, target by target in one process (thread pools
pinned to 1 before numpy is imported), interleaved:

* ``optik``: ``optik.solve_ik_all(m, T).q``, the public call and its solutions as one array
  (validation, the derived closed form's compiled driver: every branch, its FK check, the 2 pi
  shift and the joint-limit filter, sorted by distance to the mid-limit start; see
  ``optik.closed_form.ik_all``), the counterpart of EAIK's ``calculate_IK(T).Q``; the
  ``IKResult`` of each solution is made when first read, and that cost is timed apart
  (``list(solutions)``, column "IKResult objects");
* ``optik AllSolutions``: ``ik(T)`` of ``ik = optik.AllSolutions(m)`` (built once per arm,
  untimed), the same solutions as one ``(K, 6)`` array without the options and result object of
  ``solve_ik_all`` (compared with its ``.q``, column "AllSolutions differs"); timed on every other
  pose (below);
* ``EAIK`` (the ``eaik`` package, where installed): its compiled ``Robot.calculate_IK(T X)``
  (without EAIK's Python wrapper), built once per arm by EAIK's own URDF parser (UR arms) or
  DH constructor (PUMA 560), and from optik's joint axes at ``q = 0`` for the seed arm; ``X`` maps
  optik's tool frame to EAIK's (EAIK's FK equals ``m.fk(q) X``, checked on 16 configurations);
* ``ik-geo`` (the ``ik_geo`` package, where installed): its compiled ``Robot.get_ik(R, p)`` for
  the arm's family (``three_parallel_two_intersecting`` for the UR arms and the seed arm,
  ``spherical_two_intersecting`` for the PUMA 560), built from optik's joint axes at ``q = 0``
  with the points of intersecting axes moved to their common point (as ik-geo's formulas assume);
  its end frame is the last joint's, so its target is ``R = R_T R_home^T`` (its bindings read
  the 3x3 array transposed, so the transpose is passed), made outside the timing. Its exact
  solutions count (not the least-squares ones it flags).

Arms: the UR5 and UR10 URDFs of example-robot-data (``*_joint_limited_robot.urdf``, base
``base_link``, tip ``tool0``; skipped with a note when example-robot-data is not installed), the
PUMA 560 of the catalog (spherical wrist, standard DH) and the seed's 6R arm (its derived closed
form; the hand-written one is its cross-check in the tests).

Checks (each recomputed here from the returned ``q``): an EAIK (ik-geo) solution counts when its FK by
``m.fk`` matches the target (position and orientation error <= 1e-6) and it lies within the limits
after the 2 pi shift of ``m.wrap``; it is *found* when an optik solution lies within 1e-4 rad of
it (max-norm, angles modulo 2 pi). Every optik solution must pass the same FK and limit check;
*duplicates* are pairs of optik solutions of one target closer than 1e-4 rad; *extra* are optik
solutions that no valid EAIK solution matches. The checks run on every pose of the timed run.

The solvers take turns: pose ``k`` starts with the ``k``-th of them (cyclically), since the first
call after the previous pose's checks runs with colder caches. One optik call is timed per pose,
``solve_ik_all`` for even ``k`` and ``AllSolutions`` for odd ``k`` (the other one is made after the
timed calls, for the checks): a second call into the same kernel would run with the caches
the first one warmed, which no peer call gets. Before timing, each arm's
single-target kernel is built and compiled to C and each peer solves
one pose (untimed warm-up for every solver). Times: mean / median / p95 per pose of every solver,
the ratio of medians (optik / peer). Then all ``--n`` targets at once, per pose, in
`BATCH_RUNS` interleaved runs: ``optik.solve_ik_all_batch(m, targets)`` (one C call; every row of
its answer is FK- and limit-checked as above and compared with the single calls' answer) against
EAIK's ``calculate_IK`` in a Python loop and EAIK's ``calculate_IK_batched`` on one thread.

Run: ``optik benchmark all_solutions [--n 1000] [--seed 0] [--out report.md]`` (or
``python -m optik.benchmarks.bench_all_solutions``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik import plot  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.benchmarks.peer_arms import (  # noqa: E402
    axis_offsets,
    eaik_dh,
    eaik_robot,
    ik_geo_target,
    ur_arm,
    valid_solutions,
)
from optik.closed_form.derived import chain_axes, derive, derive_axes  # noqa: E402
from optik.harness.tally import timing_ms  # noqa: E402
from optik.mechanism import Mechanism  # noqa: E402
from optik.solvers.base import joint_distance  # noqa: E402

try:  # an optional peer
    import ik_geo
except ImportError:  # pragma: no cover - depends on the environment
    ik_geo = None

BATCH_RUNS = 5
"""Interleaved runs of the whole-batch timings (median per pose reported)."""
SAME = 1e-4
"""Joint distance under which two solutions are the same (the same-branch rule)."""


def _arms() -> tuple[list[Mechanism], list[str]]:
    arms, notes = [], []
    for name in ("ur5", "ur10"):
        m, note = ur_arm(name)
        if m is None:
            notes.append(note)
        else:
            arms.append(m)
    arms += [optik.catalog.puma560(), optik.catalog.seed_6r_arm()]
    return arms, notes


IK_GEO_FAMILY = {
    "three_parallel (5-6 intersecting)": ("three_parallel_two_intersecting", ((4, 5),)),
    "spherical_wrist (1-2 intersecting)": ("spherical_two_intersecting", ((0, 1), (3, 4, 5))),
}
"""optik's family name -> ik-geo's constructor and the groups of joints (0-based) whose axes meet."""


def _common_point(h: np.ndarray, r: np.ndarray, joints: Sequence[int]) -> np.ndarray:
    """The point closest to the lines ``r_i + s h_i`` (least squares; their intersection)."""
    proj = [np.eye(3) - np.outer(h[i], h[i]) for i in joints]
    return np.linalg.solve(sum(proj), sum(p @ r[i] for p, i in zip(proj, joints, strict=True)))


def _ik_geo_robot(m: Mechanism, family: str) -> tuple[object, np.ndarray] | None:
    """ik-geo's robot for the arm's family and the home rotation to strip from targets, or None
    when ik-geo has no constructor for the family."""
    if ik_geo is None or family not in IK_GEO_FAMILY:
        return None
    name, groups = IK_GEO_FAMILY[family]
    ax = chain_axes(m)
    h = ax.h / np.linalg.norm(ax.h, axis=1)[:, None]
    r = np.array(ax.r, dtype=float)
    for joints in groups:
        r[list(joints)] = _common_point(h, r, joints)
    return getattr(ik_geo.Robot, name)(h, axis_offsets(r, ax.home)), ax.home[:3, :3]


@dataclass
class Row:
    """The tallies of one arm."""

    name: str
    family: str
    n: int
    eaik_model: str = "-"
    optik_times: list[float] = field(default_factory=list)
    array_times: list[float] = field(default_factory=list)
    array_differs: int = 0
    results_times: list[float] = field(default_factory=list)
    eaik_times: list[float] = field(default_factory=list)
    eaik_valid: int = 0
    ikgeo_times: list[float] = field(default_factory=list)
    ikgeo_valid: int = 0
    ikgeo_found: int = 0
    found: int = 0
    optik_solutions: int = 0
    optik_failed_check: int = 0
    duplicates: int = 0
    extra: int = 0
    outside_limits: int = 0
    batch_times: list[tuple[float, float]] = field(default_factory=list)  # (wall, CPU) per pose
    eaik_loop_times: list[tuple[float, float]] = field(default_factory=list)
    eaik_batched_times: list[tuple[float, float]] = field(default_factory=list)
    batch_failed_check: int = 0
    batch_differs: int = 0


def _medians(times: list[tuple[float, float]]) -> tuple[float, float]:
    """Median wall and CPU time per pose in us."""
    wall, cpu = np.median(np.asarray(times), axis=0)
    return 1e6 * float(wall), 1e6 * float(cpu)


def _stats(times: list[float]) -> tuple[float, float, float]:
    """``(mean, median, p95)`` in us."""
    mean, median, p95 = timing_ms(times)
    return 1e3 * mean, 1e3 * median, 1e3 * p95


def run_arm(m: Mechanism, n: int, seed: int) -> Row:
    solver = derive(m) or derive_axes(chain_axes(m))
    family = solver.structure.name if solver is not None else "none"
    row = Row(m.name, family, n)
    targets = m.fk(m.random_q(n, seed=seed))
    robot, x, row.eaik_model = eaik_robot(m) if eaik_dh is not None else (None, np.eye(4), "-")
    theirs_targets = targets @ x  # EAIK's tool frame (outside the timing)
    geo = _ik_geo_robot(m, family)
    # ik-geo's targets: the last joint's frame, the rotation transposed for its bindings (untimed)
    geo_targets = [ik_geo_target(t, geo[1]) for t in targets] if geo else []
    optik.solve_ik_all(m, targets[0])  # builds the cached kernel and FK evaluator (untimed)
    ik = optik.AllSolutions(m)  # built once (untimed)
    ik(targets[0])
    if derive(m) is not None:
        derive(m).compile()  # as after its first calls (it compiles itself when hot)
    if robot is not None:
        robot.calculate_IK(theirs_targets[0])  # warm-up, as optik's
    if geo:
        geo[0].get_ik(*geo_targets[0])
    for k, (t, t_eaik) in enumerate(zip(targets, theirs_targets, strict=True)):
        # one optik call per pose (the second would find the caches the first warmed)
        calls = [
            ("optik", lambda t=t: optik.solve_ik_all(m, t)) if k % 2 == 0 else ("array", lambda t=t: ik(t))
        ]
        if robot is not None:
            calls.append(("eaik", lambda t=t_eaik: robot.calculate_IK(t)))
        if geo:
            calls.append(("ikgeo", lambda k=k: geo[0].get_ik(*geo_targets[k])))
        got = _timed_in_turn(calls, k, row)
        sols = got["optik"] if "optik" in got else optik.solve_ik_all(m, t)  # the other one untimed
        array = got["array"] if "array" in got else ik(t)
        assert sols.q.shape[0] == len(sols)  # the solutions as one array, like EAIK.Q
        row.array_differs += not np.array_equal(array, sols.q.reshape(-1, m.n_q))
        t0 = time.perf_counter()
        list(sols)
        row.results_times.append(time.perf_counter() - t0)
        valid = valid_solutions(m, np.asarray(got["eaik"].Q), t) if robot is not None else []
        ours = [s.q for s in sols]
        if geo:
            geo_valid = valid_solutions(
                m, [np.asarray(q, dtype=float) for q, least_squares in got["ikgeo"] if not least_squares], t
            )
            row.ikgeo_valid += len(geo_valid)
            row.ikgeo_found += sum(any(joint_distance(m, v, o) < SAME for o in ours) for v in geo_valid)
        row.optik_solutions += len(ours)
        row.outside_limits += len(sols.outside_limits)
        row.optik_failed_check += len(ours) - len(valid_solutions(m, ours, t))
        pairs = [(a, b) for i, a in enumerate(ours) for b in ours[i + 1 :]]
        row.duplicates += sum(joint_distance(m, a, b) < SAME for a, b in pairs)
        row.eaik_valid += len(valid)
        row.found += sum(any(joint_distance(m, v, o) < SAME for o in ours) for v in valid)
        if robot is not None:
            row.extra += sum(all(joint_distance(m, o, v) >= SAME for v in valid) for o in ours)
    _run_batches(m, row, targets, robot, list(theirs_targets))
    return row


def _timed_in_turn(calls: list[tuple[str, Callable[[], object]]], k: int, row: Row) -> dict[str, object]:
    """Each call timed once, pose ``k`` starting with call ``k mod len(calls)`` (the first call
    after the previous pose's checks runs with colder caches: the turns share that out); the
    answers by name."""
    got: dict[str, object] = {}
    times = {
        "optik": row.optik_times, "array": row.array_times, "eaik": row.eaik_times, "ikgeo": row.ikgeo_times
    }  # fmt: skip
    for name, call in calls[k % len(calls) :] + calls[: k % len(calls)]:
        t0 = time.perf_counter()
        got[name] = call()
        times[name].append(time.perf_counter() - t0)
    return got


def _per_pose(call: Callable[[], Any], n: int, times: list[tuple[float, float]]) -> Any:
    """``call()``, with its wall and process CPU time (all threads) over ``n`` appended to ``times``."""
    wall, cpu = time.perf_counter(), time.process_time()
    out = call()
    times.append(((time.perf_counter() - wall) / n, (time.process_time() - cpu) / n))
    return out


def _run_batches(m: Mechanism, row: Row, targets: np.ndarray, robot: object, theirs: list) -> None:
    """All targets at once, per pose: optik's ``solve_ik_all_batch`` (one C call), EAIK's
    ``calculate_IK`` looped in Python and its ``calculate_IK_batched`` on 1 thread, interleaved
    over `BATCH_RUNS` runs, each timed by the wall clock and by the process CPU time (all threads:
    EAIK's batched call runs in a worker thread); every row of optik's answer is checked (FK and
    limits) and compared with the single calls'."""
    optik.solve_ik_all_batch(m, targets[:10])  # warm-up, as the peers'
    n = len(targets)
    for _ in range(BATCH_RUNS):
        batch = _per_pose(lambda: optik.solve_ik_all_batch(m, targets), n, row.batch_times)
        if robot is not None:
            _per_pose(lambda: [robot.calculate_IK(t) for t in theirs], n, row.eaik_loop_times)
            _per_pose(lambda: robot.calculate_IK_batched(theirs, 1), n, row.eaik_batched_times)
    for i, t in enumerate(targets):  # the last run's answer, every row
        rows = batch[i].q
        row.batch_failed_check += len(rows) - len(valid_solutions(m, rows, t))
        row.batch_differs += not np.array_equal(rows, optik.solve_ik_all(m, t).q)


def report(rows: list[Row], notes: list[str], command: str) -> str:
    lines = [
        f"`{command}` (one process, targets interleaved pose by pose; times per pose in us)",
        "",
        "| arm | family | EAIK built by | poses | EAIK solutions in limits | found by optik "
        "| optik solutions | duplicates "
        "| failed FK/limit check | extra | optik mean / median / p95 | EAIK mean / median / p95 "
        "| ratio of means / medians (optik / EAIK) | optik `AllSolutions` mean / median / p95 "
        "| ratio of means / medians (AllSolutions / EAIK) | AllSolutions differs "
        "| ik-geo solutions in limits | found by optik "
        "| ik-geo mean / median / p95 | ratio of means / medians (optik / ik-geo) "
        "| IKResult objects (mean) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        om, omed, op95 = _stats(r.optik_times)
        am, amed, ap95 = _stats(r.array_times)
        if r.eaik_times:
            em, emed, ep95 = _stats(r.eaik_times)
            peer = f"{em:.1f} / {emed:.1f} / {ep95:.1f}"
            ratio = f"{om / em:.2f} / {omed / emed:.2f}"
            array_ratio = f"{am / em:.2f} / {amed / emed:.2f}"
            found = f"{r.found} ({100.0 * r.found / max(r.eaik_valid, 1):.1f} %)"
        else:
            peer, ratio, array_ratio, found = "EAIK not installed", "-", "-", "-"
        if r.ikgeo_times:
            gm, gmed, gp95 = _stats(r.ikgeo_times)
            geo = (
                f"{r.ikgeo_valid} | {r.ikgeo_found} ({100.0 * r.ikgeo_found / max(r.ikgeo_valid, 1):.1f} %) "
                f"| {gm:.1f} / {gmed:.1f} / {gp95:.1f} | {om / gm:.1f} / {omed / gmed:.1f}"
            )
        else:
            geo = "- | - | ik-geo not installed or no constructor for the family | -"
        lines.append(
            f"| {r.name} | {r.family} | {r.eaik_model} | {r.n} "
            f"| {r.eaik_valid if r.eaik_times else '-'} | {found} "
            f"| {r.optik_solutions} | {r.duplicates} | {r.optik_failed_check} "
            f"| {r.extra if r.eaik_times else '-'} "
            f"| {om:.1f} / {omed:.1f} / {op95:.1f} | {peer} | {ratio} "
            f"| {am:.1f} / {amed:.1f} / {ap95:.1f} | {array_ratio} | {r.array_differs} | {geo} "
            f"| {_stats(r.results_times)[0]:.1f} |"
        )
    lines += [
        "",
        f"All poses in one call (per pose in us, median of {BATCH_RUNS} interleaved runs, wall clock "
        "(process CPU time, all threads); optik's rows each FK- and limit-checked and compared with its "
        "single calls):",
        "",
        "| arm | optik `solve_ik_all_batch` | EAIK `calculate_IK` looped "
        "| EAIK `calculate_IK_batched` (1 thread) "
        "| ratio optik / looped, wall (CPU) | ratio optik / batched, wall (CPU) "
        "| failed FK/limit check | differs from single calls |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        b = _medians(r.batch_times)
        if r.eaik_loop_times:
            loop, batched = _medians(r.eaik_loop_times), _medians(r.eaik_batched_times)
            peer = (
                f"{loop[0]:.2f} ({loop[1]:.2f}) | {batched[0]:.2f} ({batched[1]:.2f}) "
                f"| {b[0] / loop[0]:.2f} ({b[1] / loop[1]:.2f}) "
                f"| {b[0] / batched[0]:.2f} ({b[1] / batched[1]:.2f})"
            )
        else:
            peer = "EAIK not installed | - | - | -"
        checks = f"{r.batch_failed_check} | {r.batch_differs}"
        lines.append(f"| {r.name} | {b[0]:.2f} ({b[1]:.2f}) | {peer} | {checks} |")
    lines += ["", *(f"- {note}" for note in notes)]
    lines.append(
        f"- optik left out {sum(r.outside_limits for r in rows)} solutions outside the joint limits "
        "(reported in `IKSolutions.outside_limits`, not in the counts above)"
    )
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = benchmark_parser("all_solutions", __doc__)
    parser.add_argument("--n", type=int, default=1000, help="random poses per arm (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="seed of joint vectors (default: %(default)s)")
    parser.add_argument("--out", type=Path, help="also write the report (markdown) to this file")
    args = parser.parse_args(argv)
    if args.n < 1:
        parser.error("--n must be >= 1")
    arms, notes = _arms()
    if eaik_dh is None:
        notes.append('EAIK not installed (pip install "optik[peers]"): skipped')
    if ik_geo is None:
        notes.append('ik-geo not installed (pip install "optik[peers]"): skipped')
    rows = []
    for m in arms:
        rows.append(run_arm(m, args.n, args.seed))
        print(f"{m.name}: done", flush=True)
    command = "optik benchmark all_solutions " + " ".join(argv or [])
    text = report(rows, notes, command.strip())
    print(text)
    if args.out is not None:
        plot.write_atomic(args.out, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    ok = all(
        r.found == r.eaik_valid
        and r.ikgeo_found == r.ikgeo_valid
        and r.duplicates == 0
        and r.array_differs == 0
        and r.optik_failed_check == 0
        and r.batch_failed_check == 0
        and r.batch_differs == 0
        for r in rows
    )
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
