"""The 1-D search IK (`optik.closed_form.search_1d`) on 6R arms with special end axes, against the
general 6R solver's perturbation fallback and the peers that support such arms.

Method (docs/benchmarks.md): per geometry, ``--arms`` random arms (standard DH rows
``d ~ U(-1, 1)``, ``a ~ U(0.1, 1)``, ``alpha ~ U(-pi, pi)``, with the entries of the geometry set
to zero, joint limits ``+-U(2, pi)``), ``--poses`` random joint vectors within the limits per
arm, targets by the mechanism's own FK (``m.fk``); then, target by target in the same process
(thread pools pinned to 1 before numpy is imported):

* ``optik search_1d``: `optik.closed_form.search_1d.solve_search_1d` on one target (validation,
  search, polish, check); the arm's targets are also solved in one stacked call (time per target
  shown); the arm's family is chosen before timing (`family_of`, cached);
* ``optik general_6r``: `optik.closed_form.general_6r.solve_general_6r` (for arms special at both
  ends its count check fails and the solutions come from a nearby generic arm, not certified);
* ``ik-geo two_intersecting`` (the ``ik_geo`` package, IK-Geo's 1-D search for axes 5-6
  intersecting) on the geometries where axes 5-6 intersect, built once per arm from the same
  joint lines (the points of axes 5 and 6 at their intersection, as its decomposition needs);
  its answers are the grid points of a coarse search without refinement (all flagged least
  squares, FK errors about 1e-5 to 1e-3), so they are counted twice: verified to 1e-8 like the
  others, and to 1e-3 (FK) with round trips to 1e-2 rad; they are left out of the union;
* ``EAIK`` (the ``eaik`` package) where ``Robot.has_known_decomposition()`` is True for the arm
  (EAIK 1.2 knows none of these geometries: the table says how many arms it supported).

Reported per geometry and solver: round trips (the drawn ``q`` among the verified answers, 1e-6
rad modulo 2 pi), solutions per target (each verified here by ``m.fk`` to 1e-8), the share of the
union of all solvers' verified solutions that a solver found, duplicates (two answers within 1e-4
rad), answers that fail the FK check, and mean / median / p95 time per target with the ratio of
means to ``optik search_1d``. ``--geometries one-end`` runs the same on geometries with one special
end pair, which the general 6R solver covers (certified): the measurement behind the registry's
choice (``all``: both sets).

Run: ``optik benchmark search_1d [--arms 20] [--poses 50] [--seed 0] [--geometries both-ends]``
(or ``python -m optik.benchmarks.bench_search_1d``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402

from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.benchmarks.peer_arms import axis_offsets, ik_geo_target  # noqa: E402
from optik.closed_form.derived import chain_axes, derive  # noqa: E402
from optik.closed_form.general_6r import covers, solve_general_6r  # noqa: E402
from optik.closed_form.search_1d import search_of, solve_search_1d  # noqa: E402
from optik.closed_form.structure import intersection  # noqa: E402
from optik.harness.tally import timing_ms  # noqa: E402
from optik.mechanism import Mechanism, dh_chain  # noqa: E402
from optik.spatial import angle_distance  # noqa: E402

try:  # optional peers
    import ik_geo
except ImportError:  # pragma: no cover - depends on the environment
    ik_geo = None
try:
    import eaik.pybindings.EAIK as eaik
except ImportError:  # pragma: no cover - depends on the environment
    eaik = None

BOTH_ENDS = {
    "1-2 and 5-6 intersect": {"a": [0, 4]},
    "1-2 intersect, 5-6 parallel": {"a": [0], "alpha": [4]},
    "1-2 parallel, 5-6 intersect": {"a": [4], "alpha": [0]},
    "1-2 and 5-6 parallel": {"alpha": [0, 4]},
    "4, 5, 6 parallel": {"alpha": [3, 4]},
    "1, 2, 3 parallel": {"alpha": [0, 1]},
}
"""Geometries special at both ends (``covers`` is False): DH entries set to zero."""
ONE_END = {
    "1-2 intersect": {"a": [0]},
    "5-6 intersect": {"a": [4]},
    "1-2 parallel": {"alpha": [0]},
    "5-6 parallel": {"alpha": [4]},
}
"""Geometries with one special end pair (``covers`` is True)."""

FK_TOL = 1e-8
SAME = 1e-4


def special_arm(rng: np.random.Generator, zero: dict[str, list[int]]) -> Mechanism:
    """A random standard-DH arm with the given entries zero and joint limits ``+-U(2, pi)``."""
    a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
    a[zero.get("a", [])] = 0.0
    alpha[zero.get("alpha", [])] = 0.0
    lim = rng.uniform(2.0, np.pi, 6)
    return dh_chain([(d[i], a[i], alpha[i]) for i in range(6)], "standard", lower=-lim, upper=lim)


def _verified(
    m: Mechanism, qs: Sequence[Sequence[float]], target: np.ndarray, tol: float = FK_TOL
) -> list[np.ndarray]:
    """The answers whose FK (``m.fk``) matches the target to ``tol`` (entries of the pose)."""
    out = []
    for q in qs:
        t = m.fk(np.asarray(q, dtype=float))
        if np.abs(t[:3, 3] - target[:3, 3]).max() <= tol and np.abs(t[:3, :3] - target[:3, :3]).max() <= tol:
            out.append(np.asarray(q, dtype=float))
    return out


@dataclass
class Tally:
    """Per-solver counters over the targets it ran on."""

    times: list[float] = field(default_factory=list)
    targets: int = 0
    round_trips: int = 0
    solutions: int = 0
    of_union: int = 0
    union: int = 0
    duplicates: int = 0
    failed_check: int = 0

    def add(
        self, dt: float, raw: Sequence[np.ndarray], good: list[np.ndarray], q: np.ndarray, trip: float = 1e-6
    ) -> None:
        self.times.append(dt)
        self.targets += 1
        self.round_trips += bool(good) and bool(np.min(angle_distance(np.array(good), q)) < trip)
        self.solutions += len(good)
        self.failed_check += len(raw) - len(good)
        self.duplicates += sum(
            bool(angle_distance(good[i], good[j]) < SAME) for i in range(len(good)) for j in range(i)
        )


def _ik_geo_two_intersecting(m: Mechanism) -> Callable[[np.ndarray], list[np.ndarray]] | None:
    """IK-Geo's 1-D search for axes 5-6 intersecting, from the joint lines at ``q = 0``."""
    if ik_geo is None:
        return None
    axes = chain_axes(m)
    r = axes.r.copy()
    r[4] = r[5] = intersection(axes, 4, 5)
    robot = ik_geo.Robot.two_intersecting(axes.h, axis_offsets(r, axes.home))
    home = axes.home[:3, :3]

    def solve(target: np.ndarray) -> list[np.ndarray]:
        return [np.asarray(s) for s, _ in robot.get_ik(*ik_geo_target(target, home))]

    return solve


def _eaik(m: Mechanism) -> Callable[[np.ndarray], list[np.ndarray]] | None:
    """EAIK's solver for the arm when it knows a decomposition, else None."""
    if eaik is None:
        return None
    ax = chain_axes(m)
    robot = eaik.Robot(ax.h.T, axis_offsets(ax.r, ax.home).T, ax.home[:3, :3], [], True)
    if not robot.has_known_decomposition():
        return None
    return lambda t: list(np.asarray(robot.calculate_IK(t).Q))


def run_geometry(
    label: str, zero: dict[str, list[int]], arms: int, poses: int, rng: np.random.Generator
) -> None:
    tallies: dict[str, Tally] = {"optik search_1d": Tally(), "optik search_1d (stacked)": Tally()}
    tallies["optik general_6r"] = Tally()
    n_covered = n_eaik = 0
    families: dict[str, int] = {}
    for _ in range(arms):
        m = special_arm(rng, zero)
        assert derive(m) is None
        n_covered += covers(m)
        search = search_of(m)
        families[search.family.name] = families.get(search.family.name, 0) + 1
        peers: dict[str, Callable[[np.ndarray], list[np.ndarray]]] = {}
        geo = (
            _ik_geo_two_intersecting(m)
            if "5-6 intersect" in label or label.endswith("1-2 and 5-6 intersect")
            else None
        )
        if geo is not None:
            peers["ik-geo two_intersecting"] = geo
        ea = _eaik(m)
        if ea is not None:
            peers["EAIK"] = ea
            n_eaik += 1
        qs = m.random_q(poses, seed=int(rng.integers(1 << 30)))
        targets = m.fk(qs)
        solve_general_6r(m, targets[0])  # untimed: DH description cached
        start = time.perf_counter()
        stacked = solve_search_1d(m, targets)
        per = (time.perf_counter() - start) / poses
        for q, target, batch in zip(qs, targets, stacked, strict=True):
            found: dict[str, list[np.ndarray]] = {}
            t0 = time.perf_counter()
            ours = solve_search_1d(m, target)
            dt = time.perf_counter() - t0
            found["optik search_1d"] = _verified(m, ours.q, target)
            tallies["optik search_1d"].add(dt, list(ours.q), found["optik search_1d"], q)
            found["optik search_1d (stacked)"] = _verified(m, batch.q, target)
            tallies["optik search_1d (stacked)"].add(
                per, list(batch.q), found["optik search_1d (stacked)"], q
            )
            t0 = time.perf_counter()
            gen = solve_general_6r(m, target)
            dt = time.perf_counter() - t0
            found["optik general_6r"] = _verified(m, gen.q, target)
            tallies["optik general_6r"].add(dt, list(gen.q), found["optik general_6r"], q)
            for name, peer in peers.items():
                t0 = time.perf_counter()
                raw = peer(target)
                dt = time.perf_counter() - t0
                if name.startswith("ik-geo"):  # approximate answers: counted apart, not in the union
                    tallies.setdefault(name, Tally()).add(dt, raw, _verified(m, raw, target), q)
                    approx = name + " (FK 1e-3, round trip 1e-2)"
                    tallies.setdefault(approx, Tally()).add(dt, raw, _verified(m, raw, target, 1e-3), q, 1e-2)
                    continue
                found[name] = _verified(m, raw, target)
                tallies.setdefault(name, Tally()).add(dt, raw, found[name], q)
            union: list[np.ndarray] = []
            for sols in found.values():
                for s in sols:
                    if all(angle_distance(s, u) >= SAME for u in union):
                        union.append(s)
            for name, sols in found.items():
                tallies[name].union += len(union)
                tallies[name].of_union += sum(any(angle_distance(u, s) < SAME for s in sols) for u in union)
    fam = ", ".join(f"{k}: {v}" for k, v in sorted(families.items()))
    print(
        f"\n### {label}: {arms} arms x {poses} poses; covers() True on {n_covered}; EAIK decomposes {n_eaik}"
    )
    print(f"families chosen: {fam}\n")
    print(
        "| solver | targets | round trip % | solutions / target | share of union % | duplicates "
        "| failed FK | mean ms | median ms | p95 ms | mean / search_1d |"
    )
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
    base = float(np.mean(tallies["optik search_1d"].times))
    for name, t in tallies.items():
        if not t.targets:
            continue
        mean, median, p95 = timing_ms(t.times)
        cells = [
            name,
            f"{t.targets}",
            f"{100.0 * t.round_trips / t.targets:.1f}",
            f"{t.solutions / t.targets:.2f}",
            f"{100.0 * t.of_union / max(t.union, 1):.1f}",
            f"{t.duplicates}",
            f"{t.failed_check}",
            f"{mean:.3f}",
            f"{median:.3f}",
            f"{p95:.3f}",
            f"{mean / 1e3 / base:.2f}",
        ]
        print("| " + " | ".join(cells) + " |")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print markdown tables."""
    ap = benchmark_parser("search_1d", __doc__)
    ap.add_argument("--arms", type=int, default=20, help="random arms per geometry")
    ap.add_argument("--poses", type=int, default=50, help="random poses per arm")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument(
        "--geometries",
        choices=("both-ends", "one-end", "all"),
        default="both-ends",
        help="special at both ends (covers() False), at one end (covers() True), or all",
    )
    ap.add_argument("--only", default=None, help="run only the geometries whose label contains this")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print(f"## 1-D search: ik-geo {'yes' if ik_geo else 'no'}, EAIK {'yes' if eaik else 'no'}")
    cases = {
        **(BOTH_ENDS if args.geometries != "one-end" else {}),
        **(ONE_END if args.geometries != "both-ends" else {}),
    }
    for label, zero in cases.items():
        if args.only is None or args.only in label:
            run_geometry(label, zero, args.arms, args.poses, rng)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
