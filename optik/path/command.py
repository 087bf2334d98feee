"""``optik path PROBLEM``: plan the ``[path]`` of a problem file, write its figure and arrays."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from optik.path.figures import path_figure
from optik.path.plan import plan_path
from optik.plot import check_writable, save_figure, write_atomic
from optik.problem_files import add_problems_dir, find_problem


def add_parser(sub: Any) -> None:
    """Register ``path`` on the ``optik`` subcommand parsers."""
    p = sub.add_parser(
        "path",
        help="plan a problem's [path]: a joint path over every IK solution",
        description=(
            "Plan the [path] table of a problem file (a line, an arc, a polyline or waypoints) with "
            "optik.plan_path, print what was found and the checks, and write DIR/NAME_path.png (joint "
            "trajectories with their limits, the tool's error, branch changes) and DIR/NAME_path.npz "
            "(q, t, qd, qdd, branch). Exit 0 when the path passes every check, 1 when not."
        ),
    )
    p.add_argument("problem", metavar="PROBLEM", help="problem name or a .toml file with a [path] table")
    add_problems_dir(p, argparse.SUPPRESS)
    p.add_argument("--out", metavar="DIR", default="path-out", help="output folder (default: %(default)s)")
    p.set_defaults(func=run)


def _savez(path: str, arrays: dict[str, np.ndarray]) -> None:
    with open(path, "wb") as f:  # a file object: numpy appends no ".npz" to the name
        np.savez(f, **arrays)


def run(args: argparse.Namespace) -> int:
    """Body of ``optik path``."""
    out = check_writable(args.out, "out", directory=True)
    problem = find_problem(args.problem, getattr(args, "problems_dir", None))
    m = problem.mechanism()
    poses, times = problem.path_poses()
    path = plan_path(m, poses, times, **problem.path_options())
    print(f"{problem.name}: {path.message}")
    print("checks: " + ", ".join(f"{k} {'ok' if ok else 'FAILED'}" for k, ok in path.checks.items()))
    if len(path.q):
        written = save_figure(
            path_figure(m, path, title=f"{problem.name}: {path.message[:90]}"),
            out / f"{problem.name}_path.png",
        )
        print(f"wrote {written}")
        arrays = {"q": path.q, "t": path.t, "qd": path.qd, "qdd": path.qdd, "branch": path.branch}
        target = out / f"{problem.name}_path.npz"
        write_atomic(target, lambda tmp: _savez(tmp, arrays))
        print(f"wrote {Path(target)}")
    return 0 if path.success else 1
