"""Velocity dampers: collision avoidance as inequality rows of the differential-IK QP.

For every pair of the exact check (`optik.collision.check`: the robot against the world, and
against itself) whose signed distance ``d`` is below the *influence distance* ``d_i``, with
witness points ``p_a`` on the robot link ``a`` and ``p_b`` on ``b`` (a world object, or another
link), the distance changes to first order by

    delta d = n^T (J_a(p_a) - J_b(p_b)) dq,   n = (p_a - p_b) / |p_a - p_b|   (``-n`` when ``d < 0``)

with ``J_x(p) = J_v - [p - o_x]_x J_w`` the Jacobian of the point ``p`` fixed to link ``x``
(origin ``o_x``, geometric Jacobian ``[J_v; J_w]``; zero for a world object). The damper of
Faverjon and Tournassoud, in the discrete form of a control barrier function, lets the
distance shrink by at most the fraction ``gamma`` of its excess over the margin ``d_s`` per step:

    d + delta d >= d_s + (1 - gamma) (d - d_s)   <=>   -n^T (J_a - J_b) dq <= gamma (d - d_s),

one row ``G dq <= h`` per pair (pairs further than ``d_i`` give none: the QP is unchanged away
from obstacles). A pair already closer than the margin gets a row that pushes it out.
"""

from __future__ import annotations

import threading
import weakref
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_float
from optik.collision.check import check
from optik.collision.robot import RobotGeometry, robot_geometry
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism

__all__ = ["DAMPER_GAIN", "INFLUENCE", "damper_rows"]

INFLUENCE = 0.05
"""Default influence distance ``d_i`` (m)."""

DAMPER_GAIN = 0.5
"""Default ``gamma``: the fraction of the excess distance a step may use up."""


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


_JACOBIANS: weakref.WeakKeyDictionary[RobotGeometry, ca.Function] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def _link_jacobians(geo: RobotGeometry) -> ca.Function:
    """``q -> [J_1, ..., J_L]``: the geometric Jacobians of ``geo.links`` side by side (one
    function, built once per geometry, so a step evaluates every link's Jacobian in one call)."""
    with _LOCK:
        hit = _JACOBIANS.get(geo)
    if hit is None:
        m = geo.mechanism
        jac = ca.horzcat(*(m.jacobian_expr(link) for link in geo.links))
        hit = ca.Function("collision_link_jacobians", [m.q_sym], [jac])
        with _LOCK:
            hit = _JACOBIANS.setdefault(geo, hit)
    return hit


def _point_jacobian(jacobians: np.ndarray, poses: np.ndarray, k: int, p: np.ndarray) -> np.ndarray:
    """The ``3 x n`` Jacobian of point ``p`` (base frame) fixed to link ``k``."""
    jac = jacobians[k]
    return jac[:3] - _skew(p - poses[k, :3, 3]) @ jac[3:]


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
    smallest exact distance found (``inf``: no pair within the influence distance).

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
    report = check(m, q, world, margin=d_i, self_collision=self_collision)
    rows, rhs = [], []
    if report.close_pairs:
        geo = robot_geometry(m)
        index = {link: k for k, link in enumerate(geo.links)}
        poses = geo.link_poses(q)
        jacobians = np.asarray(_link_jacobians(geo)(q)).reshape(6, len(geo.links), m.n_q).transpose(1, 0, 2)
    for pair in report.close_pairs:
        delta = pair.point_a - pair.point_b
        length = float(np.linalg.norm(delta))
        if length < 1e-12:
            continue  # touching at one point: no direction (the check still decides success)
        n = delta / length * (1.0 if pair.distance >= 0 else -1.0)
        jac = _point_jacobian(jacobians, poses, index[pair.a], pair.point_a)
        if not pair.world:
            jac = jac - _point_jacobian(jacobians, poses, index[pair.b], pair.point_b)
        rows.append(-(n @ jac))
        rhs.append(gamma * (pair.distance - d_s))
    g = np.array(rows, dtype=float).reshape(-1, m.n_q)
    return g, np.array(rhs, dtype=float), report.min_distance
