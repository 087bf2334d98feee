"""``step``: one differential-IK step by QP, damped least squares, pseudo-inverse or a strict
priority hierarchy, with a result that says what happened."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optik.checks import as_name
from optik.diffik.base import Limit, Task, positive
from optik.diffik.linalg import solve_pseudo_inverse
from optik.diffik.problem import DiffIKProblem, build_qp
from optik.diffik.qp import default_solver, solve_qp
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism

METHODS = ("qp", "dls", "pinv", "priority")
"""Methods of [`step`][optik.diffik.step.step]."""

DLS_DAMPING = 0.05
"""Default ``lambda_max`` of ``method="dls"``."""
DLS_THRESHOLD = 0.05
"""Default singular-value threshold of the adaptive damping of ``method="dls"``."""
PRIORITY_DAMPING = 0.01
"""Default ``lambda_max`` (adaptive, threshold equal) of ``method="priority"``."""


@dataclass
class StepResult:
    """Outcome of one step.

    Attributes:
        v: joint velocity ``dq / dt``.
        q: next configuration ``q + v dt``, within the limits (or, starting outside, no farther
            out than before); closed chains are projected back onto their closures (see
            [`integrate`][optik.diffik.step.integrate]).
        status: ``"ok"``; ``"saturated"`` (pseudo-inverse methods that held coordinates at
            their bounds or scaled the task velocity down to fit them);
            ``"qp_infeasible_fallback"`` / ``"qp_failed_fallback"`` (the QP had no solution and
            the DLS answer within the bounds was used).
        method: the method used; solver: the QP backend (None for the others).
        task_errors: norm of each task's error at the current ``q``, in task order.
        closure_error: max-norm of the loop-closure residual at the current ``q``.
        solve_time: wall time of the step (s).
        message: what went wrong, if anything.
        problem: the [`DiffIKProblem`][optik.diffik.DiffIKProblem] that was solved.
    """

    v: np.ndarray
    q: np.ndarray
    status: str
    method: str
    solver: str | None
    task_errors: list[float]
    closure_error: float
    solve_time: float
    message: str = ""
    problem: DiffIKProblem | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        """True unless the QP failed and a fallback was used."""
        return not self.status.startswith("qp_")


CLOSURE_TOL = 1e-12
"""Closure residual (max-norm) to which [`integrate`][optik.diffik.step.integrate] projects closed chains."""


def integrate(m: Mechanism, q: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
    """``q + v dt`` clipped to ``[min(lower, q), max(upper, q)]``: rounding and solver tolerance
    never take a coordinate out of its limits, nor farther out when it started outside.

    For closed chains the step keeps ``J_c dq = -c`` only to first order; the new configuration is
    projected back onto ``c(q) = 0`` by up to 3 Gauss-Newton corrections
    ``q <- q - J_c^+ c(q)`` (minimum norm, second order in the step), each clipped the same way.
    """
    lo, hi = np.minimum(m.lower, q), np.maximum(m.upper, q)
    q_next = np.clip(q + v * dt, lo, hi)
    if m.is_closed:
        f = m.closure_function
        for _ in range(3):
            c, jc = f(q_next)
            c = np.asarray(c, dtype=float).reshape(-1)
            if np.max(np.abs(c)) <= CLOSURE_TOL:
                break
            q_next = np.clip(q_next - np.linalg.pinv(np.asarray(jc, dtype=float)) @ c, lo, hi)
    return q_next


def _dls(problem: DiffIKProblem, method: str, options: dict[str, Any]) -> tuple[np.ndarray, int, float]:
    if method == "pinv":
        kw = {"damping": 0.0, "threshold": 0.0, "hierarchy": "projection"}
    elif method == "priority":
        kw = {"damping": PRIORITY_DAMPING, "threshold": PRIORITY_DAMPING, "hierarchy": "strict"}
    else:
        kw = {"damping": DLS_DAMPING, "threshold": DLS_THRESHOLD, "hierarchy": "projection"}
    unknown = set(options) - {"damping", "threshold", "joint_weights", "adaptive"}
    if unknown:
        raise InvalidArgumentError("options", f"unknown options for method {method!r}: {sorted(unknown)}")
    kw.update({k: v for k, v in options.items() if k != "adaptive"})
    kw["damping"] = positive(kw["damping"], "damping")
    kw["threshold"] = positive(kw["threshold"], "threshold")
    if options.get("adaptive") is False:
        kw["threshold"] = 0.0
    return solve_pseudo_inverse(problem, **kw)


def step(
    m: Mechanism,
    q: Any,
    tasks: Sequence[Task] | Task,
    dt: float,
    method: str = "qp",
    solver: str | None = None,
    limits: Sequence[Limit] | None = None,
    *,
    v_prev: Any = None,
    damping: float | None = None,
    closure_gain: float = 1.0,
    **options: Any,
) -> StepResult:
    """One differential-IK step: the joint velocity that best achieves the tasks within the limits.

    Methods (formulas in ``docs/solvers/diffik.md``):

    * ``"qp"``: the QP of [`build_qp`][optik.diffik.step.build_qp] (tasks weighted by cost; limits and
      closures exact) by ``solver`` (None: [`default_solver`][optik.diffik.qp.default_solver]; ``"osqp"``,
      ``"daqp"``, ``"cvxpy"`` or any qpsolvers backend). An infeasible or failed QP falls back to the DLS
      answer within the bounds, with status ``"qp_infeasible_fallback"``/``"qp_failed_fallback"``.
    * ``"dls"``: damped least squares ``J^T (J J^T + lambda^2 I)^-1`` with adaptive damping
      (options ``damping`` = ``lambda_max``, ``threshold``; ``adaptive=False`` for fixed
      ``lambda = damping``; ``joint_weights`` for a weighted inverse). Tasks of priority > 0 are
      projected into the null space of the priority-0 tasks.
    * ``"pinv"``: the Moore-Penrose pseudo-inverse (no damping), same projection.
    * ``"priority"``: strict recursive hierarchy over all priority values, the top level exact
      unless singular (adaptive damping ``0.01``).

    The pseudo-inverse methods keep the bounds by saturation in the null space. Loop closures of
    closed chains are always kept (top level / equality constraint).

    Args:
        m: the mechanism.
        q: current coordinates.
        tasks: the tasks.
        dt: time step (s).
        method: ``"qp"``, ``"dls"``, ``"pinv"`` or ``"priority"``.
        solver: QP backend (``method="qp"`` only).
        limits: see [`build_qp`][optik.diffik.step.build_qp].
        v_prev: previous velocity (acceleration limits).
        damping: QP Tikhonov weight (default 1e-12) or DLS ``lambda`` (see above).
        closure_gain: gain of the loop-closure constraint.
        **options: method options (``threshold``, ``adaptive``, ``joint_weights`` for the
            pseudo-inverse methods; backend settings for ``"qp"``).

    Returns:
        A [`StepResult`][optik.diffik.step.StepResult].

    Raises:
        OptikError: a subclass naming the argument, for malformed input or an unknown method.
    """
    start = time.perf_counter()
    as_name(method, "method", METHODS)
    if solver is not None:
        as_name(solver, "solver")
    qp_damping = 1e-12 if damping is None or method != "qp" else damping
    problem = build_qp(m, q, tasks, dt, limits, v_prev=v_prev, damping=qp_damping, closure_gain=closure_gain)
    status, message, used = "ok", "", None
    if method == "qp":
        used = default_solver() if solver is None else solver
        out = solve_qp(problem, used, **options)
        if out.dq is not None:
            dq = np.clip(out.dq, problem.lb, problem.ub)
        else:
            dq, _, _ = _dls(problem, "dls", {})
            status = f"qp_{out.status}_fallback"
            message = f"QP {out.status} ({out.detail}); used the DLS step within the bounds"
    else:
        if damping is not None:
            options = {**options, "damping": damping}
        dq, n_sat, scale = _dls(problem, method, options)
        if n_sat or scale < 1.0:
            status = "saturated"
            message = f"{n_sat} coordinate(s) held at a bound, task velocity scaled by {scale:.3g}"
    v = dq / problem.dt
    errors = np.sqrt(np.add.reduceat(problem.errors**2, problem.cache.starts)).tolist()
    closure = float(np.max(np.abs(problem.closure))) if problem.closure.size else 0.0
    return StepResult(
        v=v,
        q=integrate(m, problem.q, v, problem.dt),
        status=status,
        method=method,
        solver=used,
        task_errors=errors,
        closure_error=closure,
        solve_time=time.perf_counter() - start,
        message=message,
        problem=problem,
    )
