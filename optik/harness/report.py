"""Benchmark outputs: console table, JSON, CSV, Markdown report and PNG charts, written atomically.

Files written into the output directory (each through a temporary file and ``os.replace``):

* ``results.json``: run metadata, per problem the targets, the summary of every contender,
  the notes, and every call (time, success, errors, closed-form distance, status);
* ``results.csv``: one row per (problem, contender) with the summary columns;
* ``report.md``: the tables and notes as Markdown, with the charts;
* ``<problem>.png``: success rate vs median time (p5-p95 bars) and the distribution of the
  final errors, per contender.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import platform
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from optik.harness.contenders import ProblemRun
from optik.plot import save_figure, write_atomic
from optik.problem_files import problem_summary

__all__ = ["COLUMNS", "coinciding", "format_table", "machine_info", "write_outputs"]

COLUMNS = (
    ("solver", "solver", "{}"),
    ("success_pct", "success %", "{:.1f}"),
    ("mean_ms", "mean ms", "{:.3g}"),
    ("median_ms", "median ms", "{:.3g}"),
    ("p95_ms", "p95 ms", "{:.3g}"),
    ("ratio", "x fastest", "{:.2f}"),
    ("overshoot_max", "max overshoot", "{:.1e}"),
    ("cf_err_max", "max err vs cf", "{:.1e}"),
    ("branch_pct", "cf branch %", "{:.0f}"),
    ("ref_branch_pct", "ref branch %", "{:.0f}"),
)
"""Summary columns of the tables: key, header, format."""

CSV_KEYS = (
    "problem",
    "solver",
    "kind",
    "n",
    "success_pct",
    "mean_ms",
    "median_ms",
    "p95_ms",
    "max_ms",
    "ratio",
    "overshoot_max",
    "cf_err_median",
    "cf_err_max",
    "branch_pct",
    "ref_branch_pct",
    "time_limit_s",
)


def _fmt(value: Any, pattern: str) -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return "-"
    return pattern.format(value)


def _rows(run: ProblemRun) -> list[list[str]]:
    return [[_fmt(s[key], pat) for key, _, pat in COLUMNS] for s in run.summary()]


def _heading(run: ProblemRun) -> str:
    t = run.targets
    drawn = f"{len(t)} targets ({t.sampling} sampling, task {t.task})" if t is not None else "no targets"
    return f"{run.problem.name}: {run.problem.description}. {drawn}, time limit {run.time_limit:g} s per call"


def _align(cells: Sequence[str], widths: Sequence[int]) -> str:
    """First cell left-aligned, the others right-aligned."""
    return "  ".join(
        c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(cells, widths, strict=True))
    )


def _write_text(path: Path, text: str) -> Path:
    return write_atomic(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def format_table(run: ProblemRun) -> str:
    """The problem's summary as a fixed-width text table (with its notes)."""
    lines = [_heading(run)]
    rows = _rows(run)
    if rows:
        headers = [h for _, h, _ in COLUMNS]
        widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
        lines.append(_align(headers, widths))
        lines.append("  ".join("-" * w for w in widths))
        lines += [_align(r, widths) for r in rows]
    lines += [f"  note: {n}" for n in run.notes]
    return "\n".join(lines)


def machine_info() -> dict[str, Any]:
    """Python, platform, CPU count and library versions, for the report header."""
    import casadi

    import optik

    return {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        "optik": optik.__version__,
        "numpy": np.__version__,
        "casadi": casadi.__version__,
    }


def _clean(x: Any) -> Any:
    """JSON-safe values: NaN/inf -> None, numpy scalars/arrays -> Python."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    return x


def _problem_json(run: ProblemRun) -> dict[str, Any]:
    t = run.targets
    return {
        "problem": problem_summary(run.problem),
        "time_limit_s": run.time_limit,
        "elapsed_s": run.elapsed,
        "targets": None
        if t is None
        else {"n": len(t), "sampling": t.sampling, "task": t.task, "draws": t.draws},
        "summary": run.summary(),
        "notes": run.notes,
        "calls": {
            r.name: {
                key: [getattr(c, key) for c in r.calls]
                for key in (
                    "time",
                    "success",
                    "position_error",
                    "orientation_error",
                    "closure_error",
                    "limits_ok",
                    "cf_distance",
                    "ref_distance",
                    "status",
                    "overshoot",
                )
            }
            for r in run.runs
        },
    }


def _markdown(runs: Sequence[ProblemRun], meta: dict[str, Any], charts: dict[str, str]) -> str:
    out = [
        "# optik benchmark report",
        "",
        f"Command: `{meta['command']}`, {meta['date']}, {meta['elapsed_s']:.0f} s in total.",
        f"Machine: {meta['machine']['platform']}, {meta['machine']['cpus']} CPUs, Python "
        f"{meta['machine']['python']}, CasADi {meta['machine']['casadi']}, optik {meta['machine']['optik']}.",
        "",
        "Method: targets are poses of random joint vectors within limits (loop closures satisfied); "
        "every solver starts at the mid-limit configuration, with the same time limit and tolerances; "
        "every call is timed, failures included (one untimed warm-up call per solver). "
        "`x fastest`: median time over the fastest median among solvers with a success. "
        "Every answer is clipped into the limits before it is judged (optik's `solve_ik` clips its own); "
        "`max overshoot`: how far the raw answer was outside the limits (0 for optik, already clipped). "
        "Where the problem has a URDF, every success is re-checked by Pinocchio's FK. "
        "`max err vs cf`: largest joint distance of a successful answer to the nearest closed-form branch; "
        "`cf branch %` / `ref branch %`: successes on a closed-form branch / on the branch the target "
        "was drawn from (distance < 1e-4).",
        "",
    ]
    headers = [h for _, h, _ in COLUMNS]
    for run in runs:
        out += [f"## {run.problem.name}", "", _heading(run) + ".", ""]
        rows = _rows(run)
        if rows:
            out.append("| " + " | ".join(headers) + " |")
            out.append("|" + "|".join("---" if i == 0 else "---:" for i in range(len(headers))) + "|")
            out += ["| " + " | ".join(r) + " |" for r in rows]
            out.append("")
        out += [f"- note: {n}" for n in run.notes]
        if run.notes:
            out.append("")
        if run.problem.name in charts:
            out += [f"![{run.problem.name}]({charts[run.problem.name]})", ""]
    return "\n".join(out)


def coinciding(
    points: Sequence[tuple[float, float]], dx: float = 0.04, dy: float = 3.0
) -> list[tuple[int, int]]:
    """For each ``(log10 time, success %)`` point of a chart, ``(rank, size)``: its place among
    the points that coincide with it on the chart (within ``dx`` decades and ``dy`` %, linked
    transitively) and how many those are; a point alone is ``(0, 1)``."""
    group = list(range(len(points)))
    for i, (xi, yi) in enumerate(points):
        for j in range(i):
            xj, yj = points[j]
            if abs(xi - xj) <= dx and abs(yi - yj) <= dy:
                old, new = group[i], group[j]
                group = [new if g == old else g for g in group]
    out = []
    for i, g in enumerate(group):
        members = [k for k, h in enumerate(group) if h == g]
        out.append((members.index(i), len(members)))
    return out


def _chart(run: ProblemRun) -> Figure:
    """Success vs median time (p5-p95 bars, log scale) and the final-error distributions.
    Contenders that land on the same spot are drawn as concentric markers (the first the
    largest) with their names stacked beside them, so that none hides another."""
    fig = Figure(figsize=(10, 4), layout="constrained")
    fig.suptitle(f"{run.problem.name}: {len(run.targets or [])} targets, {run.time_limit:g} s limit")
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    names, errors, spots = [], [], []
    for r in run.runs:
        t = 1e3 * np.array([c.time for c in r.calls])
        spots.append(
            (float(np.log10(max(np.median(t), 1e-12))), 100.0 * float(np.mean([c.success for c in r.calls])))
        )
    places = coinciding(spots)
    for i, r in enumerate(run.runs):
        t = 1e3 * np.array([c.time for c in r.calls])
        ok = spots[i][1]
        med, lo, hi = np.median(t), np.percentile(t, 5), np.percentile(t, 95)
        color = f"C{i % 10}"
        rank, size = places[i]
        ax1.errorbar(
            [med],
            [ok],
            xerr=[[med - lo], [hi - med]],
            fmt="o" if r.kind == "method" else "s",
            markersize=6 + 6 * (size - 1 - rank),
            color=color,
            capsize=3,
            label=r.name,
            zorder=2 + rank,
        )
        if size > 1:  # names stacked below the spot (above it near 0 %)
            step = -10 if ok > 50 else 10
            ax1.annotate(
                r.name,
                (med, ok),
                xytext=(8, step * (rank + 1)),
                textcoords="offset points",
                fontsize=7,
                color=color,
            )
        names.append(r.name)
        e = np.array([max(c.position_error, c.orientation_error, c.closure_error) for c in r.calls])
        errors.append(np.log10(np.maximum(e, 1e-16)))
    ax1.set_xscale("log")
    ax1.set_xlabel("time per call [ms] (median, p5-p95)")
    ax1.set_ylabel("success [%]")
    ax1.set_ylim(-5, 105)
    ax1.set_title("success vs time", fontsize=9)
    ax1.grid(True, which="both", alpha=0.3)
    if names:
        ax1.legend(fontsize=8, loc="lower left")
        ax2.boxplot(errors, tick_labels=names, showfliers=True)
        tol = max(run.problem.tolerances.position, run.problem.tolerances.orientation)
        ax2.axhline(np.log10(tol), color="tab:red", ls="--", lw=1, label="tolerance")
        ax2.legend(fontsize=8)
    ax2.set_ylabel("log10 final error")
    ax2.set_title("max(position, orientation, closure) error per call", fontsize=9)
    ax2.tick_params(axis="x", labelrotation=30)
    return fig


def write_outputs(
    runs: Sequence[ProblemRun], out_dir: str | os.PathLike[str], meta: dict[str, Any]
) -> list[Path]:
    """Write JSON, CSV, Markdown and charts atomically into ``out_dir`` (created when missing).

    Args:
        runs: the problem results.
        out_dir: output directory.
        meta: run metadata (``command``, ``date``, ``elapsed_s``, ``machine``, ...).

    Returns:
        The paths written.
    """
    d = Path(out_dir)
    written: list[Path] = []
    charts: dict[str, str] = {}
    for run in runs:
        if run.runs:
            name = f"{run.problem.name}.png"
            written.append(save_figure(_chart(run), d / name))
            charts[run.problem.name] = name
    payload = _clean({"meta": meta, "problems": [_problem_json(r) for r in runs]})
    text = json.dumps(payload, indent=1, allow_nan=False)
    written.append(_write_text(d / "results.json", text))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=CSV_KEYS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for run in runs:
        for s in run.summary():
            writer.writerow({**_clean(s), "problem": run.problem.name, "time_limit_s": run.time_limit})
    written.append(_write_text(d / "results.csv", buf.getvalue()))
    written.append(_write_text(d / "report.md", _markdown(runs, meta, charts)))
    return written
