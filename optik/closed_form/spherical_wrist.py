"""IK branches of a 6R chain whose axes 4, 5, 6 meet in one point (spherical wrist).

Notation of `optik.closed_form.structure`: ``T(q) = E_1 ... E_6 M``, axes ``h_i`` through
points ``r_i`` at ``q = 0``, ``w`` the wrist centre (common point of axes 4-6), ``R = R_T R_M^T``
the target rotation relative to the home pose. The wrist joints do not move ``w``, so its target
position is ``W = R (w - p_M) + p_T = E_1 E_2 E_3 (w)``, a 3R position problem:

* ``1-2 intersecting`` at ``s``: ``|W - s| = |E_3(w) - s|`` is an SP3 in ``q3``; then
  ``rot(h2, q2) (E_3(w) - s) = rot(h1, -q1) (W - s)`` is an SP2 in ``(q2, -q1)``;
* ``2-3 parallel`` (``h = h2 = h3``): rotations about axes parallel to ``h`` keep the
  ``h``-component, so ``h . rot(h1, -q1) (W - r1) = h . (w - r1)`` is an SP4 in ``-q1``; with
  ``W1 = E_1^-1(W)``, ``|E_3(w) - r2| = |W1 - r2|`` an SP3 in ``q3`` and
  ``rot(h2, q2) (E_3(w) - r2) = W1 - r2`` an SP1 in ``q2``;
* ``2-3 intersecting`` at ``s``: ``|E_1^-1(W) - s| = |w - s|`` is an SP3 in ``-q1``; then
  ``rot(h3, q3) (w - s) = rot(h2, -q2) (W1 - s)`` an SP2 in ``(q3, -q2)``;
* ``1-2 parallel`` (``h = h1 = h2``): ``h . (E_3(w) - r1) = h . (W - r1)`` is an SP4 in ``q3``;
  ``|E_2(E_3(w)) - r1| = |W - r1|`` an SP3 in ``q2``; ``rot(h1, q1) (E_2 E_3(w) - r1) = W - r1``
  an SP1 in ``q1``;
* ``general``: ``r1 - r2 + rot(h1, -q1) (W - r1) = rot(h2, q2) (r3 - r2 + rot(h3, q3) (w - r3))``
  is an SP5 in ``(-q1, q2, q3)`` (up to four triples; numpy only).

Then the wrist: ``R36 = (rot(h1, q1) rot(h2, q2) rot(h3, q3))^T R = rot(h4, q4) rot(h5, q5)
rot(h6, q6)``; ``rot(h5, q5) h6 = rot(h4, -q4) R36 h6`` is an SP2 in ``(q5, -q4)`` and
``rot(h6, q6) x = (rot(h4, q4) rot(h5, q5))^T R36 x`` (``x`` perpendicular to ``h6``) an SP1 in
``q6``; for an orthogonal wrist (`flips`: PUMA and most industrial arms) the second SP2 root
is the flip ``(q4 + pi, -q5, q6 + pi)`` of the first, which costs no ``atan2``. Up to 8
branches (4 x 2), as component tuples (`optik.closed_form.vec3`); each is checked by the caller
(the flipped ones too: the FK check does not rely on the identity).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from optik.closed_form import subproblems as sp
from optik.closed_form import vec3 as v3
from optik.closed_form.structure import Axes, common_point, intersection

Branch = tuple[Any, Any, Any, Any, Any, Any]


def _position(axes: Axes, case: str, wc: v3.Vec, ops: v3.Ops) -> Iterator[tuple[Any, Any, Any]]:
    """The four ``(q1, q2, q3)`` placing the wrist centre at ``wc`` (decoupled cases)."""
    h = [v3.vec(a) for a in axes.h]
    r = [v3.vec(a) for a in axes.r]
    w = v3.vec(common_point(axes, 3, 4, 5))
    w_r3 = v3.sub(w, r[2])
    if case == "1-2 intersecting":
        s = v3.vec(intersection(axes, 0, 1))
        for q3 in sp.sp3_c(h[2], w_r3, v3.sub(s, r[2]), v3.norm(v3.sub(wc, s), ops), ops):
            v = v3.add(v3.sub(r[2], s), v3.rot(h[2], ops.cos(q3), ops.sin(q3), w_r3))
            for q2, mq1 in sp.sp2_c(h[1], v, h[0], v3.sub(wc, s), ops):
                yield v3.neg(mq1, ops), q2, q3
    elif case == "2-3 parallel":
        wc_r1 = v3.sub(wc, r[0])
        for mq1 in sp.sp4_c(h[1], h[0], wc_r1, v3.dot(h[1], v3.sub(w, r[0])), ops):
            w1 = v3.add(r[0], v3.rot(h[0], ops.cos(mq1), ops.sin(mq1), wc_r1))
            for q3 in sp.sp3_c(h[2], w_r3, v3.sub(r[1], r[2]), v3.norm(v3.sub(w1, r[1]), ops), ops):
                e3 = v3.add(r[2], v3.rot(h[2], ops.cos(q3), ops.sin(q3), w_r3))
                yield v3.neg(mq1, ops), sp.sp1_c(h[1], v3.sub(e3, r[1]), v3.sub(w1, r[1]), ops), q3
    elif case == "2-3 intersecting":
        s = v3.vec(intersection(axes, 1, 2))
        wc_r1 = v3.sub(wc, r[0])
        for mq1 in sp.sp3_c(h[0], wc_r1, v3.sub(s, r[0]), float(np.linalg.norm(np.subtract(w, s))), ops):
            w1 = v3.add(r[0], v3.rot(h[0], ops.cos(mq1), ops.sin(mq1), wc_r1))
            for q3, mq2 in sp.sp2_c(h[2], v3.sub(w, s), h[1], v3.sub(w1, s), ops):
                yield v3.neg(mq1, ops), v3.neg(mq2, ops), q3
    elif case == "1-2 parallel":
        wc_r1 = v3.sub(wc, r[0])
        d3 = v3.dot(h[0], wc_r1) - v3.dot(h[0], v3.sub(r[2], r[0]))
        for q3 in sp.sp4_c(h[0], h[2], w_r3, d3, ops):
            y = v3.add(r[2], v3.rot(h[2], ops.cos(q3), ops.sin(q3), w_r3))
            for q2 in sp.sp3_c(h[1], v3.sub(y, r[1]), v3.sub(r[0], r[1]), v3.norm(wc_r1, ops), ops):
                z = v3.add(r[1], v3.rot(h[1], ops.cos(q2), ops.sin(q2), v3.sub(y, r[1])))
                yield sp.sp1_c(h[0], v3.sub(z, r[0]), wc_r1, ops), q2, q3
    else:
        raise ValueError(f"no decoupled position case {case!r}")  # callers route 'general' to SP5


def _position_sp5(axes: Axes, wc: v3.Vec) -> Iterator[tuple[Any, Any, Any]]:
    """The four ``(q1, q2, q3)`` of the general case by SP5 (numpy arrays)."""
    r, h = axes.r, axes.h
    w = common_point(axes, 3, 4, 5)
    wc_a = np.stack(np.broadcast_arrays(*wc), axis=-1)
    ones = np.ones_like(wc_a)
    mq1, q2, q3, _ = sp.sp5(
        (r[0] - r[1]) * ones, wc_a - r[0], (r[2] - r[1]) * ones, (w - r[2]) * ones, h[0], h[1], h[2]
    )
    for j in range(4):
        yield -mq1[..., j], q2[..., j], q3[..., j]


def _wrist(
    axes: Axes, rel: v3.Mat, q123: tuple[Any, Any, Any], ops: v3.Ops
) -> Iterator[tuple[Any, Any, Any]]:
    """The two ``(q4, q5, q6)`` of the wrist for the arm angles ``q123``."""
    h = [v3.vec(a) for a in axes.h]
    r03 = v3.mat_mul(
        v3.mat_mul(
            v3.rot_mat(h[0], ops.cos(q123[0]), ops.sin(q123[0])),
            v3.rot_mat(h[1], ops.cos(q123[1]), ops.sin(q123[1])),
        ),
        v3.rot_mat(h[2], ops.cos(q123[2]), ops.sin(q123[2])),
    )
    r36 = v3.mat_mul(v3.transpose(r03), rel)
    x = np.cross(axes.h[5], axes.h[4])
    x = v3.vec(x / np.linalg.norm(x))
    r36x = v3.mat_vec(r36, x)
    pairs = sp.sp2_c(h[4], h[5], h[3], v3.mat_vec(r36, h[5]), ops)
    flip = flips(axes)
    for q5, mq4 in pairs[:1] if flip else pairs:
        r45 = v3.mat_mul(
            v3.rot_mat(h[3], ops.cos(mq4), -ops.sin(mq4)), v3.rot_mat(h[4], ops.cos(q5), ops.sin(q5))
        )
        q4, q6 = v3.neg(mq4, ops), sp.sp1_c(h[5], x, v3.mat_t_vec(r45, r36x), ops)
        yield q4, q5, q6
        if flip:
            yield v3.half_turn(q4, ops), v3.neg(q5, ops), v3.half_turn(q6, ops)


FLIP_TOL = 1e-14
"""Largest ``|h4 . h5|`` and ``| |h4 . h6| - 1 |`` (unit axes at ``q = 0``) of a wrist solved by
its flip (`flips`): the flipped solution is then off by about this much, far within the FK check."""


def flips(axes: Axes) -> bool:
    """True when the second wrist solution is the first one flipped, ``(q4 + pi, -q5, q6 + pi)``:
    ``h5`` perpendicular to ``h4`` and ``h6`` parallel to it at ``q = 0`` (the usual wrist:
    PUMA, most industrial arms). Then ``rot(h4, pi) rot(h5, -q5) = rot(h5, q5) rot(h4, pi)``
    (``rot(h4, pi)`` maps ``h5`` to ``-h5``) and ``rot(h4, pi) rot(h6, pi) = I`` (``h6 = +-h4``),
    so both give the same wrist rotation; the SP2 of `_wrist` is solved for one root and its
    second SP1 (``q6``) is not needed (the other root of that SP2 is ``-q5`` modulo ``2 pi``:
    its constant phase ``atan2(h4 . (h5 x h6), h4 . h6)`` is 0 or pi)."""
    h4, h5, h6 = (np.asarray(a, dtype=float) / np.linalg.norm(a) for a in axes.h[3:6])
    return abs(float(h4 @ h5)) <= FLIP_TOL and abs(abs(float(h4 @ h6)) - 1.0) <= FLIP_TOL


def branches(axes: Axes, case: str, rel: v3.Mat, pt: v3.Vec, ops: v3.Ops) -> list[Branch]:
    """The 8 IK branches for the relative target rotation ``rel = R_T R_M^T`` and position ``pt``."""
    w = common_point(axes, 3, 4, 5)
    wc = v3.add(v3.mat_vec(rel, v3.vec(w - axes.home[:3, 3])), pt)
    arm = _position_sp5(axes, wc) if case == "general" else _position(axes, case, wc, ops)
    return [(*q123, *q456) for q123 in arm for q456 in _wrist(axes, rel, q123, ops)]
