"""The ``optik`` command: ``bench``, ``solve``, ``fk`` and ``plot`` on the problem files, and
``benchmark`` for the focused benchmark scripts of `optik.benchmarks`.

Every problem subcommand takes a problem name (a file shipped in ``problems/``, or
of ``--problems-dir``) or the path of a ``.toml`` problem file, and has ``--help``. Bad arguments
give a one-line message naming the argument and exit code 2; unreachable targets and
non-assemblable inputs are normal outcomes (exit code 1 when nothing was solved). The
problem-set benchmark lives in [`optik.harness`][optik.harness]; ``optik benchmark NAME`` imports
``optik.benchmarks.bench_NAME`` and calls its ``main(argv)``.

Target and joint values are given as numbers, per task space of the problem:

| task | ``--target`` values |
|---|---|
| position2d | ``x y`` |
| pose2d | ``x y phi`` |
| position | ``x y z`` |
| orientation | ``roll pitch yaw`` |
| pose | ``x y z roll pitch yaw`` (``Rot(z, yaw) Rot(y, pitch) Rot(x, roll)``), or 16 numbers row by row |
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import textwrap
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

import matplotlib
import numpy as np
from matplotlib.figure import Figure

import optik
from optik import closed_form, spatial
from optik.errors import OptikError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.problem_files import Problem, add_problems_dir, find_problem

__all__ = ["build_parser", "main", "parse_target"]

PLOT_MODES = ("config", "branches", "assembly", "workspace", "all")


class UsageError(Exception):
    """A bad command-line argument: ``argument`` names the option."""

    def __init__(self, argument: str, message: str) -> None:
        super().__init__(f"argument {argument}: {message}")


def _problem(name: str, directory: str | None) -> Problem:
    try:
        return find_problem(name, directory)
    except OptikError as exc:
        raise _usage(exc) from None


def parse_target(task: str, values: Sequence[float]) -> np.ndarray:
    """The 4x4 target transform from command-line numbers (see the module docstring).

    Raises:
        UsageError: wrong number of values for the task.
    """
    v = np.asarray(values, dtype=float)
    expected = {"position2d": (2,), "pose2d": (3,), "position": (3,), "orientation": (3,), "pose": (6, 16)}
    if len(v) not in expected[task]:
        want = " or ".join(str(k) for k in expected[task])
        raise UsageError("--target", f"task {task!r} takes {want} numbers, got {len(v)}")
    if task == "position2d":
        return spatial.translation(v[0], v[1], 0.0)
    if task == "pose2d":
        return spatial.planar_pose(v[0], v[1], v[2])
    if task == "position":
        return spatial.translation(*v)
    if task == "orientation":
        return spatial.transform(spatial.rpy_to_rot(*v))
    if len(v) == 16:
        return v.reshape(4, 4)
    return spatial.transform(spatial.rpy_to_rot(v[3], v[4], v[5]), v[:3])


def _vector(values: Sequence[float] | None, size: int, argument: str, what: str) -> np.ndarray | None:
    if values is None:
        return None
    if len(values) != size:
        raise UsageError(argument, f"expected {size} values ({what}), got {len(values)}")
    return np.asarray(values, dtype=float)


def _fmt_q(m: Mechanism, q: np.ndarray) -> str:
    return "  ".join(f"{n}={v:+.6f}" for n, v in zip(m.coordinate_names, q, strict=True))


def _pose_text(m: Mechanism, t: np.ndarray, digits: int = 6) -> str:
    """``x y phi`` (planar) or ``x y z roll pitch yaw`` of a transform, for printing."""
    if m.planar:
        names, values = ("x", "y", "phi"), spatial.planar_pose_of(t)
    else:
        names, values = ("x", "y", "z", "roll", "pitch", "yaw"), [*t[:3, 3], *spatial.rot_to_rpy(t[:3, :3])]
    return "  ".join(f"{n}={float(v):+.{digits}f}" for n, v in zip(names, values, strict=True))


def _writable(path: Path | str | None, name: str, directory: bool = False) -> None:
    """Fail before the work when the output ``--plot`` / ``--out`` cannot be written."""
    from optik.plot import check_writable

    if path is not None:
        try:
            check_writable(path, name, directory)
        except OptikError as exc:
            raise _usage(exc) from None


def _save(fig: Figure, path: Path) -> Path:
    from optik.plot import save_figure

    written = save_figure(fig, path)
    print(f"wrote {written}")
    return written


ARGUMENTS = {
    "n": "--n",
    "time_limit": "--time-limit",
    "solvers": "--solvers",
    "target": "--target",
    "q0": "--q0",
    "q": "--q",
    "actuated": "--q",
    "method": "--method",
    "plot": "--plot",
    "out": "--out",
}
"""Library argument names -> command-line options, for error messages."""


def _usage(exc: OptikError) -> UsageError:
    """A [`UsageError`][optik.cli.UsageError] for a library error, naming the command-line option."""
    text = str(exc)
    prefix = f"{getattr(exc, 'argument', '')}: "
    return UsageError(_option(exc), text[len(prefix) :] if text.startswith(prefix) else text)


def _option(exc: OptikError) -> str:
    """The option an error is about: its ``argument`` mapped to the command line."""
    if isinstance(exc, SolverUnavailableError):
        return "--method"
    return ARGUMENTS.get(getattr(exc, "argument", ""), "PROBLEM")


# ---------------------------------------------------------------------------- bench
def _cmd_bench(args: argparse.Namespace) -> int:
    from optik.harness import run_bench

    solvers = [s for item in args.solvers or () for s in item.split(",") if s] or None
    _writable(args.out, "out", directory=True)
    try:
        outcome = run_bench(
            args.problem,
            solvers=solvers,
            n=args.n,
            quick=args.quick,
            out=args.out,
            time_limit=args.time_limit,
            problem_dir=args.problems_dir,
            progress=not args.no_progress,
            command="optik " + " ".join(shlex.quote(a) for a in args.argv),
        )
    except OptikError as exc:
        raise _usage(exc) from None
    return 0 if any(r.runs for r in outcome.runs) else 1


# ---------------------------------------------------------------------------- solve
def _cmd_solve(args: argparse.Namespace) -> int:
    _writable(args.plot, "plot")
    problem = _problem(args.problem, args.problems_dir)
    m = problem.mechanism()
    task = problem.mechanism_task
    target = parse_target(task, args.target)
    q0 = _vector(args.q0, m.n_q, "--q0", ", ".join(m.coordinate_names))
    try:
        if args.all:
            results = optik.solve_ik_all(
                m, target, q0, args.method, task=task, time_limit=args.time_limit, tol=problem.tolerances
            )
        else:
            results = [
                optik.solve_ik(
                    m, target, q0, args.method, task=task, time_limit=args.time_limit, tol=problem.tolerances
                )
            ]
    except OptikError as exc:
        raise _usage(exc) from None
    print(f"{problem.name}: IK of {_pose_text(m, target)} (task {task}, angles in rad)")
    for i, r in enumerate(results, 1):
        print(
            f"[{i}] {r.method}: success={r.success}  time={1e3 * r.solve_time:.3f} ms  "
            f"position error={r.position_error:.2e}  orientation error={r.orientation_error:.2e}  "
            f"closure={r.closure_error:.2e}"
        )
        print(f"    {_fmt_q(m, r.q)}")
        if not r.success and r.message:
            print(f"    {r.message}")
    if not results:
        print("no solution: the target is unreachable within the joint limits")
    if args.all:
        print(results.message)
    if args.plot and results:
        from optik.plot import draw_branches

        _save(draw_branches(m, [r.q for r in results], title=f"{problem.name}: IK solutions"), args.plot)
    return 0 if any(r.success for r in results) else 1


# ---------------------------------------------------------------------------- fk
def _assembly_modes(m: Mechanism, actuated: np.ndarray) -> list[np.ndarray]:
    """All assembly modes: the closed form when registered, else
    [`optik.solve_fk_all`][optik.solve_fk_all]."""
    if closed_form.has_fk(m):
        return closed_form.fk(m, actuated)
    return [np.asarray(r.q) for r in optik.solve_fk_all(m, actuated) if r.success]


def _wrap_notes(m: Mechanism, actuated: np.ndarray) -> list[str]:
    """One line per actuated angle outside its limits: the value modulo 2 pi that the assembly
    modes are solved at (`Mechanism.wrap`), or that none lies within the limits."""
    q = m.mid_q()
    q[m.actuated_indices] = actuated
    wrapped = m.wrap(q)
    notes = []
    for i in m.actuated_indices:
        lo, hi, v, w = m.lower[i], m.upper[i], q[i], wrapped[i]
        if m.revolute_mask[i] and not lo <= v <= hi:
            name, span = m.coordinate_names[i], f"[{lo:.6g}, {hi:.6g}]"
            where = f"taken modulo 2 pi as {w:.6f}" if lo <= w <= hi else "and stays outside them modulo 2 pi"
            notes.append(f"{name}={v:g} is outside its limits {span}: {where}")
    return notes


def _cmd_fk(args: argparse.Namespace) -> int:
    _writable(args.plot, "plot")
    problem = _problem(args.problem, args.problems_dir)
    m = problem.mechanism()
    n_act = len(m.actuated_indices)
    if not m.is_closed or len(args.q) == m.n_q:
        q = _vector(args.q, m.n_q, "--q", ", ".join(m.coordinate_names))
        qs = [q]
        if m.is_closed:
            gap = float(np.max(np.abs(m.closure(q))))
            if gap > problem.tolerances.closure:
                print(f"warning: the loop closures are violated by {gap:.2e} at this q")
    else:
        names = ", ".join(m.coordinate_names[i] for i in m.actuated_indices)
        actuated = _vector(args.q, n_act, "--q", f"all {m.n_q} coordinates, or the actuated {names}")
        for note in _wrap_notes(m, actuated):
            print(f"note: {note}")
        qs = _assembly_modes(m, actuated)
        print(f"{problem.name}: {len(qs)} assembly mode(s) within limits for {names} = {args.q}")
    for i, q in enumerate(qs, 1):
        print(f"[{i}] {_pose_text(m, m.fk(q))}")
        print(f"    {_fmt_q(m, q)}")
        if args.matrix:
            print(np.array2string(m.fk(q), precision=6, suppress_small=True))
    if args.plot and qs:
        from optik.plot import draw_branches

        _save(draw_branches(m, qs, title=f"{problem.name}: FK"), args.plot)
    return 0 if qs else 1


# ---------------------------------------------------------------------------- plot
def _cmd_plot(args: argparse.Namespace) -> int:
    from optik.plot import draw, draw_branches, workspace

    _writable(args.out, "out", directory=True)
    problem = _problem(args.problem, args.problems_dir)
    m = problem.mechanism()
    task = problem.mechanism_task
    out_dir = Path(args.out)
    modes = [args.mode] if args.mode != "all" else [k for k in PLOT_MODES if k != "all"]
    if args.mode == "assembly" and not m.is_closed:
        raise UsageError("--mode", f"'assembly' needs a closed chain; {m.name} is open")
    q = _vector(args.q, m.n_q, "--q", ", ".join(m.coordinate_names))
    reference = None
    if q is None or args.target is None:
        try:
            reference = problem.sample_targets(1, seed=args.seed).q[0]
        except OptikError as exc:
            print(f"note: no reference configuration ({exc})")
    q_show = q if q is not None else reference
    target = (
        parse_target(task, args.target)
        if args.target is not None
        else (m.fk(q_show) if q_show is not None else None)
    )
    written: list[Path] = []
    name = problem.name
    if "config" in modes and q_show is not None:
        ax = draw(m, q_show)
        ax.set_title(f"{name}")
        written.append(_save(ax.figure, out_dir / f"{name}_config.png"))
    if "branches" in modes and target is not None:
        sols = [r.q for r in optik.solve_ik_all(m, target, task=task, tol=problem.tolerances) if r.success]
        what = f"{len(sols)} IK branch{'es' if len(sols) != 1 else ''}"
        title = f"{name}: {what} of {_pose_text(m, target, 3)}"
        fig = draw_branches(m, sols, title=title, near=q_show)
        written.append(_save(fig, out_dir / f"{name}_branches.png"))
    if "assembly" in modes and m.is_closed and q_show is not None:
        actuated = q_show[m.actuated_indices]
        sols = _assembly_modes(m, actuated)
        names = ", ".join(
            f"{m.coordinate_names[i]}={v:.3f}" for i, v in zip(m.actuated_indices, actuated, strict=True)
        )
        title = f"{name}: {len(sols)} assembly mode{'s' if len(sols) != 1 else ''} for {names}"
        fig = draw_branches(m, sols, title=title, label="assembly mode")
        written.append(_save(fig, out_dir / f"{name}_assembly.png"))
    if "workspace" in modes:
        n = args.n if args.n is not None else (2000 if m.planar or not m.is_closed else 200)
        written.append(_save(workspace(m, n=n, seed=args.seed), out_dir / f"{name}_workspace.png"))
    return 0 if written else 1


def _benchmark_list() -> str:
    """The benchmarks, one per line: ``NAME  description``."""
    from optik import benchmarks

    listed = benchmarks.summaries()
    width = max(map(len, listed), default=0)
    return "\n".join(
        textwrap.fill(text, 79, initial_indent=f"  {name:<{width}}  ", subsequent_indent=" " * (width + 4))
        for name, text in listed.items()
    )


def _cmd_benchmark(args: argparse.Namespace) -> int:
    from optik import benchmarks

    names = benchmarks.available()
    if args.name is None:
        print(f"{len(names)} benchmarks; run one with: optik benchmark NAME [ARGS] (NAME --help: options)")
        print(_benchmark_list())
        return 0
    if args.name not in names:
        raise UsageError("NAME", f"unknown benchmark {args.name!r}; available: {', '.join(names)}")
    return benchmarks.run(args.name, args.args)


# ---------------------------------------------------------------------------- parser
class _Parser(argparse.ArgumentParser):
    """argparse with the one-line error format ``optik <cmd>: error: ...`` and exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _argument(text: str, convert: Callable[[str], Any], valid: Callable[[Any], bool], expected: str) -> Any:
    """``convert(text)`` when it converts and is ``valid``, else an ``ArgumentTypeError`` saying
    what was ``expected``."""
    try:
        v = convert(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
    if not valid(v):
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
    return v


def _positive_int(text: str) -> int:
    return _argument(text, int, lambda v: v >= 1, "a positive integer")


def _positive_float(text: str) -> float:
    return _argument(text, float, lambda v: v > 0 and np.isfinite(v), "a positive number of seconds")


def _finite(text: str) -> float:
    return _argument(text, float, np.isfinite, "a finite number")


def _common(p: argparse.ArgumentParser, many: bool = False) -> None:
    if many:
        p.add_argument(
            "problem", nargs="*", metavar="PROBLEM", help="problem names or .toml files (default: all)"
        )
    else:
        p.add_argument("problem", metavar="PROBLEM", help="problem name (e.g. five_bar) or a .toml file")
    add_problems_dir(p, argparse.SUPPRESS)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``optik`` command."""
    parser = _Parser(
        prog="optik",
        description="Kinematics by constrained optimization: benchmark, solve, FK and plots of the problems.",
        epilog=(
            "Problems are the TOML files shipped in problems/ (e.g. planar_3r, five_bar, "
            "stewart_gough, panda), or of --problems-dir."
        ),
    )
    parser.add_argument("--version", action="version", version=f"optik {optik.__version__}")
    add_problems_dir(parser, None)  # before the subcommand, or after it (the subcommand's wins)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    b = sub.add_parser(
        "bench",
        help="benchmark every applicable solver and peer",
        description=(
            "Run every applicable IK method (closed form, lm, nlp, dls, qp) and peer (TRAC-IK, Pink, "
            "ikpy) on the same targets; print a table per problem and write results.json, "
            "results.csv, report.md and one PNG chart per problem into --out."
        ),
    )
    _common(b, many=True)
    from optik.harness import known_solvers

    b.add_argument(
        "--solvers",
        nargs="+",
        metavar="NAME",
        help=f"only these methods / peers, space or comma separated: {', '.join(known_solvers())} "
        "(default: every one that applies)",
    )
    b.add_argument("--n", type=_positive_int, help="targets per problem (default: from each file)")
    b.add_argument(
        "--quick", action="store_true", help="the quick settings: fewer targets, shorter time limits"
    )
    b.add_argument(
        "--out", default="bench-out", metavar="DIR", help="output directory (default: %(default)s)"
    )
    b.add_argument(
        "--time-limit",
        type=_positive_float,
        metavar="S",
        help="seconds per IK call (default: from each file)",
    )
    b.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    b.set_defaults(func=_cmd_bench)

    s = sub.add_parser(
        "solve",
        help="inverse kinematics of one target",
        description=(
            "Solve the IK of one target of a problem's mechanism. --target takes the numbers of the "
            "problem's task: position2d 'x y', pose2d 'x y phi', position 'x y z', "
            "pose 'x y z roll pitch yaw' or 16 matrix entries."
        ),
    )
    _common(s)
    s.add_argument(
        "--target", type=_finite, nargs="+", required=True, metavar="V", help="target values (see above)"
    )
    s.add_argument(
        "--method",
        help=f"IK method: {', '.join(optik.solvers.methods())} (default: the best available for the problem)",
    )
    s.add_argument(
        "--q0", type=_finite, nargs="+", metavar="Q", help="start configuration (default: mid-limit)"
    )
    s.add_argument(
        "--time-limit", type=_positive_float, default=0.5, metavar="S", help="seconds (default: %(default)s)"
    )
    s.add_argument("--all", action="store_true", help="every distinct branch (optik.solve_ik_all)")
    s.add_argument("--plot", type=Path, metavar="FILE", help="save a figure of the solutions (e.g. sol.png)")
    s.set_defaults(func=_cmd_solve)

    f = sub.add_parser(
        "fk",
        help="forward kinematics",
        description=(
            "Pose of the end effector. Open chains: --q takes every coordinate. Closed chains: --q takes "
            "every coordinate (the closures are checked) or only the actuated ones (every assembly mode "
            "is printed)."
        ),
    )
    _common(f)
    f.add_argument(
        "--q",
        type=_finite,
        nargs="+",
        required=True,
        metavar="Q",
        help="joint values: every coordinate, or (closed chains) only the actuated ones",
    )
    f.add_argument("--matrix", action="store_true", help="also print the 4x4 transform")
    f.add_argument("--plot", type=Path, metavar="FILE", help="save a figure of the configuration(s)")
    f.set_defaults(func=_cmd_fk)

    p = sub.add_parser(
        "plot",
        help="figures: a configuration, IK branches, assembly modes, workspace",
        description=(
            "Write PNG figures of a problem's mechanism into --out: 'config' (one configuration), 'branches' "
            "(every IK branch of a target), 'assembly' (every assembly mode of the actuated values, closed "
            "chains), 'workspace' (sampled reachable points) or 'all'. Without --q / --target a reference "
            "configuration is drawn from the problem's target sampling."
        ),
    )
    _common(p)
    p.add_argument("--mode", choices=PLOT_MODES, default="all", help="what to draw (default: %(default)s)")
    p.add_argument("--q", type=_finite, nargs="+", metavar="Q", help="configuration (every coordinate)")
    p.add_argument("--target", type=_finite, nargs="+", metavar="V", help="target for 'branches'")
    p.add_argument(
        "--n", type=_positive_int, help="workspace samples (default 2000; 200 for spatial closed chains)"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the sampling (default: %(default)s)")
    p.add_argument("--out", default="plots", metavar="DIR", help="output directory (default: %(default)s)")
    p.set_defaults(func=_cmd_plot)

    from optik import benchmarks

    k = sub.add_parser(
        "benchmark",
        help=f"run a focused benchmark script: {', '.join(benchmarks.available())}",
        description=textwrap.fill(
            "Run the benchmark script optik.benchmarks.bench_NAME with the remaining arguments, e.g. "
            "'optik benchmark ik --n 1000' (Panda: lm / nlp against TRAC-IK) or 'optik benchmark diffik' "
            "(QP step against Pink). 'optik benchmark NAME --help' shows a script's own options and "
            "defaults; 'optik benchmark' alone lists the benchmarks.",
            79,
        ),
        epilog="benchmarks:\n" + _benchmark_list(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    k.add_argument(
        "name",
        nargs="?",
        metavar="NAME",
        help=f"the benchmark (one of: {', '.join(benchmarks.available())}; none: list them)",
    )
    k.add_argument("args", nargs=argparse.REMAINDER, help="arguments passed to the script (see NAME --help)")
    k.set_defaults(func=_cmd_benchmark)

    from optik.view.command import add_parser as add_view  # optik view: the browser viewer

    add_view(sub)
    from optik.reach import add_parser as add_reach  # optik reach: capability maps

    add_reach(sub)
    from optik.path.command import add_parser as add_path  # optik path: Cartesian paths

    add_path(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``optik`` console script; returns the exit code.

    0: success; 1: ran, but nothing was solved / assembled; 2: bad arguments (one line naming
    the argument on stderr).
    """
    matplotlib.use("Agg")
    args_list = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(args_list)
    args.argv = args_list
    try:
        return int(args.func(args))
    except BrokenPipeError:  # the reader stopped (e.g. `optik benchmark | head`): no traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except UsageError as exc:
        sub = f"optik {args.command}"
        sys.stderr.write(f"{sub}: error: {exc}\n")
        return 2
    except OptikError as exc:
        sys.stderr.write(f"optik {args.command}: error: {exc}\n")
        return 2


if __name__ == "__main__":
    sys.exit(main())
