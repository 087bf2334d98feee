"""General 6R inverse kinematics, all solutions: the eigenvalue solver against two peers.

Method (docs/benchmarks.md): random arms (standard DH rows ``d ~ U(-1, 1)``, ``a ~ U(0.1, 1)``,
``alpha ~ U(-pi, pi)``: no two axes parallel or intersecting), random joint vectors
``q ~ U(-pi, pi)^6`` per arm, targets by the mechanism's own FK (``m.fk``), then, target by
target in the same process (thread pools pinned to 1 before numpy is imported):

* ``optik general_6r``: `optik.closed_form.general_6r.solve_general_6r` on one target
  (validation, elimination, eigenvalues, polishing and the ``m.fk`` check of every solution
  included); the same arm's targets are also solved in one stacked call (time per target shown);
* ``ik-geo gen_six_dof`` (the Python ``ik_geo`` package, IK-Geo's general 6-DOF solver), where
  installed: built once per arm from the same joint lines (`ik_geo_robot`; its own FK equals
  ``m.fk`` to rounding, checked in ``tests/test_ik_geo_peer.py``). Its search is approximate by
  design: a 100 x 100 grid over ``(q1, q2)`` keeps the cells whose wrist-alignment error is below
  0.1, then Nelder-Mead refines one minimum per blob to a simplex spread of 1e-6 and ``q6`` comes
  from subproblem 1 (flagged least-squares). So under the project's 1e-6 rule it finds nothing;
  a solution of it counts when its FK error (position, and largest entry of the rotation
  difference) is <= 1e-3, its round trip and match with our solutions at 1e-2 rad, and the
  distribution of its FK errors and the number within 1e-6 are printed below the table;
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
Times: mean / median / p95 per target and the ratio of means to ``optik general_6r``. Each
arm's first call (which derives its DH description and builds the FK check on the mechanism's
own FK: a real cost of a user's first target of an arm) is timed as its own row, ``optik
general_6r (first call of an arm)``, one sample per arm; ``optik general_6r`` is each target
once after it. A second table times the steady state: each arm's targets ``--repeats`` more
times, round by round, optik's call and ik-geo's alternating target by target (`Steady`).

Then, on ``--special`` random arms per case, the same round trips on special geometries that no
decomposable family covers (one or two pairs of consecutive axes intersecting or parallel):
the share of arms that `covers` accepts, and of targets that pass the count check and the round
trip.

``--search-16`` instead searches random arms and poses (then local perturbations of the best)
for a pose with 16 real solutions and prints it: the reference instance of
``tests/test_general_6r.py`` was found this way (``--seed 7``: 1-2 minutes), then rounded to two
decimals and re-checked.

Run: ``optik benchmark general_6r [--arms 200] [--poses 5] [--multistart-arms 20]
[--seed 0] [--repeats 5] [--plot docs/measured/general_6r_counts.png]`` (or
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
from optik.benchmarks.peer_arms import axis_offsets, ik_geo_target  # noqa: E402
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

    def add(
        self,
        dt: float,
        qs: Sequence[np.ndarray],
        q: np.ndarray,
        ours: np.ndarray,
        tol: float,
        same: float = 1e-4,
    ) -> None:
        """One target: round trip when a solution is within ``tol`` of the drawn ``q``; a solution
        and one of ``ours`` are the same branch within ``same`` (rad)."""
        self.times.append(dt)
        self.round_trips += any(angle_distance(s, q) < tol for s in qs)
        self.solutions += len(qs)
        self.ours += len(ours)
        self.found_of_ours += sum(any(angle_distance(s, o) < same for s in qs) for o in ours)
        self.extra += sum(all(angle_distance(s, o) >= same for o in ours) for s in qs)


GEO_FK_TOL = 1e-3
"""FK error up to which an ik-geo ``gen_six_dof`` answer counts (its search is approximate)."""
GEO_SAME = 1e-2
"""Joint distance (rad) at which an ik-geo answer is the same branch as one of ours."""


def ik_geo_robot(m: Mechanism) -> tuple[object, np.ndarray]:
    """ik-geo's general 6-DOF robot of a 6R chain, and the rotation to strip from its targets.

    ik-geo's model (``Kinematics::forward_kinematics``): unit axes ``h_i`` and offsets ``p_i``
    in the base frame at ``q = 0``, ``p_0`` from the base to a point of axis 1, ``p_i`` from
    axis ``i`` to axis ``i + 1`` and ``p_6`` from axis 6 to the tool, and
    ``R_06 = prod_i rot(h_i, q_i)``, ``p_0T = p_0 + sum_i R_0i p_i`` (``R_0i`` the product up
    to joint ``i``). Its end rotation is the identity at ``q = 0``, so optik's tool pose ``T``
    is its ``(R_T R_home^T, p_T)`` with ``R_home`` the tool rotation at ``q = 0``; angles and
    their signs are optik's (same axes, same zero).

    Args:
        m: a serial 6R mechanism.

    Returns:
        The ``ik_geo.Robot`` and ``R_home``.
    """
    axes = axes_of(m)
    return ik_geo.Robot.gen_six_dof(axes.h, axis_offsets(axes.r, axes.home)), axes.home[:3, :3]


def fk_errors(m: Mechanism, qs: Sequence[Sequence[float]], target: np.ndarray) -> np.ndarray:
    """Per candidate, by ``m.fk``: the larger of the position error and the largest entry of
    ``|R(q) - R_T|`` (the quantity the success rule bounds by 1e-6)."""
    out = []
    for q in qs:
        t = m.fk(np.asarray(q, dtype=float))
        out.append(max(np.linalg.norm(t[:3, 3] - target[:3, 3]), np.abs(t[:3, :3] - target[:3, :3]).max()))
    return np.asarray(out, dtype=float)


class Steady:
    """The steady state of the single-target call: after an arm's targets were solved once, each
    target ``repeats`` more times, round by round over the arm's targets, each optik call followed
    by ik-geo's on the same target (when installed), so both see the same machine state; the
    samples of all arms pooled. Resolves the per-call cost, which a cold single call per target
    (the main table's ``optik general_6r`` row) blurs by cache and branch-predictor state."""

    def __init__(self, repeats: int) -> None:
        self.repeats = repeats
        self.times: dict[str, list[float]] = {"optik general_6r": [], "ik-geo gen_six_dof": []}

    def run(self, m: Mechanism, targets: np.ndarray, robot: tuple[object, np.ndarray] | None) -> None:
        """The repeats on one arm's ``targets`` (``robot``: ik-geo's, or None)."""
        args = [ik_geo_target(t, robot[1]) for t in targets] if robot is not None else []
        for _ in range(self.repeats):
            for k, target in enumerate(targets):
                start = time.perf_counter()
                solve_general_6r(m, target)
                self.times["optik general_6r"].append(time.perf_counter() - start)
                if robot is not None:
                    start = time.perf_counter()
                    robot[0].get_ik(*args[k])
                    self.times["ik-geo gen_six_dof"].append(time.perf_counter() - start)

    def table(self, n: int) -> None:
        """Print the steady-state table (``n`` targets)."""
        if not self.repeats:
            return
        base = float(np.mean(self.times["optik general_6r"]))
        print(f"\n## Steady state: {n} targets x {self.repeats} repeats, interleaved target by target\n")
        print("| solver | calls | mean ms | median ms | p95 ms | mean / general_6r |")
        print("|---|--:|--:|--:|--:|--:|")
        for name, t in self.times.items():
            if t:
                mean, median, p95 = timing_ms(t)
                print(
                    f"| {name} | {len(t)} | {mean:.3f} | {median:.3f} | {p95:.3f} | {mean / 1e3 / base:.2f} |"
                )


def run(arms: int, poses: int, multistart_arms: int, seed: int, plot: str | None, repeats: int) -> int:
    rng = np.random.default_rng(seed)
    tallies = {
        "optik general_6r": Tally(),
        "optik general_6r (stacked)": Tally(),
        "optik general_6r (first call of an arm)": Tally(),
    }
    if ik_geo is not None:
        tallies["ik-geo gen_six_dof"] = Tally()
    if multistart_arms:
        tallies["optik solve_ik_all (lm)"] = Tally()
    steady = Steady(repeats)
    counts: Counter[int] = Counter()
    count_ok, max_err, flagged = 0, 0.0, []
    geo_errors: list[float] = []
    for k in range(arms):
        m = _random_arm(rng)
        qs = rng.uniform(-np.pi, np.pi, (poses, 6))
        targets = m.fk(qs)
        start = time.perf_counter()  # the first call: derives the DH description, builds the FK check
        first = solve_general_6r(m, targets[0])
        tallies["optik general_6r (first call of an arm)"].add(
            time.perf_counter() - start, list(first.q), qs[0], first.q, 1e-8
        )
        start = time.perf_counter()
        stacked = solve_general_6r(m, targets)
        per = (time.perf_counter() - start) / poses
        robot = ik_geo_robot(m) if ik_geo is not None else None
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
                rob, home = robot
                args = ik_geo_target(target, home)  # outside the timing, like optik's validation inside
                start = time.perf_counter()
                raw = rob.get_ik(*args)
                dt = time.perf_counter() - start
                cand = [np.asarray(s, dtype=float) for s, _ in raw]
                err = fk_errors(m, cand, target)
                geo_errors.extend(err.tolist())
                found = [s for s, e in zip(cand, err, strict=True) if e <= GEO_FK_TOL]
                tallies["ik-geo gen_six_dof"].add(dt, found, q, ours, GEO_SAME, GEO_SAME)
            if multistart:
                start = time.perf_counter()
                res = optik.solve_ik_all(m, target, time_limit=1.0, closed_form=False)
                dt = time.perf_counter() - start
                found = [r.q for r in res if r.success]
                tallies["optik solve_ik_all (lm)"].add(dt, found, q, ours, 1e-4)
        steady.run(m, targets, robot)
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
        e = np.asarray(geo_errors)
        med, p95, top = np.quantile(e, [0.5, 0.95, 1.0]) if e.size else (np.nan,) * 3
        print(
            f"\nik-geo gen_six_dof returned {e.size} candidates: FK error median {med:.1e}, p95 {p95:.1e}, "
            f"max {top:.1e}; {int((e <= 1e-6).sum())} within 1e-6 (the project's success rule), "
            f"{int((e <= 1e-4).sum())} within 1e-4, {int((e <= GEO_FK_TOL).sum())} within {GEO_FK_TOL:g} "
            f"(the table's rule, round trip and match at {GEO_SAME:g} rad)."
        )
    for line in flagged[:10]:
        print(f"- flagged: {line}")
    steady.table(n)
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
    ap.add_argument("--repeats", type=int, default=5, help="steady-state repeats per target (0: skip)")
    ap.add_argument("--plot", default=None, help="write the histogram of real-solution counts here")
    ap.add_argument("--special", type=int, default=20, help="arms per special geometry (0: skip)")
    ap.add_argument("--search-16", action="store_true", help="search for a pose with 16 real solutions")
    ap.add_argument("--budget", type=float, default=300.0, help="time budget of --search-16 (s)")
    args = ap.parse_args(argv)
    if args.arms < 1 or args.poses < 1 or args.multistart_arms < 0 or args.repeats < 0:
        ap.error("--arms and --poses must be >= 1, --multistart-arms and --repeats >= 0")
    if args.search_16:
        return search_16(args.seed, args.budget)
    code = run(
        args.arms, args.poses, min(args.multistart_arms, args.arms), args.seed, args.plot, args.repeats
    )
    if args.special > 0:
        special(args.special, args.poses, args.seed)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
