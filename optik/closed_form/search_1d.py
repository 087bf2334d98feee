"""All IK solutions of 6R arms with a special pair of end axes, by a 1-D search.

A 6R arm whose axes 1-2 (or 5-6) intersect or are parallel, but that belongs to no decomposable
family (`optik.closed_form.structure.detect`), has no subproblem decomposition into closed
forms; when its other end is special too, the general eigenvalue solver is singular from both
ends (`optik.closed_form.general_6r.covers` is False). Fixing one joint angle ``theta`` of such
an arm leaves subproblems with closed forms and one scalar equation ``e(theta) = 0`` that the
remaining angles do not satisfy in general; the IK solutions are the zeros of ``e`` on each
branch of the subproblems. In product-of-exponentials form (`optik.closed_form.structure`,
``R06 = R_t R_M^T = R_1 ... R_6`` with ``R_i = rot(h_i, q_i)``, ``E_i`` the motion of joint
``i``):

* **5-6 intersecting** at ``W`` (`scan_56_intersecting`): ``E_5 E_6`` fix ``W``, so
  ``E_1 E_2 E_3 E_4 W = w``, ``w = R06 (W - p_M) + p_t``. Sweep ``q4``; then ``(q1, q2, q3)``
  solve the SP5 ``r_1 - r_2 + rot(h_1, -q1) (w - r_1) = rot(h_2, q2) (r_3 - r_2 + rot(h_3, q3)
  (E_4 W - r_3))`` (up to four branches), and the wrist ``R_5 R_6 = A = (R_1 ... R_4)^T R06``
  exists when ``e = h_5 . A h_6 - h_5 . h_6 = 0``; then ``q5``, ``q6`` by SP1. When axes 1-2
  meet at ``C`` the SP5 degenerates (``p0 = 0``: a Kinova Jaco): ``E_1 E_2`` fix ``C``, so
  ``q3`` solves the SP3 ``|E_3 E_4 W - C| = |w - C|`` and ``(q1, q2)`` the SP2
  ``rot(h_1, -q1) (w - C) = rot(h_2, q2) (E_3 E_4 W - C)`` (`_sp3_sp2`).
* **1-2 parallel** along ``k`` (`scan_12_parallel`): ``R_1 R_2`` is a rotation about ``k``
  and ``E_1 E_2`` keep the ``k`` component of a point, so ``k^T R_3 ... R_6 = k^T R06`` and
  ``k . (E_3 ... E_6 p_M) = k . p_t``. Sweep ``q3``; multiplied by ``R_6^T h_5`` the first and
  rewritten with ``k^T R_3 R_4 R_5 = k^T R06 R_6^T`` the second are the SP6 in ``(q4, q6)``
  ``(R_3^T k) . rot(h_4, q4) h_5 - (R06^T k) . rot(-h_6, q6) h_5 = 0``,
  ``(R_3^T k) . rot(h_4, q4) (r_5 - r_4) + (R06^T k) . rot(-h_6, q6) (r_6 - r_5) = k . p_t -
  k . r_3 - (R_3^T k) . (r_4 - r_3) - (R06^T k) . (p_M - r_6)`` (up to four branches); ``q5`` by
  SP1, ``R_1 R_2 = R06 (R_3 ... R_6)^T``, and the planar pair needs
  ``R_1 (r_2 - r_1) = y = p_t - r_1 - R_1 R_2 (X - r_2)``, ``X = E_3 ... E_6 p_M``: the error is
  ``e = |y_perp| - |(r_2 - r_1)_perp|`` (components normal to ``k``), then ``q1``, ``q2`` by SP1.
* **1-2 intersecting** and **5-6 parallel**: the inverse chain (`Axes.reversed`, whose axes 5-6
  are the arm's axes 2-1) by the two scans above, ``q = -reverse(q')``.

`FAMILIES` lists them in the order `family_of` tries them; the scans are vectorized over
targets and angles.

**The search** (`Search1D.solve`), per target, all targets at once:

1. ``e`` and the branches (all six angles) at `SAMPLES` angles evenly spaced on the circle
   (spacing ``h = 2 pi / SAMPLES``); a branch is valid where its subproblems hold to
   `VALID_TOL` (times the arm's size);
2. the branches of neighbouring samples are matched by the permutation with the smallest total
   joint distance; a matched pair closer than `JUMP` rad continues a branch;
3. candidates: every sign change of ``e`` along a continued branch (a bracket, refined by
   `REFINE_STEPS` Illinois steps that re-solve the subproblems at the new angle and follow the
   branch nearest the interpolated one); two close zeros that a parabola through three samples
   of one branch predicts (same signs at the samples, vertex beyond zero); and the ends of
   branches where two branches of opposite signs of ``e`` end (or begin) together (a zero near
   the turning point where they merge);
4. the intervals where something may hide are sampled again at `SUBDIVISIONS` sub-intervals,
   `LEVELS` times (finest spacing ``h / SUBDIVISIONS^LEVELS``), and step 2-3 run on them: where
   a branch ends, begins or jumps; where a continued branch comes within one interval of a
   zero without a sign change (a near tangency); and where the smallest residual of the invalid
   branches has a local minimum below `NEAR_TOL` (a branch may exist on an island of the swept
   angle shorter than the spacing);
5. every candidate is polished by up to `POLISH_STEPS` damped Gauss-Newton steps on the exact
   pose residual ``[p - p*; log(R R*^T)]``, kept when its FK error is at most ``CHECK_TOL``
   (`optik.closed_form.derived`: 1e-9 times the arm's size, 1e-9 rad), wrapped to
   ``(-pi, pi]`` and deduplicated (max-norm distance below `SAME_TOL`, angles modulo 2 pi). At
   most 16 are returned (the Bezout bound of a 6R; more would mean a self-motion, and the
   reason says so).

**What it guarantees, and what not.** Every answer is a verified solution. Completeness is
*not* certified. A simple zero of ``e`` is found when it is the only one on its branch within
one sample interval (``h = 2 pi / 256 = 2.5e-2`` rad of the swept joint by default), and in
the subdivided intervals down to ``h / 256 = 9.6e-5`` rad; pairs of zeros that the parabola
test predicts and zeros at the turning point of two branches are found too. Zeros can be
missed when they lie closer together than the spacing where they are, at double zeros (a pose
on a boundary of the workspace), on islands of valid angles that the residual test does not
flag, and near singular poses where Gauss-Newton does not converge from the candidate. The
measured recovery of the generating configuration over random arms and targets is in the docs
page (``docs/solvers/search_1d.md``) and in ``optik benchmark search_1d``. `solve_search_1d`
returns this with every answer (`Search1DSolutions.certified` is always False, ``reason`` names
the family and the resolution).
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from optik.checks import as_transform
from optik.closed_form import registry
from optik.closed_form.derived import CHECK_TOL, _errors, _solve_steps, _wrap, chain_axes, derive
from optik.closed_form.general_6r import covers
from optik.closed_form.structure import Axes, intersection, parallel
from optik.closed_form.subproblems import rot, sp1, sp2, sp3, sp5, sp6
from optik.errors import InvalidArgumentError, ShapeError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.spatial import angle_distance

__all__ = [
    "FAMILIES",
    "SAMPLES",
    "Search1D",
    "Search1DSolutions",
    "families_of",
    "family_of",
    "scan_12_parallel",
    "scan_56_intersecting",
    "search_rows",
    "solve_search_1d",
]

SAMPLES = 256
"""Angles sampled on the circle (spacing ``2 pi / SAMPLES``)."""
SUBDIVISIONS = 16
"""Each flagged interval is sampled again at this many sub-intervals."""
LEVELS = 2
"""Levels of subdivision (the finest spacing is ``2 pi / (SAMPLES SUBDIVISIONS^LEVELS)``)."""
NEAR_TOL = 0.05
"""A local minimum of the smallest residual of the invalid branches below this flags its
intervals for subdivision (a branch may exist on a shorter interval of the swept angle than the
spacing)."""
MAX_FLAGGED = 64
"""Most intervals of one target subdivided per level (the first in angle order; the reason says
when a target had more): bounds the work per target."""
VALID_TOL = 1e-6
"""A branch is valid where its subproblems hold to this (times the arm's size)."""
JUMP = 0.5
"""Largest joint distance (rad, max-norm) between matched branches of consecutive samples."""
REFINE_STEPS = 4
"""Illinois (modified regula falsi) steps per bracket."""
POLISH_STEPS = 8
"""Largest number of Gauss-Newton steps per candidate."""
SAME_TOL = 1e-4
"""Two verified solutions closer than this (rad, max-norm, modulo 2 pi) are one."""
_EXACT = 1e-14
"""FK error below which a candidate needs no further Gauss-Newton step."""
TRIAL_TARGETS = 8
"""Seeded FK targets on which `family_of` compares the families of an arm that has several."""
CHUNK = 64
"""Targets searched together by `Search1D.solve`."""
MAX_SOLUTIONS = 16
"""The Bezout bound of a 6R arm: at most this many isolated solutions."""

_Brackets = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
Scan = Callable[[Axes, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(a * b, axis=-1)


def _apply(axes: Axes, i: int, q: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``E_i(q) x``: the point ``x (..., 3)`` moved by joint ``i`` at angle ``q (...)``."""
    return axes.r[i] + rot(axes.h[i], q, x - axes.r[i])


def _rotate(axes: Axes, joints: range | list[int], q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R_a ... R_b v`` for ``joints = [a, ..., b]`` (``q (..., 6)``; the last joint acts first)."""
    for i in reversed(list(joints)):
        v = rot(axes.h[i], q[..., i], v)
    return v


def _unrotate(axes: Axes, joints: range | list[int], q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(R_a ... R_b)^T v`` for ``joints = [a, ..., b]``."""
    for i in joints:
        v = rot(axes.h[i], -q[..., i], v)
    return v


def _perpendicular(k: np.ndarray) -> np.ndarray:
    """A unit vector normal to the unit vector ``k``."""
    w = np.cross(k, np.eye(3)[int(np.argmin(np.abs(k)))])
    return w / np.linalg.norm(w)


def scan_56_intersecting(
    axes: Axes, theta: np.ndarray, r06: np.ndarray, pt: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The branches and errors of an arm with axes 5-6 intersecting, ``q4 = theta`` (module
    docstring).

    Args:
        axes: the chain.
        theta: ``(...)`` values of ``q4``.
        r06, pt: ``(..., 3, 3)`` and ``(..., 3)``: ``R_t R_M^T`` and the target position,
            broadcasting with ``theta``.

    Returns:
        ``q (..., 4, 6)``, ``e (..., 4)`` (dimensionless) and ``res (..., 4)``: how far the
        branch is from solving its subproblems (relative to the arm's size; complex roots of a
        quartic give a placeholder with a residual that grows with their imaginary part).
    """
    h, r = axes.h, axes.r
    wp = intersection(axes, 4, 5)
    w = np.einsum("...ij,j->...i", r06, wp - axes.home[:3, 3]) + pt
    w4 = _apply(axes, 3, theta, wp)
    w, w4 = np.broadcast_arrays(w, w4)
    c = intersection(axes, 0, 1)
    if c is None:
        args = np.broadcast_arrays(r[0] - r[1], w - r[0], r[2] - r[1], w4 - r[2], h[0], h[1], h[2])
        t1, t2, t3, _ = sp5(*args)
    else:  # SP5 degenerates (p0 = 0 at the common point C): SP3 in q3, then SP2 in (q1, q2)
        t1, t2, t3 = _sp3_sp2(axes, c, w, w4)
    shape = t1.shape
    q = np.zeros((*shape, 6))
    q[..., 0], q[..., 1], q[..., 2] = -t1, t2, t3
    q[..., 3] = np.asarray(theta)[..., None]
    # subproblem check: E_1 E_2 E_3 (E_4 W) = w
    x = w4[..., None, :]
    for i in (2, 1, 0):
        x = _apply(axes, i, q[..., i], x)
    res = np.linalg.norm(x - w[..., None, :], axis=-1) / axes.size
    # the wrist: A = (R_1 .. R_4)^T R06, e = h5 . A h6 - h5 . h6
    a6 = _unrotate(axes, range(4), q, np.einsum("...ij,j->...i", r06, h[5])[..., None, :])
    a5 = _unrotate(axes, range(4), q, np.einsum("...ij,j->...i", r06, h[4])[..., None, :])
    e = a6 @ h[4] - h[4] @ h[5]
    q[..., 4] = sp1(h[4], h[5], a6)[0]
    q[..., 5] = sp1(h[5], h[4], rot(h[4], -q[..., 4], a5))[0]
    return q, e, res


def _sp3_sp2(
    axes: Axes, c: np.ndarray, w: np.ndarray, w4: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``E_1 E_2 E_3 w4 = w`` when axes 1-2 meet at ``c``: ``E_1 E_2`` fix ``c``, so
    ``|E_3 w4 - c| = |w - c|`` (SP3 in ``q3``) and then
    ``rot(h_1, -q1) (w - c) = rot(h_2, q2) (E_3 w4 - c)`` (SP2). Returns ``(t1, t2, t3)``,
    ``(..., 4)`` each, in the form of `sp5` (``q1 = -t1``); a least-squares root where none is
    real (the caller's residual tells)."""
    h, r = axes.h, axes.r
    t3, _ = sp3(h[2], w4 - r[2], np.broadcast_to(c - r[2], w4.shape), np.linalg.norm(w - c, axis=-1))
    x3 = r[2] + rot(h[2], t3, (w4 - r[2])[..., None, :])  # (..., 2, 3)
    t1, t2, _ = sp2(h[0], np.broadcast_to((w - c)[..., None, :], x3.shape), h[1], x3 - c)
    return t1.reshape(*t1.shape[:-2], 4), t2.reshape(*t2.shape[:-2], 4), np.repeat(t3, 2, axis=-1)


def scan_12_parallel(
    axes: Axes, theta: np.ndarray, r06: np.ndarray, pt: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The branches and errors of an arm with axes 1-2 parallel, ``q3 = theta`` (module
    docstring); arguments and returns as `scan_56_intersecting`, ``e`` relative to the arm's
    size."""
    h, r, home = axes.h, axes.r, axes.home
    k = h[0]
    kt = np.einsum("...ji,j->...i", r06, k)  # R06^T k
    k3 = rot(h[2], -np.asarray(theta), np.broadcast_to(k, (*np.shape(theta), 3)))  # R_3^T k
    k3, kt = np.broadcast_arrays(k3, kt)
    d1 = pt @ k - k @ r[2] - _dot(k3, r[3] - r[2]) - kt @ (home[:3, 3] - r[5])
    hs = np.stack([k3, kt, k3, kt])
    ps = np.stack(np.broadcast_arrays(r[4] - r[3], r[5] - r[4], h[4], -h[4]))
    t4, t6, _ = sp6(hs, h[3], -h[5], ps, np.stack([d1, np.zeros_like(d1)], axis=-1))
    shape = t4.shape
    q = np.zeros((*shape, 6))
    q[..., 2] = np.asarray(theta)[..., None]
    q[..., 3], q[..., 5] = t4, t6
    ktb = np.broadcast_to(kt[..., None, :], (*shape, 3))
    # q5: rot(h5, q5) (R6 R06^T k) = R4^T R3^T k
    u = rot(h[3], -t4, k3[..., None, :])
    v = rot(h[5], t6, ktb)
    q[..., 4] = sp1(h[4], v, u)[0]
    # subproblem check: both SP6 equations and the SP1 of q5
    res = np.linalg.norm(rot(h[4], q[..., 4], v) - u, axis=-1)
    x = home[:3, 3]
    for i in (5, 4, 3, 2):
        x = _apply(axes, i, q[..., i], x)
    res = np.maximum(res, np.abs(x @ k - (pt @ k)[..., None]) / axes.size)
    # R_1 R_2 = R06 (R_3 .. R_6)^T; y = p_t - r_1 - R_1 R_2 (X - r_2)
    r06b = r06[..., None, :, :]

    def r12(vec: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", r06b, _unrotate(axes, range(2, 6), q, vec))

    y = pt[..., None, :] - r[0] - r12(x - r[1])
    d = r[1] - r[0]
    d_perp = d - (d @ k) * k
    y_perp = y - (y @ k)[..., None] * k
    e = (np.linalg.norm(y_perp, axis=-1) - np.linalg.norm(d_perp)) / axes.size
    q[..., 0] = sp1(k, d_perp, y_perp)[0]
    n = _perpendicular(k)
    q[..., 1] = sp1(h[1], n, rot(k, -q[..., 0], r12(n)))[0]
    return q, e, res


@dataclass(frozen=True)
class Family:
    """A searchable family: its name, scan, swept joint and whether it works on the inverse chain."""

    name: str
    scan: Scan
    swept: int
    reversed: bool
    applies: Callable[[Axes], bool]


FAMILIES = (
    Family("5-6 intersecting", scan_56_intersecting, 3, False, lambda a: intersection(a, 4, 5) is not None),
    Family("1-2 parallel", scan_12_parallel, 2, False, lambda a: parallel(a, 0, 1)),
    Family("1-2 intersecting", scan_56_intersecting, 3, True, lambda a: intersection(a, 0, 1) is not None),
    Family("5-6 parallel", scan_12_parallel, 2, True, lambda a: parallel(a, 4, 5)),
)
"""The families `family_of` tries, in this order (the reversed ones on the inverse chain)."""


def families_of(axes: Axes) -> list[Family]:
    """The families of `FAMILIES` that a 6R chain belongs to (empty for other chains)."""
    return [fam for fam in FAMILIES if fam.applies(axes)] if axes.n == 6 else []


def family_of(axes: Axes) -> Family | None:
    """The searchable family of a 6R chain, or None: the only one of `families_of`, else the one
    whose search recovers the most generating configurations of `TRIAL_TARGETS` seeded random
    FK targets (the first in `FAMILIES` order on a tie). The subproblems of a family can
    degenerate on the remaining axes (SP5 of ``5-6 intersecting`` when axes 1-2 intersect and
    2-3 are parallel, as on a PUMA 560) while another family of the same arm is regular."""
    fams = families_of(axes)
    if len(fams) <= 1:
        return fams[0] if fams else None
    q = np.random.default_rng(0).uniform(-np.pi, np.pi, (TRIAL_TARGETS, 6))
    t = axes.fk(q)

    def hits(fam: Family) -> int:
        sols = Search1D(axes, fam).solve(t)
        pairs = zip(sols, q, strict=True)
        return sum(bool(len(s.q)) and bool(np.min(angle_distance(s.q, qi)) < 1e-6) for s, qi in pairs)

    scores = [hits(fam) for fam in fams]
    return fams[int(np.argmax(scores))]


@dataclass
class Search1DSolutions:
    """The IK solutions of one target found by the 1-D search.

    Attributes:
        q: ``(k, 6)`` verified solutions, angles wrapped to ``(-pi, pi]``, ``k <= 16``.
        fk_error: the largest FK error of a returned solution (position / arm size, rad).
        candidates: candidates polished (brackets, parabola and turning-point candidates).
        certified: always False: a sampled search cannot prove that no zero was missed.
        reason: the family, the sampling resolution, and what was dropped (if anything).
    """

    q: np.ndarray
    fk_error: float
    candidates: int
    certified: bool
    reason: str

    def __len__(self) -> int:
        return len(self.q)

    def __iter__(self) -> Any:
        return iter(list(self.q))


@functools.cache
def _permutations(b: int) -> np.ndarray:
    """All permutations of ``range(b)``, ``(b!, b)``."""
    return np.array(list(itertools.permutations(range(b))))


@dataclass(frozen=True)
class Search1D:
    """The 1-D search IK of one 6R chain (module docstring).

    Attributes:
        axes: the chain.
        family: its searchable family.
        samples: angles sampled on the circle.
        chunk: targets searched together (bounds the memory: a few hundred kB per target).
    """

    axes: Axes
    family: Family
    samples: int = SAMPLES
    chunk: int = CHUNK

    @property
    def resolution(self) -> float:
        """The sample spacing ``2 pi / samples`` (rad): the smallest separation of two zeros on
        one branch that the sign test resolves everywhere."""
        return 2.0 * np.pi / self.samples

    @property
    def finest(self) -> float:
        """The spacing in the intervals subdivided `LEVELS` times (rad)."""
        return self.resolution / SUBDIVISIONS**LEVELS

    @cached_property
    def chain(self) -> Axes:
        """The chain the scan works on: ``axes``, or its inverse for the reversed families."""
        return self.axes.reversed() if self.family.reversed else self.axes

    def _scan(self, theta: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The family's scan, returned for the arm itself: ``q (..., B, 6)``, ``e``, ``res``
        (see `scan_56_intersecting`) for targets ``t (..., 4, 4)`` broadcasting with ``theta``."""
        chain = self.chain
        if self.family.reversed:
            rt = np.swapaxes(t[..., :3, :3], -1, -2)
            pt = -np.einsum("...ij,...j->...i", rt, t[..., :3, 3])
        else:
            rt, pt = t[..., :3, :3], t[..., :3, 3]
        r06 = rt @ chain.home[:3, :3].T
        q, e, res = self.family.scan(chain, theta, r06, pt)
        if self.family.reversed:
            q = -q[..., ::-1]
        return q, e, res

    def solve(self, t: np.ndarray) -> list[Search1DSolutions]:
        """The solutions of targets ``t (N, 4, 4)`` (validated by the caller), `chunk` targets
        at a time."""
        t = np.asarray(t, dtype=float).reshape(-1, 4, 4)
        return [s for i in range(0, len(t), self.chunk) for s in self._solve(t[i : i + self.chunk])]

    def _solve(self, t: np.ndarray) -> list[Search1DSolutions]:
        """`solve` on one chunk of targets."""
        n_t = len(t)
        theta = -np.pi + self.resolution * np.arange(self.samples + 1)  # closed: last = first + 2 pi
        grid = np.broadcast_to(theta, (n_t, self.samples + 1))
        rows = np.arange(n_t)
        starts: list[np.ndarray] = []
        owners: list[np.ndarray] = []
        capped = np.zeros(n_t, dtype=bool)
        brackets: list[_Brackets] = []
        for level in range(LEVELS + 1):
            q0, own, found, flags = self._grid(grid, t[rows])
            starts.append(q0)
            owners.append(rows[own])
            brackets.append((rows[found[0]], *found[1:]))
            if level == LEVELS:
                break
            kept = flags & (np.cumsum(flags, axis=1) <= MAX_FLAGGED)
            capped[rows[(flags & ~kept).any(axis=1)]] = True
            kk, jj = np.nonzero(kept)
            if not kk.size:
                break
            lo, hi = grid[kk, jj], grid[kk, jj + 1]
            grid = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, SUBDIVISIONS + 1)
            rows = rows[kk]
        # all brackets of all levels refined together (one subproblem call per Illinois step)
        nb = np.concatenate([b[0] for b in brackets])
        ends, branch, errors = (np.concatenate([b[i] for b in brackets], axis=1) for i in (1, 2, 3))
        if nb.size:
            starts.append(
                self._refine(t[nb], (ends[0], ends[1]), (branch[0], branch[1]), (errors[0], errors[1]))
            )
            owners.append(nb)
        own = np.concatenate(owners)
        qp, err = self._polish(np.concatenate(starts), t[own])
        return [self._collect(qp[own == n_], err[own == n_], bool(capped[n_])) for n_ in range(n_t)]

    def _grid(self, theta: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, _Brackets, np.ndarray]:
        """Steps 2-3 of the module docstring on the angle grids ``theta (K, G)`` (increasing
        along each row) of targets ``t (K, 4, 4)``.

        Returns:
            The candidates ``(M, 6)`` and the row of each ``(M,)`` except the brackets; the
            brackets (rows ``(L,)``, then the two ends' angles ``(2, L)``, branches
            ``(2, L, 6)`` and errors ``(2, L)``, refined later); and ``(K, G - 1)`` flags of the
            intervals to subdivide: where a branch ends, begins or jumps, where a branch is
            nearly valid at an end (a local minimum, below `NEAR_TOL`, of the smallest residual
            of the invalid branches: an island of valid angles may lie in between), and where
            a continued branch comes within one interval of a zero without a sign change.
        """
        q, e, res = self._scan(theta, t[:, None])
        valid = res <= VALID_TOL
        e = np.where(valid, e, np.nan)
        b = q.shape[-2]
        qa, qb = q[:, :-1], q[:, 1:]
        va, vb = valid[:, :-1], valid[:, 1:]
        ea, eb_all = e[:, :-1], e[:, 1:]
        # 2. matching of sample k to k + 1 by the best permutation
        cost = angle_distance(qa[..., :, None, :], qb[..., None, :, :])  # (K, G-1, B, B)
        cost = np.where(va[..., :, None] & vb[..., None, :], cost, 2.0 * np.pi)
        perms = _permutations(b)
        total = cost[..., np.arange(b), perms].sum(axis=-1)
        match = perms[np.argmin(total, axis=-1)]  # (K, G-1, B): branch i at k -> match[i] at k+1
        dist = np.take_along_axis(cost, match[..., None], axis=-1)[..., 0]
        cont = dist < JUMP
        eb = np.take_along_axis(eb_all, match, axis=-1)
        qn = np.take_along_axis(qb, match[..., None], axis=-2)  # the matched branch at k+1
        starts: list[np.ndarray] = []
        owners: list[np.ndarray] = []
        # 3a. brackets
        nb, kb, ib = np.nonzero(cont & (ea * eb <= 0.0))
        brackets = (
            nb,
            np.stack([theta[nb, kb], theta[nb, kb + 1]]),
            np.stack([qa[nb, kb, ib], qn[nb, kb, ib]]),
            np.stack([ea[nb, kb, ib], eb[nb, kb, ib]]),
        )
        # 3b. two close zeros: a parabola through three samples of a continued branch
        # (samples k-1, k, k+1 = interval k-1's start, its end = interval k's start, interval k's end)
        inv = np.argsort(match, axis=-1)  # interval k-1: the branch at k-1 continued by branch i at k
        e0 = np.take_along_axis(ea[:, :-1], inv[:, :-1], axis=-1)  # e at k-1 of the branch i at k
        c0 = np.take_along_axis(cont[:, :-1], inv[:, :-1], axis=-1)
        e1, e2, c1 = ea[:, 1:], eb[:, 1:], cont[:, 1:]
        curv = e2 - 2.0 * e1 + e0
        slope = 0.5 * (e2 - e0)
        with np.errstate(invalid="ignore", divide="ignore"):
            disc = slope**2 - 2.0 * curv * e1  # f(x) = e1 + slope x + curv x^2 / 2, x in samples
            pair = c0 & c1 & (e1 * e2 > 0) & (e1 * e0 > 0) & (e1 * curv < 0) & (disc > 0)
            pair &= np.abs(slope / curv) <= 1.0
        npp, kp, ip = np.nonzero(pair)
        for sign in (-1.0, 1.0):
            if not npp.size:
                break
            x = np.clip(
                (-slope[npp, kp, ip] + sign * np.sqrt(disc[npp, kp, ip])) / curv[npp, kp, ip], -1.0, 1.0
            )
            qk = qa[npp, kp + 1, ip]
            other = np.where((x >= 0)[:, None], qn[npp, kp + 1, ip], qa[npp, kp, inv[npp, kp, ip]])
            starts.append(qk + np.abs(x)[:, None] * _wrap(other - qk))
            owners.append(npp)
        # 3c. two branches of opposite signs of e ending at k (or beginning at k + 1) together
        received = np.zeros_like(cont)
        n_, k_, i_ = np.nonzero(cont)
        received[n_, k_, match[n_, k_, i_]] = True
        ended, begun = va & ~cont, vb & ~received
        for ends_, at, e_at in ((ended, qa, ea), (begun, qb, eb_all)):
            lo = np.min(np.where(ends_, e_at, np.inf), axis=-1)
            hi = np.max(np.where(ends_, e_at, -np.inf), axis=-1)
            nt, kt = np.nonzero((lo < 0) & (hi > 0))
            if nt.size:
                sel, bb = np.nonzero(ends_[nt, kt])
                starts.append(at[nt[sel], kt[sel], bb])
                owners.append(nt[sel])
        # flags of the intervals to subdivide
        # an island of valid angles between two samples: a local minimum of the smallest residual
        # of the invalid branches, below NEAR_TOL
        r = np.min(np.where(valid, np.inf, res), axis=-1)  # (K, G)
        pad = np.pad(r, ((0, 0), (1, 1)), constant_values=np.inf)
        left, right = pad[:, :-2], pad[:, 2:]
        dip = (r <= left) & (r <= right) & ((r < 0.99 * left) | (r < 0.99 * right)) & (r <= NEAR_TOL)
        with np.errstate(invalid="ignore"):
            close = cont & (ea * eb > 0) & (np.minimum(np.abs(ea), np.abs(eb)) < np.abs(eb - ea))
        flags = ended.any(-1) | begun.any(-1) | dip[:, :-1] | dip[:, 1:] | close.any(-1)
        if starts:
            return np.concatenate(starts), np.concatenate(owners), brackets, flags
        return np.zeros((0, 6)), np.zeros(0, dtype=int), brackets, flags

    def _refine(
        self,
        t: np.ndarray,
        ends: tuple[np.ndarray, np.ndarray],
        branch: tuple[np.ndarray, np.ndarray],
        errors: tuple[np.ndarray, np.ndarray],
    ) -> np.ndarray:
        """Illinois steps on brackets ``ends = (ta, tb)`` of the branch ``(qa, qb)`` with errors
        ``(ea, eb)`` of opposite signs, for targets ``t``; returns the branch at the best angle
        found (smallest ``|e|``)."""
        (ta, tb), (qa, qb), (ea, eb) = ends, branch, errors
        best_q = np.where((np.abs(ea) <= np.abs(eb))[:, None], qa, qb)
        best_e = np.minimum(np.abs(ea), np.abs(eb))
        side = np.zeros(len(ta), dtype=int)
        for _ in range(REFINE_STEPS):
            with np.errstate(invalid="ignore", divide="ignore"):
                frac = np.clip(np.where(ea != eb, ea / (ea - eb), 0.5), 0.0, 1.0)
            frac = np.where(np.isfinite(frac), frac, 0.5)
            tm = ta + frac * (tb - ta)
            guess = qa + frac[:, None] * _wrap(qb - qa)
            qm, em, vm = self._scan(tm, t)
            d = np.where(vm <= VALID_TOL, angle_distance(qm, guess[:, None, :]), np.inf)
            j = np.argmin(d, axis=-1)
            ok = np.take_along_axis(d, j[:, None], axis=-1)[:, 0] < JUMP
            qn = qm[np.arange(len(tm)), j]
            en = em[np.arange(len(tm)), j]
            better = ok & (np.abs(en) < best_e)
            best_q = np.where(better[:, None], qn, best_q)
            best_e = np.where(better, np.abs(en), best_e)
            left = ok & (en * ea > 0)  # the zero lies in [tm, tb]
            right = ok & ~left
            # Illinois: halve the stale end's error when the same end is kept twice
            ea_new = np.where(left, en, np.where(right & (side == -1), ea * 0.5, ea))
            eb_new = np.where(right, en, np.where(left & (side == 1), eb * 0.5, eb))
            ta, qa = np.where(left, tm, ta), np.where(left[:, None], qn, qa)
            tb, qb = np.where(right, tm, tb), np.where(right[:, None], qn, qb)
            ea, eb = ea_new, eb_new
            side = np.where(left, 1, np.where(right, -1, side))
        return best_q

    def _polish(self, q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Damped Gauss-Newton on the exact pose residual (steps clipped to `JUMP` rad); returns
        ``q`` and the FK errors ``max(|dp| / size, angle)``."""
        q = q.copy()
        err = np.full(len(q), np.inf)
        todo = np.arange(len(q))
        for step in range(POLISH_STEPS + 1):
            if not len(todo):
                break
            pose, jac = self.axes.jacobian(q[todo])
            res, angle = _errors(pose, t[todo])
            err[todo] = np.maximum(np.linalg.norm(res[:, :3], axis=-1) / self.axes.size, angle)
            active = err[todo] > _EXACT
            if step == POLISH_STEPS:
                break
            todo, jac, res = todo[active], jac[active], res[active]
            dq = _solve_steps(jac, res)
            big = np.abs(dq).max(axis=-1, initial=0.0)
            q[todo] -= dq * np.minimum(1.0, JUMP / np.maximum(big, 1e-300))[:, None]
        return q, err

    def _collect(self, q: np.ndarray, err: np.ndarray, capped: bool) -> Search1DSolutions:
        """Verified, wrapped, deduplicated solutions of one target."""
        good = err <= CHECK_TOL
        q, err = _wrap(q[good]), err[good]
        order = np.argsort(err)
        kept: list[int] = []
        for i in order.tolist():
            if all(angle_distance(q[i], q[j]) >= SAME_TOL for j in kept):
                kept.append(i)
        reason = (
            f"1-D search ({self.family.name}, {self.samples} samples, spacing {self.resolution:.1e} rad, "
            f"{self.finest:.1e} where subdivided): not certified complete"
        )
        if capped:
            reason += f"; over {MAX_FLAGGED} intervals to subdivide at a level: the first {MAX_FLAGGED} were"
        if len(kept) > MAX_SOLUTIONS:
            reason += (
                f"; {len(kept)} distinct verified solutions, more than the {MAX_SOLUTIONS} of an"
                " isolated 6R solution set (a self-motion): the 16 most accurate are returned"
            )
            kept = kept[:MAX_SOLUTIONS]
        qk = q[kept] if kept else np.zeros((0, 6))
        return Search1DSolutions(qk, float(np.max(err[kept], initial=0.0)), int(good.size), False, reason)


_SEARCH: PerMechanism[Search1D | None] = PerMechanism()


def search_of(m: Mechanism) -> Search1D | None:
    """The 1-D search of a 6R serial chain with a searchable family (cached per mechanism), or
    None (not a 6R pose chain, or no special end pair)."""
    try:
        return _SEARCH[m]
    except KeyError:
        pass
    axes = chain_axes(m) if m.n_q == 6 else None
    fam = None if axes is None else family_of(axes)
    out = None if fam is None else Search1D(axes, fam)  # type: ignore[arg-type]
    _SEARCH[m] = out
    return out


def solve_search_1d(m: Mechanism, target: Any) -> Search1DSolutions | list[Search1DSolutions]:
    """All IK solutions that the 1-D search finds, with the evidence of what it guarantees.

    Args:
        m: a serial chain of six revolute joints (task ``"pose"``) with axes 1-2 or 5-6
            intersecting or parallel (`family_of`); any such arm, also one that a closed form
            or the general 6R solver covers.
        target: a 4x4 end-effector pose, or ``(N, 4, 4)`` poses.

    Returns:
        A `Search1DSolutions` (a list of ``N`` for stacked targets): ``q`` holds verified
        solutions (FK error at most 1e-9, distinct to `SAME_TOL`), ``certified`` is False and
        ``reason`` names the family and the sampling resolution (module docstring: what the
        search resolves and what it can miss). An unreachable pose gives an empty ``q``.

    Raises:
        InvalidArgumentError: ``m`` is not a 6R chain with a special end pair; a target is
            not a proper 4x4 transform (``ShapeError``, ``NonFiniteError``).
    """
    if not isinstance(m, Mechanism):
        raise InvalidArgumentError("m", f"expected an optik Mechanism, got {type(m).__name__}")
    search = search_of(m)
    if search is None:
        raise InvalidArgumentError(
            "m", f"{m.name!r}: not a 6R serial chain with axes 1-2 or 5-6 intersecting or parallel"
        )
    t = np.asarray(target, dtype=float)
    if t.ndim == 2:
        return search.solve(as_transform(t, "target")[None])[0]
    if t.ndim != 3 or t.shape[1:] != (4, 4) or not len(t):
        raise ShapeError("target", f"expected a 4x4 transform or (N, 4, 4) with N >= 1, got shape {t.shape}")
    return search.solve(np.stack([as_transform(ti, f"target[{i}]") for i, ti in enumerate(t)]))


def search_rows(m: Mechanism) -> registry.IKSolver | None:
    """Registry deriver, tried after the decomposable families and the general 6R solver: a 6R
    arm of no decomposable family that `covers` rejects (special at both ends) and that has a
    searchable family gets the 1-D search (not certified: `solve_search_1d` says so)."""
    if m.n_q != 6 or derive(m) is not None or covers(m):
        return None
    search = search_of(m)
    if search is None:
        return None

    def rows(_: Mechanism, t: np.ndarray) -> list[list[float]]:
        found = search.solve(t[None])[0]
        return registry.Uncertified(found.q.tolist(), found.reason)

    return rows


registry.register_deriver(search_rows)
