"""IK branches of a 6R chain whose axes 2, 3, 4 are parallel (UR arms, the seed 6R arm).

Notation of `optik.closed_form.structure`; ``h = h2 = h3 = h4``, ``R = R_T R_M^T`` (so that
``rot(h1, q1) ... rot(h6, q6) = R``) and ``P6 = R (r6 - p_M) + p_T`` the target position of the
point ``r6`` of axis 6 (which joint 6 does not move). Rotations about axes parallel to ``h`` keep
``h``-components and ``h^T rot(h, t) = h^T``, which removes ``q2, q3, q4``:

* position: ``h . rot(h1, -q1) (P6 - r1) - h . rot(h5, q5) (r6 - r5) = h . (r5 - r1)``;
* orientation: ``h . rot(h1, -q1) R h6 - h . rot(h5, q5) h6 = 0``.

This is an SP6 in ``(-q1, q5)`` (up to four pairs; numpy only). When axes 5 and 6 intersect,
``r5 = r6`` is their common point and the equations decouple: an SP4 in ``-q1``, then an SP4 in
``q5`` (2 x 2 pairs). Then ``rot(h6, -q6) rot(h5, -q5) h = R^T rot(h1, q1) h`` is an SP1 in
``-q6``, ``theta = q2 + q3 + q4`` the SP1 of
``rot(h, theta) = rot(h1, q1)^T R rot(h6, q6)^T rot(h5, q5)^T``, and with ``Y = E_1^-1(P6)``,
``z = E_5(r6)`` the planar two-link problem ``E_2 E_3 (r4) = Y - rot(h, theta) (z - r4) =: Y'``:
``|E_3(r4) - r2| = |Y' - r2|`` is an SP3 in ``q3``, ``rot(h, q2) (E_3(r4) - r2) = Y' - r2`` an
SP1 in ``q2``, and ``q4 = theta - q2 - q3``. Up to 8 branches, and 8 more candidates for the wrist singularity
(`_rest`), as component tuples (`optik.closed_form.vec3`); each is checked by the caller.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from optik.closed_form import subproblems as sp
from optik.closed_form import vec3 as v3
from optik.closed_form.spherical_wrist import Branch
from optik.closed_form.structure import Axes, intersection

VOID_TOL = 1e-12
"""The position SP4 of q1 is void (``P6`` on axis 1) when its ``sqrt(a^2 + b^2)`` is below this
times the arm's size (`_pairs_decoupled`)."""


def _points(axes: Axes, case: str) -> tuple[list[v3.Vec], list[v3.Vec]]:
    """Axes and points as tuples, ``r5 = r6`` = the common point of axes 5, 6 when they meet."""
    r = list(axes.r)
    if case == "5-6 intersecting":
        r[4] = r[5] = intersection(axes, 4, 5)
    return [v3.vec(a) for a in axes.h], [v3.vec(a) for a in r]


def _pairs_decoupled(
    h: list[v3.Vec], r: list[v3.Vec], p6: v3.Vec, rh6: v3.Vec, size: float, ops: v3.Ops
) -> Iterator[tuple[Any, Any]]:
    """The four ``(q1, q5)`` when axes 5 and 6 intersect (two SP4).

    When ``P6`` lies on axis 1 and the position SP4 is void (its ``a = b = 0``: every ``q1``
    or none meets the position), ``q1`` takes a representative: ``theta = q2 + q3 + q4`` is
    chosen so that the two-link target is in the middle of its reach (as in `_rest`, with
    ``Y = P6`` and ``z = r5``), and ``q1`` so that this ``theta`` fits the orientation:
    ``rot(h, -theta) rot(h1, -q1) R h6`` must make the angle of ``h5`` and ``h6`` with ``h5``,
    the SP4 ``(rot(h, theta) h5) . rot(h1, -q1) R h6 = h5 . h6``."""
    k = h[1]
    a, b, c = sp.sp4_terms_c(k, h[0], v3.sub(p6, r[0]), v3.dot(k, v3.sub(r[4], r[0])))
    y, v = v3.sub(p6, r[1]), v3.sub(r[4], r[3])
    theta = sp.sp4_c(y, k, v, 0.5 * (v3.dot(y, y) + v3.dot(v, v) - _mid_reach(k, r)), ops)[0]
    h5_theta = v3.rot(k, ops.cos(theta), ops.sin(theta), h[4])
    void = a * a + b * b <= (VOID_TOL * size) ** 2
    mid = sp.sp4_terms_c(h5_theta, h[0], rh6, v3.dot(h[4], h[5]))
    terms = [ops.where(void, m, t) for m, t in zip(mid, (a, b, c), strict=True)]
    for mq1 in sp.sp4_roots_c(*terms, ops):
        lhs = v3.dot(k, v3.rot(h[0], ops.cos(mq1), ops.sin(mq1), rh6))
        for q5 in sp.sp4_c(k, h[4], h[5], lhs, ops):
            yield v3.neg(mq1, ops), q5


def _pairs_sp6(h: list[v3.Vec], r: list[v3.Vec], p6: v3.Vec, rh6: v3.Vec) -> Iterator[tuple[Any, Any]]:
    """The four ``(q1, q5)`` of the general case by SP6 (numpy arrays)."""
    a = [np.asarray(v, dtype=float) for v in (h[0], h[1], h[4], h[5], r[0], r[4], r[5])]
    h1, hh, h5, h6, r1, r5, r6 = a
    p6a = np.stack(np.broadcast_arrays(*p6), axis=-1)
    rh6a = np.stack(np.broadcast_arrays(*rh6), axis=-1)
    ones = np.ones_like(p6a)
    n = p6a.shape[:-1]
    d = np.stack([np.full(n, hh @ (r5 - r1)), np.zeros(n)], axis=-1)
    hs = np.stack([hh * ones, -hh * ones, hh * ones, -hh * ones])
    ps = np.stack([p6a - r1, (r6 - r5) * ones, rh6a, h6 * ones])
    mq1, q5, _ = sp.sp6(hs, h1, h5, ps, d)
    for j in range(4):
        yield -mq1[..., j], q5[..., j]


def _perpendicular(k: np.ndarray) -> v3.Vec:
    x = np.cross(k, np.eye(3)[int(np.argmin(np.abs(k)))])
    return v3.vec(x / np.linalg.norm(x))


def _planar(
    k: v3.Vec, r: list[v3.Vec], y: v3.Vec, z: v3.Vec, theta: Any, ops: v3.Ops
) -> Iterator[tuple[Any, Any, Any]]:
    """``(q2, q3, q4)`` of the two-link problem for ``theta = q2 + q3 + q4``."""
    yp = v3.sub(y, v3.rot(k, ops.cos(theta), ops.sin(theta), v3.sub(z, r[3])))
    r4_r3 = v3.sub(r[3], r[2])
    for q3 in sp.sp3_c(k, r4_r3, v3.sub(r[1], r[2]), v3.norm(v3.sub(yp, r[1]), ops), ops):
        e3 = v3.add(r[2], v3.rot(k, ops.cos(q3), ops.sin(q3), r4_r3))
        q2 = sp.sp1_c(k, v3.sub(e3, r[1]), v3.sub(yp, r[1]), ops)
        yield q2, q3, theta - q2 - q3


def _mid_reach(k: v3.Vec, r: list[v3.Vec]) -> float:
    """The squared distance ``|E_3(r4) - r2|^2`` in the middle of its range over ``q3``:
    ``(u_h - w_h)^2 + |u_perp|^2 + |w_perp|^2`` for ``u = r4 - r3``, ``w = r2 - r3``."""
    kk = np.asarray(k)
    u = np.subtract(r[3], r[2])
    w = np.subtract(r[1], r[2])
    uh, wh = kk @ u, kk @ w
    return float((uh - wh) ** 2 + (u @ u - uh * uh) + (w @ w - wh * wh))


def _rest(
    h: list[v3.Vec], r: list[v3.Vec], rel: v3.Mat, p6: v3.Vec, q1: Any, q5: Any, ops: v3.Ops
) -> Iterator[Branch]:
    """The four candidates completing ``(q1, q5)``: two regular ones and two for the wrist
    singularity.

    Regular: ``q6`` by SP1, ``theta`` from the orientation. When ``rot(h5, -q5) h`` is parallel
    to ``h6`` (axis 6 parallel to axes 2-4) every ``q6`` fits the SP1 and only ``theta + q6``
    is fixed: the representative then takes ``theta`` so that the two-link target lies in the
    middle of its reach, ``(Y - r2) . rot(h, theta) (z - r4) = (|Y - r2|^2 + |z - r4|^2 - rho^2)
    / 2`` (an SP4, ``rho^2`` from `_mid_reach`), and ``q6`` from
    ``rot(h6, q6) = (rot(h1, q1) rot(h, theta) rot(h5, q5))^T R``. Away from the singularity
    these two fail the FK check and are dropped."""
    k = h[1]
    r01 = v3.rot_mat(h[0], ops.cos(q1), ops.sin(q1))
    r45 = v3.rot_mat(h[4], ops.cos(q5), ops.sin(q5))
    y = v3.add(r[0], v3.mat_t_vec(r01, v3.sub(p6, r[0])))
    z = v3.add(r[4], v3.mat_vec(r45, v3.sub(r[5], r[4])))
    x = _perpendicular(np.asarray(k))
    q6 = v3.neg(sp.sp1_c(h[5], v3.mat_t_vec(r45, k), v3.mat_t_vec(rel, v3.mat_vec(r01, k)), ops), ops)
    r56 = v3.rot_mat(h[5], ops.cos(q6), ops.sin(q6))
    r14 = v3.mat_mul(v3.mat_mul(v3.transpose(r01), rel), v3.transpose(v3.mat_mul(r45, r56)))
    theta = sp.sp1_c(k, x, v3.mat_vec(r14, x), ops)
    for q234 in _planar(k, r, y, z, theta, ops):
        yield q1, *q234, q5, q6
    a = v3.sub(y, r[1])
    v = v3.sub(z, r[3])
    theta_s = sp.sp4_c(a, k, v, 0.5 * (v3.dot(a, a) + v3.dot(v, v) - _mid_reach(k, r)), ops)[0]
    r14_s = v3.rot_mat(k, ops.cos(theta_s), ops.sin(theta_s))
    r56_s = v3.mat_mul(v3.transpose(v3.mat_mul(v3.mat_mul(r01, r14_s), r45)), rel)
    x6 = _perpendicular(np.asarray(h[5]))
    q6_s = sp.sp1_c(h[5], x6, v3.mat_vec(r56_s, x6), ops)
    for q234 in _planar(k, r, y, z, theta_s, ops):
        yield q1, *q234, q5, q6_s


def stand_ins(count: int) -> tuple[int, ...]:
    """For each of the ``count`` candidates of `branches`, the index of the regular candidate
    that it stands in for at the wrist singularity, or -1 for a regular one: `_rest` yields
    the two regular candidates of a ``(q1, q5)`` pair, then their two representatives. A
    representative is only needed when its regular candidate fails the FK check (when both
    pass, they are two points of the same one-parameter family of solutions)."""
    return tuple(-1 if k % 4 < 2 else k - 2 for k in range(count))


def branches(axes: Axes, case: str, rel: v3.Mat, pt: v3.Vec, ops: v3.Ops) -> list[Branch]:
    """The 8 IK branches for the relative target rotation ``rel = R_T R_M^T`` and position ``pt``."""
    h, r = _points(axes, case)
    p6 = v3.add(v3.mat_vec(rel, v3.vec(np.asarray(r[5]) - axes.home[:3, 3])), pt)
    rh6 = v3.mat_vec(rel, h[5])
    if case == "5-6 intersecting":
        pairs = _pairs_decoupled(h, r, p6, rh6, axes.size, ops)
    else:
        pairs = _pairs_sp6(h, r, p6, rh6)
    return [b for q1, q5 in pairs for b in _rest(h, r, rel, p6, q1, q5, ops)]
