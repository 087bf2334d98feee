"""Structure of a serial revolute chain: its joint axes at ``q = 0`` and the 6R families they form.

A chain of ``n`` revolute joints is, in product-of-exponentials form,

``T(q) = E_1(q_1) E_2(q_2) ... E_n(q_n) M``, ``E_i(t) x = r_i + rot(h_i, t) (x - r_i)``,

with ``h_i`` the unit axis of joint ``i`` and ``r_i`` a point on it, both in the base frame at
``q = 0``, and ``M = T(0)``. ``axes_of`` reads ``h_i`` and ``r_i`` from the geometric
Jacobian at ``q = 0`` (column ``i`` is ``[h_i x (p - r_i); h_i]``, so ``r_i = p + h_i x v_i`` is
the point of the axis nearest the end effector ``p``) and accepts the chain only when this model
reproduces the mechanism's FK at random configurations: any serial mechanism of revolute joints
(URDF, DH, catalog) qualifies, whatever its frame conventions.

``detect`` names the decomposable family of a 6R chain from relations of consecutive axes,
which hold at every configuration: *intersecting* (the common perpendicular is shorter than
``DIST_TOL`` times the arm's size, axes not parallel) and *parallel* (``|h_i x h_j|`` below
``ANGLE_TOL``). Both tolerances are loose enough for URDF files that print angles and lengths
to 6 digits; the derived solvers polish every branch on the exact model afterwards.

Families (IK-Geo / EAIK naming), tried in this order:

* ``spherical_wrist``: axes 4, 5, 6 meet in one point; the position part is solved by subproblems
  according to the first three axes (``1-2 intersecting``, ``2-3 parallel``, ``2-3 intersecting``,
  ``1-2 parallel``, else the general SP5);
* ``spherical_base``: axes 1, 2, 3 meet in one point (the reversed chain has a spherical wrist);
* ``three_parallel``: axes 2, 3, 4 parallel (UR arms, the seed 6R arm);
* ``three_parallel_reversed``: axes 3, 4, 5 parallel (the reversed chain has 2, 3, 4 parallel).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from optik.closed_form import vec3 as v3
from optik.closed_form.subproblems import rot
from optik.mechanism import Mechanism

ANGLE_TOL = 1e-5
"""Axes with ``|h_i x h_j|`` below this are parallel."""
DIST_TOL = 1e-5
"""Non-parallel axes closer than this (times the arm's size) intersect; points closer than this
(times the size) coincide."""
CHECK_CONFIGS = 3
"""Random configurations at which ``axes_of`` compares its model with the mechanism's FK."""


@dataclass(frozen=True)
class Axes:
    """A revolute chain in product-of-exponentials form (see the module docstring).

    Attributes:
        h: ``(n, 3)`` unit axes at ``q = 0`` (base frame).
        r: ``(n, 3)`` a point on each axis.
        home: ``(4, 4)`` end-effector pose at ``q = 0``.
    """

    h: np.ndarray
    r: np.ndarray
    home: np.ndarray

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.h.shape[0]

    @cached_property
    def size(self) -> float:
        """A length scale of the arm: the largest distance of an axis point or the end effector
        from the base origin (at least 1e-3)."""
        pts = np.vstack([self.r, self.home[:3, 3]])
        return max(float(np.max(np.linalg.norm(pts, axis=1))), 1e-3)

    def fk_c(self, q: Sequence[Any], ops: v3.Ops) -> tuple[v3.Mat, v3.Vec]:
        """FK on components (`optik.closed_form.vec3`): ``(R, p)`` for joint values ``q``
        (numpy arrays or CasADi symbols): ``p = E_1(E_2(... E_n(p_M)))``, ``R = R_1 ... R_n R_M``."""
        rr: v3.Mat = tuple(v3.vec(row) for row in self.home[:3, :3])  # type: ignore[assignment]
        p = v3.vec(self.home[:3, 3])
        for i in range(self.n - 1, -1, -1):
            ri = v3.rot_mat(v3.vec(self.h[i]), ops.cos(q[i]), ops.sin(q[i]))
            r = v3.vec(self.r[i])
            p = v3.add(r, v3.mat_vec(ri, v3.sub(p, r)))
            rr = v3.mat_mul(ri, rr)
        return rr, p

    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector poses ``(..., 4, 4)`` for ``q (..., n)``."""
        q = np.asarray(q, dtype=float)
        rr, p = self.fk_c([q[..., i] for i in range(self.n)], v3.NUMPY)
        out = np.zeros((*q.shape[:-1], 4, 4))
        for i in range(3):
            out[..., i, 3] = p[i]
            for j in range(3):
                out[..., i, j] = rr[i][j]
        out[..., 3, 3] = 1.0
        return out

    def jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Poses ``(..., 4, 4)`` and geometric Jacobians ``(..., 6, n)`` (``[v; w]`` at the end
        effector, base frame) for ``q (..., n)``."""
        q = np.asarray(q, dtype=float)
        shape = q.shape[:-1]
        rr = np.broadcast_to(np.eye(3), (*shape, 3, 3)).copy()
        tr = np.zeros((*shape, 3))
        w = np.empty((*shape, self.n, 3))
        pts = np.empty((*shape, self.n, 3))
        for i in range(self.n):  # current axis i: (E_1 ... E_{i-1}) applied to (h_i, r_i)
            w[..., i, :] = np.einsum("...ij,j->...i", rr, self.h[i])
            pts[..., i, :] = np.einsum("...ij,j->...i", rr, self.r[i]) + tr
            ri = _rotation(self.h[i], q[..., i])
            # E_1..E_i = (R, t) with E_i x = r_i + R_i (x - r_i)
            tr = tr + np.einsum("...ij,...j->...i", rr, self.r[i] - np.einsum("...ij,j->...i", ri, self.r[i]))
            rr = rr @ ri
        pose = np.zeros((*shape, 4, 4))
        pose[..., :3, :3] = rr @ self.home[:3, :3]
        pose[..., :3, 3] = np.einsum("...ij,j->...i", rr, self.home[:3, 3]) + tr
        pose[..., 3, 3] = 1.0
        v = np.cross(w, pose[..., None, :3, 3] - pts)
        jac = np.concatenate([np.swapaxes(v, -1, -2), np.swapaxes(w, -1, -2)], axis=-2)
        return pose, jac

    def lock(self, index: int, value: float) -> Axes:
        """The chain with joint ``index`` fixed at ``value``: the later axes and the home pose
        are moved by ``E_index(value)`` (``E_i E_j = (E_i E_j E_i^-1) E_i``)."""
        rot_i = _rotation(self.h[index], np.asarray(value, dtype=float))
        keep = [j for j in range(self.n) if j != index]
        h = self.h.copy()
        r = self.r.copy()
        after = np.arange(self.n) > index
        h[after] = h[after] @ rot_i.T
        r[after] = self.r[index] + (r[after] - self.r[index]) @ rot_i.T
        home = self.home.copy()
        home[:3, :3] = rot_i @ home[:3, :3]
        home[:3, 3] = self.r[index] + rot_i @ (home[:3, 3] - self.r[index])
        return Axes(h[keep], r[keep], home)

    def reversed(self) -> Axes:
        """The inverse chain: ``T(q)^-1 = E'_1(-q_n) ... E'_n(-q_1) M^-1`` with
        ``E'_k = M^-1 E_{n+1-k} M`` (axes ``R_M^T h``, points ``M^-1 r``)."""
        rm, pm = self.home[:3, :3], self.home[:3, 3]
        inv = np.eye(4)
        inv[:3, :3] = rm.T
        inv[:3, 3] = -rm.T @ pm
        return Axes(self.h[::-1] @ rm, (self.r[::-1] - pm) @ rm, inv)


def _rotation(k: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``rot(k, t)`` as matrices ``(..., 3, 3)``."""
    return np.swapaxes(rot(k, t[..., None], np.eye(3)), -1, -2)


def axes_of(m: Mechanism) -> Axes | None:
    """The product-of-exponentials model of a serial chain of revolute joints, or None when ``m``
    is not one (closed chains, prismatic or spherical joints, couplings; see the module
    docstring)."""
    if m.is_closed or not bool(np.all(m.revolute_mask)) or m.spherical_slices or m.n_q == 0:
        return None
    zero = np.zeros(m.n_q)
    home = m.fk(zero)
    jac = m.jacobian(zero)
    w = jac[3:].T
    norms = np.linalg.norm(w, axis=1)
    if np.any(np.abs(norms - 1.0) > 1e-9):
        return None
    h = w / norms[:, None]
    r = home[:3, 3] + np.cross(h, jac[:3].T)
    axes = Axes(h, r, home)
    rng = np.random.default_rng(0)
    qs = rng.uniform(-np.pi, np.pi, (CHECK_CONFIGS, m.n_q))
    if np.max(np.abs(axes.fk(qs) - m.fk(qs))) > 1e-9 * axes.size:
        return None
    return axes


# ------------------------------------------------------------------------------ line relations
def parallel(axes: Axes, i: int, j: int) -> bool:
    """Axes ``i`` and ``j`` are parallel (or anti-parallel)."""
    return float(np.linalg.norm(np.cross(axes.h[i], axes.h[j]))) < ANGLE_TOL


def intersection(axes: Axes, i: int, j: int) -> np.ndarray | None:
    """The common point of non-parallel axes ``i`` and ``j`` (midpoint of their common
    perpendicular), or None when they are parallel or do not intersect."""
    hi, hj = axes.h[i], axes.h[j]
    n = np.cross(hi, hj)
    sn = float(np.linalg.norm(n))
    if sn < ANGLE_TOL:
        return None
    d = axes.r[j] - axes.r[i]
    if abs(float(d @ n)) / sn > DIST_TOL * axes.size:
        return None
    # r_i + s hi = r_j + t hj (least squares)
    a = np.stack([hi, -hj], axis=1)
    s, t = np.linalg.lstsq(a, d, rcond=None)[0]
    return 0.5 * (axes.r[i] + s * hi + axes.r[j] + t * hj)


def common_point(axes: Axes, i: int, j: int, k: int) -> np.ndarray | None:
    """The point where consecutive axes ``i``, ``j``, ``k`` all meet, or None."""
    a = intersection(axes, i, j)
    b = intersection(axes, j, k)
    if a is None or b is None or np.linalg.norm(a - b) > DIST_TOL * axes.size:
        return None
    return 0.5 * (a + b)


@dataclass(frozen=True)
class Structure:
    """A detected 6R family.

    Attributes:
        family: ``"spherical_wrist"``, ``"spherical_base"``, ``"three_parallel"`` or
            ``"three_parallel_reversed"``.
        position: how the position part is solved (for the spherical families: ``"1-2
            intersecting"``, ``"2-3 parallel"``, ``"2-3 intersecting"``, ``"1-2 parallel"``,
            ``"general"``; for the parallel ones: ``"5-6 intersecting"`` or ``"general"``).
        reversed: True when the solver works on the reversed chain.
    """

    family: str
    position: str
    reversed: bool

    @property
    def name(self) -> str:
        """E.g. ``"spherical_wrist (2-3 parallel)"``."""
        return f"{self.family} ({self.position})"


def position_case(axes: Axes) -> str:
    """How the first three axes of a spherical-wrist chain decouple (see ``Structure``)."""
    if intersection(axes, 0, 1) is not None:
        return "1-2 intersecting"
    if parallel(axes, 1, 2) and not parallel(axes, 0, 1):
        return "2-3 parallel"
    if intersection(axes, 1, 2) is not None:
        return "2-3 intersecting"
    if parallel(axes, 0, 1) and not parallel(axes, 1, 2):
        return "1-2 parallel"
    return "general"


def parallel_case(axes: Axes) -> str | None:
    """How a chain with axes 2, 3, 4 parallel decouples, or None when it does not (axis 1 or
    axis 5 parallel to them)."""
    if parallel(axes, 0, 1) or parallel(axes, 4, 1):
        return None
    return "5-6 intersecting" if intersection(axes, 4, 5) is not None else "general"


def detect(axes: Axes) -> Structure | None:
    """The decomposable family of a 6R chain (see the module docstring), or None."""
    if axes.n != 6:
        return None
    back = axes.reversed()
    wrist = common_point(axes, 3, 4, 5) is not None
    base = common_point(back, 3, 4, 5) is not None
    # a decoupled position part first, then the general SP5 one
    if wrist and position_case(axes) != "general":
        return Structure("spherical_wrist", position_case(axes), False)
    if base and position_case(back) != "general":
        return Structure("spherical_base", position_case(back), True)
    if wrist:
        return Structure("spherical_wrist", "general", False)
    if base:
        return Structure("spherical_base", "general", True)
    if parallel(axes, 1, 2) and parallel(axes, 2, 3):
        case = parallel_case(axes)
        if case is not None:
            return Structure("three_parallel", case, False)
    if parallel(back, 1, 2) and parallel(back, 2, 3):
        case = parallel_case(back)
        if case is not None:
            return Structure("three_parallel_reversed", case, True)
    return None
