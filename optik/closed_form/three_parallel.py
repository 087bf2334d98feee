"""IK candidates of a 6R chain whose axes 2, 3, 4 are parallel (UR arms, the seed 6R arm).

Notation of `optik.closed_form.structure`; ``h = h2 = h3 = h4``, ``R = R_T R_M^T`` (so that
``rot(h1, q1) ... rot(h6, q6) = R``) and ``P6 = R (r6 - p_M) + p_T`` the target position of the
point ``r6`` of axis 6 (which joint 6 does not move). Rotations about axes parallel to ``h`` keep
``h``-components and ``h^T rot(h, t) = h^T``, which removes ``q2, q3, q4``:

* position: ``h . rot(h1, -q1) (P6 - r1) - h . rot(h5, q5) (r6 - r5) = h . (r5 - r1)``;
* orientation: ``h . rot(h1, -q1) R h6 - h . rot(h5, q5) h6 = 0``.

This is an SP6 in ``(-q1, q5)`` (up to four pairs). When axes 5 and 6 intersect, ``r5 = r6`` is
their common point and the equations decouple: an SP4 in ``-q1``, then an SP4 in ``q5`` (up to
2 x 2 pairs). Then ``rot(h6, -q6) rot(h5, -q5) h = R^T rot(h1, q1) h`` is an SP1 in ``-q6``,
``theta = q2 + q3 + q4`` the SP1 of ``rot(h, theta) = rot(h1, q1)^T R rot(h6, q6)^T rot(h5, q5)^T``,
and with ``Y = E_1^-1(P6)``, ``z = E_5(r6)`` the planar two-link problem
``E_2 E_3 (r4) = Y - rot(h, theta) (z - r4) =: Y'``: ``|E_3(r4) - r2| = |Y' - r2|`` is an SP3
in ``q3``, ``rot(h, q2) (E_3(r4) - r2) = Y' - r2`` an SP1 in ``q2``, and
``q4 = theta - q2 - q3``. Up to 8 candidates; each is checked by the caller.
"""

from __future__ import annotations

import numpy as np

from optik.closed_form import subproblems as sp
from optik.closed_form.structure import Axes, intersection


def _mats(k: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.swapaxes(sp.rot(k, t[..., None], np.eye(3)), -1, -2)


def _perpendicular(k: np.ndarray) -> np.ndarray:
    x = np.cross(k, np.eye(3)[int(np.argmin(np.abs(k)))])
    return x / np.linalg.norm(x)


def candidates(axes: Axes, case: str, t: np.ndarray) -> np.ndarray:
    """IK candidates ``(N, 8, 6)`` for targets ``t (N, 4, 4)``."""
    h1, h, h5, h6 = axes.h[0], axes.h[1], axes.h[4], axes.h[5]
    r1, r2, r3, r4 = axes.r[0], axes.r[1], axes.r[2], axes.r[3]
    r5, r6 = axes.r[4], axes.r[5]
    if case == "5-6 intersecting":
        r5 = r6 = intersection(axes, 4, 5)
    rm, pm = axes.home[:3, :3], axes.home[:3, 3]
    n = t.shape[0]
    rel = t[:, :3, :3] @ rm.T
    p6 = np.einsum("nij,j->ni", rel, r6 - pm) + t[:, :3, 3]
    rh6 = rel @ h6  # (N, 3)
    if case == "5-6 intersecting":
        mq1, _ = sp.sp4(h, h1, p6 - r1, np.full(n, h @ (r5 - r1)))  # (N, 2)
        lhs = np.sum(h * sp.rot(h1, mq1, rh6[:, None]), axis=-1)  # (N, 2)
        q5, _ = sp.sp4(h, h5, h6, lhs)  # (N, 2, 2)
        mq1 = np.repeat(mq1, 2, axis=1)
        q5 = q5.reshape(n, 4)
    else:
        hh = np.stack(np.broadcast_arrays(h, -h, h, -h, p6))[:4]
        pp = np.stack(np.broadcast_arrays(p6 - r1, r6 - r5, rh6, h6))
        d = np.stack([np.full(n, h @ (r5 - r1)), np.zeros(n)], axis=-1)
        mq1, q5, _ = sp.sp6(hh, h1, h5, pp, d)  # (N, 4)
    q1 = -mq1
    r01 = _mats(h1, q1)  # (N, 4, 3, 3)
    r45 = _mats(h5, q5)
    lhs = np.einsum("nkji,j->nki", r45, h)  # rot(h5, -q5) h
    rhs = np.einsum("nji,nkjl,l->nki", rel, r01, h)  # R^T rot(h1, q1) h
    mq6, _ = sp.sp1(h6, lhs, rhs)
    q6 = -mq6
    r14 = (
        np.swapaxes(r01, -1, -2)
        @ rel[:, None]
        @ np.swapaxes(_mats(h6, q6), -1, -2)
        @ np.swapaxes(r45, -1, -2)
    )
    x = _perpendicular(h)
    theta, _ = sp.sp1(h, x, r14 @ x)  # (N, 4)
    y = r1 + np.einsum("nkji,nj->nki", r01, p6 - r1)  # E_1^-1(P6)
    z = r5 + np.einsum("nkij,j->nki", r45, r6 - r5)
    yp = y - np.einsum("nkij,nkj->nki", _mats(h, theta), z - r4)
    q3, _ = sp.sp3(h, r4 - r3, r2 - r3, np.linalg.norm(yp - r2, axis=-1))  # (N, 4, 2)
    e3 = r3 + sp.rot(h, q3, r4 - r3)  # (N, 4, 2, 3)
    q2, _ = sp.sp1(h, e3 - r2, yp[:, :, None] - r2)
    out = np.empty((n, 4, 2, 6))
    out[..., 0] = q1[..., None]
    out[..., 1] = q2
    out[..., 2] = q3
    out[..., 3] = theta[..., None] - q2 - q3
    out[..., 4] = q5[..., None]
    out[..., 5] = q6[..., None]
    return out.reshape(n, 8, 6)
