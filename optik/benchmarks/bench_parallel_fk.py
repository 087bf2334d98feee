"""Forward kinematics of parallel mechanisms: all assembly modes (closed form) and numerical FK.

Method (docs/benchmarks.md): poses drawn at random (seeded), actuated values by the closed-form IK, then
each solver on the same inputs in the same process, every call timed (failures included).
Thread pools are pinned to 1 before numpy is imported (the machine has 2 cores).

1. 3-RPR, all real assembly modes: the degree-6 polynomial (``optik.solve_fk_all``, closed form)
   against the numerical multi-start (``method="numeric"``) on the same leg lengths: recall (the
   drawn pose is among the modes), mean number of modes, mean / median / p95 time, ratio.
   Random geometries are used as well as the catalog default (which only ever has 2 or 4
   real modes), so that 6-mode cases occur; each new mechanism is solved once untimed first
   (building its CasADi functions is set-up, not solving).
2. Stewart-Gough, all real postures by homotopy continuation: random general 6-6 geometries and
   the catalog geometry (planar hexagons); time per call, histogram of real postures, complex
   solutions found (40 for a general 6-6), recall of the drawn pose. A heavier check repeats
   each case with 3 independent rounds (fresh gamma and patch each) and counts postures that
   the single run missed.
3. Numerical ``optik.solve_fk`` on every closed catalog chain: tracking from a closed ``q0``
   whose actuators are moved by a small step, and a cold start from mid-limit: success rate
   and time per call.

No peer library solves the FK of closed chains, so the comparisons are internal (closed form vs
numeric on the same inputs).

Run: ``optik benchmark parallel_fk [--n-rpr 500] [--n-sg 10] [--n-fk 200] [--seed 0]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik import closed_form  # noqa: E402
from optik.closed_form import parallel  # noqa: E402
from optik.solvers.fk import same_mode  # noqa: E402


def _stats(times: Sequence[float]) -> str:
    t = np.asarray(times) * 1e3
    return f"{t.mean():9.2f} | {np.median(t):9.2f} | {np.percentile(t, 95):9.2f}"


def bench_3rpr(n: int, rng: np.random.Generator) -> None:
    """Closed form vs numeric multi-start, all modes, same leg lengths."""
    print(f"\n## 3-RPR: all real assembly modes ({n} random geometries + {n} catalog poses)\n")
    print(f"| {'solver':<22} | recall | modes | {'mean ms':>9} | {'median':>9} | {'p95':>9} | ratio |")
    print("|---|---|---|---|---|---|---|")
    cases = []
    catalog_3rpr = optik.catalog.planar_3rpr()
    while len(cases) < 2 * n:
        if len(cases) < n:
            b, p = rng.normal(size=(3, 2)), 0.7 * rng.normal(size=(3, 2))
            m = optik.catalog.planar_3rpr(base=b, platform=p, leg_limits=(0.0, 100.0))
            pose = optik.Pose2D(*rng.normal(size=2), rng.uniform(-np.pi, np.pi))
        else:
            m = catalog_3rpr
            pose = optik.Pose2D(*rng.uniform([0.6, 0.4, -np.pi], [1.4, 1.1, np.pi]))
        qs = closed_form.ik(m, pose)
        if qs:
            optik.solve_fk_all(m, qs[0][m.actuated_indices])  # untimed: builds the CasADi functions
            cases.append((m, qs[0]))
    base_mean = None
    for label, kwargs in (("closed form (degree 6)", {}), ("numeric multi-start", {"method": "numeric"})):
        times, hits, counts = [], 0, []
        for m, q in cases:
            start = time.perf_counter()
            res = optik.solve_fk_all(m, q[m.actuated_indices], seed=0, **kwargs)
            times.append(time.perf_counter() - start)
            counts.append(len(res))
            hits += any(same_mode(m, r.q, q, 1e-6) for r in res)
        mean = float(np.mean(times))
        base_mean = base_mean or mean
        print(
            f"| {label:<22} | {100 * hits / len(cases):5.1f}% | {np.mean(counts):5.2f} | {_stats(times)} "
            f"| {mean / base_mean:5.1f} |"
        )
    hist = np.bincount([len(closed_form.fk(m, q[m.actuated_indices])) for m, q in cases], minlength=7)
    print(f"\nreal modes (closed form) 0..6: {hist.tolist()}")


def bench_stewart(n: int, rng: np.random.Generator, heavy: int) -> None:
    """Homotopy continuation on random general and catalog geometries."""
    print(f"\n## Stewart-Gough: all real postures ({n} random general 6-6 + {n} catalog cases)\n")
    print(
        "| geometry | recall | postures (mean) | complex | rounds | mean s | median s | p95 s | max s "
        f"| missed vs {heavy}-round union |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    sg = optik.catalog.stewart_gough()
    per_case = {}
    for label in ("random 6-6", "catalog"):
        times, hits, counts, cplx, rounds, missed = [], 0, [], [], [], 0
        for i in range(n):
            if label == "catalog":
                b, p = sg.params["base"], sg.params["platform"]
            else:
                b, p = rng.normal(size=(6, 3)), 0.6 * rng.normal(size=(6, 3))
            r = (
                parallel.quat_to_rot(rng.normal(size=4))
                if label != "catalog"
                else optik.spatial.rpy_to_rot(*rng.uniform(-0.4, 0.4, 3))
            )
            t = np.array([0.0, 0.0, 1.0]) + 0.2 * rng.normal(size=3)
            rho = np.linalg.norm(p @ r.T + t - b, axis=1)
            fk = parallel.stewart_poses(b, p, rho, seed=i)
            times.append(fk.solve_time)
            counts.append(len(fk.poses))
            cplx.append(fk.complex_solutions)
            rounds.append(fk.rounds)
            hits += any(
                np.allclose(r2, r, atol=1e-8) and np.allclose(t2, t, atol=1e-8) for r2, t2 in fk.poses
            )
            if heavy > 1 and i < max(2, n // 3):
                union = list(fk.poses)
                for k in range(1, heavy):
                    extra = parallel.stewart_poses(b, p, rho, seed=1000 * k + i, max_rounds=1)
                    for r2, t2 in extra.poses:
                        if not any(
                            np.allclose(r2, r3, atol=1e-7) and np.allclose(t2, t3, atol=1e-7)
                            for r3, t3 in union
                        ):
                            union.append((r2, t2))
                missed += len(union) - len(fk.poses)
        tt = np.asarray(times)
        print(
            f"| {label} | {100 * hits / n:5.1f}% | {np.mean(counts):5.2f} (max {max(counts)}) "
            f"| {np.mean(cplx):5.1f} | {np.mean(rounds):4.2f} | {tt.mean():6.2f} | {np.median(tt):6.2f} "
            f"| {np.percentile(tt, 95):6.2f} | {tt.max():6.2f} | {missed} |"
        )
        per_case[label] = counts
    for label, counts in per_case.items():
        print(f"\n{label}: real postures per case {counts}")


def bench_solve_fk(n: int, rng: np.random.Generator) -> None:
    """Numerical solve_fk on every closed catalog chain: tracking and cold starts."""
    print(f"\n## Numerical solve_fk ({n} cases per mechanism)\n")
    print(f"| mechanism | start | success | {'mean ms':>9} | {'median':>9} | {'p95':>9} |")
    print("|---|---|---|---|---|---|")
    makers = {
        "five_bar": lambda: optik.Position(rng.uniform(-0.2, 1.2), rng.uniform(0.9, 1.7)),
        "doggy": lambda: optik.Pose2D(rng.uniform(-0.3, 0.3), rng.uniform(0.55, 1.0), rng.uniform(-0.5, 0.5)),
        "slider_crank": lambda: optik.Position(rng.uniform(-1.2, 1.2), 0.0),
        "planar_3rpr": lambda: optik.Pose2D(*rng.uniform([0.6, 0.4, -np.pi], [1.4, 1.1, np.pi])),
        "stewart_gough": lambda: optik.spatial.transform(
            optik.spatial.rpy_to_rot(*rng.uniform(-0.3, 0.3, 3)),
            np.array([0, 0, 1.0]) + rng.uniform(-0.15, 0.15, 3),
        ),
    }
    for name, make in makers.items():
        m = getattr(optik.catalog, name)()
        pairs = []
        while len(pairs) < n:
            q1 = closed_form.ik(m, make())
            q0 = closed_form.ik(m, make())
            if q1 and q0:
                pairs.append((q0[0], q1[0]))
        optik.solve_fk(m, pairs[0][1][m.actuated_indices])  # build the CasADi function once
        for label in ("tracking from q0", "cold (mid-limit)"):
            times, ok = [], 0
            for q0, q1 in pairs:
                a = q1[m.actuated_indices]
                start = time.perf_counter()
                res = optik.solve_fk(m, a, q0=q0 if label.startswith("tracking") else None)
                times.append(time.perf_counter() - start)
                ok += res.success
            print(f"| {name} | {label} | {100 * ok / n:5.1f}% | {_stats(times)} |")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the three benchmarks and print their tables (markdown); returns 0."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-rpr", type=int, default=500, help="3-RPR cases per geometry kind")
    ap.add_argument("--n-sg", type=int, default=10, help="Stewart-Gough cases per geometry kind")
    ap.add_argument("--heavy", type=int, default=3, help="independent runs in the completeness check")
    ap.add_argument("--n-fk", type=int, default=200, help="solve_fk cases per mechanism")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if min(args.n_rpr, args.n_sg, args.n_fk, args.heavy) < 1:
        ap.error("--n-rpr, --n-sg, --n-fk and --heavy must be >= 1")
    rng = np.random.default_rng(args.seed)
    bench_3rpr(args.n_rpr, rng)
    bench_stewart(args.n_sg, rng, args.heavy)
    bench_solve_fk(args.n_fk, rng)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
