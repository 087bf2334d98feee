"""Fuzzing of the public API: hypothesis strategies of calls with valid and corrupted arguments,
and the classification of every outcome against optik's promise.

The promise: every public call returns a result or raises an [`OptikError`][optik.OptikError],
within its time limit and bounded memory, and a result that claims success is right. Each call
is classified as one of `CLASSES`:

* ``ok``: a result, and where it claims something (``success=True``, a closed-form branch, a
  step within the limits) an independent check recomputed from the returned ``q`` agrees: FK
  by ``m.fk`` and the error computed here (distance of the origins, rotation angle
  ``atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2)`` of ``R = R_fk^T R_target``, planar heading
  difference), closure residual by ``m.closure``, limits by exact comparisons;
* ``optik_error``: an [`OptikError`][optik.OptikError] (the expected answer to corrupted input);
* ``leak``: any other exception (the failure the promise excludes);
* ``false_success``: a claimed success that fails the independent check;
* ``overtime``: the call worked longer than its time limit plus `OVERTIME_SLACK` (CPU time of
  the process and its children, at most the wall-clock time; first-time setup that the result
  reports in ``extra["setup_time"]`` excluded): the promise of ``docs/reliability.md``, a time
  limit plus one iteration; or it ran (waiting, say) past `WALL_CEILING` times that on the wall
  clock: a hang. A busy machine delays a call on the wall clock without making it work longer,
  so it does not make a call overtime.

Every strategy draws a `Call`: the entry point's name, a
closure that makes the call (argument objects such as ``Pose2D`` are constructed inside it, so
that their validation is part of the call) and the check of its result. Mechanisms come from a
fixed pool (built once: solvers compile code per mechanism), except in the constructor entries.
"""

from __future__ import annotations

import contextlib
import math
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

import optik
from optik import catalog, closed_form, diffik, problem_files, spatial
from optik.errors import OptikError

CLASSES = ("ok", "optik_error", "leak", "false_success", "overtime")
"""Outcome classes, in the order of the reports."""

FAILURES = ("leak", "false_success", "overtime")
"""The classes that break the promise."""

NAN, INF = float("nan"), float("inf")

BAD_VALUES: tuple[Any, ...] = (
    NAN,
    INF,
    -INF,
    1e300,
    -1e300,
    1e-300,
    0.0,
    -1.0,
    10**30,
    True,
    "abc",
    "",
    None,
    [],
    [[]],
    [1.0, "a"],
    [[1.0, 2.0], [3.0]],
    1j,
    [1j, 2.0],
    {"a": 1},
    b"x",
    object(),
    np.zeros((2, 3, 4)),
    np.array(["a", "b"]),
)
"""Corrupted values of any argument: non-finite, huge, zero, negative, wrong types and shapes,
unhashable, ragged, complex."""


@dataclass
class Call:
    """One call of the public API.

    Attributes:
        entry: name of the entry point (counts are reported per entry).
        run: makes the call and returns its result.
        check: ``result -> None`` when the result keeps its promise, else what is wrong.
        limit: the call's time limit (s); ``overtime`` past ``limit + OVERTIME_SLACK`` of CPU
            time, or `WALL_CEILING` times that of wall-clock time.
        label: short description of the arguments (for the failure report).
        key: what the call may build on first use (mechanism, method, task, frame...); the first
            calls of each key get `FIRST_CALL_GRACE` more seconds until one of them returned a
            result (first-time code generation and compilation do not count against time
            limits; a call rejected before it built anything does not use up the grace); None
            for calls that build nothing.
    """

    entry: str
    run: Callable[[], Any]
    check: Callable[[Any], str | None] = field(default=lambda result: None)
    limit: float = 1.0
    label: str = ""
    key: tuple | None = None


FIRST_CALL_GRACE = 60.0
"""Extra seconds of the first call of each `Call.key` (a C compilation may take this long on a
loaded machine); every later call of the key is held to ``limit + OVERTIME_SLACK``."""

OVERTIME_SLACK = 0.25
"""Seconds past its time limit after which a call is ``overtime``: one iteration of the slowest
solver plus scheduling delays on a loaded machine, about 3 times the largest overrun measured by
``optik benchmark time_limits`` over 1,000 calls per solver on a loaded 2-core machine (92 ms;
the table in ``docs/reliability.md``). The former rule, 3 x the limit + 0.5 s, let a 0.1 s call
run 0.8 s."""

WALL_CEILING = 20.0
"""A call still running after ``WALL_CEILING x (limit + OVERTIME_SLACK)`` wall-clock seconds (plus
its first-call grace) is a hang, interrupted and ``overtime`` however little CPU time it used (a
deadlock or a blocked read does not work): far above the delay a loaded machine adds to an
honest call."""

_SEEN_KEYS: set[tuple] = set()


@dataclass
class Outcome:
    """The classification of one call."""

    entry: str
    kind: str
    seconds: float
    detail: str = ""
    label: str = ""


class CallTimeout(BaseException):
    """Raised by the watchdog in a call that runs far past its limit (a hang)."""


def _on_alarm(signum: int, frame: Any) -> None:
    raise CallTimeout


def classify(call: Call, wall_ceiling: float = WALL_CEILING) -> Outcome:
    """Run one call and classify its outcome (see the module docstring).

    A watchdog (``SIGALRM``, main thread only) interrupts a call after ``wall_ceiling x (limit +
    OVERTIME_SLACK)`` wall-clock seconds (plus its first-call grace) so that a hang is reported
    as ``overtime`` instead of stopping the run; in other threads the same ceiling classifies
    a call once it returns.
    """
    with warnings.catch_warnings():  # numpy's overflow warnings of extreme inputs: not findings
        warnings.simplefilter("ignore", RuntimeWarning)
        return _classify(call, wall_ceiling)


def _cpu_seconds() -> float:
    """CPU seconds used by this process (all its threads) and by its children waited for (the
    command-line entries run ``optik`` in a subprocess; a background compiler that ends during a
    call counts too, which the bound by the wall-clock time in `_classify` keeps within what the
    wall-clock rule charged)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _classify(call: Call, wall_ceiling: float) -> Outcome:
    first = call.key is not None and call.key not in _SEEN_KEYS
    grace = FIRST_CALL_GRACE if first else 0.0
    ceiling = wall_ceiling * (call.limit + OVERTIME_SLACK) + grace
    watch = hasattr(signal, "setitimer") and _main_thread()
    if watch:
        previous = signal.signal(signal.SIGALRM, _on_alarm)
        signal.setitimer(signal.ITIMER_REAL, min(ceiling, 600.0))
    start, cpu_start = time.perf_counter(), _cpu_seconds()
    kind, detail, setup = "ok", "", 0.0
    try:
        try:
            result = call.run()
        finally:
            seconds, cpu = time.perf_counter() - start, _cpu_seconds() - cpu_start
            if watch:
                signal.setitimer(signal.ITIMER_REAL, 0.0)
                signal.signal(signal.SIGALRM, previous)
        setup = _setup_time(result)
        problem = call.check(result)
        if problem is not None:
            kind, detail = "false_success", problem
    except OptikError as exc:
        kind, detail = "optik_error", f"{type(exc).__name__}: {exc}"[:300]
    except CallTimeout:
        seconds = time.perf_counter() - start
        kind, detail = "overtime", "interrupted by the watchdog (a hang)"
    except SystemExit as exc:  # argparse's usage errors in the in-process CLI
        if exc.code not in (0, 2):
            kind, detail = "leak", f"SystemExit({exc.code!r})"
    except Exception as exc:
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
        kind, detail = "leak", f"{type(exc).__name__}: {exc}"[:300] + where
    if kind == "ok" and call.key is not None:  # built by now (a call rejected early built nothing)
        _SEEN_KEYS.add(call.key)
    worked = min(cpu, seconds)  # threads may work in parallel: at most the wall-clock time
    if kind in ("ok", "optik_error") and (
        worked - setup > call.limit + OVERTIME_SLACK + grace or seconds - setup > ceiling
    ):
        kind, detail = (
            "overtime",
            f"{worked:.3f} s of CPU, {seconds:.3f} s of wall clock (setup {setup:.3f} s) for a limit"
            f" of {call.limit:g} s",
        )
    return Outcome(call.entry, kind, seconds, detail, call.label)


def spin(seconds: float) -> None:
    """Work (not wait) for ``seconds`` of this process's CPU time: a call that runs past its
    limit, for the tests of the overtime rule."""
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def _main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def _setup_time(result: Any) -> float:
    results = result if isinstance(result, list) else [result]
    return sum(
        float(getattr(r, "extra", {}).get("setup_time", 0.0) or 0.0) for r in results if hasattr(r, "extra")
    )


@dataclass
class Tally:
    """Counts per class and per entry, the failures (first few per entry) and the timing."""

    counts: Counter = field(default_factory=Counter)
    per_entry: dict[str, Counter] = field(default_factory=dict)
    failures: list[Outcome] = field(default_factory=list)
    slowest: dict[str, float] = field(default_factory=dict)
    seconds: Counter = field(default_factory=Counter)
    max_failures: int = 200

    def add(self, outcome: Outcome) -> None:
        self.counts[outcome.kind] += 1
        self.per_entry.setdefault(outcome.entry, Counter())[outcome.kind] += 1
        self.slowest[outcome.entry] = max(self.slowest.get(outcome.entry, 0.0), outcome.seconds)
        self.seconds[outcome.entry] += outcome.seconds
        if outcome.kind in FAILURES and len(self.failures) < self.max_failures:
            self.failures.append(outcome)

    @property
    def calls(self) -> int:
        return sum(self.counts.values())

    @property
    def n_failures(self) -> int:
        return sum(self.counts[k] for k in FAILURES)

    def report(self) -> str:
        lines = [f"calls: {self.calls}"]
        lines.append("  ".join(f"{k}: {self.counts[k]}" for k in CLASSES))
        width = max((len(e) for e in self.per_entry), default=5)
        head = "  ".join(f"{k:>13}" for k in CLASSES)
        lines.append(f"{'entry':<{width}}  {head}   mean ms  slowest s")
        for entry in sorted(self.per_entry):
            c = self.per_entry[entry]
            cells = "  ".join(f"{c[k]:>13}" for k in CLASSES)
            mean = 1e3 * self.seconds[entry] / max(sum(c.values()), 1)
            lines.append(f"{entry:<{width}}  {cells}   {mean:7.1f}  {self.slowest[entry]:9.3f}")
        for f in self.failures[:50]:
            lines.append(f"FAILURE {f.kind} {f.entry} [{f.label[:160]}]: {f.detail}")
        return "\n".join(lines)


def peak_rss_mib() -> float:
    """Peak resident memory of this process so far (MiB, ``getrusage``)."""
    kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kib / 1024.0 if sys.platform != "darwin" else kib / 2**20


# ------------------------------------------------------------------------------ the independent checks
def _rotation_angle(r_a: np.ndarray, r_b: np.ndarray) -> float:
    m = r_a.T @ r_b
    skew = np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    return float(math.atan2(0.5 * np.linalg.norm(skew), 0.5 * (np.trace(m) - 1.0)))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def task_error(task: str, pose: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """Position and orientation error of ``pose`` against ``target`` in a task space, computed
    here from the two transforms (not by the library)."""
    d = pose[:3, 3] - target[:3, 3]
    planar = task in ("pose2d", "position2d")
    pos = float(np.hypot(d[0], d[1])) if planar else float(np.linalg.norm(d))
    if task in ("position", "position2d"):
        return pos, 0.0
    if task == "pose2d":
        heading = math.atan2(pose[1, 0], pose[0, 0]) - math.atan2(target[1, 0], target[0, 0])
        return pos, abs(_wrap(heading))
    ori = _rotation_angle(pose[:3, :3], target[:3, :3])
    return (0.0 if task == "orientation" else pos), ori


def _tolerances(tol: Any) -> tuple[float, float, float]:
    if isinstance(tol, optik.Tolerances):
        return tol.position, tol.orientation, tol.closure
    if tol is None:
        d = optik.Tolerances()
        return d.position, d.orientation, d.closure
    t = float(tol)
    return t, t, optik.Tolerances().closure


def _transform(target: Any) -> np.ndarray:
    if isinstance(target, (optik.Pose2D, optik.Position)):
        return target.as_transform()
    return np.asarray(target, dtype=float)


def _within(q: np.ndarray, m: optik.Mechanism) -> bool:
    return bool(np.all(q >= m.lower) and np.all(q <= m.upper))


def _implied_task(m: optik.Mechanism, target: Any, task: str | None) -> str:
    if task is not None:
        return task
    if isinstance(target, optik.Pose2D):
        return "pose2d"
    if isinstance(target, optik.Position):
        return "position2d" if m.planar else "position"
    return m.task


def _each(one: Callable[[Any], str | None]) -> Callable[[Any], str | None]:
    """A check of a result or a list of results (``solve_ik_all``, ``solve_fk_all``) by ``one``."""

    def check(result: Any) -> str | None:
        for r in result if isinstance(result, (list, optik.results.IKSolutions)) else [result]:
            problem = one(r)
            if problem:
                return problem
        return None

    return check


def check_ik(m: optik.Mechanism, target: Any, task: str | None, frame: str | None, tol: Any) -> Callable:
    """The check of an ``IKResult`` (or a list of them): status agrees with success; a success is
    within the limits, meets the tolerances by FK recomputed from ``q`` and closes its loops."""
    slack = 1.0 + 1e-6

    def one(res: Any) -> str | None:
        # evaluated here, not when the call is drawn: the call returned, so its arguments are valid
        pos_tol, ori_tol, clo_tol = _tolerances(tol)
        t, space = _transform(target), _implied_task(m, target, task)
        if not isinstance(res, optik.IKResult):
            return f"not an IKResult: {type(res).__name__}"
        if res.success != (res.status == "solved"):
            return f"success={res.success} with status {res.status!r}"
        if not res.success:
            return None
        q = np.asarray(res.q, dtype=float)
        if q.shape != (m.n_q,) or not np.isfinite(q).all():
            return f"q of shape {q.shape} / not finite"
        if not _within(q, m):
            return "success outside the joint limits"
        pos, ori = task_error(space, m.fk(q, frame), t)
        clo = float(np.max(np.abs(m.closure(q)))) if m.is_closed else 0.0
        if pos > pos_tol * slack + 1e-15 or ori > ori_tol * slack + 1e-15 or clo > clo_tol * slack + 1e-15:
            return f"claimed success: position {pos:.3g}, orientation {ori:.3g}, closure {clo:.3g} ({space})"
        return None

    return _each(one)


def check_fk(m: optik.Mechanism, actuated: np.ndarray, tol: Any) -> Callable:
    """The check of an ``FKResult`` (or a list): a success closes its loops, keeps the actuated
    values, lies within the limits and its pose is ``m.fk(q)``."""
    idx = m.actuated_indices

    def one(res: Any) -> str | None:
        clo_tol = _tolerances(tol)[2] if tol is None or isinstance(tol, optik.Tolerances) else float(tol)
        if not isinstance(res, optik.FKResult):
            return f"not an FKResult: {type(res).__name__}"
        if not res.success:
            return None
        q = np.asarray(res.q, dtype=float)
        if q.shape != (m.n_q,) or not np.isfinite(q).all():
            return "q not finite"
        clo = float(np.max(np.abs(m.closure(q)))) if m.is_closed else 0.0
        if clo > clo_tol * (1 + 1e-6) + 1e-15:
            return f"claimed success with closure {clo:.3g}"
        a = np.asarray(actuated, dtype=float).reshape(-1)
        if np.max(np.abs(_angle_diff(m, q[idx] - a, idx)), initial=0.0) > 1e-9 * (
            1.0 + np.abs(a).max(initial=0.0)
        ):
            return "claimed success with other actuated values"
        if not _within(q, m):
            return "claimed success outside the limits"
        if np.abs(m.fk(q) - np.asarray(res.pose)).max() > 1e-9 * (1.0 + np.abs(res.pose).max()):
            return "pose is not fk(q)"
        return None

    return _each(one)


def _angle_diff(m: optik.Mechanism, d: np.ndarray, idx: Sequence[int]) -> np.ndarray:
    ang = m.revolute_mask[list(idx)]
    out = np.array(d, dtype=float)
    out[ang] = [(_wrap(v)) for v in out[ang]]
    return out


def _size(m: optik.Mechanism) -> float:
    """A length scale of a mechanism: the largest origin offset of its joints (at least 1)."""
    return max([1.0] + [float(np.abs(j.origin[:3, 3]).sum()) for j in m.joints])


def check_branches(m: optik.Mechanism, target: Any, respect_limits: bool) -> Callable:
    """The check of ``closed_form.ik``: every branch reproduces the target (task rows of the
    mechanism, to rounding relative to its size) and respects the limits when asked."""

    def check(rows: Any) -> str | None:
        t = _transform(target)
        scale = _size(m) * (1.0 + float(np.abs(t[:3, 3]).max()))
        if not isinstance(rows, list):
            return f"not a list: {type(rows).__name__}"
        for q in rows:
            q = np.asarray(q, dtype=float)
            if q.shape != (m.n_q,) or not np.isfinite(q).all():
                return "branch not finite"
            pos, ori = task_error(m.task, m.fk(q), t)
            if pos > 1e-9 * scale or ori > 1e-7:
                return (
                    f"branch misses the target: position {pos:.3g} (scale {scale:.3g}), orientation {ori:.3g}"
                )
            if respect_limits and not _within(q, m):
                return "branch outside the limits"
        return None

    return check


def check_modes(m: optik.Mechanism, actuated: np.ndarray, respect_limits: bool) -> Callable:
    """The check of ``closed_form.fk``: every mode closes its loops (relative to the size) with
    the given actuated values, within the limits when asked."""
    idx = m.actuated_indices

    def check(rows: Any) -> str | None:
        a = np.asarray(actuated, dtype=float).reshape(-1)
        scale = _size(m) * (1.0 + float(np.abs(a).max(initial=0.0)))
        if not isinstance(rows, list):
            return f"not a list: {type(rows).__name__}"
        for q in rows:
            q = np.asarray(q, dtype=float)
            if q.shape != (m.n_q,) or not np.isfinite(q).all():
                return "mode not finite"
            clo = float(np.max(np.abs(m.closure(q)))) if m.is_closed else 0.0
            if clo > 1e-8 * scale:
                return f"mode does not close: {clo:.3g} (scale {scale:.3g})"
            if np.max(np.abs(_angle_diff(m, q[idx] - a, idx)), initial=0.0) > 1e-9 * scale:
                return "mode with other actuated values"
            if respect_limits and not _within(q, m):
                return "mode outside the limits"
        return None

    return check


def check_transform(result: Any) -> str | None:
    """A finite proper rigid transform (or a batch of them)."""
    t = np.asarray(result, dtype=float)
    if t.shape[-2:] != (4, 4) or not np.isfinite(t).all():
        return f"not a finite transform: shape {t.shape}"
    if not t.size:
        return None
    r = t[..., :3, :3]
    if np.abs(np.swapaxes(r, -1, -2) @ r - np.eye(3)).max() > 1e-9 or np.any(np.linalg.det(r) < 0):
        return "rotation block not orthonormal"
    return None


def check_mechanism(result: Any) -> str | None:
    """A mechanism whose mid-limit FK is a proper transform."""
    if not isinstance(result, optik.Mechanism):
        return f"not a Mechanism: {type(result).__name__}"
    return check_transform(result.fk(result.mid_q()))


def check_step(m: optik.Mechanism, q0: Any, limits: Any) -> Callable:
    """A step stays within ``[min(lower, q0), max(upper, q0)]`` and, when a ``VelocityLimit`` is
    given, within its speeds; ``v`` and ``q`` are finite."""

    def check(res: Any) -> str | None:
        q, v = np.asarray(res.q, dtype=float), np.asarray(res.v, dtype=float)
        if not (np.isfinite(q).all() and np.isfinite(v).all()):
            return "q or v not finite"
        start = np.asarray(q0, dtype=float)
        if np.any(q < np.minimum(m.lower, start) - 1e-9) or np.any(q > np.maximum(m.upper, start) + 1e-9):
            return "step leaves the limits"
        for lim in limits or ():
            if isinstance(lim, diffik.VelocityLimit) and not m.is_closed:
                cap = np.broadcast_to(lim.v_max, v.shape)
                if np.any(np.abs(v) > cap * (1 + 1e-6) + 1e-9):
                    return f"speed {np.abs(v).max():.3g} above the velocity limit"
        return None

    return check


def check_track(m: optik.Mechanism, q0: Any) -> Callable:
    """A tracked path is finite and, from a start within the limits, stays within them."""

    def check(res: Any) -> str | None:
        q = np.asarray(res.q, dtype=float)
        if not np.isfinite(q).all() or not np.isfinite(res.v).all():
            return "path not finite"
        if _within(np.asarray(q0, dtype=float), m) and not all(_within(row, m) for row in q):
            return "path leaves the limits"
        return None

    return check


# ------------------------------------------------------------------------------ the mechanism pool
POOL_NAMES = (*problem_files.default_constructors(), "planar_2r_fixed", "planar_3r_thin")
"""The mechanisms the solver entries draw from (catalog defaults and two degenerate variants)."""


@cache
def pool(name: str) -> optik.Mechanism:
    """A mechanism of `POOL_NAMES`, built once."""
    if name == "planar_2r_fixed":  # lower == upper
        return catalog.planar_2r().with_limits([0.3, 0.2], [0.3, 0.2])
    if name == "planar_3r_thin":
        return catalog.planar_3r(lengths=(1e-9, 1e3, 1e3))
    return getattr(catalog, name)()


ASSEMBLED = 12
"""Assembled reference configurations per closed chain (computed once, see `assembled`)."""


@cache
def assembled(m: optik.Mechanism) -> tuple[np.ndarray, ...]:
    """Configurations of a closed chain that close its loops within the limits: closed-form FK
    modes of seeded random actuated values (computed once: the Stewart-Gough FK of every mode
    takes 0.3 s; at most 2 s are spent), the mid-limit configuration when none assembles."""
    rng = np.random.default_rng(0)
    idx = m.actuated_indices
    found: list[np.ndarray] = []
    deadline = time.perf_counter() + 2.0  # a few Stewart-Gough solves; instant for the others
    for _ in range(10 * ASSEMBLED):
        if len(found) >= ASSEMBLED or not closed_form.has_fk(m) or time.perf_counter() > deadline:
            break
        found += closed_form.fk(m, rng.uniform(m.lower[idx], m.upper[idx]))[:2]
    return tuple(found) or (m.mid_q(),)


def _reference_q(m: optik.Mechanism, u: Sequence[float]) -> np.ndarray:
    """A configuration within the limits from numbers in ``[0, 1]`` (closed chains: one of
    `assembled`, picked by the first number)."""
    if m.is_closed:
        modes = assembled(m)
        return modes[min(int(u[0] * len(modes)), len(modes) - 1)]
    lo, hi = np.maximum(m.lower, -10.0), np.minimum(m.upper, 10.0)
    return lo + (hi - lo) * np.resize(np.asarray(u, dtype=float), m.n_q)


finite = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
"""Ordinary numbers."""
extreme = st.sampled_from([1e300, -1e300, 1e150, 1e9, -1e9, 1e-9, 1e-300, 0.0, 5e-324])
"""Huge, tiny and zero finite numbers."""
bad = st.sampled_from(BAD_VALUES)
"""Corrupted values."""
number = st.one_of(finite, finite, extreme, bad)
"""A number argument: mostly ordinary, sometimes extreme or corrupted."""
unit = st.floats(0.0, 1.0)


@cache
def vector(n: int) -> st.SearchStrategy:
    """An ``n``-vector argument: ordinary, with one extreme or corrupted entry, the wrong length,
    or a corrupted value instead."""
    ordinary = st.lists(finite, min_size=n, max_size=n)
    spoiled = st.tuples(ordinary, st.integers(0, max(n - 1, 0)), st.one_of(extreme, bad)).map(
        lambda t: [*t[0][: t[1]], t[2], *t[0][t[1] + 1 :]] if n else [t[2]]
    )
    return st.one_of(ordinary, ordinary, spoiled, st.lists(finite, max_size=n + 3), bad)


POOL_WEIGHT = {"stewart_gough": 1}
"""Relative frequency of a pool mechanism (default 4): the Stewart-Gough platform's FK of every
mode tracks 40 homotopy paths (0.3 s and more per call), so it is drawn less often."""


@cache
def _weighted(names: tuple[str, ...]) -> st.SearchStrategy:
    return st.sampled_from([n for n in names for _ in range(POOL_WEIGHT.get(n, 4))])


def _mechanism_names(*, closed: bool | None = None) -> st.SearchStrategy:
    return _weighted(tuple(n for n in POOL_NAMES if closed is None or pool(n).is_closed == closed))


_TARGET_KINDS = st.sampled_from(
    ["transform", "pose2d", "position", "far", "huge", "nan", "skewed", "shape", "bad"]
)


@cache
def targets(m: optik.Mechanism) -> st.SearchStrategy:
    """The (cached) strategy of `draw_target` for ``m``."""
    return draw_target(m)


@st.composite
def draw_target(draw: Any, m: optik.Mechanism) -> tuple[Any, str]:
    """A target for ``m`` (and its description): FK of a configuration within the limits as a
    4x4, Pose2D or Position, the same pushed out of reach, or a corrupted one."""
    q = _reference_q(m, draw(_units(m.n_q)))
    t = m.fk(q)
    kind = draw(_TARGET_KINDS)
    if kind == "transform":
        return t, "T(fk)"
    if kind == "pose2d":
        x, y, phi = spatial.planar_pose_of(t)
        return optik.Pose2D(float(x), float(y), float(phi)), "Pose2D(fk)"
    if kind == "position":
        return optik.Position(t[:3, 3]), "Position(fk)"
    if kind == "far":
        far = t.copy()
        far[:3, 3] *= draw(st.sampled_from([3.0, 10.0, 1e3]))
        return far, "T(far)"
    if kind == "huge":
        return draw(st.sampled_from([optik.Position(1e300, 0.0), optik.Position(-1e150, 1e150, 0.0)])), "huge"
    if kind == "nan":
        spoiled = t.copy()
        spoiled[draw(st.integers(0, 2)), draw(st.integers(0, 3))] = draw(st.sampled_from([NAN, INF]))
        return spoiled, "T(nan)"
    if kind == "skewed":
        skewed = t.copy()
        skewed[:3, :3] *= 1.5
        return skewed, "T(skewed)"
    if kind == "shape":
        return t[:3], "T[:3]"
    return draw(bad), "bad"


@cache
def _units(n: int) -> st.SearchStrategy:
    return st.lists(unit, min_size=n, max_size=n)


@cache
def _frame(m: optik.Mechanism) -> st.SearchStrategy:
    return st.one_of(st.none(), st.none(), st.sampled_from(list(m.frames)), bad, st.just("no_such_frame"))


_TASKS = ("pose", "position", "orientation", "pose2d", "position2d")


@cache
def _tol() -> st.SearchStrategy:
    return st.one_of(
        st.none(),
        st.none(),
        st.sampled_from([1e-6, 1e-4, 1e-2]),
        st.builds(
            optik.Tolerances,
            st.sampled_from([1e-6, 1e-3]),
            st.sampled_from([1e-6, 1e-3]),
            st.sampled_from([1e-9, 1e-6]),
        ),
        bad,
    )


bad_time = st.sampled_from([NAN, INF, -INF, -1.0, 0.0, 1e-300, "abc", [], [0.1], 1j, True, object()])
"""Corrupted time limits (no huge finite ones: a call may legitimately run up to its limit)."""


@cache
def _time_limit() -> st.SearchStrategy:
    return st.one_of(st.sampled_from([0.005, 0.02, 0.05]), st.sampled_from([0.005, 0.02]), bad_time)


def _limit(value: Any, default: float) -> float:
    """The time limit a call honours: its argument when that is a valid one, else the default."""
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        return default
    return v if math.isfinite(v) and v > 0 else default


def _key(*parts: Any) -> tuple[str, ...]:
    """A hashable `Call.key` from arguments of any type (their short reprs)."""
    return tuple(_short(p) for p in parts)


def _short(value: Any) -> str:
    text = repr(value) if not isinstance(value, np.ndarray) else f"array{value.shape}"
    return text if len(text) <= 60 else text[:57] + "..."


# ------------------------------------------------------------------------------ the entry strategies
METHODS = ("closed_form", "lm", "nlp", "dls", "qp")

_CLEAN = st.booleans()
_CLEAN_TIME = st.sampled_from([0.005, 0.02])
_SEED = st.integers(0, 100)
_SEED_ARG = st.one_of(st.none(), _SEED, bad)
_METHOD_ARG = st.one_of(st.none(), st.sampled_from(METHODS), bad)
_TASK_ARG = st.one_of(st.none(), st.none(), st.sampled_from(_TASKS), bad)
_OPTIONS_ARG = st.one_of(
    st.just({}),
    st.just({}),
    st.dictionaries(
        st.sampled_from(["max_restarts", "damping", "max_iterations", "no_such_option", "solver"]),
        number,
        max_size=1,
    ),
)


@cache
def _maybe_vector(n: int) -> st.SearchStrategy:
    return st.one_of(st.none(), st.none(), vector(n))


@st.composite
def solve_ik_call(draw: Any, method: str | None = None) -> Call:
    """``optik.solve_ik`` with every argument drawn (``method``: one method, else drawn too)."""
    closed = [n for n in POOL_NAMES if closed_form.has_ik(pool(n))]
    name = draw(
        st.sampled_from(closed) if method == "closed_form" and draw(st.integers(0, 4)) else _mechanism_names()
    )
    m = pool(name)
    target, what = draw(targets(m))
    meth = method if method is not None else draw(_METHOD_ARG)
    if draw(_CLEAN):  # every other argument valid (the target may still be unreachable)
        q0 = draw(st.one_of(st.none(), st.just(m.mid_q()), st.just(_reference_q(m, draw(_units(m.n_q))))))
        task, frame, time_limit, tol, seed, options = None, None, draw(_CLEAN_TIME), None, draw(_SEED), {}
    else:
        q0 = draw(_maybe_vector(m.n_q))
        task = draw(_TASK_ARG)
        frame = draw(_frame(m))
        time_limit = draw(_time_limit())
        tol = draw(_tol())
        seed = draw(_SEED_ARG)
        options = draw(_OPTIONS_ARG)
    label = (
        f"solve_ik {name} {what} method={meth!r} q0={_short(q0)} task={task!r} frame={_short(frame)} "
        f"time_limit={_short(time_limit)} tol={_short(tol)} seed={_short(seed)} {options}"
    )
    return Call(
        f"solve_ik[{method or 'any'}]",
        lambda: optik.solve_ik(
            m, target, q0, meth, task=task, frame=frame, time_limit=time_limit, tol=tol, seed=seed, **options
        ),
        check_ik(m, target, task, frame, tol),
        _limit(time_limit, 0.1),
        label,
        _key("solve_ik", name, meth, task, frame, type(target).__name__),
    )


@st.composite
def solve_ik_all_call(draw: Any) -> Call:
    name = draw(_mechanism_names())
    m = pool(name)
    target, what = draw(targets(m))
    meth = draw(st.one_of(st.none(), st.none(), st.sampled_from(["lm", "nlp"]), bad))
    time_limit = draw(_time_limit())
    tol = draw(_tol())
    kwargs = draw(
        st.one_of(
            st.just({}),
            st.just({}),
            st.dictionaries(
                st.sampled_from(["patience", "max_solutions", "closed_form"]), number, max_size=1
            ),
        )
    )
    label = (
        f"solve_ik_all {name} {what} method={meth!r} time_limit={_short(time_limit)} tol={_short(tol)} "
        f"{kwargs}"
    )
    return Call(
        "solve_ik_all",
        lambda: optik.solve_ik_all(m, target, None, meth, time_limit=time_limit, tol=tol, **kwargs),
        check_ik(m, target, None, None, tol),
        _limit(time_limit, 1.0),
        label,
        _key("solve_ik_all", name, meth, type(target).__name__),
    )


@st.composite
def solve_fk_call(draw: Any, all_modes: bool = False) -> Call:
    name = draw(_mechanism_names(closed=True) if draw(st.integers(0, 9)) else _mechanism_names())
    m = pool(name)
    n_act = len(m.actuated_indices)
    q = _reference_q(m, draw(_units(m.n_q)))
    actuated: Any = draw(st.one_of(st.just(list(q[m.actuated_indices])), vector(n_act)))
    time_limit = draw(st.one_of(st.sampled_from([0.02, 0.2]), bad_time))
    tol = draw(st.one_of(st.none(), st.sampled_from([1e-9, 1e-6]), bad))
    if name == "stewart_gough" and all_modes:  # homotopy over 40 paths: keep the share bounded
        actuated = list(q[m.actuated_indices]) if draw(st.integers(0, 3)) else actuated
    label = (
        f"solve_fk{'_all' if all_modes else ''} {name} actuated={_short(actuated)} "
        f"time_limit={_short(time_limit)} tol={_short(tol)}"
    )
    fn = optik.solve_fk_all if all_modes else optik.solve_fk
    return Call(
        "solve_fk_all" if all_modes else "solve_fk",
        lambda: fn(m, actuated, time_limit=time_limit, tol=tol),
        check_fk(m, actuated, tol),
        _limit(time_limit, 1.0),
        label,
        _key("solve_fk", name, all_modes),
    )


@st.composite
def closed_form_ik_call(draw: Any) -> Call:
    names = [n for n in POOL_NAMES if closed_form.has_ik(pool(n))]
    name = draw(st.sampled_from(names))
    m = pool(name)
    target, what = draw(targets(m))
    respect = draw(st.booleans())
    return Call(
        "closed_form.ik",
        lambda: closed_form.ik(m, target, respect_limits=respect),
        check_branches(m, target, respect),
        1.0,
        f"closed_form.ik {name} {what} respect_limits={respect}",
    )


@st.composite
def closed_form_fk_call(draw: Any) -> Call:
    name = draw(_weighted(tuple(n for n in POOL_NAMES if closed_form.has_fk(pool(n)))))
    m = pool(name)
    n_act = len(m.actuated_indices)
    q = _reference_q(m, draw(_units(m.n_q)))
    actuated: Any = draw(st.one_of(st.just(q[m.actuated_indices]), vector(n_act)))
    respect = draw(st.booleans())
    return Call(
        "closed_form.fk",
        lambda: closed_form.fk(m, actuated, respect_limits=respect),
        check_modes(m, actuated, respect),
        2.0,
        f"closed_form.fk {name} actuated={_short(actuated)} respect_limits={respect}",
    )


@st.composite
def mechanism_call(draw: Any) -> Call:
    name = draw(_mechanism_names())
    m = pool(name)
    what = draw(st.sampled_from(["fk", "fk_batch", "jacobian", "closure", "wrap", "with_limits"]))
    q = draw(st.one_of(vector(m.n_q), vector(m.n_q)))
    frame = draw(_frame(m))
    if what == "fk":
        run, check = (lambda: m.fk(q, frame)), check_transform
    elif what == "fk_batch":
        batch = draw(st.one_of(st.just([q, q]), st.just(np.zeros((0, m.n_q))), bad))
        run, check = (lambda: m.fk(batch)), check_transform
    elif what == "jacobian":
        run, check = (
            (lambda: m.jacobian(q, frame)),
            (lambda j: None if np.isfinite(j).all() else "not finite"),
        )
    elif what == "closure":
        run, check = (lambda: m.closure(q)), (lambda c: None if np.isfinite(c).all() else "not finite")
    elif what == "wrap":
        run, check = (lambda: m.wrap(q)), (lambda w: None if np.isfinite(w).all() else "not finite")
    else:
        lo = draw(st.one_of(st.none(), vector(m.n_q)))
        run, check = (lambda: m.with_limits(lo, None)), check_mechanism
    return Call(
        f"Mechanism.{what.split('_')[0]}",
        run,
        check,
        1.0,
        f"Mechanism.{what} {name} q={_short(q)} frame={_short(frame)}",
    )


_CONSTRUCTORS: dict[str, dict[str, st.SearchStrategy]] = {
    "planar_2r": {"lengths": vector(2), "lower": vector(2), "upper": vector(2)},
    "planar_3r": {"lengths": vector(3), "lower": vector(3), "upper": vector(3)},
    "rp_arm": {"lower": vector(2), "upper": vector(2)},
    "pp_arm": {"lower": vector(2), "upper": vector(2)},
    "seed_6r_arm": {"d2": number, "d3": number, "d4": number, "lower": vector(6)},
    "five_bar": {
        "base": st.one_of(st.just([[0.0, 0.0], [1.0, 0.0]]), vector(2), bad),
        "lengths": vector(4),
        "tool": number,
    },
    "doggy": {
        "feet": st.one_of(st.just([[0.0, 0.0], [1.0, 0.0]]), vector(2), bad),
        "hips": st.one_of(st.just([[-0.2, 0.0], [0.2, 0.0]]), vector(2), bad),
        "legs": vector(2),
    },
    "slider_crank": {"crank": number, "rod": number, "offset": number},
    "planar_3rpr": {
        "base": st.one_of(vector(3), st.just([[0, 0], [1, 0], [0.5, 1]]), bad),
        "platform": st.one_of(vector(3), bad),
        "leg_limits": vector(2),
    },
    "stewart_gough": {
        "base": st.one_of(vector(6), st.lists(vector(3), min_size=5, max_size=7), bad),
        "platform": st.one_of(vector(6), st.lists(vector(3), min_size=6, max_size=6), bad),
        "leg_limits": vector(2),
    },
}


@st.composite
def constructor_call(draw: Any) -> Call:
    """A catalog constructor or builder with drawn keyword arguments."""
    kind = draw(st.sampled_from([*_CONSTRUCTORS, "planar_chain", "dh_chain", "urdf_path", "panda"]))
    if kind == "planar_chain":
        types = draw(st.one_of(st.sampled_from(["R", "RR", "RPR", "PP"]), bad))
        lengths = draw(st.one_of(vector(2), vector(3)))
        run = lambda: optik.mechanism.planar_chain(types, lengths)  # noqa: E731
        label = f"planar_chain({types!r}, {_short(lengths)})"
    elif kind == "dh_chain":
        conv = draw(st.one_of(st.sampled_from(["seed", "standard", "modified"]), bad))
        rows = draw(
            st.one_of(
                st.lists(vector(3), min_size=1, max_size=3), st.lists(vector(2), min_size=1, max_size=3), bad
            )
        )
        run = lambda: optik.mechanism.dh_chain(rows, conv)  # noqa: E731
        label = f"dh_chain({_short(rows)}, {conv!r})"
    elif kind == "urdf_path":
        robot = draw(st.one_of(st.sampled_from(["panda", "iiwa14", "no_such_robot"]), bad))
        return Call("catalog", lambda: catalog.urdf_path(robot), lambda p: None, 1.0, f"urdf_path({robot!r})")
    elif kind == "panda":
        run, label = catalog.panda, "panda()"
    else:
        params = _CONSTRUCTORS[kind]
        chosen = draw(st.sets(st.sampled_from(sorted(params)), max_size=len(params)))
        kwargs = {k: draw(params[k]) for k in sorted(chosen)}
        run = lambda: getattr(catalog, kind)(**kwargs)  # noqa: E731
        label = f"{kind}({', '.join(f'{k}={_short(v)}' for k, v in kwargs.items())})"
    return Call("catalog", run, check_mechanism, 2.0, label)


@st.composite
def joint_call(draw: Any) -> Call:
    kwargs: dict[str, Any] = {}
    jtype = draw(
        st.one_of(st.sampled_from(["revolute", "prismatic", "fixed", "universal", "spherical"]), bad)
    )
    for key, strategy in (
        ("origin", st.one_of(st.just(np.eye(4)), bad, st.just(np.full((4, 4), NAN)))),
        ("axis", st.one_of(vector(3), st.just("z"))),
        ("lower", st.one_of(number, vector(2))),
        ("upper", st.one_of(number, vector(2))),
        ("actuated", st.one_of(st.booleans(), bad)),
    ):
        if draw(st.booleans()):
            kwargs[key] = draw(strategy)
    name = draw(st.one_of(st.just("j"), bad))
    label = f"Joint({name!r}, {jtype!r}, {', '.join(f'{k}={_short(v)}' for k, v in kwargs.items())})"
    return Call("Joint", lambda: optik.Joint(name, jtype, "a", "b", **kwargs), lambda j: None, 1.0, label)


def _mutate(text: str, draw: Any) -> str:
    """A corrupted version of a text: cut, characters inserted or deleted, a number replaced."""
    how = draw(st.sampled_from(["cut", "insert", "delete", "number", "same", "bytes"]))
    n = len(text)
    at = draw(st.integers(0, max(n - 1, 0)))
    if how == "cut":
        return text[:at]
    if how == "insert":
        return (
            text[:at]
            + draw(st.sampled_from(["<", ">", '"', "[", "]", "\x00", "\ud800", "é", "=", "\n[x]\n"]))
            + text[at:]
        )
    if how == "delete":
        return text[:at] + text[at + draw(st.integers(1, 20)) :]
    if how == "number":
        return text.replace(
            draw(st.sampled_from(["0.", "1", "3", "-"])),
            draw(st.sampled_from(["nan", "inf", "1e309", "-1e300", "x", "", "999999999999999999999"])),
            1,
        )
    if how == "bytes":
        return text + "\udcff"
    return text


@cache
def _texts() -> dict[str, str]:
    out = {"panda.urdf": Path(catalog.urdf_path("panda")).read_text(encoding="utf-8")}
    problems = Path(optik.problem_files.PROBLEM_DIR)
    for p in sorted(problems.glob("*.toml")):
        out[p.name] = p.read_text(encoding="utf-8")
    return out


def _write(text: str, suffix: str) -> str:
    fd, path = tempfile.mkstemp(suffix=suffix, prefix="optik-fuzz-")
    with os.fdopen(fd, "wb") as f:
        f.write(text.encode("utf-8", errors="surrogatepass"))
    return path


def _with_file(text: str, suffix: str, use: Callable[[str], Any]) -> Callable[[], Any]:
    def run() -> Any:
        path = _write(text, suffix)
        try:
            return use(path)
        finally:
            os.unlink(path)

    return run


@st.composite
def urdf_call(draw: Any) -> Call:
    text = _mutate(_texts()["panda.urdf"], draw)
    base = draw(st.one_of(st.just("panda_link0"), st.none(), st.just("nowhere"), bad))
    tip = draw(st.one_of(st.just("panda_link8"), st.just("panda_link4"), st.none(), bad))
    run = _with_file(text, ".urdf", lambda p: optik.Mechanism.from_urdf(p, base, tip))
    return Call(
        "from_urdf",
        run,
        check_mechanism,
        3.0,
        f"from_urdf base={_short(base)} tip={_short(tip)} text[{len(text)}]",
    )


@st.composite
def problem_file_call(draw: Any) -> Call:
    files = [n for n in _texts() if n.endswith(".toml")]
    name = draw(st.sampled_from(files))
    text = _mutate(_texts()[name], draw)
    sample = draw(st.booleans())

    def use(path: str) -> Any:
        problem = optik.problem_files.load_problem(path)
        m = problem.mechanism()
        if sample and not m.is_closed:
            problem.sample_targets(1)
        return m

    return Call(
        "problem_file", _with_file(text, ".toml", use), check_mechanism, 3.0, f"load_problem {name} mutated"
    )


@st.composite
def task_call(draw: Any) -> Call:
    kind = draw(
        st.sampled_from(
            [
                "FrameTask",
                "PositionTask",
                "OrientationTask",
                "Pose2DTask",
                "PostureTask",
                "JointLimitTask",
                "ManipulabilityTask",
                "VelocityLimit",
                "ConfigurationLimit",
                "AccelerationLimit",
            ]
        )
    )
    cls = getattr(diffik, kind)
    if kind in ("VelocityLimit", "AccelerationLimit", "ConfigurationLimit"):
        arg = draw(st.one_of(number, vector(3)))
        return Call("diffik.task", lambda: cls(arg), lambda r: None, 1.0, f"{kind}({_short(arg)})")
    if kind in ("PostureTask", "JointLimitTask", "ManipulabilityTask"):
        first = draw(st.one_of(vector(3), st.just(3), number))
        extra = draw(
            st.dictionaries(st.sampled_from(["cost", "gain", "priority", "lm_damping"]), number, max_size=2)
        )
        if kind == "JointLimitTask" and draw(st.booleans()):
            extra["exponent"] = draw(number)
        if kind == "ManipulabilityTask" and draw(st.booleans()):
            extra["space"] = draw(st.one_of(st.sampled_from(_TASKS), bad))
        return Call(
            "diffik.task",
            lambda: cls(first, **extra),
            lambda r: None,
            1.0,
            f"{kind}({_short(first)}, {extra})",
        )
    target = draw(
        st.one_of(st.none(), st.just(np.eye(4)), st.just(optik.Pose2D(0.1, 0.2, 0.3)), vector(3), bad)
    )
    frame = draw(st.one_of(st.none(), st.just("ee"), bad))
    extra = draw(st.dictionaries(st.sampled_from(["gain", "priority", "lm_damping"]), number, max_size=2))
    return Call(
        "diffik.task",
        lambda: cls(frame, target, **extra),
        lambda r: None,
        1.0,
        f"{kind}({_short(frame)}, {_short(target)}, {extra})",
    )


def _tracking_task(m: optik.Mechanism, target: Any) -> diffik.Task:
    task = diffik.tracking_task(m, None, None)
    task.set_target(target)
    return task


@st.composite
def step_call(draw: Any) -> Call:
    name = draw(_mechanism_names())
    m = pool(name)
    q0 = _reference_q(m, draw(_units(m.n_q)))
    q: Any = draw(st.one_of(st.just(q0), st.just(q0), vector(m.n_q)))
    target, what = draw(targets(m))
    dt = draw(st.one_of(st.sampled_from([0.01, 0.1, 1.0]), number))
    method = draw(st.one_of(st.sampled_from(["qp", "dls", "pinv", "priority"]), bad))
    solver = draw(st.one_of(st.none(), st.none(), st.sampled_from(["osqp", "daqp", "no_such_solver"]), bad))
    limits = draw(
        st.one_of(
            st.none(),
            st.just([diffik.VelocityLimit(1.0)]),
            st.just([diffik.VelocityLimit(2.0), diffik.AccelerationLimit(50.0)]),
            bad,
        )
    )
    options = draw(
        st.one_of(
            st.just({}),
            st.dictionaries(
                st.sampled_from(["damping", "joint_weights", "adaptive"]),
                st.one_of(number, vector(m.n_q)),
                max_size=1,
            ),
        )
    )
    label = (
        f"diffik.step {name} q={_short(q)} {what} dt={_short(dt)} method={method!r} solver={solver!r} "
        f"limits={_short(limits)} {options}"
    )
    return Call(
        "diffik.step",
        lambda: diffik.step(m, q, [_tracking_task(m, target)], dt, method, solver, limits, **options),
        check_step(m, q, limits if isinstance(limits, list) else None)
        if isinstance(q, np.ndarray)
        else (lambda r: None),
        1.0,
        label,
        _key("step", name, method, solver, type(target).__name__, limits),
    )


@st.composite
def track_call(draw: Any) -> Call:
    name = draw(st.sampled_from(["planar_2r", "planar_3r", "seed_6r_arm", "five_bar", "panda"]))
    m = pool(name)
    q0 = _reference_q(m, draw(_units(m.n_q)))
    t0 = m.fk(q0)
    kind = draw(st.sampled_from(["line", "positions", "points", "pose2d", "bad"]))
    n = draw(st.integers(2, 12))
    shift = draw(st.sampled_from([0.01, 0.3, 3.0]))
    t1 = t0.copy()
    t1[0, 3] += shift
    if kind == "line":
        path: Any = diffik.line_path(t0, t1, shift / ((n - 1) * 0.01), 0.01)  # n samples
    elif kind == "positions":
        path = [optik.Position(t0[:3, 3] + [shift * k / n, 0.0, 0.0]) for k in range(n)]
    elif kind == "points":
        path = np.array([t0[:3, 3] + [shift * k / n, 0.0, 0.0] for k in range(n)])
    elif kind == "pose2d":
        x, y, phi = spatial.planar_pose_of(t0)
        path = [optik.Pose2D(float(x) + shift * k / n, float(y), float(phi)) for k in range(n)]
    else:
        path = draw(bad)
    method = draw(st.one_of(st.sampled_from(["qp", "dls"]), bad))
    dt = draw(st.one_of(st.just(0.01), number))
    label = f"diffik.track {name} {kind} n={n} shift={shift} method={method!r} dt={_short(dt)}"
    return Call(
        "diffik.track",
        lambda: diffik.track(m, q0, path, dt, method),
        check_track(m, q0),
        0.1 * n + 1.0,
        label,
        _key("track", name, kind, method),
    )


@st.composite
def path_call(draw: Any) -> Call:
    kind = draw(st.sampled_from(["line", "circle", "polyline"]))
    if kind == "line":
        speed = draw(st.one_of(number, st.just(1e-9)))
        end = draw(st.one_of(st.just(spatial.translation(1.0, 0.0, 0.0)), bad))
        run = lambda: diffik.line_path(np.eye(4), end, speed, 0.01)  # noqa: E731
        label = f"line_path(speed={_short(speed)}, end={_short(end)})"
    elif kind == "circle":
        args = [draw(st.one_of(vector(3), bad)), draw(number), draw(st.one_of(number, st.just(1e-9))), 0.01]
        kw = draw(
            st.dictionaries(
                st.sampled_from(["turns", "start_angle", "normal", "rotation"]),
                st.one_of(number, vector(3)),
                max_size=2,
            )
        )
        run = lambda: diffik.circle_path(*args, **kw)  # noqa: E731
        label = f"circle_path({', '.join(_short(a) for a in args)}, {kw})"
    else:
        points = draw(
            st.one_of(st.just([[0.3, 0, 0.5], [0.4, 0.1, 0.5]]), st.lists(vector(3), max_size=4), bad)
        )
        speed, dt = draw(st.one_of(number, st.just(1e-9))), draw(number)
        run = lambda: diffik.polyline_path(points, speed, dt)  # noqa: E731
        label = f"polyline_path({_short(points)}, {_short(speed)}, {_short(dt)})"
    return Call("diffik.path", run, check_transform, 1.0, label)


_PROBLEMS = ("planar_2r", "planar_3r", "five_bar", "seed_6r_arm", "stewart_gough", "no_such_problem")


def _cli_args(draw: Any) -> list[str]:
    command = draw(st.sampled_from(["solve", "fk", "plot", "solve", "fk"]))
    problem = draw(st.sampled_from(_PROBLEMS))
    numbers = [
        str(draw(st.one_of(finite, extreme, st.sampled_from(["nan", "inf", "x", "1e309"]))))
        for _ in range(draw(st.integers(0, 7)))
    ]
    args = [command, problem]
    if command == "solve":
        args += ["--target", *numbers] if numbers else ["--target", "1", "0.5"]
        if draw(st.booleans()):
            args += ["--method", draw(st.sampled_from(["lm", "nlp", "closed_form", "warp"]))]
        if draw(st.booleans()):
            args += ["--time-limit", draw(st.sampled_from(["0.02", "0", "-1", "nan", "x"]))]
    elif command == "fk":
        args += ["--q", *numbers] if numbers else ["--q", "0.1", "0.2"]
    else:
        args += ["--mode", draw(st.sampled_from(["config", "branches", "sideways"]))]
    if draw(st.integers(0, 3)) == 0:
        args += [
            "--plot" if command != "plot" else "--out",
            draw(st.sampled_from(["/proc/x.png", "{tmp}/p.zzz", "{tmp}"])),
        ]
    return args


@st.composite
def cli_call(draw: Any, subprocess_run: bool = False) -> Call:
    """The ``optik`` command in process (``main(argv)``) or through a subprocess: exit code 0, 1
    or 2 and never a traceback."""
    args = _cli_args(draw)

    def run() -> Any:
        with tempfile.TemporaryDirectory(prefix="optik-fuzz-cli-") as tmp:
            argv = [a.replace("{tmp}", tmp) for a in args]
            if not subprocess_run:
                import contextlib
                import io

                from optik.cli import main

                out, err = io.StringIO(), io.StringIO()
                with contextlib.chdir(tmp), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                    code = main(argv)
                return code, err.getvalue()
            env = {**os.environ, "MPLBACKEND": "Agg"}
            proc = subprocess.run(
                [sys.executable, "-m", "optik.cli", *argv],
                capture_output=True,
                text=True,
                timeout=120,
                env=env,
                cwd=tmp,
            )
            return proc.returncode, proc.stderr

    def check(result: Any) -> str | None:
        code, err = result
        if code not in (0, 1, 2) or "Traceback" in err:
            return f"exit code {code}: {err.strip().splitlines()[-1] if err.strip() else ''}"[:300]
        return None

    entry = "cli (subprocess)" if subprocess_run else "cli"
    method = args[args.index("--method") + 1] if "--method" in args else None
    key = None if subprocess_run else _key("cli", *args[:2], method)
    return Call(entry, run, check, 20.0 if subprocess_run else 5.0, "optik " + " ".join(args), key)


ENTRIES: dict[str, Callable[[], st.SearchStrategy]] = {
    **{f"solve_ik[{meth}]": (lambda meth=meth: solve_ik_call(meth)) for meth in METHODS},
    "solve_ik[any]": lambda: solve_ik_call(None),
    "solve_ik_all": solve_ik_all_call,
    "solve_fk": lambda: solve_fk_call(False),
    "solve_fk_all": lambda: solve_fk_call(True),
    "closed_form.ik": closed_form_ik_call,
    "closed_form.fk": closed_form_fk_call,
    "Mechanism": mechanism_call,
    "catalog": constructor_call,
    "Joint": joint_call,
    "from_urdf": urdf_call,
    "problem_file": problem_file_call,
    "diffik.task": task_call,
    "diffik.step": step_call,
    "diffik.track": track_call,
    "diffik.path": path_call,
    "cli": lambda: cli_call(False),
    "cli (subprocess)": lambda: cli_call(True),
}
"""Every fuzzed entry point: name -> strategy of its calls."""

WEIGHTS: dict[str, int] = {
    "solve_ik[closed_form]": 6,
    "solve_ik[lm]": 6,
    "solve_ik[nlp]": 3,
    "solve_ik[dls]": 3,
    "solve_ik[qp]": 3,
    "solve_ik[any]": 6,
    "solve_ik_all": 2,
    "solve_fk": 4,
    "solve_fk_all": 2,
    "closed_form.ik": 8,
    "closed_form.fk": 5,
    "Mechanism": 10,
    "catalog": 8,
    "Joint": 6,
    "from_urdf": 3,
    "problem_file": 3,
    "diffik.task": 6,
    "diffik.step": 6,
    "diffik.track": 1,
    "diffik.path": 5,
    "cli": 1,
}
"""Relative frequency of each entry in the mixed stream (the subprocess CLI is run apart: it
costs a process start per call)."""


def mixed(weights: dict[str, int] | None = None) -> st.SearchStrategy:
    """Calls of every entry point, in the proportions of ``weights``."""
    w = WEIGHTS if weights is None else weights
    names = [name for name, k in w.items() for _ in range(k)]
    return st.sampled_from(names).flatmap(lambda name: ENTRIES[name]())


def warm_up() -> None:
    """Build the pool and solve once per mechanism and method, so that first-time compilation is
    not timed against the calls' limits (it is excluded anyway where results report it)."""
    for name in POOL_NAMES:
        m = pool(name)
        if m.is_closed:
            assembled(m)
        t = m.fk(_reference_q(m, [0.5] * m.n_q))
        for method in METHODS:
            with contextlib.suppress(OptikError):
                optik.solve_ik(m, t, method=method, time_limit=0.05)
        m.jacobian(m.mid_q())
        if m.is_closed:
            m.closure(m.mid_q())
