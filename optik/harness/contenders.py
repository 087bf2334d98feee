"""The benchmark harness: every applicable solver and peer on the same targets, timed call by call.

Method (docs/benchmarks.md): per problem, reference configurations are drawn within limits (loop closures
satisfied) and their poses are the targets; every contender solves every target from the
mid-limit seed ``q0 = (lower + upper) / 2`` with the same time limit and tolerances. Calls are
interleaved target by target (target 1 for every contender, then target 2, ...) so that a noisy
machine slows every contender alike. Each contender gets one untimed warm-up call first (CasADi
functions and NLPs are built once, peers load their URDF); after that every call is timed with
``time.perf_counter`` around the whole call, failures included.

The rules of [`optik.harness.peers.rules`][optik.harness.peers.rules] hold for every contender: every answer
is wrapped and clipped into the limits ([`settle`][optik.harness.peers.rules.settle], what `solve_ik` does to
its own answers) and its raw overshoot is recorded; success is judged by one function for everybody
([`optik.solvers.base.evaluate`][optik.solvers.base.evaluate]): position, orientation and closure errors
within the problem's tolerances and the joint limits satisfied exactly, and, where the problem has a URDF
chain, the same pose check by the independent [`Referee`][optik.harness.peers.rules.Referee] (Pinocchio's
FK where installed). Where a closed-form IK exists, each
successful answer is compared with the nearest closed-form branch (max-norm joint distance, angles modulo 2
pi): the *closed-form error*, and *branch agreement* when that distance is below
[`optik.solvers.base.BRANCH_TOL`][optik.solvers.base.BRANCH_TOL].
"""

from __future__ import annotations

import itertools
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import optik
from optik import closed_form, native
from optik.errors import InvalidArgumentError, OptikError
from optik.harness.peers import PeerUnavailable, load_peer
from optik.harness.peers.rules import Referee, overshoot, settle, warm_up
from optik.mechanism import Mechanism
from optik.problem_files import PEERS, Problem, TargetSet
from optik.progress import Progress
from optik.solvers import methods
from optik.solvers.base import BRANCH_TOL, evaluate, joint_distance

__all__ = [
    "Call",
    "Contender",
    "ProblemRun",
    "SolverRun",
    "contenders",
    "known_solvers",
    "run_problem",
    "run_problems",
]


@dataclass(frozen=True)
class Call:
    """One timed solve.

    Attributes:
        time: wall time of the call (s).
        success: every tolerance met and limits satisfied.
        position_error, orientation_error, closure_error: errors of the returned ``q``.
        limits_ok: the settled ``q`` is within limits.
        overshoot: how far the raw answer was outside the limits (before it was settled).
        cf_distance: joint distance to the nearest closed-form branch (NaN: no closed form or
            no branch).
        ref_distance: joint distance to the reference configuration the target was made from.
        status: the solver's status, or the exception text when the call raised.
    """

    time: float
    success: bool
    position_error: float
    orientation_error: float
    closure_error: float
    limits_ok: bool
    cf_distance: float
    ref_distance: float
    status: str
    overshoot: float = 0.0


def _percentile(x: np.ndarray, p: float) -> float:
    return float(np.percentile(x, p)) if len(x) else float("nan")


@dataclass
class SolverRun:
    """All calls of one contender on one problem."""

    name: str
    kind: str
    calls: list[Call] = field(default_factory=list)

    def stats(self, fastest_median: float) -> dict[str, Any]:
        """Summary: success %, mean / median / p95 / max time (ms), ratio of the median time to
        ``fastest_median``, largest raw limit overshoot, closed-form error (median, max) and branch
        agreement (% of the successes that land on a closed-form branch / on the reference branch)."""
        t = np.array([c.time for c in self.calls])
        ok = np.array([c.success for c in self.calls], dtype=bool)
        cf = np.array([c.cf_distance for c in self.calls])[ok]
        cf = cf[np.isfinite(cf)]
        ref = np.array([c.ref_distance for c in self.calls])[ok]
        median = float(np.median(t)) if len(t) else float("nan")
        n_ok = int(ok.sum())
        return {
            "solver": self.name,
            "kind": self.kind,
            "n": len(self.calls),
            "success_pct": 100.0 * n_ok / len(self.calls) if self.calls else float("nan"),
            "mean_ms": 1e3 * float(np.mean(t)) if len(t) else float("nan"),
            "median_ms": 1e3 * median,
            "p95_ms": 1e3 * _percentile(t, 95),
            "max_ms": 1e3 * float(np.max(t)) if len(t) else float("nan"),
            "ratio": median / fastest_median if fastest_median > 0 else float("nan"),
            "overshoot_max": max((c.overshoot for c in self.calls), default=float("nan")),
            "cf_err_median": float(np.median(cf)) if len(cf) else float("nan"),
            "cf_err_max": float(np.max(cf)) if len(cf) else float("nan"),
            "branch_pct": 100.0 * float(np.mean(cf < BRANCH_TOL)) if len(cf) else float("nan"),
            "ref_branch_pct": 100.0 * float(np.mean(ref < BRANCH_TOL)) if n_ok else float("nan"),
            "failures": dict(Counter(c.status for c in self.calls if not c.success)),
        }


@dataclass
class ProblemRun:
    """The outcome of one problem: its targets, one [`SolverRun`][optik.harness.contenders.SolverRun] per
    contender, notes."""

    problem: Problem
    targets: TargetSet | None
    runs: list[SolverRun]
    notes: list[str]
    elapsed: float
    time_limit: float

    def summary(self) -> list[dict[str, Any]]:
        """[`SolverRun.stats`][optik.harness.contenders.SolverRun.stats] of every contender; ratios
        relative to the fastest median time among the contenders that solved at least one target."""
        medians = [
            float(np.median([c.time for c in r.calls]))
            for r in self.runs
            if r.calls and any(c.success for c in r.calls)
        ]
        fastest = min(medians) if medians else float("nan")
        return [r.stats(fastest) for r in self.runs]


@dataclass
class Contender:
    """A named solve function ``(q0, target) -> (raw q, status)`` of one method or peer (an empty
    status is filled in from the evaluation: ``"solved"`` or ``"not_converged"``)."""

    name: str
    kind: str
    solve: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, str]]


def known_solvers() -> list[str]:
    """Names usable in ``--solvers``: the registered IK methods and the peers."""
    return sorted(methods()) + list(PEERS)


def _method_contender(m: Mechanism, name: str, task: str, problem: Problem, time_limit: float) -> Contender:
    counter = itertools.count()  # a fresh restart seed per call, the same sequence in every run

    def solve(q0: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, str]:
        res = optik.solve_ik(
            m,
            target,
            q0,
            method=name,
            task=task,
            time_limit=time_limit,
            tol=problem.tolerances,
            seed=next(counter),
        )
        return np.asarray(res.q, dtype=float), res.status

    return Contender(name, "method", solve)


def _peer_contender(name: str, problem: Problem, time_limit: float) -> Contender:
    peer = load_peer(name, problem)

    def solve(q0: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, str]:
        return peer.solve(q0, target, time_limit, problem.tolerances), ""

    return Contender(name, "peer", solve)


def contenders(
    problem: Problem, time_limit: float, only: Sequence[str] | None = None
) -> tuple[list[Contender], list[str]]:
    """The contenders of a problem and notes on those that cannot run.

    Methods: the file's list (default: every registered method), kept when registered and
    applicable to the mechanism and task. Peers: the file's list, kept when their adapter loads.
    ``only`` restricts both to the given names.
    """
    m = problem.mechanism()
    task = problem.mechanism_task
    registry = methods()
    wanted = list(problem.methods) if problem.methods is not None else sorted(registry)
    notes: list[str] = []
    out: list[Contender] = []
    for name in wanted:
        if only is not None and name not in only:
            continue
        if name not in registry:
            notes.append(f"method {name!r} is not registered in this build of optik: skipped")
        elif not registry[name].applies(m, task):
            notes.append(f"method {name!r} does not apply to {m.name} with task {task!r}: skipped")
        else:
            out.append(_method_contender(m, name, task, problem, time_limit))
    for name in problem.peers:
        if only is not None and name not in only:
            continue
        try:
            out.append(_peer_contender(name, problem, time_limit))
        except PeerUnavailable as exc:
            notes.append(f"peer unavailable: {exc}")
    return out, notes


def _closed_form_branches(m: Mechanism, targets: TargetSet) -> list[list[np.ndarray]] | None:
    if not closed_form.has_ik(m):
        return None
    return [closed_form.ik(m, t) for t in targets.poses]


def _referee(problem: Problem, m: Mechanism) -> Referee | None:
    """The independent check of a problem with a URDF chain (None without one)."""
    chain = problem.urdf_chain()
    if chain is None:
        return None
    urdf, base, tip = chain
    return Referee(m, urdf, base, tip)


def _call(c: Contender, q0: np.ndarray, target: np.ndarray) -> tuple[float, np.ndarray, str]:
    start = time.perf_counter()
    try:
        q, status = c.solve(q0, target)
    except Exception as exc:  # a crashing contender is a failed call, reported with its message
        elapsed = time.perf_counter() - start
        return elapsed, q0, f"error: {type(exc).__name__}: {exc}"
    return time.perf_counter() - start, q, status


def run_problem(
    problem: Problem,
    quick: bool = False,
    n: int | None = None,
    time_limit: float | None = None,
    only: Sequence[str] | None = None,
    progress: Progress | None = None,
) -> ProblemRun:
    """Benchmark one problem.

    Args:
        problem: the problem.
        quick: use the file's quick settings (``quick_n`` targets, ``quick_time_limit``).
        n: number of targets (overrides the file).
        time_limit: seconds per call (overrides the file).
        only: restrict to these solver / peer names.
        progress: progress display (one step per call).

    Returns:
        The runs; a problem that cannot be set up (e.g. sampling needs a missing solver) gives
        no runs and a note saying why.
    """
    start = time.perf_counter()
    limit = problem.call_time_limit(quick) if time_limit is None else time_limit
    if limit <= 0:
        raise InvalidArgumentError("time_limit", f"must be > 0 seconds, got {limit}")
    count = problem.target_count(quick) if n is None else n
    try:
        m = problem.mechanism()
        targets = problem.sample_targets(count)
        cons, notes = contenders(problem, limit, only)
        branches = _closed_form_branches(m, targets)
    except OptikError as exc:
        return ProblemRun(problem, None, [], [f"problem skipped: {exc}"], time.perf_counter() - start, limit)
    if len(targets) < count:
        notes.append(f"only {len(targets)} of {count} targets could be drawn ({targets.draws} draws)")
    task = targets.task
    q0 = m.mid_q()
    ready: list[Contender] = []
    warmed: list[str] = []
    # untimed warm-up, the same for every contender: builds CasADi functions, NLPs, peer solvers once
    warm_up(lambda c=c: warmed.append(_call(c, q0, targets.poses[0])[2]) for c in cons)
    for c, status in zip(cons, warmed, strict=True):
        if status.startswith("error:"):
            notes.append(f"{c.name} failed its warm-up call and was skipped ({status})")
        else:
            ready.append(c)
    native.wait()  # C libraries still building in the background: time the compiled code
    referee = _referee(problem, m) if task == "pose" else None
    runs = [SolverRun(c.name, c.kind) for c in ready]
    if progress is not None:
        progress.start(problem.name, len(targets) * len(ready))
    for k, (ref, target) in enumerate(zip(targets.q, targets.poses, strict=True)):
        cf = branches[k] if branches is not None else []
        for c, run in zip(ready, runs, strict=True):
            elapsed, raw, status = _call(c, q0, target)
            q = settle(m, raw)
            err = evaluate(m, q, target, task, None)
            ok = err.ok(problem.tolerances)
            if ok and referee is not None:  # every claimed success re-checked by the independent FK
                ok = referee.judge(q, target, problem.tolerances).success
            run.calls.append(
                Call(
                    time=elapsed,
                    success=ok,
                    position_error=err.position,
                    orientation_error=err.orientation,
                    closure_error=err.closure,
                    limits_ok=err.limits_ok,
                    cf_distance=min((joint_distance(m, q, b) for b in cf), default=float("nan")),
                    ref_distance=joint_distance(m, q, ref),
                    status=status or ("solved" if ok else "not_converged"),
                    overshoot=overshoot(m, raw),
                )
            )
            if progress is not None:
                progress.step()
    for r in runs:
        raised = [c.status for c in r.calls if c.status.startswith("error:")]
        if raised:
            notes.append(f"{r.name} raised in {len(raised)} calls, first: {raised[0]}")
    if progress is not None:
        progress.finish()
    return ProblemRun(problem, targets, runs, notes, time.perf_counter() - start, limit)


def run_problems(
    problems: Sequence[Problem],
    quick: bool = False,
    n: int | None = None,
    time_limit: float | None = None,
    only: Sequence[str] | None = None,
    progress: Progress | None = None,
    on_done: Callable[[ProblemRun], None] | None = None,
) -> list[ProblemRun]:
    """[`run_problem`][optik.harness.contenders.run_problem] for each problem in turn; ``on_done``
    sees each result as it lands."""
    out = []
    for p in problems:
        res = run_problem(p, quick, n, time_limit, only, progress)
        out.append(res)
        if on_done is not None:
            on_done(res)
    return out
