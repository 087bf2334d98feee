"""The nodes of a path's graph: every solution of every pose, with its turns.

A revolute joint whose range is wider than ``2 pi`` reaches one angle in several ways: ``q``,
``q + 2 pi``, ... are distinct configurations of the joint (a cable wraps differently) and a
path may need any of them to stay continuous. `turn_copies` lists, for each solution, every
combination of the shifts ``2 pi k`` (``|k| <= 2``) of its angles that keeps each within its
limits; the closed forms return one representative per solution (wrapped into the limits).

Most paths need no such copy: `optik.path.plan` first plans on the representatives with the
angles of *wrapping* joints (revolute, range at least ``2 pi``) compared modulo ``2 pi`` (a
relaxation: no copy path is shorter), and `realize` turns that answer into configurations by
counting its turns; only when the turns do not fit the limits is the graph of every copy needed.
"""

from __future__ import annotations

import numpy as np

from optik.errors import SolverUnavailableError
from optik.mechanism import Mechanism
from optik.solvers import solve_ik_all, solve_ik_all_batch
from optik.solvers.closed import many_binding_of
from optik.spatial import wrap_to_limits

SHIFTS = 2.0 * np.pi * np.array([0.0, 1.0, -1.0, 2.0, -2.0])
"""Multiples of ``2 pi`` tried on each angle."""


def turn_copies(
    q: np.ndarray, lower: np.ndarray, upper: np.ndarray, angles: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Every copy of the rows of ``q (K, n)`` with its angles shifted by multiples of ``2 pi``
    within ``[lower, upper]``.

    Args:
        q: configurations within the limits.
        lower, upper: joint limits ``(n,)``.
        angles: ``(n,)`` True for the revolute coordinates.

    Returns:
        The copies ``(M, n)`` (each row of ``q`` first, unshifted) and, for each, the row of ``q``
        it copies ``(M,)``.
    """
    rows, source = q, np.arange(len(q))
    for j in np.flatnonzero(angles):
        vals = rows[:, j, None] + SHIFTS[None, :]
        ok = (vals >= lower[j]) & (vals <= upper[j])
        r, s = np.nonzero(ok)
        rows = rows[r].copy()
        rows[:, j] = vals[r, s]
        source = source[r]
    return rows, source


def into_limits(q: np.ndarray, lower: np.ndarray, upper: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """The rows of ``q (..., n)`` with their angles shifted by whole turns into the limits
    (`optik.spatial.wrap_to_limits`), NaN rows where some coordinate does not fit.

    Args:
        q: configurations, any leading shape.
        lower, upper: joint limits ``(n,)``.
        angles: ``(n,)`` True for the revolute coordinates.
    """
    rows = q.reshape(-1, q.shape[-1])
    with np.errstate(invalid="ignore"):  # inf limits
        # the least shift 2 pi k above lower - SLACK; past upper + SLACK no whole turn fits
        up = rows + np.where(angles, _TURN * np.ceil((lower - FIT_SLACK - rows) / _TURN), 0.0)
    may = np.all(np.isfinite(rows) & (up <= upper + FIT_SLACK), axis=-1)  # a cheap, loose first test
    out = np.full(rows.shape, np.nan)
    out[may] = wrap_to_limits(rows[may], lower, upper, angles)
    out[~np.all((out >= lower) & (out <= upper), axis=-1)] = np.nan
    return out.reshape(q.shape)


_TURN = 2.0 * np.pi
FIT_SLACK = 1e-9
"""Margin of the first test of `into_limits`: a row it rejects misses the limits by more than a
rounding, so only the rows that may fit go through `optik.spatial.wrap_to_limits`."""


def wrapping(m: Mechanism) -> np.ndarray:
    """Per coordinate, ``2 pi`` for a revolute joint whose range is at least ``2 pi`` (it can
    turn past ``+-pi``), else 0: the periods of the relaxed graph."""
    angles = np.asarray(m.revolute_mask, dtype=bool)
    return np.where(angles & (m.upper - m.lower >= 2.0 * np.pi), 2.0 * np.pi, 0.0)


def realize(rows: np.ndarray, periods: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray | None:
    """Configurations ``(N, n)`` of a path through the representatives ``rows (N, n)`` of the
    relaxed graph: each wrapping angle continues its last value by the step modulo ``2 pi``
    (whole turns counted exactly, ``q = row + 2 pi turns``), the whole joint shifted by the whole
    turns nearest zero that fit it within its limits; None when some joint's sweep does not fit.
    """
    q = rows.copy()
    for j in np.flatnonzero(periods > 0.0):
        step = np.diff(rows[:, j])
        turns = np.concatenate([[0.0], np.cumsum(-np.round(step / periods[j]))])
        swept = rows[:, j] + periods[j] * turns
        lo = np.ceil((lower[j] - swept.min()) / periods[j])
        hi = np.floor((upper[j] - swept.max()) / periods[j])
        if lo > hi:
            return None
        shift = min(max(0.0, lo), hi)
        q[:, j] = rows[:, j] + periods[j] * (turns + shift)
        if np.any(q[:, j] < lower[j]) or np.any(q[:, j] > upper[j]):  # rounding at a limit
            return None
    return q


def closed_form_solutions(
    m: Mechanism, poses: np.ndarray, frame: str | None
) -> tuple[np.ndarray, np.ndarray]:
    """Every solution within the limits of each of ``poses (P, 4, 4)``, by ``m``'s closed form
    (certified complete), as rows ``(K, n)`` pose after pose and the count of each pose
    ``(P,)``: one `optik.solve_ik_all_batch` call (one C call over every pose) when the closed
    form has a compiled many-target driver and the tool is the end effector, else
    `optik.solve_ik_all` pose by pose.

    Raises:
        SolverUnavailableError: ``m`` has no closed form (a redundant arm: plan with
            ``self_motion``), or its answer is not certified complete (the graph would then
            miss solutions).
    """
    if frame is None and m.n_q == 6 and many_binding_of(m) is not None:
        batch = solve_ik_all_batch(m, poses)
        bad = np.flatnonzero(~batch.certified)
        if bad.size:
            k = int(bad[0])
            _uncertified(m, k, batch[k].uncertified_reason)
        return batch.q, np.asarray(batch.counts, dtype=np.int64)
    out = []
    for k, t in enumerate(poses):
        sols = solve_ik_all(m, t, method="closed_form", frame=frame)
        if not sols.certified:
            _uncertified(m, k, sols.uncertified_reason)
        out.append(np.asarray(sols.q, dtype=float).reshape(-1, m.n_q))
    counts = np.array([len(x) for x in out], dtype=np.int64)
    return (np.concatenate(out) if out else np.zeros((0, m.n_q))), counts


def _uncertified(m: Mechanism, k: int, reason: str | None) -> None:
    raise SolverUnavailableError(
        f"the closed form of {m.name!r} does not certify that it found every solution of "
        f"pose {k} ({reason}); plan_path needs every solution"
    )
