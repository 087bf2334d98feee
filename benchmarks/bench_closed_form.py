"""Throughput of the vectorized closed forms: planar 2R, planar 3R and the seed's 6R arm.

Method (docs/benchmarks.md): random joint vectors drawn uniformly within the limits (seeded), targets by
the mechanism's own FK, then the vectorized solver on all targets at once in one process on one
core (thread pools pinned to 1 before numpy is imported). Each solver call is timed ``--repeat``
times over the same targets; the table shows the median and best throughput (targets/s, every
branch of every target computed). Correctness on a subsample of ``--verify`` targets: the share
of targets whose original joint vector is among the reachable branches (1e-6, angles modulo
2 pi) and the largest FK error of any reachable branch. For scale, the same subsample is also
solved one target at a time through ``optik.closed_form.ik`` (validation, limits and branch
merging included), with mean / median / p95 time per call and the ratio to the vectorized
per-target time.

Run: ``optik benchmark closed_form [--n 1000000] [--n-6r 200000] [--repeat 5]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402

import numpy as np  # noqa: E402

from optik import Mechanism, catalog, closed_form, spatial  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.harness.tally import timing_ms  # noqa: E402

Solver = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``targets (N, 4, 4) -> (q (N, B, n), ok (N, B))``."""


@dataclass
class Case:
    """One mechanism, its vectorized solver and the number of targets to time it on."""

    name: str
    mechanism: Mechanism
    solve: Solver
    n: int


def _cases(n: int, n_6r: int) -> list[Case]:
    l2 = (1.0, 0.8)
    l3 = (1.0, 0.8, 0.5)
    d = (1.0, 0.8, 0.3)

    def solve_3r(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x, y, phi = spatial.planar_pose_of(t).T
        return closed_form.ik_planar_3r(l3, x, y, phi)

    return [
        Case(
            "planar_2r",
            catalog.planar_2r(l2),
            lambda t: closed_form.ik_planar_2r(l2, t[:, 0, 3], t[:, 1, 3]),
            n,
        ),
        Case("planar_3r", catalog.planar_3r(l3), solve_3r, n),
        Case("seed_6r_arm", catalog.seed_6r_arm(*d), lambda t: closed_form.ik_seed_6r(*d, t), n_6r),
    ]


def _verify(m: Mechanism, q_true: np.ndarray, q: np.ndarray, ok: np.ndarray) -> tuple[float, float]:
    """(share of targets whose q is recovered, max FK error of reachable branches)."""
    ang = m.revolute_mask
    d = q - q_true[:, None, :]
    d[..., ang] = (d[..., ang] + np.pi) % (2 * np.pi) - np.pi
    recovered = ((np.max(np.abs(d), axis=-1) < 1e-6) & ok).any(axis=1)
    t = m.fk(q_true)
    flat_ok = ok.reshape(-1)
    tb = m.fk(q.reshape(-1, m.n_q)[flat_ok])
    tt = np.repeat(t, q.shape[1], axis=0)[flat_ok]
    if m.task == "position2d":
        tb, tt = tb[:, :2, 3], tt[:, :2, 3]
    return float(recovered.mean()), float(np.max(np.abs(tb - tt)))


def _per_call_times(m: Mechanism, targets: np.ndarray) -> np.ndarray:
    times = np.empty(len(targets))
    for i, t in enumerate(targets):
        start = time.perf_counter()
        closed_form.ik(m, t)
        times[i] = time.perf_counter() - start
    return times


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the table; returns 0 (1 if the 3R is below 1e6 targets/s)."""
    ap = benchmark_parser("closed_form", __doc__)
    ap.add_argument("--n", type=int, default=1_000_000, help="targets for 2R and 3R")
    ap.add_argument("--n-6r", type=int, default=200_000, help="targets for the 6R arm (8 branches each)")
    ap.add_argument("--repeat", type=int, default=5, help="timed calls per solver")
    ap.add_argument("--verify", type=int, default=20_000, help="targets checked by FK and timed per call")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    args = ap.parse_args(argv)
    if min(args.n, args.n_6r, args.repeat, args.verify) < 1:
        ap.error("--n, --n-6r, --repeat and --verify must be >= 1")

    print(
        "| mechanism | targets | vectorized targets/s: median of the calls | best | FK-checked targets "
        "| recovered | max FK err | one ik() call us: mean / median / p95 | ratio |\n"
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|"
    )
    status = 0
    for case in _cases(args.n, args.n_6r):
        m = case.mechanism
        q_true = m.random_q(case.n, seed=args.seed)
        targets = m.fk(q_true)
        rates = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            q, ok = case.solve(targets)
            rates.append(case.n / (time.perf_counter() - start))
        k = min(args.verify, case.n)
        recovered, fk_err = _verify(m, q_true[:k], q[:k], ok[:k])
        per_call = _per_call_times(m, targets[:k])
        median_rate = float(np.median(rates))
        mean, median, p95 = (1e3 * ms for ms in timing_ms(per_call))  # us
        print(
            f"| {case.name} | {case.n} | {median_rate:.3e} | {max(rates):.3e} | {k} | {recovered:.2%} "
            f"| {fk_err:.1e} | {mean:.1f} / {median:.1f} / {p95:.1f} | {mean * 1e-6 * median_rate:.0f} |"
        )
        if case.name == "planar_3r" and median_rate < 1e6:
            status = 1
    print(
        "\nratio = mean time of one closed_form.ik call / vectorized time per target; every branch of the "
        "first FK-checked targets (not of every timed target) is checked by FK"
    )
    return status


if __name__ == "__main__":
    raise SystemExit(main())
