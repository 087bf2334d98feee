"""IK on the Franka Panda: optik ``lm`` and ``nlp`` against TRAC-IK, same URDF, same targets, same run.

Method (docs/benchmarks.md): the Panda chain is loaded from the shipped URDF
(``optik.catalog.arms.urdf_path("panda")``, ``panda_link0`` -> ``panda_link8``) by optik and by
TRAC-IK (``pytracik``, Speed mode). ``--n`` joint vectors are drawn uniformly within the limits
(seeded), the targets are their FK poses, and every solver starts from the mid-limit seed with
the time limit ``--time-limit`` (5 ms) and tolerance ``--tol`` (1e-5). Every call is timed
with ``time.perf_counter`` around the public call (``optik.solve_ik(...)`` with its input
validation and result check; ``TracIK.ik(...)`` with its quaternion conversion), failures
included. Success is judged for every solver by the same check: position error and geodesic
orientation error <= ``--tol`` and joint limits satisfied exactly (TRAC-IK's own success flag,
on its twist error, is shown next to it). The NLP method runs with its own budget
``--nlp-time-limit`` (one IPOPT solve from the mid-limit seed takes longer than 5 ms here), on
the first ``--n-nlp`` targets, with IPOPT (``nlp``) and with ``sqpmethod`` (``nlp-sqp``). The
methods run interleaved per target so that load changes on a shared machine hit all of them
alike; the table reports success rate, mean / median / p95 time and the ratio of each mean time
to TRAC-IK's.

Run: ``optik benchmark ik [--n 10000] [--time-limit 0.005] [--tol 1e-5]
[--methods lm,nlp,nlp-sqp,tracik] [--n-nlp 1000] [--nlp-time-limit 0.3]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik import native  # noqa: E402
from optik.benchmarks import benchmark_parser  # noqa: E402
from optik.catalog.arms import URDF_CHAINS, urdf_path  # noqa: E402
from optik.solvers.base import evaluate  # noqa: E402

Solver = Callable[[np.ndarray], tuple[np.ndarray | None, bool]]
"""``target 4x4 -> (q or None, the solver's own success flag)``."""


@dataclass
class Record:
    """Per-solver outcomes over the targets."""

    name: str
    times: list[float] = field(default_factory=list)
    success: list[bool] = field(default_factory=list)
    own_success: list[bool] = field(default_factory=list)

    def row(self, reference_mean: float | None) -> str:
        t = np.asarray(self.times) * 1e3
        ratio = f"{t.mean() / reference_mean:.3f}" if reference_mean else "-"
        return (
            f"| {self.name} | {len(t)} | {100 * np.mean(self.success):.2f} | "
            f"{100 * np.mean(self.own_success):.2f} | {t.mean():.3f} | {np.median(t):.3f} | "
            f"{np.percentile(t, 95):.3f} | {ratio} |"
        )


HEADER = (
    "| solver | n | success % | own success % | mean ms | median ms | p95 ms | mean / TRAC-IK mean |\n"
    "|---|--:|--:|--:|--:|--:|--:|--:|"
)


def _optik_solver(
    m: optik.Mechanism, method: str, q0: np.ndarray, limit: float, tol: float, **options: object
) -> Solver:
    def solve(target: np.ndarray) -> tuple[np.ndarray | None, bool]:
        res = optik.solve_ik(m, target, q0, method=method, time_limit=limit, tol=tol, **options)
        return res.q, res.success

    return solve


def _tracik_solver(path: str, base: str, tip: str, q0: np.ndarray, limit: float, tol: float) -> Solver:
    from trac_ik import TracIK

    ik = TracIK(base, tip, path, timeout=limit, epsilon=tol, solver_type="Speed")

    def solve(target: np.ndarray) -> tuple[np.ndarray | None, bool]:
        q = ik.ik(target[:3, 3], target[:3, :3], q0)
        return (None, False) if q is None else (np.asarray(q, dtype=float), True)

    return solve


def run(
    n: int = 10000,
    time_limit: float = 0.005,
    tol: float = 1e-5,
    methods: Sequence[str] = ("lm", "nlp", "nlp-sqp", "tracik"),
    n_nlp: int = 1000,
    nlp_time_limit: float = 0.3,
    seed: int = 0,
) -> dict[str, Record]:
    """Run the benchmark and return the records by solver label."""
    path = str(urdf_path("panda"))
    base, tip = URDF_CHAINS["panda"]
    m = optik.Mechanism.from_urdf(path, base, tip)
    q0 = m.mid_q()
    targets = m.fk(m.random_q(n, seed=seed))
    solvers: dict[str, tuple[Solver, int]] = {}
    for name in methods:
        if name == "tracik":
            solvers["TRAC-IK (Speed)"] = (_tracik_solver(path, base, tip, q0, time_limit, tol), n)
        elif name in ("nlp", "nlp-sqp"):
            solver = "ipopt" if name == "nlp" else "sqpmethod"
            label = f"optik nlp {solver} ({nlp_time_limit * 1e3:g} ms)"
            nlp = _optik_solver(m, "nlp", q0, nlp_time_limit, tol, solver=solver)
            solvers[label] = (nlp, min(n, n_nlp))
        else:
            solvers[f"optik {name}"] = (_optik_solver(m, name, q0, time_limit, tol), n)
    for solve, _ in solvers.values():  # build and compile once, outside the timings
        solve(targets[0])
    native.wait()  # the C libraries built in the background: time the compiled code
    records = {label: Record(label) for label in solvers}
    tolerances = optik.Tolerances(position=tol, orientation=tol)
    for i, target in enumerate(targets):
        for label, (solve, count) in solvers.items():
            if i >= count:
                continue
            t0 = time.perf_counter()
            q, own = solve(target)
            records[label].times.append(time.perf_counter() - t0)
            ok = q is not None and evaluate(m, q, target, "pose", None).ok(tolerances)
            records[label].success.append(bool(ok))
            records[label].own_success.append(bool(own))
    return records


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point (also called by the ``optik`` CLI)."""
    p = benchmark_parser("ik", __doc__)
    p.add_argument("--n", type=int, default=10000, help="number of targets")
    p.add_argument("--time-limit", type=float, default=0.005, help="time limit per call (s)")
    p.add_argument("--tol", type=float, default=1e-5, help="position / orientation tolerance")
    p.add_argument(
        "--methods",
        default="lm,nlp,nlp-sqp,tracik",
        help="comma list of lm, nlp (IPOPT), nlp-sqp (sqpmethod), tracik, and any registered method",
    )
    p.add_argument("--n-nlp", type=int, default=1000, help="targets for the (slower) nlp method")
    p.add_argument("--nlp-time-limit", type=float, default=0.3, help="time limit of nlp calls (s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    args = p.parse_args(argv)
    methods = [s.strip() for s in args.methods.split(",") if s.strip()]
    if "tracik" in methods:
        try:
            import trac_ik  # noqa: F401
        except ImportError:
            print('pytracik is not installed (pip install "optik[peers]"): TRAC-IK skipped')
            methods.remove("tracik")
    records = run(args.n, args.time_limit, args.tol, methods, args.n_nlp, args.nlp_time_limit, args.seed)
    ref = next((r for label, r in records.items() if label.startswith("TRAC-IK")), None)
    ref_mean = float(np.mean(ref.times)) * 1e3 if ref else None
    print(
        f"Panda (URDF), {args.n} random targets within limits, mid-limit seed, time limit "
        f"{args.time_limit * 1e3:g} ms, tol {args.tol:g} (same check for every solver)"
    )
    print(HEADER)
    for r in records.values():
        print(r.row(ref_mean))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
