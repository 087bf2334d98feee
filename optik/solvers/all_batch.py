"""``solve_ik_all_batch``: every IK solution of many targets in one call, as arrays.

For an arm whose closed form is derived (``optik.closed_form.derived``) and compiled, the
targets go through one C call (``optik.closed_form.ik_all``, the many-target binding: the
single-target driver run target after target with the interpreter lock released), and the
solutions come back as flat arrays (`optik.results.IKSolutionsBatch`): no Python object is
made per solution or per target. A target the driver hands back (a candidate to polish, two
close candidates, an invalid transform) and every target of a mechanism without such a driver
is answered by ``optik.solve_ik_all`` itself, with the same answer it gives alone, and its rows
are spliced in place.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from optik.checks import as_transform, as_vector, real_array
from optik.errors import ShapeError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.results import IKSolutions, IKSolutionsBatch
from optik.solvers.all import solve_ik_all
from optik.solvers.closed import many_binding_of


def solve_ik_all_batch(m: Mechanism, targets: Any, q0: Any = None, **options: Any) -> IKSolutionsBatch:
    """Every distinct IK solution within the joint limits of each of many targets.

    Args:
        m: the mechanism.
        targets: ``(M, 4, 4)`` transforms (or one ``(4, 4)``).
        q0: None (each target's solutions are ordered by their distance to the middle of the
            limits), one start ``(n,)`` for all, or one per target ``(M, n)``.
        **options: further arguments of ``optik.solve_ik_all`` (e.g. ``method``,
            ``time_limit``); with any, every target goes through ``solve_ik_all``.

    Returns:
        An ``optik.results.IKSolutionsBatch``: target ``i``'s solutions, nearest its start
        first, are rows ``offsets[i]:offsets[i + 1]`` of ``q``, the same as
        ``solve_ik_all(m, targets[i], q0)`` gives.

    Raises:
        OptikError: malformed input (the argument named, ``targets[i]`` for one bad target),
            or what ``solve_ik_all`` raises for the options.
    """
    start = time.perf_counter()
    t = real_array(targets, "targets")
    if t.shape == (4, 4):
        t = t[None]
    if t.ndim != 3 or t.shape[1:] != (4, 4):
        raise ShapeError("targets", f"expected (M, 4, 4) transforms, got shape {t.shape}")
    t = np.ascontiguousarray(t, dtype=np.float64)
    starts = _starts(m, q0, len(t))
    many = None if options or m.n_q != 6 else many_binding_of(m)
    got = None
    if many is not None:
        try:
            got = many(t, starts, m.lower, m.upper, True)
        except RuntimeError as exc:  # the generated code reported an error
            raise SolverUnavailableError(str(exc)) from None
    if got is None:
        n = m.n_q
        empty = np.zeros(len(t), dtype=np.int64)
        got = (np.zeros((0, n)), np.zeros((0, 2)), empty, np.zeros((0, n)), empty.copy(), empty + 2)
    q, errors, counts, outside, outside_counts, status = got
    certified = status == 0
    general = {}
    for i in np.flatnonzero(status).tolist():
        if status[i] == 1:
            as_transform(t[i], f"targets[{i}]")  # raises the named error
        q_i = None if starts is None else (starts if starts.ndim == 1 else starts[i])
        general[i] = sols = solve_ik_all(m, t[i], q_i, **options)
        certified[i] = sols.certified
    if general:
        q, errors, counts, outside, outside_counts = _splice(
            m.n_q, general, q, errors, counts, outside, outside_counts
        )
    return IKSolutionsBatch(
        q, errors, counts, outside, outside_counts, certified, time.perf_counter() - start, general
    )


def _starts(m: Mechanism, q0: Any, count: int) -> np.ndarray | None:
    """``q0`` checked: None, ``(n,)`` or ``(count, n)``, finite, C-contiguous."""
    if q0 is None:
        return None
    a = real_array(q0, "q0")
    if a.ndim == 2:
        if a.shape != (count, m.n_q):
            raise ShapeError("q0", f"expected ({m.n_q},) or ({count}, {m.n_q}), got shape {a.shape}")
        for row in a:
            as_vector(row, "q0", m.n_q)
        return np.ascontiguousarray(a, dtype=np.float64)
    return np.ascontiguousarray(as_vector(a, "q0", m.n_q), dtype=np.float64)


def _splice(
    n: int,
    general: dict[int, IKSolutions],
    q: np.ndarray,
    errors: np.ndarray,
    counts: np.ndarray,
    outside: np.ndarray,
    outside_counts: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The arrays with the rows of the targets of ``general`` put in their place."""
    counts, outside_counts = counts.copy(), outside_counts.copy()
    at, out_at = np.cumsum(counts), np.cumsum(outside_counts)  # rows before each target's end
    pieces: tuple[list, list, list] = ([], [], [])
    done = done_out = 0
    for i, sols in sorted(general.items()):
        end, end_out = int(at[i]), int(out_at[i])  # the target's own counts are 0
        rows = np.array([r.q for r in sols]).reshape(-1, n)
        errs = np.array([(r.position_error, r.orientation_error) for r in sols]).reshape(-1, 2)
        off = np.array(sols.outside_limits).reshape(-1, n)
        pieces[0].extend((q[done:end], rows))
        pieces[1].extend((errors[done:end], errs))
        pieces[2].extend((outside[done_out:end_out], off))
        done, done_out = end, end_out
        counts[i], outside_counts[i] = len(rows), len(off)
    pieces[0].append(q[done:])
    pieces[1].append(errors[done:])
    pieces[2].append(outside[done_out:])
    return (
        np.concatenate(pieces[0]),
        np.concatenate(pieces[1]),
        counts,
        np.concatenate(pieces[2]),
        outside_counts,
    )
