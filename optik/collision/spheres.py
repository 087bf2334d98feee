"""Conservative sphere and capsule models of the robot and smooth distance bounds, as CasADi expressions.

The solvers cannot call coal inside their iterations, so they constrain a model that contains
the robot: each part's geometry (`optik.collision.shapes.shape_vertices`: hull vertices ``V``
and a radius ``r`` whose balls around the hull contain the shape) is fitted with a **capsule**
along the principal axis of ``V`` that makes it smallest (the segment spans the projections
of ``V`` on the axis; the radius is the largest distance of a vertex from the axis, plus
``r``), and the capsule is covered by ``n`` **spheres** on its segment, spaced
``s = L / (n - 1) <= rho`` apart, of radius ``R = sqrt(rho^2 + (s / 2)^2)``: every point of
the capsule is within ``R`` of a sphere centre, so the spheres contain the part.

Distances (`distance_expressions`), each a lower bound of the exact signed distance, so that
``bound >= margin`` implies clearance ``>= margin``:

* part to part (self-collision): the distance of the two capsules, ``|x_a - x_b| - rho_a - rho_b``
  at the closest points of their segments (`segment_distance`): one row per part pair;
* sphere to a world obstacle: the obstacle's rounded box (`optik.collision.slots`, which contains
  it) through its signed distance function at the centre, minus ``R``: one row per moving
  sphere and slot, the slots being parameters of the generated code.

Euclidean norms are smoothed as ``sqrt(x^2 + e^2) - e`` (``e = 1e-9`` m; never more than the
norm) so that every bound has a gradient everywhere.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from optik.collision.robot import RobotGeometry
from optik.collision.shapes import shape_vertices
from optik.collision.slots import SLOT_SIZE, slot_distance, smooth_norm

__all__ = [
    "DistanceRows",
    "SphereModel",
    "capsule_gaps",
    "distance_expressions",
    "fit_capsule",
    "relative_segment_distance",
    "segment_distance",
    "separable_pairs",
    "sphere_model",
]

_EPS = 1e-9


def fit_capsule(v: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray, float]:
    """``(a, b, rho)``: a capsule with segment ``a``-``b`` and radius ``rho`` containing the
    balls of radius ``r`` around the points ``v`` (``(N, 3)``): along the principal axis of
    ``v`` that gives the smallest capsule."""
    centre = v.mean(axis=0)
    if len(v) < 2 or np.allclose(v, centre):
        return centre, centre.copy(), float(r + np.max(np.linalg.norm(v - centre, axis=1)))
    best = None
    for axis in np.linalg.svd(v - centre, full_matrices=False)[2]:
        t = (v - centre) @ axis
        rho = float(np.linalg.norm((v - centre) - np.outer(t, axis), axis=1).max() + r)
        volume = np.pi * rho**2 * (t.max() - t.min()) + 4 / 3 * np.pi * rho**3
        if best is None or volume < best[0]:
            best = (volume, centre + t.min() * axis, centre + t.max() * axis, rho)
    return best[1], best[2], best[3]


@dataclass(frozen=True)
class SphereModel:
    """Capsules and spheres containing a robot's parts.

    Attributes:
        part: index of the part (`RobotGeometry.parts`) each sphere covers.
        centres: ``(S, 3)`` centres in the frame of the part's link.
        radii: ``(S,)`` radii.
        segments: ``(P, 2, 3)`` each part's capsule segment in its link frame.
        capsule_radii: ``(P,)`` the capsules' radii.
    """

    part: np.ndarray
    centres: np.ndarray
    radii: np.ndarray
    segments: np.ndarray
    capsule_radii: np.ndarray


def _cover(a: np.ndarray, b: np.ndarray, rho: float) -> tuple[np.ndarray, np.ndarray]:
    length = float(np.linalg.norm(b - a))
    n = 1 if length == 0 else int(np.ceil(length / rho)) + 1
    s = 0.0 if n == 1 else length / (n - 1)
    t = np.linspace(0.0, 1.0, n)[:, None]
    return a + t * (b - a), np.full(n, np.sqrt(rho**2 + (s / 2) ** 2))


_CACHE: weakref.WeakKeyDictionary[RobotGeometry, SphereModel] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def sphere_model(geo: RobotGeometry) -> SphereModel:
    """The sphere model of a robot's geometry (fitted once, cached with it)."""
    with _LOCK:
        hit = _CACHE.get(geo)
    if hit is not None:
        return hit
    parts, centres, radii, segments, rhos = [], [], [], [], []
    for k, p in enumerate(geo.parts):
        v, r = shape_vertices(p.shape)
        v = v @ p.offset[:3, :3].T + p.offset[:3, 3]  # into the link frame
        a, b, rho = fit_capsule(v, r)
        c, rr = _cover(a, b, rho)
        parts += [k] * len(c)
        centres.append(c)
        radii.append(rr)
        segments.append((a, b))
        rhos.append(rho)
    model = SphereModel(
        np.array(parts, dtype=int),
        np.concatenate(centres),
        np.concatenate(radii),
        np.array(segments, dtype=float).reshape(-1, 2, 3),
        np.array(rhos, dtype=float),
    )
    with _LOCK:
        return _CACHE.setdefault(geo, model)


SEPARABLE_SAMPLES = 200
"""Configurations sampled by `separable_pairs`."""


def separable_pairs(geo: RobotGeometry, bound: float) -> np.ndarray:
    """The self-collision part pairs (rows of ``geo.self_pairs``) whose capsules are apart by
    ``bound`` in at least 5 % of `SEPARABLE_SAMPLES` configurations drawn within the limits
    (seeded; `capsule_gaps`). The others (the capsule of a squat base against a link fixed just
    above it, say) would make every configuration infeasible: the solvers leave them to the exact
    check, which still decides success. So would the kept pairs together when no sample has them
    all apart by ``bound``: then none is kept. TALOS (torso and left arm solved, 754 pairs): 752
    pass one by one, but no sample of the 200 clears them all, nor does any of the 100 clear
    configurations of ``optik benchmark collision_self`` (its capsules, e.g. of the right thigh
    and the right gripper, are up to 0.16 m closer than coal's meshes); the dual Panda's 376
    are all apart in 109 samples."""
    gaps = capsule_gaps(geo) >= bound
    kept = gaps.sum(axis=1) >= 0.05 * SEPARABLE_SAMPLES
    if not gaps[kept].all(axis=0).any():
        kept[:] = False
    return kept


def capsule_gaps(geo: RobotGeometry) -> np.ndarray:
    """``(pairs, SEPARABLE_SAMPLES)``: the capsule distance (`segment_distance` minus both radii)
    of each self-collision pair of ``geo`` at `SEPARABLE_SAMPLES` configurations drawn within the
    limits (seed 0), computed once per geometry (the constrained kernel's build asks for it, so
    that no solve pays for it): the link poses of all samples in one mapped evaluation, then
    one mapped `segment_distance` over every (pair, sample)."""
    with _LOCK:
        hit = _GAPS.get(geo)
    if hit is not None:
        return hit
    m, model, pairs = geo.mechanism, sphere_model(geo), geo.self_pairs
    if len(pairs) == 0:
        gaps = np.zeros((0, SEPARABLE_SAMPLES))
    else:
        poses = ca.vertcat(*[ca.vec(m.frame_expr(link)[:3, :]) for link in geo.links])
        links = ca.Function("link_poses", [m.q_sym], [poses]).map(SEPARABLE_SAMPLES)
        # (samples, links, 4, 3) -> rotation R[s, l] (3, 3) and translation t[s, l] (3,)
        flat = np.asarray(links(m.random_q(SEPARABLE_SAMPLES, seed=0).T)).T
        tf = flat.reshape(SEPARABLE_SAMPLES, len(geo.links), 4, 3).transpose(0, 1, 3, 2)
        rot, trans = tf[..., :3], tf[..., 3]
        part_link = np.asarray(geo.part_link)
        # segment ends of every part at every sample: (samples, parts, 2, 3)
        ends = np.einsum("spij,pkj->spki", rot[:, part_link], model.segments) + trans[:, part_link, None]
        i, j = pairs[:, 0], pairs[:, 1]
        cols = [ends[:, i, 0], ends[:, i, 1], ends[:, j, 0], ends[:, j, 1]]  # each (samples, pairs, 3)
        args = [c.reshape(-1, 3).T for c in cols]
        gaps = np.asarray(_segment_function().map(args[0].shape[1])(*args)).reshape(SEPARABLE_SAMPLES, -1).T
        gaps = gaps - model.capsule_radii[i, None] - model.capsule_radii[j, None]
    with _LOCK:
        return _GAPS.setdefault(geo, gaps)


_GAPS: weakref.WeakKeyDictionary[RobotGeometry, np.ndarray] = weakref.WeakKeyDictionary()


def _segment_function() -> ca.Function:
    """`segment_distance` as a function of its four points (3-vectors)."""
    p1, q1, p2, q2 = (ca.SX.sym(name, 3) for name in ("p1", "q1", "p2", "q2"))
    return ca.Function("segment_distance", [p1, q1, p2, q2], [segment_distance(p1, q1, p2, q2)])


def _clamp01(x: ca.SX) -> ca.SX:
    return ca.fmin(ca.fmax(x, 0), 1)


def segment_distance(p1: ca.SX, q1: ca.SX, p2: ca.SX, q2: ca.SX) -> ca.SX:
    """The distance of segments ``p1 q1`` and ``p2 q2`` (the norm smoothed as in the module
    docstring): the closest parameters of the two lines, ``s`` clamped to ``[0, 1]``, then ``t``
    the closest to that point, clamped, then ``s`` the closest to that one, clamped (Ericson,
    *Real-Time Collision Detection*, 5.1.9; each step can only shorten a distance between two
    points of the segments, and the first gives the minimum whenever ``t`` needs no clamping).
    Degenerate segments (points) and parallel ones are covered by a floor on the divisors."""
    return relative_segment_distance(q1 - p1, q2 - p2, p1 - p2)


def relative_segment_distance(d1: ca.SX, d2: ca.SX, r: ca.SX) -> ca.SX:
    """`segment_distance` of the segments ``p1 + s d1`` and ``p2 + t d2`` (``s, t`` in ``[0, 1]``)
    from their directions and ``r = p1 - p2``: the distance depends on the four points only
    through these 9 numbers (it is invariant to a common translation), so its Hessian in them
    is 9 x 9 instead of 12 x 12 (`optik.solvers.collision_nlp`)."""
    a, e, b = ca.dot(d1, d1), ca.dot(d2, d2), ca.dot(d1, d2)
    c, f = ca.dot(d1, r), ca.dot(d2, r)
    tiny = 1e-12
    s = _clamp01((b * f - c * e) / ca.fmax(a * e - b * b, tiny))
    t = _clamp01((b * s + f) / ca.fmax(e, tiny))
    s = _clamp01((b * t - c) / ca.fmax(a, tiny))
    return smooth_norm(r + s * d1 - t * d2, _EPS)


def _segments(
    model: SphereModel, geo: RobotGeometry, link_poses: Sequence[ca.SX], k: int
) -> tuple[ca.SX, ca.SX]:
    t = link_poses[int(geo.part_link[k])]
    a, b = model.segments[k]
    return ca.mtimes(t[:3, :3], ca.DM(a)) + t[:3, 3], ca.mtimes(t[:3, :3], ca.DM(b)) + t[:3, 3]


def _self_rows(
    geo: RobotGeometry, model: SphereModel, link_poses: Sequence[ca.SX], pairs: np.ndarray
) -> ca.SX:
    ends = [_segments(model, geo, link_poses, k) for k in range(len(geo.parts))]
    rows = [
        segment_distance(*ends[int(i)], *ends[int(j)]) - model.capsule_radii[i] - model.capsule_radii[j]
        for i, j in pairs
    ]
    return ca.vertcat(*rows) if rows else ca.SX(0, 1)


@dataclass(frozen=True)
class DistanceRows:
    """Lower bounds of the robot's signed distances to a world of slots and to itself.

    Attributes:
        world: one row per (moving sphere, slot): the sphere's distance to the slot's rounded box.
        active: the slot's active flag of each ``world`` row (0: an empty slot).
        world_pairs: names of each ``world`` row: the part and the slot index.
        self_rows: one row per self-collision part pair: the distance of their capsules.
        self_pairs: names of each ``self_rows`` row.
    """

    world: ca.SX
    active: ca.SX
    world_pairs: list[tuple[str, int]]
    self_rows: ca.SX
    self_pairs: list[tuple[str, str]]


def distance_expressions(
    geo: RobotGeometry,
    link_poses: Sequence[ca.SX],
    slots: ca.SX,
    self_collision: bool,
    bound: float | None = None,
) -> DistanceRows:
    """Lower bounds of the signed distances of the robot model, to the world's slots and to itself.

    Args:
        geo: the robot geometry.
        link_poses: symbolic 4x4 pose of each of ``geo.links`` (e.g. ``m.frame_expr(link)``).
        slots: the world as ``capacity * SLOT_SIZE`` symbols (`optik.collision.slots`); spheres of
            parts on the base body get no rows (constant in ``q``: the exact check alone judges them).
        self_collision: include the robot's self-collision pairs (`RobotGeometry.self_pairs`).
        bound: the distance the solver will require: self pairs the capsules cannot keep that far
            apart are left out (`separable_pairs`; None: keep every pair).
    """
    model = sphere_model(geo)
    m = geo.mechanism
    moving = [m.frames[link][0] != m.base for link in geo.links]
    world, active, names = [], [], []
    n_slots = slots.shape[0] // SLOT_SIZE
    for s, k in enumerate(model.part):
        if not moving[int(geo.part_link[k])]:
            continue
        t = link_poses[int(geo.part_link[k])]
        centre = ca.mtimes(t[:3, :3], ca.DM(model.centres[s])) + t[:3, 3]
        for j in range(n_slots):
            slot = slots[j * SLOT_SIZE : (j + 1) * SLOT_SIZE]
            world.append(slot_distance(slot, centre, _EPS) - model.radii[s])
            active.append(slot[SLOT_SIZE - 1])
            names.append((geo.parts[k].name, j))
    pairs = np.zeros((0, 2), dtype=int)
    if self_collision:
        pairs = geo.self_pairs if bound is None else geo.self_pairs[separable_pairs(geo, bound)]
    empty = ca.SX(0, 1)
    return DistanceRows(
        ca.vertcat(*world) if world else empty,
        ca.vertcat(*active) if active else empty,
        names,
        _self_rows(geo, model, link_poses, pairs),
        [(geo.parts[i].name, geo.parts[j].name) for i, j in pairs],
    )
