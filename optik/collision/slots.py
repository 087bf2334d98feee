"""A world as parameters of generated code: each obstacle a rounded box in one of a fixed number of slots.

The compiled collision-aware kernels (`optik.solvers.collision_free`) must not depend on where the
obstacles are, or each moved object would need new C. So a world enters them as numbers: up to
``capacity`` *slots*, each holding one **rounded box** ``B(T, h, r)``, the points within ``r`` of
the box of half extents ``h`` at pose ``T = [R, t]``. Its signed distance at a point ``p`` is
exact and has a closed form: with ``l = R^T (p - t)`` and ``u = |l| - h`` (per axis),

    sdf(p) = |max(u, 0)| + min(max_i u_i, 0) - r.

One family covers the primitives exactly and the rest conservatively (containing them):

| obstacle | slot |
|---|---|
| box of edges ``s`` | ``h = s / 2``, ``r = 0`` (exact) |
| sphere of radius ``r`` | ``h = 0`` (exact) |
| capsule ``(r, L)`` | ``h = (0, 0, L / 2)`` (exact) |
| cylinder ``(r, L)`` | the box ``h = (r, r, L / 2)``, ``r = 0`` (contains it) |
| convex mesh | the smaller box of its hull vertices along the mesh's or their principal axes |
| point cloud | one sphere slot per point |

A slot is 17 numbers: ``vec(R)`` (column-major), ``t``, ``h``, ``r`` and an *active* flag (1 for
an obstacle, 0 for an empty slot, whose rows the kernels multiply by 0). `capacity_for` rounds the
number of obstacles up to a power of two (at least `MIN_CAPACITY`), so one library per robot
serves every world of up to that many objects, and `World.move` costs nothing.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from optik.collision.parts import Part
from optik.collision.shapes import shape_vertices

__all__ = [
    "MIN_CAPACITY",
    "SLOT_SIZE",
    "capacity_for",
    "rounded_box",
    "slot_distance",
    "slot_values",
    "smooth_norm",
]

SLOT_SIZE = 17
"""Numbers per slot: ``vec(R)`` (9), ``t`` (3), ``h`` (3), ``r``, active."""

MIN_CAPACITY = 8
"""The smallest number of slots a kernel is built with."""


def capacity_for(n: int) -> int:
    """The slot capacity for ``n`` obstacles: the next power of two ``>= max(n, MIN_CAPACITY)``."""
    c = MIN_CAPACITY
    while c < n:
        c *= 2
    return c


def _box_of(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(R, centre, h)``: a box containing the points ``v`` (``(N, 3)``), along their own axes or
    their principal axes, whichever box is smaller."""
    boxes = []
    for axes in (np.eye(3), np.linalg.svd(v - v.mean(axis=0), full_matrices=False)[2].T):
        if np.linalg.det(axes) < 0:
            axes = axes * np.array([1.0, 1.0, -1.0])
        local = v @ axes
        lo, hi = local.min(axis=0), local.max(axis=0)
        boxes.append((float(np.prod(hi - lo)), axes, axes @ ((lo + hi) / 2), (hi - lo) / 2))
    _, axes, centre, h = min(boxes, key=lambda b: b[0])
    return axes, centre, h


def rounded_box(part: Part) -> tuple[np.ndarray, np.ndarray, float]:
    """``(T, h, r)``: the rounded box of a placed world part (see the module's table): the part
    lies within it, exactly so for boxes, spheres and capsules."""
    s, kind, t = part.shape.size, part.shape.kind, part.offset
    if kind == "box":
        return t, np.asarray(s) / 2, 0.0
    if kind == "sphere":
        return t, np.zeros(3), s[0]
    if kind == "capsule":
        return t, np.array([0.0, 0.0, s[1] / 2]), s[0]
    if kind == "cylinder":
        return t, np.array([s[0], s[0], s[1] / 2]), 0.0
    v, r = shape_vertices(part.shape)  # a mesh: its hull vertices (r = 0)
    axes, centre, h = _box_of(v)
    local = np.eye(4)
    local[:3, :3], local[:3, 3] = axes, centre
    return t @ local, h, r


def slot_values(parts: Sequence[Part], capacity: int) -> np.ndarray:
    """The ``capacity * SLOT_SIZE`` parameter values of a world's parts (`optik.World.parts`),
    the empty slots zero (inactive).

    Raises:
        ValueError: more parts than ``capacity`` (the caller sizes it by `capacity_for`).
    """
    if len(parts) > capacity:
        raise ValueError(f"{len(parts)} obstacles do not fit {capacity} slots")
    out = np.zeros((capacity, SLOT_SIZE))
    for k, part in enumerate(parts):
        t, h, r = rounded_box(part)
        out[k] = np.concatenate([t[:3, :3].ravel(order="F"), t[:3, 3], h, [r, 1.0]])
    return out.ravel()


def smooth_norm(x: ca.SX, eps: float) -> ca.SX:
    """``sqrt(|x|^2 + eps^2) - eps``: never more than ``|x|``, differentiable everywhere."""
    return ca.sqrt(ca.sumsqr(x) + eps**2) - eps


def slot_distance(slot: ca.SX, p: ca.SX, eps: float) -> ca.SX:
    """The signed distance of point ``p`` to the rounded box of ``slot`` (``SLOT_SIZE`` symbols),
    its norm smoothed as ``sqrt(x^2 + eps^2) - eps`` (never more than the norm)."""
    rot = ca.reshape(slot[:9], 3, 3)
    local = ca.mtimes(rot.T, p - slot[9:12])
    u = ca.fabs(local) - slot[12:15]
    return smooth_norm(ca.fmax(u, 0), eps) + ca.fmin(ca.mmax(u), 0) - slot[15]
