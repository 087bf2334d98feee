"""Figure of the IK benchmark on the Panda: docs/img/ik_panda_times.png.

Run from the repository root: ``python docs/figures/ik.py [--n 1000]``. It runs
``optik.benchmarks.bench_ik.run`` (same method: URDF model, random targets within limits,
mid-limit seed, 5 ms limit for ``lm`` and TRAC-IK, 300 ms for the NLP variants, tolerance 1e-5)
and draws, per solver, the share of targets solved within a given time (empirical distribution
of the call time of the successful calls, failures counted as never solved): the curve's right
end is the success rate.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from optik.benchmarks import bench_ik
from optik.plot import save_figure

ROOT = Path(__file__).resolve().parents[2]


def figure(n: int) -> Figure:
    """Solved share against call time, one curve per solver."""
    records = bench_ik.run(n=n, methods=("lm", "nlp", "nlp-sqp", "tracik"), n_nlp=max(n // 5, 1))
    fig = Figure(figsize=(7.0, 4.2))
    ax = fig.add_subplot()
    for label, rec in records.items():
        t = np.asarray(rec.times) * 1e3
        ok = np.asarray(rec.success)
        solved = np.sort(t[ok])
        share = np.arange(1, len(solved) + 1) / len(t)
        ax.step(solved, 100 * share, where="post", label=f"{label}: {100 * ok.mean():.1f} % solved")
    ax.set_xscale("log")
    ax.set_xlabel("call time (ms)")
    ax.set_ylabel("targets solved within that time (%)")
    ax.set_title(f"Panda IK, {n} random targets, mid-limit seed, tol 1e-5")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return fig


def main(argv: list[str] | None = None) -> Path:
    """Write the figure into ``--out`` (default ``docs/img``) and return its path."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "img"))
    parser.add_argument("--n", type=int, default=1000)
    args = parser.parse_args(argv)
    path = save_figure(figure(args.n), Path(args.out) / "ik_panda_times.png")
    print(path)
    return path


if __name__ == "__main__":
    main()
