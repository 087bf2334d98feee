"""The two abstractions of differential IK: a [`Task`][optik.diffik.base.Task] (what to achieve) and a
[`Limit`][optik.diffik.base.Limit] (what must hold), plus the symbolic helpers they share.

Both are *symbolic*: a task returns CasADi expressions of its error ``e(q, p)`` and Jacobian
``J(q, p) = de/dq`` in the coordinate symbol ``q`` and a parameter vector ``p`` (targets); a limit
returns expressions of velocity bounds. [`optik.diffik.build_qp`][optik.diffik.build_qp] stacks the
expressions of all tasks and limits into one compiled function per task structure, so changing a target or a
cost never recompiles, and one compiled call per step evaluates every task.

Task convention (the one of Pink/mink): the step ``dq = v dt`` minimises
``1/2 || W (J dq + alpha e) ||^2`` where ``W = diag(cost)`` and ``alpha`` is the task gain
(``alpha = 1`` removes the whole error in one step when the task is feasible).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from optik import spatial
from optik.checks import as_int, as_vector, real_array
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism

BIG = 1e20
"""Finite stand-in for an infinite bound (QP backends differ in how they read ``inf``)."""


def positive(value: Any, name: str) -> float:
    """A finite float ``>= 0`` (else [`InvalidArgumentError`][optik.InvalidArgumentError] naming the
    argument)."""
    v = float(as_vector(value, name, 1)[0])
    if v < 0:
        raise InvalidArgumentError(name, f"must be >= 0, got {v}")
    return v


def cost_vector(value: Any, name: str, size: int) -> np.ndarray:
    """A cost: a scalar broadcast to ``size`` rows, or ``size`` values, all ``>= 0``."""
    v = as_vector(value, name, None)
    if v.shape[0] == 1:
        v = np.full(size, v[0])
    v = as_vector(v, name, size)
    if np.any(v < 0):
        raise InvalidArgumentError(name, f"costs must be >= 0, got {v}")
    return v


def so3_left_jacobian_inverse(w: Any) -> Any:
    """Inverse left Jacobian of SO(3) (CasADi), ``d log(R)/dt = J_l^{-1}(w) omega``.

    ``J_l^{-1}(w) = I - [w]x / 2 + (1/t^2 - (1 + cos t) / (2 t sin t)) [w]x^2`` with ``t = |w|``;
    the coefficient tends to ``1/12`` at ``t = 0`` (Taylor branch below ``t^2 = 1e-6``). With it
    the derivative of [`optik.spatial.pose_error`][optik.spatial.pose_error]'s rotation vector ``log(R R*^T)``
    (the base-frame angular velocity ``omega`` perturbs ``R`` on the left) is exact, not only near the target.
    """
    t2 = ca.dot(w, w)
    t = ca.sqrt(t2 + 1e-300)
    coef = ca.if_else(
        t2 < 1e-6,
        1.0 / 12.0 + t2 / 720.0,
        1.0 / (t2 + 1e-300) - (1 + ca.cos(t)) / (2 * t * ca.sin(t) + 1e-300),
    )
    k = spatial.hat(w)
    return ca.DM.eye(3) - 0.5 * k + coef * ca.mtimes(k, k)


def frame_error_expr(m: Mechanism, frame: str | None, target: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Pose error ``e = [p - p*; log(R R*^T)]`` of a frame and its exact Jacobian ``de/dq``.

    ``de/dq = [J_v; J_l^{-1}(e_w) J_w]`` from the geometric Jacobian ``[J_v; J_w]`` (base frame).

    Args:
        m: the mechanism.
        frame: frame name (None: end effector).
        target: 4x4 ``SX`` symbol of the target transform.
    """
    e = spatial.pose_error(m.frame_expr(frame), target)
    jac = m.jacobian_expr(frame)
    jw = ca.mtimes(so3_left_jacobian_inverse(e[3:]), jac[3:, :])
    return e, ca.vertcat(jac[:3, :], jw)


class Task(ABC):
    """A task: an error ``e(q)`` to drive to zero, its Jacobian, a cost per row and a gain.

    Args:
        cost: weight of each error row (scalar or one per row), ``>= 0``.
        gain: fraction ``alpha`` of the error removed per step, in ``(0, 1]``.
        lm_damping: Levenberg-Marquardt damping ``lambda``: adds ``lambda ||W alpha e||^2 I`` to
            the QP Hessian (large steps far from the target are damped).
        priority: level in a strict hierarchy (0 highest); used by ``method="priority"`` (every
            level) and ``"dls"``/``"pinv"`` (level 0 primary, higher levels projected into its
            null space); ``method="qp"`` weighs all tasks by their costs.
    """

    dim: int
    """Number of error rows."""

    def __init__(self, cost: Any, gain: float = 1.0, lm_damping: float = 0.0, priority: int = 0) -> None:
        self.cost = cost_vector(cost, "cost", self.dim)
        g = positive(gain, "gain")
        if not 0 < g <= 1:
            raise InvalidArgumentError("gain", f"must be in (0, 1], got {g}")
        self.gain = g
        self.lm_damping = positive(lm_damping, "lm_damping")
        self.priority = as_int(priority, "priority", 0)

    def _check_coordinates(self, m: Mechanism) -> None:
        """Raise unless the task (one row per coordinate, built for ``n_q``) fits ``m``."""
        if self.dim != m.n_q:
            raise InvalidArgumentError("n_q", f"task built for {self.dim} coordinates, mechanism has {m.n_q}")

    @abstractmethod
    def key(self) -> tuple:
        """Structure of the task (class, frame, rows...): tasks with equal keys share compiled code."""

    @abstractmethod
    def parameters(self, m: Mechanism) -> np.ndarray:
        """Numeric values of the task's parameter vector ``p`` (targets), validated against ``m``."""

    @abstractmethod
    def expressions(self, m: Mechanism, q: ca.SX, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        """Symbolic error ``e`` (``dim``) and Jacobian ``de/dq`` (``dim x n_q``)."""

    def n_parameters(self, m: Mechanism) -> int:
        """Length of `parameters`."""
        return int(self.parameters(m).shape[0])

    def compute(self, m: Mechanism, q: Any) -> tuple[np.ndarray, np.ndarray]:
        """Numeric ``(e, J)`` at ``q`` (builds the CasADi function; for inspection and tests)."""
        qq = m.check_q(q)
        p = self.parameters(m)
        ps = ca.SX.sym("p", p.shape[0])
        e, jac = self.expressions(m, m.q_sym, ps)
        f = ca.Function("task", [m.q_sym, ps], [e, jac])
        ev, jv = f(qq, p)
        return np.asarray(ev, dtype=float).reshape(-1), np.asarray(jv, dtype=float).reshape(self.dim, m.n_q)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(key={self.key()}, cost={self.cost.tolist()}, gain={self.gain})"


class Limit(ABC):
    """A bound on the joint step ``dq = v dt``: ``lb(q) <= dq <= ub(q)``.

    Limits are intersected in the order of `rank` (velocity 0, configuration 1,
    acceleration 2). When a new limit's interval misses the one built so far, the point of the
    earlier interval nearest to it is kept: physical speed wins over returning into the position
    limits at once, and the position limits win over acceleration limits, so the step is always
    feasible for the bounds alone.
    """

    rank: int = 1

    @abstractmethod
    def key(self) -> tuple:
        """Structure of the limit (class and sizes)."""

    @abstractmethod
    def parameters(self, m: Mechanism) -> np.ndarray:
        """Numeric parameter vector (limit values), validated against ``m``."""

    @abstractmethod
    def bounds(self, m: Mechanism, q: ca.SX, p: ca.SX, dt: ca.SX, v_prev: ca.SX) -> tuple[ca.SX, ca.SX]:
        """Symbolic bounds ``(lb, ub)`` on ``dq`` (each ``n_q``)."""

    _cached: tuple[Mechanism, np.ndarray] | None = None

    def _parameters_of(self, m: Mechanism, build: Callable[[], np.ndarray]) -> np.ndarray:
        """``build()``, computed once per mechanism (`parameters` runs at every step)."""
        if self._cached is None or self._cached[0] is not m:
            self._cached = (m, build())
        return self._cached[1]


def rate_limits(value: Any, name: str, what: str) -> np.ndarray:
    """Per-coordinate maxima (scalar or one per coordinate), each ``> 0`` (``inf`` allowed)."""
    v = real_array(value, name).reshape(-1)
    if v.size == 0 or np.any(np.isnan(v)) or np.any(v <= 0):
        raise InvalidArgumentError(name, f"{what} must be > 0, got {v}")
    return v


def per_coordinate(values: np.ndarray, name: str, m: Mechanism) -> np.ndarray:
    """``values`` (from [`rate_limits`][optik.diffik.base.rate_limits]) broadcast to ``m.n_q`` and capped at
    [`BIG`][optik.diffik.base.BIG]."""
    v = np.broadcast_to(values, (m.n_q,)) if values.size == 1 else values
    if v.shape[0] != m.n_q:
        raise InvalidArgumentError(name, f"expected {m.n_q} values, got {v.shape[0]}")
    return as_vector(np.minimum(v, BIG), name, m.n_q)


def intersect(lb0: Any, ub0: Any, lb1: Any, ub1: Any) -> tuple[Any, Any]:
    """Intersection of ``[lb0, ub0]`` with ``[lb1, ub1]``, or the nearest point of the first
    interval when they are disjoint (elementwise, CasADi)."""
    lo = ca.fmax(lb0, lb1)
    hi = ca.fmin(ub0, ub1)
    return ca.fmin(lo, ub0), ca.fmax(hi, lb0)
