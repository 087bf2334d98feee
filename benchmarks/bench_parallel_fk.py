"""Forward kinematics of parallel mechanisms: all assembly modes (closed form) and numerical FK.

Method (docs/benchmarks.md): poses drawn at random (seeded), actuated values by the closed-form IK, then
each solver on the same inputs in the same process, every call timed (failures included).
Thread pools are pinned to 1 before numpy is imported (the machine has 2 cores).

1. 3-RPR, all real assembly modes: the degree-6 polynomial (``optik.solve_fk_all``, closed form)
   against the numerical multi-start (``method="numeric"``) on the same leg lengths: recall (the
   drawn pose is among the modes), mean number of modes, mean / median / p95 time, ratio, and the
   mean and median CPU time of the calling thread (on a loaded machine the wall-clock mean
   carries the milliseconds other processes took the core for; the CPU time does not).
   Random geometries are used as well as the catalog default (which only ever has 2 or 4
   real modes), so that 6-mode cases occur; each new mechanism is solved once untimed first
   (building its CasADi functions is set-up, not solving), and the C kernels of the closed form
   (built once per machine in the background) are waited for before the timed calls.
2. Closed-form FK per call (``closed_form.fk``, all modes): five-bar, slider-crank, 3-RPR.
3. Stewart-Gough, all real postures: the 40-path parameter homotopy (``method="auto"``, the
   default) beside the 128-path total-degree method and, with ``--fksgp DIR`` (the folder of a
   checkout of github.com/martyushev/fkSGP; skipped with a note without it), fkSGP's
   elimination-template solver (`optik.harness.peers.fksgp_peer`), on the same random general 6-6
   platforms (random orientation and position), interleaved platform by platform, each warmed up
   by one untimed call: round trips (pose ->
   leg lengths -> FK contains the pose), real postures, complex solutions, time per call, the
   largest leg-length residual of any real posture, the median time ratio; a union check against
   extra independent 128-path runs; the planar catalog geometry (where the count check fails and
   the total method completes the set). With ``--fksgp DIR`` also Dietmaier's general 6-6 instance
   with 40 real postures (made by the checkout's own ``genSGP(100, 1)``): optik and fkSGP
   alternating, wall and CPU time.
4. Numerical ``optik.solve_fk`` on every closed catalog chain: tracking from a closed ``q0``
   whose actuators are moved by a small step, and a cold start from mid-limit: success rate
   and time per call.

Apart from fkSGP on the Stewart-Gough platform, no peer library solves the FK of these closed
chains, so the other comparisons are internal (closed form vs numeric on the same inputs).

Run: ``optik benchmark parallel_fk [--n-rpr 500] [--n-sg 1000] [--n-total 1000] [--n-catalog 20]
[--heavy 3] [--n-fk 200] [--fksgp DIR] [--seed 0]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import importlib  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from types import SimpleNamespace  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik import closed_form, native  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.closed_form import parallel  # noqa: E402
from optik.harness.peers import PeerUnavailable  # noqa: E402
from optik.harness.peers.fksgp_peer import _PACKAGE, Postures, load_fksgp  # noqa: E402
from optik.harness.tally import timing_ms  # noqa: E402
from optik.solvers.fk import same_mode  # noqa: E402


def _stats(times: Sequence[float]) -> str:
    """Mean, median and p95 in ms, as table cells."""
    return " | ".join(f"{v:9.2f}" for v in timing_ms(times))


def bench_3rpr(n: int, rng: np.random.Generator) -> None:
    """Closed form vs numeric multi-start, all modes, same leg lengths."""
    print(f"\n## 3-RPR: all real assembly modes ({n} random geometries + {n} catalog poses)\n")
    print(
        f"| {'solver':<22} | recall | modes | {'mean ms':>9} | {'median':>9} | {'p95':>9} | ratio "
        "| CPU mean ms | CPU median |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
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
    native.wait()  # set-up, untimed: the C kernels (3-RPR FK, condition numbers) built and loaded
    base_mean = None
    for label, kwargs in (("closed form (degree 6)", {}), ("numeric multi-start", {"method": "numeric"})):
        times, cpu, hits, counts = [], [], 0, []
        for m, q in cases:
            start, start_cpu = time.perf_counter(), time.thread_time()
            res = optik.solve_fk_all(m, q[m.actuated_indices], seed=0, **kwargs)
            cpu.append(time.thread_time() - start_cpu)
            times.append(time.perf_counter() - start)
            counts.append(len(res))
            hits += any(same_mode(m, r.q, q, 1e-6) for r in res)
        mean = float(np.mean(times))
        base_mean = base_mean or mean
        print(
            f"| {label:<22} | {100 * hits / len(cases):5.1f}% | {np.mean(counts):5.2f} | {_stats(times)} "
            f"| {mean / base_mean:5.1f} | {1e3 * np.mean(cpu):9.3f} | {1e3 * np.median(cpu):9.3f} |"
        )
    hist = np.bincount([len(closed_form.fk(m, q[m.actuated_indices])) for m, q in cases], minlength=7)
    print(f"\nreal modes (closed form) 0..6: {hist.tolist()}")


def _sg_case(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """A random general 6-6 platform, a random pose (any orientation) and its leg lengths."""
    b, p = rng.normal(size=(6, 3)), 0.6 * rng.normal(size=(6, 3))
    r = parallel.quat_to_rot(rng.normal(size=4))
    t = np.array([0.0, 0.0, 1.0]) + 0.2 * rng.normal(size=3)
    return b, p, r, t, np.linalg.norm(p @ r.T + t - b, axis=1)


def _has(poses, r, t, tol: float = 1e-8) -> bool:
    return any(np.allclose(r2, r, atol=tol) and np.allclose(t2, t, atol=tol) for r2, t2 in poses)


def _leg_residual(b, p, rho, poses) -> float:
    return max(
        (float(np.max(np.abs(np.linalg.norm(p @ r.T + t - b, axis=1) - rho))) for r, t in poses), default=0.0
    )


def bench_stewart(
    n: int, n_total: int, rng: np.random.Generator, heavy: int, n_catalog: int, fksgp: Postures | None = None
) -> None:
    """40-path parameter homotopy (default ``method="auto"``) beside the 128-path total-degree
    method and fkSGP (when given) on the same random general 6-6 platforms, interleaved platform
    by platform."""
    n_total = min(n_total, n)
    print(f"\n## Stewart-Gough: all real postures, {n} random general 6-6 platforms\n")
    print(
        f"The 128-path method runs on the first {n_total} of them (same platforms, same process, the "
        "two methods alternating which goes first).\n"
    )
    cases = [_sg_case(rng) for _ in range(n)]
    for method in ("auto", "total"):  # untimed: compile / load the tracker, the start instance
        parallel.stewart_poses(*cases[0][:2], cases[0][4], method=method)
    if fksgp is not None:
        fksgp(*cases[0][:2], cases[0][4])  # the same untimed warm-up
    rows: dict[str, list[dict]] = {"auto": [], "total": []} | ({"fksgp": []} if fksgp else {})
    for i, (b, p, r, t, rho) in enumerate(cases):
        order = list(rows)[i % len(rows) :] + list(rows)[: i % len(rows)]
        for method in order:
            if method == "total" and i >= n_total:
                continue
            start = time.perf_counter()
            if method == "fksgp":
                assert fksgp is not None
                poses = fksgp(b, p, rho)  # the conversion to (R, t) is in the timing, as optik's
                fk = SimpleNamespace(poses=poses, complex_solutions=math.nan, complete=None, method="fksgp")
            else:
                fk = parallel.stewart_poses(b, p, rho, method=method, seed=i)
            elapsed = time.perf_counter() - start
            rows[method].append(
                {
                    "time": elapsed,
                    "poses": fk.poses,
                    "found": _has(fk.poses, r, t),
                    "residual": _leg_residual(b, p, rho, fk.poses),
                    "complex": fk.complex_solutions,
                    "complete": fk.complete,
                    "method": fk.method,
                }
            )
    print(
        "| method | platforms | round trips | missed | complete | real postures mean (max) | complex | "
        "median ms | mean ms | p95 ms | max ms | max leg residual |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    labels = {"auto": "40-path parameter (auto)", "total": "128-path total degree", "fksgp": "fkSGP (peer)"}
    for method, res in rows.items():
        tt = np.array([x["time"] for x in res]) * 1e3
        counts = [len(x["poses"]) for x in res]
        found = sum(x["found"] for x in res)
        peer = method == "fksgp"  # it returns the real postures only
        complete = "-" if peer else str(sum(x["complete"] for x in res))
        n_complex = "-" if peer else f"{np.mean([x['complex'] for x in res]):.1f}"
        print(
            f"| {labels[method]} | {len(res)} | {found}/{len(res)} | {len(res) - found} "
            f"| {complete} | {np.mean(counts):.2f} ({max(counts)}) | {n_complex} "
            f"| {np.median(tt):.2f} | {tt.mean():.2f} "
            f"| {np.percentile(tt, 95):.2f} | {tt.max():.2f} | {max(x['residual'] for x in res):.1e} |"
        )
    new, old = rows["auto"][:n_total], rows["total"]
    ratio = np.median([x["time"] for x in old]) / np.median([x["time"] for x in new])
    fewer = sum(len(a["poses"]) < len(o["poses"]) for a, o in zip(new, old, strict=True))
    more = sum(len(a["poses"]) > len(o["poses"]) for a, o in zip(new, old, strict=True))
    used = {m: sum(x["method"] == m for x in rows["auto"]) for m in ("parameter", "parameter+total", "total")}
    print(
        f"\nSame {n_total} platforms: median time ratio 128-path / 40-path = {ratio:.1f}; "
        f"platforms where the 40-path method found fewer real postures than the 128-path one: {fewer}, "
        f"more: {more}"
    )
    print(f"methods used by auto: {used}")
    if "fksgp" in rows:
        peer = rows["fksgp"]
        ratio = np.median([x["time"] for x in peer]) / np.median([x["time"] for x in rows["auto"]])
        agree = sum(
            len(a["poses"]) == len(f["poses"])
            and all(_has(a["poses"], r2, t2, 1e-7) for r2, t2 in f["poses"])
            for a, f in zip(rows["auto"], peer, strict=True)
        )
        print(
            f"Same {n} platforms against fkSGP: median time fkSGP / 40-path = {ratio:.2f}; platforms "
            f"where both found the same real postures (within 1e-7): {agree}/{n}"
        )
    else:
        print("fkSGP skipped: no checkout given (--fksgp DIR, a checkout of github.com/martyushev/fkSGP)")
    hist = np.bincount([len(x["poses"]) for x in rows["auto"]], minlength=11)
    print(f"real postures per platform (40-path), counts of 0..{len(hist) - 1}: {hist.tolist()}")
    checked = max(1, min(n, n // 50))
    missed = 0
    for b, p, _r, _t, rho in cases[:checked]:
        union = list(parallel.stewart_poses(b, p, rho).poses)
        for k in range(1, heavy):
            for r2, t2 in parallel.stewart_poses(
                b, p, rho, method="total", seed=1000 * k, max_rounds=1
            ).poses:
                if not _has(union, r2, t2, 1e-7):
                    union.append((r2, t2))
                    missed += 1
    print(
        f"union check on {checked} platforms ({heavy - 1} extra independent 128-path runs each): "
        f"postures the 40-path run missed: {missed}"
    )
    if n_catalog:
        sg = optik.catalog.stewart_gough()
        b, p = sg.params["base"], sg.params["platform"]
        print(
            f"\n### Catalog geometry (planar hexagons: 28 complex solutions, the count check fails), "
            f"{n_catalog} poses\n"
        )
        print("| method | round trips | mean ms | median ms | p95 ms | methods used |")
        print("|---|---|---|---|---|---|")
        poses = [
            (
                optik.spatial.rpy_to_rot(*rng.uniform(-0.4, 0.4, 3)),
                np.array([0.0, 0.0, 1.0]) + 0.2 * rng.normal(size=3),
            )
            for _ in range(n_catalog)
        ]
        for method in ("auto", "total"):
            times, found, used_c = [], 0, set()
            for i, (r, t) in enumerate(poses):
                rho = np.linalg.norm(p @ r.T + t - b, axis=1)
                start = time.perf_counter()
                fk = parallel.stewart_poses(b, p, rho, method=method, seed=i)
                times.append(time.perf_counter() - start)
                found += _has(fk.poses, r, t)
                used_c.add(fk.method)
            print(f"| {method} | {found}/{n_catalog} | {_stats(times)} | {sorted(used_c)} |")


def bench_closed_form_fk(n: int, rng: np.random.Generator) -> None:
    """Per-call time of the closed-form FK (all modes, full coordinates) of the planar chains."""
    print(f"\n## Closed-form FK per call (all modes, `closed_form.fk`, {n} random inputs each)\n")
    print(f"| mechanism | modes (mean) | {'mean ms':>9} | {'median':>9} | {'p95':>9} |")
    print("|---|---|---|---|---|")
    inputs = {
        "five_bar": lambda m: rng.uniform(-np.pi, np.pi, 2),
        "slider_crank": lambda m: rng.uniform(-np.pi, np.pi, 1),
        "planar_3rpr": lambda m: closed_form.ik(
            m, optik.Pose2D(*rng.uniform([0.6, 0.4, -np.pi], [1.4, 1.1, np.pi]))
        )[0][m.actuated_indices],
    }
    for name, draw in inputs.items():
        m = getattr(optik.catalog, name)()
        cases = [draw(m) for _ in range(n)]
        closed_form.fk(m, cases[0])
        times, modes = [], []
        for a in cases:
            start = time.perf_counter()
            modes.append(len(closed_form.fk(m, a, respect_limits=False)))
            times.append(time.perf_counter() - start)
        print(f"| {name} | {np.mean(modes):.2f} | {_stats(times)} |")


DIETMAIER_RUNS = 20
"""Interleaved runs of each solver on Dietmaier's instance."""


def _dietmaier(directory: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Dietmaier's general 6-6 platform with 40 real postures (Mech. Mach. Theory, 1998), as the fkSGP
    checkout ``directory`` makes it (``genSGP(100, 1)``: base, platform, squared leg lengths), or
    None when the checkout has no such generator."""
    load_fksgp(directory)  # registers the checkout's python folder as the package _PACKAGE
    try:
        sgp = importlib.import_module(f"{_PACKAGE}.genSGP").genSGP(100, 1)
    except Exception:  # another version of the checkout
        return None
    rho = np.sqrt(np.asarray(sgp["L"], dtype=float))
    return np.asarray(sgp["X"], dtype=float), np.asarray(sgp["x"], dtype=float), rho


def bench_dietmaier(fksgp: Postures, case: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    """optik's default Stewart-Gough FK and fkSGP on Dietmaier's 40-real instance, alternating
    which goes first, `DIETMAIER_RUNS` runs each (optik with a new seed each run: gamma and patch),
    timed by the wall clock and by the process CPU time."""
    b, p, rho = case
    print(f"\n## Stewart-Gough: Dietmaier's 40-real instance, {DIETMAIER_RUNS} interleaved runs each\n")
    parallel.stewart_poses(b, p, rho)  # untimed warm-up, for both
    fksgp(b, p, rho)
    rows: dict[str, list[tuple[float, float, list]]] = {"optik": [], "fksgp": []}
    for i in range(DIETMAIER_RUNS):
        for name in list(rows)[i % 2 :] + list(rows)[: i % 2]:
            wall, cpu = time.perf_counter(), time.process_time()
            poses = parallel.stewart_poses(b, p, rho, seed=i).poses if name == "optik" else fksgp(b, p, rho)
            rows[name].append((time.perf_counter() - wall, time.process_time() - cpu, poses))
    print("| solver | real postures (min / max) | median ms, wall | median ms, CPU | max leg residual |")
    print("|---|---|---|---|---|")
    med = {}
    for name, runs in rows.items():
        counts = [len(x[2]) for x in runs]
        med[name] = (np.median([x[0] for x in runs]), np.median([x[1] for x in runs]))
        residual = max(_leg_residual(b, p, rho, x[2]) for x in runs)
        print(
            f"| {name} | {min(counts)} / {max(counts)} | {1e3 * med[name][0]:.2f} | {1e3 * med[name][1]:.2f} "
            f"| {residual:.1e} |"
        )
    same = sum(
        len(a[2]) == len(f[2]) and all(_has(a[2], r2, t2, 1e-7) for r2, t2 in f[2])
        for a, f in zip(rows["optik"], rows["fksgp"], strict=True)
    )
    print(
        f"\nRatio optik / fkSGP of the medians: wall {med['optik'][0] / med['fksgp'][0]:.2f}, CPU "
        f"{med['optik'][1] / med['fksgp'][1]:.2f}; runs where both found the same real postures (within "
        f"1e-7): {same}/{DIETMAIER_RUNS}"
    )


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
    ap = benchmark_parser("parallel_fk", __doc__)
    ap.add_argument("--n-rpr", type=int, default=500, help="3-RPR cases per geometry kind")
    ap.add_argument("--n-sg", type=int, default=1000, help="random general 6-6 Stewart-Gough platforms")
    ap.add_argument(
        "--n-total",
        type=int,
        default=1000,
        help="of those, how many the 128-path method solves too (the first ones)",
    )
    ap.add_argument(
        "--n-catalog", type=int, default=20, help="Stewart-Gough poses on the planar catalog geometry"
    )
    ap.add_argument("--heavy", type=int, default=3, help="independent runs in the completeness check")
    ap.add_argument("--n-fk", type=int, default=200, help="solve_fk cases per mechanism")
    ap.add_argument("--fksgp", type=Path, help="folder of a fkSGP checkout (the Stewart-Gough peer)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    args = ap.parse_args(argv)
    if min(args.n_rpr, args.n_sg, args.n_fk, args.heavy, args.n_total) < 1 or args.n_catalog < 0:
        ap.error("--n-rpr, --n-sg, --n-total, --n-fk and --heavy must be >= 1, --n-catalog >= 0")
    rng = np.random.default_rng(args.seed)
    bench_3rpr(args.n_rpr, rng)
    bench_closed_form_fk(args.n_rpr, rng)
    fksgp = None
    if args.fksgp is not None:
        try:
            fksgp = load_fksgp(args.fksgp)
        except PeerUnavailable as exc:
            print(f"fkSGP skipped: {exc}")
    bench_stewart(args.n_sg, args.n_total, rng, args.heavy, min(args.n_catalog, args.n_sg), fksgp)
    case = _dietmaier(args.fksgp) if fksgp is not None else None
    if fksgp is not None and case is not None:
        bench_dietmaier(fksgp, case)
    elif fksgp is not None:
        print("Dietmaier's instance skipped: the fkSGP checkout has no genSGP(100, ...)")
    bench_solve_fk(args.n_fk, rng)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
