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

*Broad phase.* Only pairs that may be within ``d_i`` get an exact query: those whose screening
bound (`optik.collision.screen`: one compiled call for the part poses and a lower bound of every
pair's distance, from the spheres and capsules that contain the parts) is below ``d_i``. The
screen is built for the smallest power of two of slots that holds the world's parts (the world's
own slot values, cut there), not the world's capacity: each slot costs a bound per sphere. Parts on
the base body get no world rows (their distance does not depend on ``q``: a row
``0 <= gamma (d - d_s)`` could only make the QP infeasible; the exact check still judges them).

*Jacobians.* A second compiled function (`optik.diffik._codegen.CompiledFunction`, generated C)
gives the origin and geometric Jacobian of one link of each moving body in one call (the point
Jacobian above holds for any reference point of the body); the rows of all pairs are then two
``einsum`` products.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_float
from optik.collision.distance import coal_distance, signed_request
from optik.collision.robot import RobotGeometry, robot_geometry
from optik.collision.screen import screen
from optik.collision.shapes import coal_module
from optik.collision.slots import SLOT_SIZE
from optik.collision.world import state_of
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
    """The Jacobians the dampers of one robot geometry evaluate at every step, built once.

    Attributes:
        function: ``q -> (J, o)``: ``(6, (B + 1) n)`` the geometric Jacobians of one link of each
            of the ``B`` moving bodies that carry parts, side by side, and ``(3, B + 1)`` those
            links' origins; the last block is the base body's (zeros).
        part_body: ``(P,)`` the body of each part (``B`` for the base body, whose Jacobian is 0).
        blocked: ``(P, 1)`` ``inf`` for the parts on the base body (no world rows), else 0.
    """

    function: CompiledFunction
    part_body: np.ndarray
    blocked: np.ndarray


def _kernel(geo: RobotGeometry) -> DamperKernel:
    m = geo.mechanism
    bodies: dict[str, str] = {}  # body -> its first link with parts
    for k in geo.part_link:
        link = geo.links[int(k)]
        body = m.frames[link][0]
        if body != m.base:
            bodies.setdefault(body, link)
    index = {body: i for i, body in enumerate(bodies)}
    links = list(bodies.values())
    f = ca.Function(  # the base body's Jacobian (0) and origin (0) last, so that any part indexes it
        "collision_damper_jacobians",
        [m.q_sym],
        [
            ca.horzcat(*(m.jacobian_expr(link) for link in links), ca.SX.zeros(6, m.n_q)),
            ca.horzcat(*(m.frame_expr(link)[:3, 3] for link in links), ca.SX.zeros(3, 1)),
        ],
    )
    part_body = np.array([index.get(m.frames[geo.links[int(k)]][0], len(links)) for k in geo.part_link])
    blocked = np.where(part_body < len(links), 0.0, np.inf)[:, None]
    return DamperKernel(CompiledFunction(f), part_body, blocked)


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


def damper_rows(
    m: Mechanism,
    q: np.ndarray,
    world: Any,
    self_collision: bool,
    margin: Any = 0.0,
    influence: Any = INFLUENCE,
    gain: Any = DAMPER_GAIN,
) -> tuple[np.ndarray, np.ndarray, float]:
    """``(G, h, d_min)``: the damper rows ``G dq <= h`` at ``q`` (module docstring), ordered by
    increasing distance, and the smallest exact distance of the pairs queried (``inf``: no pair's
    screening bound is below the influence distance).

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
    state = state_of(world)
    geo = robot_geometry(m)
    kernel = damper_kernel(geo)
    n_obj = len(state.parts)
    capacity = 1 << max(n_obj - 1, 0).bit_length()  # the slots in use: every empty one costs a step time
    poses, to_world, own = screen(geo, capacity).bounds(q, state.slots[: capacity * SLOT_SIZE], n_obj)
    near_a, near_b = np.nonzero(to_world + kernel.blocked < d_i)
    pairs = list(zip(near_a.tolist(), near_b.tolist(), strict=True))
    n_world = len(pairs)
    if self_collision:
        pairs += geo.self_pairs[own < d_i].tolist()
    if not pairs:
        return np.zeros((0, m.n_q)), np.zeros(0), np.inf
    coal = coal_module()
    request = signed_request()
    tfs: dict[int, Any] = {}  # coal transforms of the robot's parts, made when first needed

    def tf(k: int) -> Any:
        got = tfs.get(k)
        if got is None:  # the rows of `poses`: row-major rotation, then translation
            got = tfs[k] = coal.Transform3s(poses[k, :9].reshape(3, 3), poses[k, 9:])
        return got

    parts = geo.parts
    found = []  # (d, row of `pairs`, coal's result) of the pairs within the influence distance
    d_min = np.inf
    for r, (a, b) in enumerate(pairs):
        if r < n_world:
            d, res = coal_distance(
                parts[a].geometry, tf(a), state.parts[b].geometry, state.transforms[b], request
            )
        else:
            d, res = coal_distance(parts[a].geometry, tf(a), parts[b].geometry, tf(b), request)
        d_min = min(d_min, d)
        if d < d_i:
            found.append((d, r, res))
    found.sort(key=lambda f: f[0])
    k = len(found)
    d, witness = np.empty(k), np.empty((k, 2, 3))
    ends = np.empty((k, 2), dtype=int)  # the bodies of each pair (the base body's for an obstacle)
    body = kernel.part_body.tolist()
    for i, (dist, r, res) in enumerate(found):
        d[i] = dist
        witness[i, 0], witness[i, 1] = res.getNearestPoint1(), res.getNearestPoint2()
        a, b = pairs[r]
        ends[i] = body[a], (body[b] if r >= n_world else -1)
    delta = witness[:, 0] - witness[:, 1]
    length = np.sqrt(np.einsum("pk,pk->p", delta, delta))
    # touching at one point (|p_a - p_b| ~ 0) has no direction: no row (the check still decides success)
    ok = length >= 1e-12
    if not ok.all():
        d, witness, ends, delta, length = d[ok], witness[ok], ends[ok], delta[ok], length[ok]
    n = delta * (np.where(d >= 0, 1.0, -1.0) / length)[:, None]
    jac, origins = kernel.function.call_flat(q)
    jt = jac.T.reshape(-1, m.n_q, 6)  # jt[body, j]: column j of the body's Jacobian (a view; -1: zeros)
    # both ends at once: n^T J_a(p_a) + (-n)^T J_b(p_b), J_b = 0 for an obstacle (body -1)
    bodies, points = ends.reshape(-1), witness.reshape(-1, 3)
    normals = (n[:, None, :] * _BOTH_ENDS).reshape(-1, 3)
    r = points - origins.T[bodies]
    w = np.concatenate([normals, np.einsum("ijk,pj,pk->pi", _LEVI_CIVITA, r, normals)], axis=1)
    rows = np.matmul(jt[bodies], w[:, :, None]).reshape(-1, 2, m.n_q).sum(axis=1)
    return -rows, gamma * (d - d_s), float(d_min)


_BOTH_ENDS = np.array([[1.0], [-1.0]])
"""The normal's sign at each end of a pair (towards ``a`` from ``b``)."""

_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[[0, 1, 2], [1, 2, 0], [2, 0, 1]] = 1.0
_LEVI_CIVITA[[0, 1, 2], [2, 0, 1], [1, 2, 0]] = -1.0
"""``(r x n)_i = eps_ijk r_j n_k``: the rows ``[n, r x n] . [J_v; J_w] = n^T (J_v - [r]_x J_w)``."""
