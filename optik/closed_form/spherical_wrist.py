"""IK candidates of a 6R chain whose axes 4, 5, 6 meet in one point (spherical wrist).

Notation of `optik.closed_form.structure`: ``T(q) = E_1 ... E_6 M``, axes ``h_i`` through
points ``r_i`` at ``q = 0``, ``w`` the wrist centre (common point of axes 4-6), ``R = R_T R_M^T``
the target rotation relative to the home pose. The wrist joints do not move ``w``, so its target
position is ``W = R (w - p_M) + p_T = E_1 E_2 E_3 (w)``, a 3R position problem:

* ``1-2 intersecting`` at ``s``: ``|W - s| = |E_3(w) - s|`` is an SP3 in ``q3``; then
  ``rot(h2, q2) (E_3(w) - s) = rot(h1, -q1) (W - s)`` is an SP2 in ``(q2, -q1)``;
* ``2-3 parallel`` (``h = h2 = h3``): rotations about axes parallel to ``h`` keep the
  ``h``-component, so ``h . rot(h1, -q1) (W - r1) = h . (w - r1)`` is an SP4 in ``q1``; with
  ``W1 = E_1^-1(W)``, ``|E_3(w) - r2| = |W1 - r2|`` an SP3 in ``q3`` and
  ``rot(h2, q2) (E_3(w) - r2) = W1 - r2`` an SP1 in ``q2``;
* ``2-3 intersecting`` at ``s``: ``|E_1^-1(W) - s| = |w - s|`` is an SP3 in ``-q1``; then
  ``rot(h3, q3) (w - s) = rot(h2, -q2) (W1 - s)`` an SP2 in ``(q3, -q2)``;
* ``1-2 parallel`` (``h = h1 = h2``): ``h . (E_3(w) - r1) = h . (W - r1)`` is an SP4 in ``q3``;
  ``|E_2(E_3(w)) - r1| = |W - r1|`` an SP3 in ``q2``; ``rot(h1, q1) (E_2 E_3(w) - r1) = W - r1``
  an SP1 in ``q1``;
* ``general``: ``r1 - r2 + rot(h1, -q1) (W - r1) = rot(h2, q2) (r3 - r2 + rot(h3, q3) (w - r3))``
  is an SP5 in ``(-q1, q2, q3)`` (up to four triples).

Then the wrist: ``R36 = (rot(h1, q1) rot(h2, q2) rot(h3, q3))^T R = rot(h4, q4) rot(h5, q5)
rot(h6, q6)``; ``rot(h5, q5) h6 = rot(h4, -q4) R36 h6`` is an SP2 in ``(q5, -q4)`` and
``rot(h6, q6) x = (rot(h4, q4) rot(h5, q5))^T R36 x`` (``x`` perpendicular to ``h6``) an SP1 in
``q6``. Up to 8 candidates (4 x 2); each is checked by the caller.
"""

from __future__ import annotations

import numpy as np

from optik.closed_form import subproblems as sp
from optik.closed_form.structure import Axes, common_point, intersection


def _ext(a: np.ndarray, n: int) -> np.ndarray:
    """``a (N, ..., 3)`` with ``n`` new axes before the last one."""
    return a.reshape(a.shape[:-1] + (1,) * n + a.shape[-1:])


def _rot_mats(k: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.swapaxes(sp.rot(k, t[..., None], np.eye(3)), -1, -2)


def position(axes: Axes, case: str, wc: np.ndarray) -> np.ndarray:
    """``(q1, q2, q3)`` candidates ``(N, 4, 3)`` placing the wrist centre at ``wc (N, 3)``."""
    h, r = axes.h, axes.r
    w = common_point(axes, 3, 4, 5)
    n = wc.shape[0]
    out = np.empty((n, 4, 3))
    if case == "1-2 intersecting":
        s = intersection(axes, 0, 1)
        d = np.linalg.norm(wc - s, axis=-1)
        q3, _ = sp.sp3(h[2], w - r[2], s - r[2], d)  # (N, 2)
        v = r[2] - s + sp.rot(h[2], q3, w - r[2])  # (N, 2, 3)
        q2, mq1, _ = sp.sp2(h[1], v, h[0], _ext(wc - s, 1))  # (N, 2, 2)
        out[..., 0] = (-mq1).reshape(n, 4)
        out[..., 1] = q2.reshape(n, 4)
        out[..., 2] = np.repeat(q3, 2, axis=1)
    elif case == "2-3 parallel":
        k = h[1]
        mq1, _ = sp.sp4(k, h[0], wc - r[0], np.full(n, k @ (w - r[0])))  # (N, 2)
        w1 = r[0] + sp.rot(h[0], mq1, _ext(wc - r[0], 1))  # (N, 2, 3)
        q3, _ = sp.sp3(h[2], w - r[2], r[1] - r[2], np.linalg.norm(w1 - r[1], axis=-1))  # (N, 2, 2)
        e3 = r[2] + sp.rot(h[2], q3, w - r[2])  # (N, 2, 2, 3)
        q2, _ = sp.sp1(h[1], e3 - r[1], _ext(w1, 1) - r[1])
        out[..., 0] = np.repeat(-mq1, 2, axis=1)
        out[..., 1] = q2.reshape(n, 4)
        out[..., 2] = q3.reshape(n, 4)
    elif case == "2-3 intersecting":
        s = intersection(axes, 1, 2)
        mq1, _ = sp.sp3(h[0], wc - r[0], s - r[0], np.full(n, np.linalg.norm(w - s)))  # (N, 2)
        w1 = r[0] + sp.rot(h[0], mq1, _ext(wc - r[0], 1))
        q3, mq2, _ = sp.sp2(h[2], w - s, h[1], w1 - s)  # (N, 2, 2)
        out[..., 0] = np.repeat(-mq1, 2, axis=1)
        out[..., 1] = (-mq2).reshape(n, 4)
        out[..., 2] = q3.reshape(n, 4)
    elif case == "1-2 parallel":
        k = h[0]
        q3, _ = sp.sp4(k, h[2], w - r[2], (wc - r[0]) @ k - k @ (r[2] - r[0]))  # (N, 2)
        y = r[2] + sp.rot(h[2], q3, w - r[2])  # (N, 2, 3)
        q2, _ = sp.sp3(h[1], y - r[1], r[0] - r[1], np.linalg.norm(wc - r[0], axis=-1)[:, None])
        z = r[1] + sp.rot(h[1], q2, _ext(y, 1) - r[1])  # (N, 2, 2, 3)
        q1, _ = sp.sp1(h[0], z - r[0], _ext(wc - r[0], 2))
        out[..., 0] = q1.reshape(n, 4)
        out[..., 1] = q2.reshape(n, 4)
        out[..., 2] = np.repeat(q3, 2, axis=1)
    else:
        mq1, q2, q3, _ = sp.sp5(
            np.broadcast_to(r[0] - r[1], wc.shape), wc - r[0], np.broadcast_to(r[2] - r[1], wc.shape),
            np.broadcast_to(w - r[2], wc.shape), h[0], h[1], h[2],
        )  # fmt: skip
        out[..., 0], out[..., 1], out[..., 2] = -mq1, q2, q3
    return out


def wrist(axes: Axes, r36: np.ndarray) -> np.ndarray:
    """``(q4, q5, q6)`` candidates ``(..., 2, 3)`` with
    ``rot(h4, q4) rot(h5, q5) rot(h6, q6) = r36 (..., 3, 3)``."""
    h4, h5, h6 = axes.h[3], axes.h[4], axes.h[5]
    q5, mq4, _ = sp.sp2(h5, h6, h4, r36 @ h6)  # (..., 2)
    x = np.cross(h6, h5)
    x = x / np.linalg.norm(x)
    r45 = _rot_mats(h4, -mq4) @ _rot_mats(h5, q5)  # (..., 2, 3, 3)
    target = np.einsum("...kji,...jl,l->...ki", r45, r36, x)  # (rot4 rot5)^T R36 x
    q6, _ = sp.sp1(h6, x, target)
    return np.stack([-mq4, q5, q6], axis=-1)


def candidates(axes: Axes, case: str, t: np.ndarray) -> np.ndarray:
    """IK candidates ``(N, 8, 6)`` of a spherical-wrist chain for targets ``t (N, 4, 4)``."""
    rm, pm = axes.home[:3, :3], axes.home[:3, 3]
    rel = t[:, :3, :3] @ rm.T  # R = R_T R_M^T
    w = common_point(axes, 3, 4, 5)
    wc = np.einsum("nij,j->ni", rel, w - pm) + t[:, :3, 3]
    q123 = position(axes, case, wc)  # (N, 4, 3)
    r03 = (
        _rot_mats(axes.h[0], q123[..., 0])
        @ _rot_mats(axes.h[1], q123[..., 1])
        @ _rot_mats(axes.h[2], q123[..., 2])
    )
    r36 = np.swapaxes(r03, -1, -2) @ rel[:, None]
    q456 = wrist(axes, r36)  # (N, 4, 2, 3)
    n = t.shape[0]
    out = np.empty((n, 4, 2, 6))
    out[..., :3] = q123[:, :, None, :]
    out[..., 3:] = q456
    return out.reshape(n, 8, 6)
