"""General 6R inverse kinematics, all solutions: the eigenvalue solver against two peers.

Method (docs/benchmarks.md): random arms (standard DH rows ``d ~ U(-1, 1)``, ``a ~ U(0.1, 1)``,
``alpha ~ U(-pi, pi)``: no two axes parallel or intersecting), random joint vectors
``q ~ U(-pi, pi)^6`` per arm, targets by the mechanism's own FK (``m.fk``), then, target by
target in the same process (thread pools pinned to 1 before numpy is imported):

* ``optik general_6r``: `optik.closed_form.general_6r.solve_general_6r` on one target
  (validation, elimination, eigenvalues, polishing and the ``m.fk`` check of every solution
  included); the same arm's targets are also solved in one stacked call (time per target shown);
* ``ik-geo gen_six_dof`` (the Python ``ik_geo`` package, IK-Geo's general 6-DOF solver by a
  2-D search over two joint angles), where installed: built once per arm from the same joint
  lines; its answers are approximate, so a solution counts when its FK error is <= 1e-3 and the
  round trip at 1e-2 rad (the number within 1e-6 is printed too);
* ``optik solve_ik_all`` with ``closed_form=False`` (multi-start ``lm`` only, with its default
  ``patience=50``, 1 s time limit; with the closed form it would return this solver's answer) on
  the targets of the first ``--multistart-arms`` arms, after one untimed call per arm that
  builds and compiles its problem.

Reported: round trips (the drawn ``q`` among the returned solutions: 1e-8 rad for optik's
closed form, 1e-4 for the multi-start), the count check of the eigenvalue solver (16 finite
solutions, real + complex = 16) and the distribution of the number of real solutions, the
largest FK error of a returned solution, and per peer the number of solutions (FK by ``m.fk``),
the share of the eigenvalue solver's solutions they found and the solutions they found that the
eigenvalue solver did not (a completeness check of the latter).
Times: mean / median / p95 per target and the ratio of means to ``optik general_6r``.

Then, on ``--special`` random arms per case, the same round trips on special geometries that no
decomposable family covers (one or two pairs of consecutive axes intersecting or parallel):
the share of arms that `covers` accepts, and of targets that pass the count check and the round
trip.

``--search-16`` instead searches random arms and poses (then local perturbations of the best)
for a pose with 16 real solutions and prints it: the reference instance of
``tests/test_general_6r.py`` was found this way (``--seed 7``: 1-2 minutes), then rounded to two
decimals and re-checked.

Run: ``optik benchmark general_6r [--arms 200] [--poses 5] [--multistart-arms 20]
[--seed 0] [--plot docs/measured/general_6r_counts.png]`` (or
``python -m optik.benchmarks.bench_general_6r``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402
from collections import Counter  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.closed_form.general_6r import General6R, covers, solve_general_6r  # noqa: E402
from optik.closed_form.structure import axes_of  # noqa: E402
from optik.harness.tally import timing_ms  # noqa: E402
from optik.mechanism import Mechanism, dh_chain  # noqa: E402
from optik.spatial import angle_distance  # noqa: E402

try:  # an optional peer
    import ik_geo
except ImportError:  # pragma: no cover - depends on the environment
    ik_geo = None


def _random_arm(rng: np.random.Generator) -> Mechanism:
    rows = [(rng.uniform(-1, 1), rng.uniform(0.1, 1), rng.uniform(-np.pi, np.pi)) for _ in range(6)]
    return dh_chain(rows, "standard")


@dataclass
class Tally:
    """Per-solver counters over the targets it ran on."""

    times: list[float] = field(default_factory=list)
    round_trips: int = 0
    solutions: int = 0
    found_of_ours: int = 0
    ours: int = 0
    extra: int = 0

    def add(self, dt: float, qs: Sequence[np.ndarray], q: np.ndarray, ours: np.ndarray, tol: float) -> None:
        self.times.append(dt)
        self.round_trips += any(angle_distance(s, q) < tol for s in qs)
        self.solutions += len(qs)
        self.ours += len(ours)
        self.found_of_ours += sum(any(angle_distance(s, o) < 1e-4 for s in qs) for o in ours)
        self.extra += sum(all(angle_distance(s, o) >= 1e-4 for o in ours) for s in qs)


def _ik_geo_robot(m: Mechanism) -> tuple[object, np.ndarray]:
    """ik-geo's general 6-DOF robot from the joint lines at q = 0 (axes h, offsets p)."""
    axes = axes_of(m)
    pts = axes.r
    p = np.vstack([pts[0], np.diff(pts, axis=0), axes.home[:3, 3] - pts[5]])
    return ik_geo.Robot.gen_six_dof(axes.h, p), axes.home[:3, :3]


def _verified(m: Mechanism, qs: Sequence[Sequence[float]], target: np.ndarray) -> list[np.ndarray]:
    """The candidates whose FK (by ``m.fk``) matches the target to 1e-6."""
    out = []
    for q in qs:
        t = m.fk(np.asarray(q, dtype=float))
        if (
            np.linalg.norm(t[:3, 3] - target[:3, 3]) <= 1e-6
            and np.abs(t[:3, :3] - target[:3, :3]).max() <= 1e-6
        ):
            out.append(np.asarray(q, dtype=float))
    return out


def run(arms: int, poses: int, multistart_arms: int, seed: int, plot: str | None) -> int:
    rng = np.random.default_rng(seed)
    tallies = {"optik general_6r": Tally(), "optik general_6r (stacked)": Tally()}
    if ik_geo is not None:
        tallies["ik-geo gen_six_dof"] = Tally()
    if multistart_arms:
        tallies["optik solve_ik_all (lm)"] = Tally()
    counts: Counter[int] = Counter()
    count_ok, max_err, flagged, geo_tight = 0, 0.0, [], 0
    for k in range(arms):
        m = _random_arm(rng)
        qs = rng.uniform(-np.pi, np.pi, (poses, 6))
        targets = m.fk(qs)
        solve_general_6r(m, targets[0])  # untimed: derives the DH description, caches the arm
        start = time.perf_counter()
        stacked = solve_general_6r(m, targets)
        per = (time.perf_counter() - start) / poses
        robot = _ik_geo_robot(m) if ik_geo is not None else None
        multistart = k < multistart_arms
        if multistart:
            optik.solve_ik_all(m, targets[0], time_limit=1.0, closed_form=False)  # untimed: builds lm
        for q, target, batch in zip(qs, targets, stacked, strict=True):
            start = time.perf_counter()
            sols = solve_general_6r(m, target)
            dt = time.perf_counter() - start
            ours = sols.q
            tallies["optik general_6r"].add(dt, list(ours), q, ours, 1e-8)
            tallies["optik general_6r (stacked)"].add(per, list(batch.q), q, ours, 1e-8)
            counts[len(ours)] += 1
            count_ok += sols.count_ok
            max_err = max(max_err, sols.fk_error)
            if not sols.count_ok:
                flagged.append(f"arm {k}: {sols.reason}")
            if robot is not None:
                rob, ee_rot = robot
                r06 = target[:3, :3] @ ee_rot.T
                start = time.perf_counter()
                raw = rob.get_ik(r06.T, target[:3, 3])  # the binding reads R transposed (its FK agrees)
                dt = time.perf_counter() - start
                tallies["ik-geo gen_six_dof"].add(
                    dt, _verified(m, [s for s, _ in raw], target), q, ours, 1e-4
                )
            if multistart:
                start = time.perf_counter()
                res = optik.solve_ik_all(m, target, time_limit=1.0, closed_form=False)
                dt = time.perf_counter() - start
                found = [r.q for r in res if r.success]
                tallies["optik solve_ik_all (lm)"].add(dt, found, q, ours, 1e-4)
    n = arms * poses
    base = float(np.mean(tallies["optik general_6r"].times))
    print(f"\n## General 6R: {arms} random arms x {poses} poses ({n} targets), seed {seed}\n")
    print(
        "| solver | targets | round trip % | solutions / target | share of general_6r's found | extra |"
        " mean ms | median ms | p95 ms | mean / general_6r |"
    )
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
    for name, t in tallies.items():
        mean, median, p95 = timing_ms(t.times)
        share = 100.0 * t.found_of_ours / max(t.ours, 1)
        print(
            f"| {name} | {len(t.times)} | {100.0 * t.round_trips / len(t.times):.1f} | "
            f"{t.solutions / len(t.times):.2f} | {share:.1f} % | {t.extra} | {mean:.3f} | "
            f"{median:.3f} | {p95:.3f} | {mean / 1e3 / base:.2f} |"
        )
    print(
        f"\nCount check passed on {count_ok} of {n} targets; largest FK error of a returned solution "
        f"{max_err:.1e}."
    )
    print("\n| real solutions | " + " | ".join(str(c) for c in range(0, 17, 2)) + " | odd |")
    print("|---|" + "--:|" * 10)
    odd = sum(v for c, v in counts.items() if c % 2)
    print("| targets | " + " | ".join(str(counts.get(c, 0)) for c in range(0, 17, 2)) + f" | {odd} |")
    if ik_geo is not None:
        print(f"\nik-geo solutions with FK error <= 1e-6: {geo_tight} (the table counts <= 1e-3).")
    for line in flagged[:10]:
        print(f"- flagged: {line}")
    if plot:
        _plot(counts, n, plot)
    return 0


def _plot(counts: Counter[int], n: int, path: str) -> None:
    from matplotlib.figure import Figure

    from optik.plot import save_figure

    fig = Figure(figsize=(6.0, 3.2), layout="constrained")
    ax = fig.add_subplot()
    xs = list(range(0, 17, 2))
    ax.bar(xs, [counts.get(c, 0) for c in xs], width=1.4, color="tab:blue")
    ax.set_xticks(xs)
    ax.set_xlabel("real IK solutions of the target (of 16 complex)")
    ax.set_ylabel("targets")
    ax.set_title(f"General 6R: real solutions over {n} random arm/pose pairs")
    print(f"figure: {save_figure(fig, path)}")


SPECIAL = {
    "axes 1-2 intersect (a1 = 0)": {"a": [0]},
    "axes 1-2 parallel (alpha1 = 0)": {"alpha": [0]},
    "axes 5-6 intersect (a5 = 0)": {"a": [4]},
    "axes 2-3 intersect, 4-5 parallel": {"a": [1], "alpha": [3]},
    "axes 1-2 and 5-6 intersect": {"a": [0, 4]},
    "axes 1-2 intersect, 5-6 parallel": {"a": [0], "alpha": [4]},
    "axes 1, 2, 3 parallel": {"alpha": [0, 1]},
    "axes 4, 5, 6 parallel": {"alpha": [3, 4]},
}
"""Special geometries (none a decomposable family): DH entries set to zero in random arms."""


def special(arms: int, poses: int, seed: int) -> None:
    """Count check and round trips on random arms with one or two special axis pairs."""
    rng = np.random.default_rng(seed)
    print(f"\n## Special geometry: {arms} random arms x {poses} poses per case\n")
    print("| geometry | covers(arm) % | count check passed % | round trip % | real solutions / target |")
    print("|---|--:|--:|--:|--:|")
    for label, zero in SPECIAL.items():
        ok = trips = found = covered = 0
        for _ in range(arms):
            a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
            a[zero.get("a", [])] = 0.0
            alpha[zero.get("alpha", [])] = 0.0
            arm = General6R(a=a, alpha=alpha, d=d)
            covered += covers(arm)
            qs = rng.uniform(-np.pi, np.pi, (poses, 6))
            for q, sols in zip(qs, solve_general_6r(arm, arm.fk(qs)), strict=True):
                ok += sols.count_ok
                trips += any(angle_distance(s, q) < 1e-8 for s in sols.q)
                found += len(sols.q)
        n = arms * poses
        print(
            f"| {label} | {100.0 * covered / arms:.0f} | {100.0 * ok / n:.1f} | "
            f"{100.0 * trips / n:.1f} | {found / n:.2f} |"
        )


def search_16(seed: int, budget: float) -> int:
    """Random search, then local perturbations of the best, for a pose with 16 real solutions."""
    rng = np.random.default_rng(seed)
    best: tuple[int, np.ndarray, np.ndarray] = (0, np.zeros(18), np.zeros(6))
    start = time.perf_counter()
    while time.perf_counter() - start < budget and best[0] < 16:
        if best[0] < 10 or rng.uniform() < 0.3:
            x = np.concatenate(
                [rng.uniform(0.1, 1.5, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)]
            )
            qs = rng.uniform(-np.pi, np.pi, (40, 6))
        else:
            x = best[1] + rng.normal(0.0, 0.05, 18)
            qs = best[2] + rng.normal(0.0, 0.1, (40, 6))
        arm = General6R(a=x[:6], alpha=x[6:12], d=x[12:])
        found = [len(s.q) if s.count_ok else 0 for s in solve_general_6r(arm, arm.fk(qs))]
        i = int(np.argmax(found))
        if found[i] > best[0] or (found[i] == best[0] and rng.uniform() < 0.3 and best[0] >= 10):
            best = (found[i], x, qs[i])
    count, x, q = best
    print(f"best: {count} real solutions after {time.perf_counter() - start:.1f} s")
    print(
        "DH rows (d, a, alpha):", [tuple(np.round((x[12 + i], x[i], x[6 + i]), 4).tolist()) for i in range(6)]
    )
    print("q:", np.round(q, 4).tolist())
    return 0 if count == 16 else 1


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark (or the 16-real-solution search) and print markdown tables."""
    ap = benchmark_parser("general_6r", __doc__)
    ap.add_argument("--arms", type=int, default=200, help="random arms")
    ap.add_argument("--poses", type=int, default=5, help="random poses per arm")
    ap.add_argument("--multistart-arms", type=int, default=20, help="arms also solved by solve_ik_all")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--plot", default=None, help="write the histogram of real-solution counts here")
    ap.add_argument("--special", type=int, default=20, help="arms per special geometry (0: skip)")
    ap.add_argument("--search-16", action="store_true", help="search for a pose with 16 real solutions")
    ap.add_argument("--budget", type=float, default=300.0, help="time budget of --search-16 (s)")
    args = ap.parse_args(argv)
    if args.arms < 1 or args.poses < 1 or args.multistart_arms < 0:
        ap.error("--arms and --poses must be >= 1, --multistart-arms >= 0")
    if args.search_16:
        return search_16(args.seed, args.budget)
    code = run(args.arms, args.poses, min(args.multistart_arms, args.arms), args.seed, args.plot)
    if args.special > 0:
        special(args.special, args.poses, args.seed)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
