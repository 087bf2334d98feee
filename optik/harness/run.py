"""``optik bench`` as a function: pick problems and solvers, run, print tables, write the files."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import TextIO

from optik.errors import InvalidArgumentError
from optik.harness.contenders import ProblemRun, known_solvers, run_problems
from optik.harness.report import format_table, machine_info, write_outputs
from optik.problem_files import Problem, default_problems, find_problem
from optik.progress import Progress

__all__ = ["BenchOutcome", "run_bench", "select_problems"]


@dataclass(frozen=True)
class BenchOutcome:
    """What [`run_bench`][optik.harness.run.run_bench] did: the problem results and the files it wrote."""

    runs: list[ProblemRun]
    files: list[Path]
    elapsed: float


def select_problems(names: Sequence[str] | None, directory: str | Path | None = None) -> list[Problem]:
    """The named problems (names or ``.toml`` paths), or the default set when ``names`` is empty."""
    if not names:
        return default_problems(directory)
    return [find_problem(n, directory) for n in names]


def run_bench(
    problems: Sequence[str] | None = None,
    solvers: Sequence[str] | None = None,
    n: int | None = None,
    quick: bool = False,
    out: str | Path = "bench-out",
    time_limit: float | None = None,
    problem_dir: str | Path | None = None,
    stream: TextIO | None = None,
    progress: bool = True,
    command: str = "optik bench",
) -> BenchOutcome:
    """Run the benchmark and write JSON, CSV, Markdown and PNG charts into ``out``.

    Args:
        problems: problem names or files (default: every problem with ``default = true``).
        solvers: restrict to these method / peer names (default: all that apply).
        n: targets per problem (default: the file's ``n``, or ``quick_n`` with ``quick``).
        quick: the quick settings of every file (fewer targets, shorter time limits).
        out: output directory.
        time_limit: seconds per IK call (default: from the files).
        problem_dir: where named problems are looked up (default: the shipped ``problems/``).
        stream: where tables go (default stdout); the progress bar goes to stderr.
        progress: show the progress bar.
        command: the command line, recorded in the report.

    Raises:
        InvalidArgumentError: unknown problem or solver name, bad ``n`` or ``time_limit``.
        ProblemFileError: an invalid problem file.
    """
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
        raise InvalidArgumentError("n", f"expected a positive integer, got {n!r}")
    if time_limit is not None and not time_limit > 0:
        raise InvalidArgumentError("time_limit", f"must be > 0 seconds, got {time_limit}")
    known = known_solvers()
    unknown = [s for s in solvers or () if s not in known]
    if unknown:
        raise InvalidArgumentError("solvers", f"unknown solver(s) {unknown}; known: {known}")
    chosen = select_problems(problems, problem_dir)
    sink = sys.stdout if stream is None else stream
    bar = Progress(len(chosen)) if progress else None
    start = time.perf_counter()

    def show(run: ProblemRun) -> None:
        sink.write(format_table(run) + "\n\n")
        sink.flush()

    runs = run_problems(chosen, quick, n, time_limit, solvers, bar, on_done=show)
    elapsed = time.perf_counter() - start
    meta = {
        "command": command,
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "quick": quick,
        "elapsed_s": elapsed,
        "machine": machine_info(),
    }
    files = write_outputs(runs, out, meta)
    writing = time.perf_counter() - start - elapsed
    whole = process_seconds()
    total = f"; {whole:.1f} s since the command started (imports and start-up included)" if whole else ""
    sink.write(
        f"{len(runs)} problems: solved in {elapsed:.1f} s, tables and charts written in {writing:.1f} s"
        f"{total}; wrote {', '.join(str(f) for f in files)}\n"
    )
    return BenchOutcome(runs, files, elapsed)


def process_seconds() -> float | None:
    """Seconds since this process started (Linux: ``/proc/self/stat`` field 22 against
    ``/proc/uptime``, to the clock tick), or None where that is not known."""
    try:
        stat = Path("/proc/self/stat").read_text().rpartition(")")[2].split()
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return uptime - int(stat[19]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None
