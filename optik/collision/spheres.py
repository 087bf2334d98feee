"""Conservative sphere models of the robot and smooth distance bounds, as CasADi expressions.

The solvers cannot call coal inside their iterations, so they constrain a model that contains
the robot: each part's geometry (`optik.collision.shapes.shape_vertices`: hull vertices ``V``
and a radius ``r`` whose balls around the hull contain the shape) is fitted with a **capsule**
along the principal axis of ``V`` that makes it smallest (the segment spans the projections
of ``V`` on the axis; the radius is the largest distance of a vertex from the axis, plus
``r``), and the capsule is covered by ``n`` **spheres** on its segment, spaced
``s = L / (n - 1) <= rho`` apart, of radius ``R = sqrt(rho^2 + (s / 2)^2)``: every point of
the capsule is within ``R`` of a sphere centre, so the spheres contain the part.

Distances (`distance_expressions`), each a lower bound of the exact signed distance of the
sphere to the other body, so that ``bound >= margin`` implies clearance ``>= margin``:

* sphere to sphere: ``|c_a - c_b| - R_a - R_b``;
* sphere to a world object, through the object's signed distance function at the centre
  ``p`` (in the object's frame), minus ``R``: a sphere ``|p| - r``; a box
  ``|max(|p| - h, 0)| + min(max_i(|p_i| - h_i), 0)``; a capsule the distance to its segment
  minus its radius; a cylinder the 2-D box function of ``(|p_xy| - r, |p_z| - L / 2)``; a convex
  mesh ``max_k(n_k . p + o_k)`` over its face planes (exact inside, a lower bound outside).

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

from optik.collision.parts import Part
from optik.collision.robot import RobotGeometry
from optik.collision.shapes import shape_vertices

__all__ = ["SphereModel", "distance_expressions", "fit_capsule", "separable_pairs", "sphere_model"]

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
    """Spheres containing a robot's parts.

    Attributes:
        part: index of the part (`RobotGeometry.parts`) each sphere covers.
        centres: ``(S, 3)`` centres in the frame of the part's link.
        radii: ``(S,)`` radii.
    """

    part: np.ndarray
    centres: np.ndarray
    radii: np.ndarray


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
    parts, centres, radii = [], [], []
    for k, p in enumerate(geo.parts):
        v, r = shape_vertices(p.shape)
        v = v @ p.offset[:3, :3].T + p.offset[:3, 3]  # into the link frame
        a, b, rho = fit_capsule(v, r)
        c, rr = _cover(a, b, rho)
        parts += [k] * len(c)
        centres.append(c)
        radii.append(rr)
    model = SphereModel(np.array(parts, dtype=int), np.concatenate(centres), np.concatenate(radii))
    with _LOCK:
        return _CACHE.setdefault(geo, model)


SEPARABLE_SAMPLES = 200
"""Configurations sampled by `separable_pairs`."""


def separable_pairs(geo: RobotGeometry, bound: float) -> np.ndarray:
    """The self-collision part pairs (rows of ``geo.self_pairs``) that the sphere model keeps
    apart by ``bound`` in at least 5 % of `SEPARABLE_SAMPLES` configurations drawn within the
    limits (seeded). The others (the model of a squat base against a link fixed just above
    it, say) would make every configuration infeasible: the solvers leave them to the exact
    check, which still decides success."""
    key = (geo, bound)
    with _LOCK:
        hit = _SEPARABLE.get(key)
    if hit is not None:
        return hit
    m = geo.mechanism
    model = sphere_model(geo)
    by_part: dict[int, np.ndarray] = {k: np.flatnonzero(model.part == k) for k in range(len(geo.parts))}
    clear = np.zeros(len(geo.self_pairs))
    for q in m.random_q(SEPARABLE_SAMPLES, seed=0):
        links = geo.link_poses(q)[geo.part_link[model.part]]
        c = np.einsum("sij,sj->si", links[:, :3, :3], model.centres) + links[:, :3, 3]
        for row, (i, j) in enumerate(geo.self_pairs):
            a, b = by_part[int(i)], by_part[int(j)]
            gap = (
                np.linalg.norm(c[a][:, None] - c[b][None], axis=2)
                - model.radii[a][:, None]
                - model.radii[b][None]
            )
            clear[row] += gap.min() >= bound
    keep = clear >= 0.05 * SEPARABLE_SAMPLES
    with _LOCK:
        return _SEPARABLE.setdefault(key, keep)


_SEPARABLE: dict[tuple[RobotGeometry, float], np.ndarray] = {}


def _norm(x: ca.SX) -> ca.SX:
    return ca.sqrt(ca.sumsqr(x) + _EPS**2) - _EPS


def _sdf(part: Part, p: ca.SX) -> ca.SX:
    """Signed distance (or a lower bound: convex meshes) of point ``p`` (base frame) to a placed part."""
    t = part.offset
    local = ca.mtimes(ca.DM(t[:3, :3].T), p - ca.DM(t[:3, 3]))
    s = part.shape.size
    kind = part.shape.kind
    if kind == "sphere":
        return _norm(local) - s[0]
    if kind == "box":
        q = ca.fabs(local) - ca.DM(np.asarray(s) / 2)
        return _norm(ca.fmax(q, 0)) + ca.fmin(ca.mmax(q), 0)
    if kind == "capsule":
        z = ca.fmin(ca.fmax(local[2], -s[1] / 2), s[1] / 2)
        return _norm(local - ca.vertcat(0, 0, z)) - s[0]
    if kind == "cylinder":
        q = ca.vertcat(_norm(local[:2]) - s[0], ca.fabs(local[2]) - s[1] / 2)
        return _norm(ca.fmax(q, 0)) + ca.fmin(ca.mmax(q), 0)
    # a convex mesh: coal's face planes n . x + o <= 0 inside
    hull = part.geometry
    normals = np.array(hull.normals(), dtype=float).reshape(-1, 3)
    offsets = np.array(hull.offsets(), dtype=float).ravel()
    return ca.mmax(ca.mtimes(ca.DM(normals), local) + ca.DM(offsets))


def distance_expressions(
    geo: RobotGeometry,
    link_poses: Sequence[ca.SX],
    obstacles: Sequence[Part],
    self_collision: bool,
    bound: float | None = None,
) -> tuple[ca.SX, list[tuple[str, str]]]:
    """Lower bounds of the signed distances of the sphere model, one row per sphere pair, with the
    names of each row's pair.

    Args:
        geo: the robot geometry.
        link_poses: symbolic 4x4 pose of each of ``geo.links`` (e.g. ``m.frame_expr(link)``).
        obstacles: the world's parts (`optik.World.parts`); parts on the base body get no rows
            against them (constant in ``q``: the exact check alone judges them).
        self_collision: include the robot's self-collision pairs (`RobotGeometry.self_pairs`).
        bound: the distance the solver will require: self pairs the model cannot keep that far
            apart are left out (`separable_pairs`; None: keep every pair).
    """
    model = sphere_model(geo)
    centres = []
    for k, c in zip(model.part, model.centres, strict=True):
        t = link_poses[int(geo.part_link[k])]
        centres.append(ca.mtimes(t[:3, :3], ca.DM(c)) + t[:3, 3])
    rows: list[ca.SX] = []
    names: list[tuple[str, str]] = []
    by_part: dict[int, list[int]] = {}
    for s, k in enumerate(model.part):
        by_part.setdefault(int(k), []).append(s)
    m = geo.mechanism
    moving = [m.frames[link][0] != m.base for link in geo.links]
    for s, k in enumerate(model.part):
        if not moving[int(geo.part_link[k])]:
            continue  # a part on the base body never moves: no constraint can change its rows
        for o in obstacles:
            rows.append(_sdf(o, centres[s]) - model.radii[s])
            names.append((geo.parts[k].name, o.name))
    if self_collision:
        pairs = geo.self_pairs if bound is None else geo.self_pairs[separable_pairs(geo, bound)]
        for i, j in pairs:
            for a in by_part[int(i)]:
                for b in by_part[int(j)]:
                    rows.append(_norm(centres[a] - centres[b]) - model.radii[a] - model.radii[b])
                    names.append((geo.parts[i].name, geo.parts[j].name))
    return (ca.vertcat(*rows) if rows else ca.SX(0, 1)), names
