"""The benchmark harness behind ``optik bench`` (the benchmark method of docs/benchmarks.md).

* [`optik.harness.contenders`][optik.harness.contenders]: contenders (registered IK methods and
  peers), targets, timed calls, summary statistics;
* [`optik.harness.peers`][optik.harness.peers]: thin adapters for TRAC-IK, Pink and ikpy;
* [`optik.harness.report`][optik.harness.report]: console table, JSON, CSV, Markdown and PNG charts;
* [`optik.harness.run`][optik.harness.run]: [`run_bench`][optik.harness.run_bench], the whole command
  as a function.
"""

from optik.harness.contenders import Call, ProblemRun, SolverRun, known_solvers, run_problem, run_problems
from optik.harness.run import BenchOutcome, run_bench, select_problems

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
