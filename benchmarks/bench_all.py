"""Every benchmark the README and the docs quote, in one sitting on one machine, written as Markdown.

``optik benchmark all --out DIR`` runs the benchmarks of `RUNS` one after the other, each in a
fresh Python process (``python -m optik.benchmarks.bench_NAME``) whose BLAS and OpenMP thread
pools are pinned to one thread through the environment (`optik.benchmarks.PINNED`, as for a
single ``optik benchmark NAME``), with full settings or the smaller ``--quick`` ones; an
argument ``{out}`` is the folder ``DIR`` (a figure written beside the tables); it captures what
each prints and writes:

* ``DIR/KEY.md`` per run (``KEY``: the benchmark's name, or `Run.page` for a benchmark run
  twice): a header with the date (UTC), the commit of the source tree
  (``git describe``; ``+ uncommitted changes`` when the tree differs from it), the machine
  (platform, CPU count, Python), the load average before and after, the exact command, and the
  benchmark's own output (its tables are Markdown);
* ``DIR/index.md``: the same header for the whole sitting and the headline table of every
  benchmark (the table and rows named in `RUNS`), each under its command and a link to its file.

With ``--readme FILE`` the text between the markers ``<!-- measured:start -->`` and
``<!-- measured:end -->`` of ``FILE`` is replaced by that headline section (links made relative
to ``FILE``), so that the README's "Measured" section is generated, never hand-copied. Every file
is written atomically (a temporary file in the same folder, then ``os.replace``).

Run: ``optik benchmark all --out docs/measured [--quick] [--only ik,batch] [--readme README.md]
[--fksgp DIR] [--pyroki DIR]``. ``--only`` takes benchmark names or page names (``balance`` selects both of
its pages, ``balance_go2`` one). How long a sitting takes is in docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from optik import benchmarks, plot

__all__ = ["RUNS", "Run", "headline", "main", "markdown_tables", "replace_between_markers"]

START, END = "<!-- measured:start -->", "<!-- measured:end -->"


@dataclass(frozen=True)
class Run:
    """One benchmark of the sitting.

    Attributes:
        name: ``optik benchmark NAME``.
        title: what it measures (the headline's title).
        full, quick: its arguments in a full and in a quick sitting.
        table: which Markdown table of its output is the headline (0: the first).
        rows: keep only the rows containing one of these strings (empty: every row).
        page: the generated page ``DIR/PAGE.md`` (empty: ``NAME``), for a benchmark run twice
            with different arguments.
        in_readme: its headline goes into the README's section too (else only into
            ``DIR/index.md``; the docs pages that quote it link to its page).
    """

    name: str
    title: str
    full: tuple[str, ...]
    quick: tuple[str, ...]
    table: int = 0
    rows: tuple[str, ...] = field(default_factory=tuple)
    page: str = ""
    in_readme: bool = True

    @property
    def key(self) -> str:
        """The page's name (``DIR/KEY.md``) and the name ``--only`` selects it by."""
        return self.page or self.name


COUNTS_PLOT = ("--plot", "{out}/general_6r_counts.png")
"""The general 6R page's histogram of real-solution counts, drawn beside the tables."""

RUNS: tuple[Run, ...] = (
    Run(
        "ik",
        "Single IK, Panda and iiwa14 (URDF), against TRAC-IK and the Robotics Toolbox's C++ ik_LM",
        ("--n", "3000", "--n-nlp", "300"),
        ("--n", "300", "--n-nlp", "30"),
    ),
    Run(
        "ik",
        "Iterated differential IK as position IK (dls, qp) beside lm and TRAC-IK, Panda",
        ("--robots", "panda", "--methods", "lm,dls,qp,trac_ik", "--n", "300"),
        ("--robots", "panda", "--methods", "lm,dls,qp,trac_ik", "--n", "30"),
        page="ik_diffik",
        in_readme=False,
    ),
    Run(
        "batch",
        "Batch IK, Panda: solve_ik_batch against TRAC-IK on 1 core and on as many cores",
        ("--n", "20000", "--block", "2000", "--n-check", "300", "--n-dask", "10000"),
        ("--n", "2000", "--block", "500", "--n-check", "50", "--n-dask", "0"),
    ),
    Run(
        "all_solutions",
        "All IK solutions of 6-axis arms, against EAIK and ik-geo",
        ("--n", "2000"),
        ("--n", "30"),
    ),
    Run(
        "robots",
        "34 arms of example-robot-data, against TRAC-IK (FK checked against Pinocchio)",
        ("--n", "50"),
        ("--n", "5", "--fk", "10"),
        rows=("| all ",),
    ),
    Run(
        "parallel_fk",
        "Stewart-Gough FK, every real posture of random general 6-6 platforms, against fkSGP",
        ("--n-rpr", "200", "--n-sg", "100", "--n-total", "50", "--n-catalog", "5", "--n-fk", "50"),
        (
            "--n-rpr",
            "20",
            "--n-sg",
            "10",
            "--n-total",
            "5",
            "--heavy",
            "1",
            "--n-catalog",
            "1",
            "--n-fk",
            "5",
        ),
        table=2,
    ),
    Run(
        "diffik",
        "Differential IK step, Panda (frame + posture tasks, limits), against Pink",
        (
            "--goals",
            "20",
        ),
        ("--goals", "3", "--steps", "100"),
    ),
    Run(
        "first_solve",
        "First solve on a never-compiled robot (fresh processes, fresh cache), against TRAC-IK and Pink",
        ("--reps", "9"),
        ("--reps", "1"),
    ),
    Run(
        "closed_form",
        "Vectorized closed forms (2R, 3R, 6R), one core",
        ("--n", "1000000", "--n-6r", "200000", "--repeat", "3"),
        ("--n", "100000", "--n-6r", "20000", "--repeat", "2", "--verify", "2000"),
    ),
    Run(
        "path",
        "Cartesian paths, UR5 and PUMA 560: plan_path against brute force over EAIK and diffik.track",
        ("--n", "1000", "--repeat", "3"),
        ("--n", "200", "--repeat", "1"),
    ),
    Run(
        "view",
        "Viewer: IK re-solve per gizmo move",
        (
            "--moves",
            "200",
        ),
        (
            "--moves",
            "20",
        ),
    ),
    Run(
        "general_6r",
        "General 6R arms, all solutions: the eigenvalue solver against ik-geo and multi-start lm",
        ("--arms", "200", "--poses", "5", "--multistart-arms", "20", "--special", "20", *COUNTS_PLOT),
        ("--arms", "10", "--poses", "2", "--multistart-arms", "2", "--special", "2", *COUNTS_PLOT),
        in_readme=False,
    ),
    Run(
        "search_1d",
        "6R arms special at one or both ends: the 1-D search against the general 6R solver and ik-geo",
        ("--arms", "5", "--poses", "20", "--geometries", "all"),  # 100 targets per geometry
        ("--arms", "2", "--poses", "5", "--geometries", "all"),
        in_readme=False,
    ),
    Run(
        "two_hands",
        "Dual Panda, both hands at once: optik's solvers against Pink",
        ("--n", "200"),
        ("--n", "20"),
        in_readme=False,
    ),
    Run(
        "balance",
        "Whole-body IK with balance, Unitree G1 hand reach: optik lm and nlp against Pink",
        ("--n", "50"),
        ("--n", "5"),
        page="balance_g1",
        in_readme=False,
    ),
    Run(
        "balance",
        "Whole-body IK with balance, Unitree Go2 base pose: optik lm and nlp against Pink",
        ("--robot", "go2", "--n", "50"),
        ("--robot", "go2", "--n", "5"),
        page="balance_go2",
        in_readme=False,
    ),
    Run(
        "collision",
        "Collision-free IK, Panda in clutter: optik against TRAC-IK + coal rejection",
        ("--n", "1000", "--time-limit", "0.01"),
        ("--n", "10", "--time-limit", "0.01", "--compile-wait", "30"),
        in_readme=False,
    ),
    Run(
        "collision_self",
        "Self-collision-free IK near the robot's own body, dual Panda and TALOS: optik against "
        "TRAC-IK + coal rejection",
        ("--n", "100", "--time-limit", "0.05"),
        ("--n", "10", "--time-limit", "0.05", "--compile-wait", "30"),
        in_readme=False,
    ),
    Run(
        "collision_qp",
        "QP differential IK past an obstacle, Panda: optik's dampers and Pink's collision barrier, same path",
        ("--steps", "200", "--repeats", "3"),
        ("--steps", "50", "--repeats", "1"),
        in_readme=False,
    ),
    Run(
        "mjcf_fk",
        "MJCF models: optik's FK against MuJoCo's mj_kinematics",
        ("--n", "200"),
        ("--n", "20", "--max-models", "5"),
        in_readme=False,
    ),
    Run(
        "time_limits",
        "Time limits: how far past its time_limit each solver returns",
        ("--calls", "1000"),
        ("--calls", "20"),
        in_readme=False,
    ),
)
"""The benchmarks the README and the docs quote, in the order they run."""


def load_average() -> str:
    """The 1, 5 and 15 minute load averages (``/proc/loadavg``), or ``"n/a"``."""
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "n/a"


def source_commit() -> str:
    """``git describe --always --dirty`` of the source tree of this file, or why there is none."""
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(
            ["git", "describe", "--always", "--dirty=+ uncommitted changes"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
    except (OSError, subprocess.SubprocessError):
        import optik

        return f"not a git checkout (optik {optik.__version__})"
    return out.stdout.strip()


def machine() -> str:
    """Platform, CPU count and Python version."""
    return f"{platform.platform()}, {os.cpu_count()} CPUs, Python {sys.version.split()[0]}"


def markdown_tables(text: str) -> list[list[str]]:
    """The Markdown tables of ``text``: runs of lines starting with ``|`` (header and separator
    included) up to a blank line; other lines inside a table (a library's message printed between
    two rows) are left out of it."""
    tables: list[list[str]] = []
    current: list[str] = []
    for line in text.splitlines():
        if line.startswith("|"):
            current.append(line.rstrip())
        elif current and not line.strip():
            tables.append(current)
            current = []
    if current:
        tables.append(current)
    return [t for t in tables if len(t) >= 2 and SEPARATOR.fullmatch(t[1])]


def headline(run: Run, output: str) -> list[str]:
    """The headline table of one benchmark's output (``run.table``, rows filtered by ``run.rows``),
    or a line saying it printed none."""
    tables = markdown_tables(output)
    if run.table >= len(tables):
        return [f"(no table {run.table} in the output: see the full output)"]
    table = tables[run.table]
    body = [r for r in table[2:] if not run.rows or any(s in r for s in run.rows)]
    return table[:2] + body


def replace_between_markers(text: str, section: str) -> str:
    """``text`` with everything between `START` and `END` replaced by ``section``.

    Raises:
        ValueError: the markers are missing or out of order.
    """
    a, b = text.find(START), text.find(END)
    if a < 0 or b < a:
        raise ValueError(f"the markers {START} and {END} are missing or out of order")
    return text[: a + len(START)] + "\n" + section.rstrip() + "\n" + text[b:]


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically with the mode a plain write would give it
    (`optik.plot.write_atomic`: temporary file in the same folder, then ``os.replace``)."""
    plot.write_atomic(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


@dataclass
class Outcome:
    """What one benchmark printed and how it went."""

    run: Run
    command: str
    output: str
    code: int
    seconds: float
    load_before: str
    load_after: str
    started: str


def run_one(run: Run, argv: Sequence[str]) -> Outcome:
    """Run one benchmark in a fresh process, its standard output captured (its standard error
    passes through; a crash is its output and exit code)."""
    command = " ".join(["optik benchmark", run.name, *argv])
    started = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    before = load_average()
    t0 = time.perf_counter()
    proc = subprocess.run(
        benchmarks.command(run.name, argv),
        stdout=subprocess.PIPE,
        text=True,
        env=benchmarks.pinned_environment(),
        check=False,
    )
    seconds = time.perf_counter() - t0
    return Outcome(run, command, proc.stdout, proc.returncode, seconds, before, load_average(), started)


def _header(o: Outcome, commit: str) -> str:
    return (
        f"Run {o.started}, commit `{commit}`, {machine()}; load average {o.load_before} before, "
        f"{o.load_after} after; {o.seconds:.0f} s; exit code {o.code}; BLAS/OpenMP pinned to 1 thread."
        f"\n\nCommand: `{o.command}`\n"
    )


SEPARATOR = re.compile(r"\|[\s:|-]+\|?")
"""A Markdown table's separator row (``|---|--:|``)."""


def spaced_tables(text: str) -> str:
    """``text`` with a blank line before every table header (a ``|`` line followed by a separator
    row) that follows a line of text: Markdown renders a table only as a block of its own, and the
    benchmarks print a table's caption right above it."""
    lines = text.splitlines()
    out: list[str] = []
    for i, line in enumerate(lines):
        header = line.startswith("|") and i + 1 < len(lines) and SEPARATOR.fullmatch(lines[i + 1].strip())
        if header and out and out[-1].strip():
            out.append("")
        out.append(line)
    return "\n".join(out)


def page(o: Outcome, commit: str) -> str:
    """The generated page of one benchmark (its output with `spaced_tables`)."""
    return (
        f"# {o.run.title}\n\n<!-- generated by `optik benchmark all`; do not edit -->\n\n"
        f"{_header(o, commit)}\n{spaced_tables(o.output.rstrip())}\n"
    )


HEADER = re.compile(
    r"^Run (?P<started>[^,]+), commit `(?P<commit>[^`]*)`, (?P<machine>[^;]+); load average "
    r"(?P<before>[^;]+?) before, (?P<after>[^;]+?) after; (?P<seconds>\d+) s; exit code (?P<code>-?\d+)",
    re.MULTILINE,
)
"""The header line `page` writes."""


@dataclass(frozen=True)
class Entry:
    """One generated page read back: its run, the header's fields and the benchmark's output."""

    run: Run
    command: str
    started: str
    commit: str
    machine: str
    load_before: str
    load_after: str
    seconds: int
    code: int
    output: str


def read_page(run: Run, text: str) -> Entry | None:
    """The `Entry` of a page `page` wrote, or None for a page of another form (hand-made, damaged)."""
    head, command = HEADER.search(text), re.search(r"^Command: `([^`]*)`$", text, re.MULTILINE)
    if head is None or command is None:
        return None
    return Entry(
        run,
        command.group(1),
        head["started"],
        head["commit"],
        head["machine"],
        head["before"],
        head["after"],
        int(head["seconds"]),
        int(head["code"]),
        text[command.end() :],
    )


def read_pages(folder: Path, runs: Sequence[Run] = RUNS) -> list[Entry]:
    """The entries of every run of ``runs`` whose page ``folder/KEY.md`` exists and reads back,
    in the order of ``runs``; a page that does not read back is left out with a warning."""
    entries = []
    for run in runs:
        path = folder / f"{run.key}.md"
        if not path.is_file():
            continue
        entry = read_page(run, path.read_text(encoding="utf-8"))
        if entry is None:
            print(f"warning: {path} does not read back as a generated page: left out", file=sys.stderr)
        else:
            entries.append(entry)
    return entries


def summary(entries: Sequence[Entry], command: str, link_prefix: str) -> str:
    """The headline section: the command that wrote it and the machine, then per page its title,
    command, link (``link_prefix + KEY.md``), run (date, commit, load average before and after)
    and headline table. The pages may come from several sittings (``--only``): each says its own."""
    machines = sorted({e.machine for e in entries})
    where = f" on {machines[0]}" if len(machines) == 1 else ""
    lines = [
        f"Generated by `{command}`{where}: the headline of every page of the folder, each page "
        "with its own run (a sitting with `--only` rewrites only its pages). Every peer gets what "
        "optik gets (the rules of `optik.harness.peers.rules`); success is re-checked by one independent FK. "
        f"The {len(entries)} runs took {sum(e.seconds for e in entries)} s together.",
        "",
    ]
    for e in entries:
        machine_note = f", {e.machine}" if len(machines) > 1 else ""
        failed = f"; exit code {e.code}" if e.code else ""
        lines += [
            f"**{e.run.title}**: `{e.command}` ([full output]({link_prefix}{e.run.key}.md)); run "
            f"{e.started}, commit `{e.commit}`{machine_note}, load average {e.load_before} before, "
            f"{e.load_after} after, {e.seconds} s{failed}",
            "",
            *headline(e.run, e.output),
            "",
        ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point (``optik benchmark all``); exit code 1 when a benchmark failed."""
    ap = argparse.ArgumentParser(prog="optik benchmark all", description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="folder of the generated Markdown files")
    ap.add_argument("--quick", action="store_true", help="the smaller settings of every benchmark")
    ap.add_argument("--only", help="comma list of benchmark names (default: all of them)")
    ap.add_argument("--readme", type=Path, help="replace this file's measured section (between the markers)")
    ap.add_argument("--fksgp", help="folder of a fkSGP checkout, passed to parallel_fk")
    ap.add_argument("--pyroki", help="folder of a PyRoki checkout, passed to batch")
    args = ap.parse_args(argv)
    names = sorted({r.name for r in RUNS} | {r.key for r in RUNS})
    only = names if not args.only else [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = sorted(set(only) - set(names))
    if unknown:
        ap.error(f"unknown benchmark(s) {unknown}; known: {', '.join(names)}")
    if args.readme is not None and not args.readme.is_file():
        ap.error(f"--readme {args.readme}: no such file")
    command = " ".join(["optik benchmark all", *(argv if argv is not None else sys.argv[1:])])
    commit = source_commit()
    outcomes = []
    started = time.perf_counter()
    for run in RUNS:
        if run.name not in only and run.key not in only:
            continue
        peers = {"parallel_fk": ("--fksgp", args.fksgp), "batch": ("--pyroki", args.pyroki)}
        extra = peers[run.name] if run.name in peers and peers[run.name][1] else ()
        settings = [a.format(out=args.out) for a in (run.quick if args.quick else run.full)]
        outcome = run_one(run, [*settings, *extra])
        write_atomic(args.out / f"{run.key}.md", page(outcome, commit))
        print(f"{run.key}: exit code {outcome.code}, {outcome.seconds:.0f} s", flush=True)
        outcomes.append(outcome)
    print(f"the sitting took {time.perf_counter() - started:.0f} s", flush=True)
    entries = read_pages(args.out)
    write_atomic(
        args.out / "index.md",
        "# Measured\n\n<!-- generated by `optik benchmark all`; do not edit -->\n\n"
        + summary(entries, command, ""),
    )
    if args.readme is not None:
        prefix = os.path.relpath(args.out.resolve(), args.readme.resolve().parent).replace(os.sep, "/") + "/"
        text = args.readme.read_text(encoding="utf-8")
        quoted = [e for e in entries if e.run.in_readme]
        write_atomic(args.readme, replace_between_markers(text, summary(quoted, command, prefix)))
    print(f"wrote {len(outcomes) + 1} files into {args.out}")
    return 0 if all(o.code == 0 for o in outcomes) else 1


if __name__ == "__main__":
    raise SystemExit(main())
