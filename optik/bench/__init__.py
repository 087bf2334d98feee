"""The benchmark harness behind ``optik bench`` (the benchmark method of docs/benchmarks.md).

* [`optik.bench.harness`][optik.bench.harness]: contenders (registered IK methods and peers), targets, timed
  calls, summary statistics;
* [`optik.bench.peers`][optik.bench.peers]: thin adapters for TRAC-IK, Pink and ikpy;
* [`optik.bench.report`][optik.bench.report]: console table, JSON, CSV, Markdown and PNG charts;
* [`optik.bench.run`][optik.bench.run]: [`run_bench`][optik.bench.run_bench], the whole command as a function.
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
