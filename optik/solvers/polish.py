"""Newton polishing of IK candidates and their deduplication by the polished accuracy.

``polish`` refines a configuration that nearly solves an IK request to full floating-point
precision by Gauss-Newton steps on the exact residual

``r(q) = [e_task(q); c(q)]``, ``e_task = pose_error(T(q), T*)`` restricted to the rows of the
task (position ``p - p*``, rotation vector ``log(R R*^T)``, planar heading ``phi - phi*``) and
``c(q)`` the loop-closure residual, with the step ``dq = -pinv(J) r`` where
``J = [J_task; dc/dq]`` (geometric Jacobian rows of the task, closure Jacobian). Coordinates
pinned by their limits (``lower = upper``, e.g. a joint locked by ``solve_ik_all(fixed=...)``)
do not move: their columns of ``J`` are left out. A step that would leave the limits holds the
coordinates it would push out where they are and is taken again without them; a step is kept
only when it lowers ``|r|``; it stops when ``|r|`` no longer decreases.

``same_point_tol`` ties the deduplication distance to that accuracy: a configuration known to
``|r|`` with smallest singular value ``sigma`` of ``J`` is determined to about ``|r| / sigma`` in
joint space, so two polished candidates closer than ``100 |r| / sigma + 1e-9`` (capped at
``BRANCH_TOL``) are the same solution, and candidates further apart are distinct solutions even
near a singular pose.
"""

from __future__ import annotations

import math

import numpy as np

from optik import spatial
from optik.mechanism import Mechanism
from optik.solvers.base import BRANCH_TOL, IKRequest

MAX_STEPS = 8
"""Gauss-Newton steps of ``polish`` at most."""


def residual(m: Mechanism, request: IKRequest, q: np.ndarray) -> np.ndarray:
    """The exact residual ``[e_task; c]`` of ``q`` (see the module docstring)."""
    pose = np.asarray(m.fk_function(request.frame)(q))
    err = spatial.pose_error(pose, request.target)
    task = request.task
    if task == "pose2d":
        phi = math.atan2(pose[1, 0], pose[0, 0]) - math.atan2(request.target[1, 0], request.target[0, 0])
        e = np.array([err[0], err[1], spatial.wrap_angle(phi)])
    else:
        e = err[list(_TASK_ROWS[task])]
    if m.is_closed:
        e = np.concatenate([e, np.asarray(m.closure_function(q)[0]).reshape(-1)])
    return e


_TASK_ROWS = {"pose": range(6), "position": range(3), "orientation": range(3, 6), "position2d": range(2)}


def _jacobian(m: Mechanism, request: IKRequest, q: np.ndarray) -> np.ndarray:
    jac = m.task_jacobian(q, request.frame, request.task)
    if m.is_closed:
        jac = np.vstack([jac, m.closure_jacobian(q)])
    return jac


def polish(m: Mechanism, request: IKRequest, q: np.ndarray) -> tuple[np.ndarray, float, float]:
    """``q`` refined by Gauss-Newton on the exact residual, within the joint limits.

    Returns:
        ``(q, |r(q)|, sigma_min(J(q)))``: the polished configuration, the norm of its residual
        and the smallest singular value of the residual's Jacobian there.
    """
    q = np.asarray(q, dtype=float).copy()
    r = residual(m, request, q)
    norm = float(np.linalg.norm(r))
    pinned = m.lower == m.upper
    held = pinned.copy()
    for _ in range(MAX_STEPS):
        if norm == 0.0 or held.all():
            break
        jac = _jacobian(m, request, q)
        jac[:, held] = 0.0  # the least-norm step leaves these coordinates where they are
        step = np.linalg.lstsq(jac, r, rcond=None)[0]
        trial = q - step
        outside = (trial < m.lower) | (trial > m.upper)
        if outside.any():
            held |= outside
            continue
        r_trial = residual(m, request, trial)
        n_trial = float(np.linalg.norm(r_trial))
        if not n_trial < norm:
            break
        q, r, norm = trial, r_trial, n_trial
    sigma = np.linalg.svd(_jacobian(m, request, q)[:, ~pinned], compute_uv=False)
    return q, norm, float(sigma[-1]) if sigma.size else 0.0


def same_point_tol(norm: float, sigma: float) -> float:
    """Joint-space distance below which two polished candidates are one solution (see the
    module docstring): ``min(BRANCH_TOL, 100 |r| / sigma + 1e-9)``."""
    if sigma <= 0.0:
        return BRANCH_TOL
    return min(BRANCH_TOL, 100.0 * norm / sigma + 1e-9)
