"""The benchmark harness behind ``optik bench`` (DESIGN.md benchmark method).

* :mod:`optik.bench.harness`: contenders (registered IK methods and peers), targets, timed
  calls, summary statistics;
* :mod:`optik.bench.peers`: thin adapters for TRAC-IK, Pink and ikpy;
* :mod:`optik.bench.report`: console table, JSON, CSV, Markdown and PNG charts;
* :mod:`optik.bench.run`: :func:`run_bench`, the whole command as a function.
"""

from optik.bench.harness import Call, ProblemRun, SolverRun, known_solvers, run_problem, run_problems
from optik.bench.run import BenchOutcome, run_bench, select_problems

__all__ = [
    "BenchOutcome",
    "Call",
    "ProblemRun",
    "SolverRun",
    "known_solvers",
    "run_bench",
    "run_problem",
    "run_problems",
    "select_problems",
]
