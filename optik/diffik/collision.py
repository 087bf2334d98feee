"""Velocity dampers: collision avoidance as inequality rows of the differential-IK QP.

For every pair (the robot against the world, and against itself) whose exact signed distance
``d`` (coal, `optik.collision.distance`) is below the *influence distance* ``d_i``, with witness
points ``p_a`` on the robot link ``a`` and ``p_b`` on ``b`` (a world object, or another link),
the distance changes to first order by

    delta d = n^T (J_a(p_a) - J_b(p_b)) dq,   n = (p_a - p_b) / |p_a - p_b|   (``-n`` when ``d < 0``)

with ``J_x(p) = J_v - [p - o_x]_x J_w`` the Jacobian of the point ``p`` fixed to link ``x``
(origin ``o_x``, geometric Jacobian ``[J_v; J_w]``; zero for a world object), so that
``n^T J_x(p) = n^T J_v + ((p - o_x) x n)^T J_w``. The damper of Faverjon and Tournassoud, in the
discrete form of a control barrier function, lets the distance shrink by at most the fraction
``gamma`` of its excess over the margin ``d_s`` per step:

    d + delta d >= d_s + (1 - gamma) (d - d_s)   <=>   -n^T (J_a - J_b) dq <= gamma (d - d_s),

one row ``G dq <= h`` per pair (pairs further than ``d_i`` give none: the QP is unchanged away
from obstacles). A pair already closer than the margin gets a row that pushes it out.

*Broad phase.* Only pairs that may be within ``d_i`` get an exact query: each part is covered by
the spheres of `optik.collision.spheres.sphere_model` (they contain it), a world object by its
bounding sphere, and the pair's lower bound ``min |c_s - c_t| - R_s - R_t`` over its spheres must
be below ``d_i``. Parts on the base body get no world rows (their distance does not depend on
``q``: a row ``0 <= gamma (d - d_s)`` could only make the QP infeasible; the exact check still
judges them).

*One evaluation.* A compiled function (`optik.diffik._codegen.CompiledFunction`, generated C)
gives, at ``q``, every part's pose, every sphere's centre, the sphere bound of every
self-collision pair and every link's origin and Jacobian in one call; the rows of all pairs are
then two ``einsum`` products.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_float
from optik.collision.check import world_parts
from optik.collision.distance import coal_transform, placed_distance
from optik.collision.parts import Part
from optik.collision.robot import RobotGeometry, robot_geometry
from optik.collision.shapes import coal_module
from optik.collision.spheres import sphere_model
from optik.diffik._codegen import CompiledFunction
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism

__all__ = ["DAMPER_GAIN", "INFLUENCE", "DamperKernel", "damper_kernel", "damper_rows"]

INFLUENCE = 0.05
"""Default influence distance ``d_i`` (m)."""

DAMPER_GAIN = 0.5
"""Default ``gamma``: the fraction of the excess distance a step may use up."""


@dataclass(frozen=True, eq=False)
class DamperKernel:
    """What the dampers of one robot geometry evaluate at every step, built once.

    Attributes:
        geo: the robot geometry.
        function: ``q -> (part poses, sphere centres, self gaps, link Jacobians, link origins)``:
            ``(12, P)`` (row-major rotation, then translation, per part), ``(3, S)``, the bound
            ``min |c_s - c_t| - R_s - R_t`` over the spheres of each self-collision pair
            (``len(geo.self_pairs)``), ``(6, L n)`` and ``(3, L)``.
        sphere_radii: ``(S,)`` radii of the covering spheres, grouped by part.
        part_first_sphere: ``(P,)`` index of each part's first sphere.
        moving: ``(P,)`` the part is not on the base body.
    """

    geo: RobotGeometry
    function: CompiledFunction
    sphere_radii: np.ndarray
    part_first_sphere: np.ndarray
    moving: np.ndarray


def _kernel(geo: RobotGeometry) -> DamperKernel:
    m = geo.mechanism
    model = sphere_model(geo)
    link_poses = [m.frame_expr(link) for link in geo.links]
    of_part = [link_poses[int(k)] for k in geo.part_link]
    part_poses = []
    for t_link, part in zip(of_part, geo.parts, strict=True):
        t = ca.mtimes(t_link, ca.DM(part.offset))
        part_poses.append(ca.vertcat(ca.vec(t[:3, :3].T), t[:3, 3]))
    centres = [
        ca.mtimes(of_part[k][:3, :3], ca.DM(c)) + of_part[k][:3, 3]
        for k, c in zip(model.part, model.centres, strict=True)
    ]
    first = np.searchsorted(model.part, np.arange(len(geo.parts)))
    counts = np.bincount(model.part, minlength=len(geo.parts))
    gaps = []
    for i, j in geo.self_pairs:
        gap = ca.SX(np.inf)
        for s in range(first[i], first[i] + counts[i]):
            for t in range(first[j], first[j] + counts[j]):
                gap = ca.fmin(gap, ca.norm_2(centres[s] - centres[t]) - model.radii[s] - model.radii[t])
        gaps.append(gap)
    f = ca.Function(
        "collision_dampers",
        [m.q_sym],
        [
            ca.horzcat(*part_poses),
            ca.horzcat(*centres),
            ca.vertcat(*gaps) if gaps else ca.SX(0, 1),
            ca.horzcat(*(m.jacobian_expr(link) for link in geo.links)),
            ca.horzcat(*(t[:3, 3] for t in link_poses)),
        ],
    )
    return DamperKernel(
        geo,
        CompiledFunction(f),
        model.radii,
        first,
        np.array([m.frames[geo.links[int(k)]][0] != m.base for k in geo.part_link], dtype=bool),
    )


_KERNELS: weakref.WeakKeyDictionary[RobotGeometry, DamperKernel] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def damper_kernel(geo: RobotGeometry) -> DamperKernel:
    """The [`DamperKernel`][optik.diffik.collision.DamperKernel] of a geometry (built once, cached
    with it; its C code builds in the background, CasADi's evaluator answering meanwhile)."""
    with _LOCK:
        hit = _KERNELS.get(geo)
    if hit is None:
        hit = _kernel(geo)
        with _LOCK:
            hit = _KERNELS.setdefault(geo, hit)
    return hit


def _candidates(
    kernel: DamperKernel,
    centres: np.ndarray,
    gaps: np.ndarray,
    obstacles: tuple[Part, ...],
    self_collision: bool,
    d_i: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(a, b, world)``: the pairs whose sphere bound is below ``d_i`` (against an obstacle:
    ``|c_s - c_o| - R_s - r_o < d_i`` for some sphere, compared squared); ``b`` indexes the
    obstacles when ``world``, else the parts."""
    a, b, world = [], [], []
    if obstacles:
        reach = kernel.sphere_radii[:, None] + np.array([o.radius for o in obstacles])[None] + d_i
        delta = centres[:, None, :] - np.array([o.centre for o in obstacles])[None]
        near = np.einsum("sok,sok->so", delta, delta) < reach * reach
        hit = np.add.reduceat(near, kernel.part_first_sphere, axis=0) > 0
        hit &= kernel.moving[:, None]
        part, obstacle = np.nonzero(hit)
        a.append(part)
        b.append(obstacle)
        world.append(np.ones(len(part), dtype=bool))
    if self_collision and len(gaps):
        close = np.flatnonzero(gaps < d_i)
        a.append(kernel.geo.self_pairs[close, 0])
        b.append(kernel.geo.self_pairs[close, 1])
        world.append(np.zeros(len(close), dtype=bool))
    if not a:
        empty = np.zeros(0, dtype=int)
        return empty, empty, np.zeros(0, dtype=bool)
    return np.concatenate(a), np.concatenate(b), np.concatenate(world)


def damper_rows(
    m: Mechanism,
    q: np.ndarray,
    world: Any,
    self_collision: bool,
    margin: Any = 0.0,
    influence: Any = INFLUENCE,
    gain: Any = DAMPER_GAIN,
) -> tuple[np.ndarray, np.ndarray, float]:
    """``(G, h, d_min)``: the damper rows ``G dq <= h`` at ``q`` (module docstring) and the
    smallest exact distance of the pairs queried (``inf``: no pair within the influence distance
    of its sphere bound). The rows are ordered by increasing distance.

    Raises:
        InvalidArgumentError: a negative ``margin``, an ``influence`` not above it, a ``gain``
            outside ``(0, 1]``, or a bad ``world``.
    """
    d_s = as_float(margin, "margin", 0.0)
    d_i = as_float(influence, "influence", 0.0)
    if not d_i > d_s:
        raise InvalidArgumentError("influence", f"must exceed the margin {d_s:g} m, got {d_i:g}")
    gamma = as_float(gain, "collision_gain")
    if not 0.0 < gamma <= 1.0:
        raise InvalidArgumentError("collision_gain", f"must be in (0, 1], got {gamma:g}")
    obstacles = world_parts(world)
    geo = robot_geometry(m)
    kernel = damper_kernel(geo)
    poses, centres, gaps, jac, origins = kernel.function(q)
    poses, centres = poses.T, centres.T  # (P, 12), (S, 3): contiguous rows
    cand_a, cand_b, cand_world = _candidates(kernel, centres, gaps, obstacles, self_collision, d_i)
    k = len(cand_a)
    if not k:
        return np.zeros((0, m.n_q)), np.zeros(0), np.inf
    coal = coal_module()
    tfs: dict[int, Any] = {}  # coal transforms by part index (obstacle b as -1 - b), made once per step

    def tf(i: int) -> Any:
        got = tfs.get(i)
        if got is None:
            if i >= 0:  # the rows of `poses`: row-major rotation, then translation
                got = coal.Transform3s(poses[i, :9].reshape(3, 3), poses[i, 9:])
            else:
                got = coal_transform(obstacles[-1 - i].offset)
            tfs[i] = got
        return got

    d, pa, pb = np.empty(k), np.empty((k, 3)), np.empty((k, 3))
    parts = geo.parts
    pairs = zip(cand_a.tolist(), cand_b.tolist(), cand_world.tolist(), strict=True)
    for r, (a, b, in_world) in enumerate(pairs):
        other, tf_b = (obstacles[b], tf(-1 - b)) if in_world else (parts[b], tf(b))
        d[r], pa[r], pb[r] = placed_distance(parts[a], tf(a), other, tf_b)
    d_min = float(d.min())
    delta = pa - pb
    length = np.sqrt(np.einsum("pk,pk->p", delta, delta))
    # touching at one point (|p_a - p_b| ~ 0) has no direction: no row (the check still decides success)
    keep = np.flatnonzero((d < d_i) & (length >= 1e-12))
    keep = keep[np.argsort(d[keep], kind="stable")]
    d, pa, pb, delta, length = d[keep], pa[keep], pb[keep], delta[keep], length[keep]
    n = delta * (np.where(d >= 0, 1.0, -1.0) / length)[:, None]
    jt = jac.T.reshape(len(geo.links), m.n_q, 6)  # jt[l, j] = column j of link l's Jacobian
    link_a = geo.part_link[cand_a[keep]]
    rows = np.einsum("pjs,ps->pj", jt[link_a], _wrench(n, pa - origins.T[link_a]))
    own = ~cand_world[keep]
    if own.any():
        link_b = geo.part_link[cand_b[keep][own]]
        rows[own] -= np.einsum("pjs,ps->pj", jt[link_b], _wrench(n[own], pb[own] - origins.T[link_b]))
    return -rows, gamma * (d - d_s), d_min


def _wrench(n: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``(k, 6)`` rows ``[n, r x n]``: ``[n, r x n] . [J_v; J_w]`` is ``n^T (J_v - [r]_x J_w)``."""
    out = np.empty((len(n), 6))
    out[:, :3] = n
    out[:, 3] = r[:, 1] * n[:, 2] - r[:, 2] * n[:, 1]
    out[:, 4] = r[:, 2] * n[:, 0] - r[:, 0] * n[:, 2]
    out[:, 5] = r[:, 0] * n[:, 1] - r[:, 1] * n[:, 0]
    return out
