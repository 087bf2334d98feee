"""``step``: one differential-IK step by QP, damped least squares, pseudo-inverse or a strict
priority hierarchy, with a result that says what happened."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optik.checks import as_name
from optik.diffik.base import Limit, Task, positive
from optik.diffik.collision import DAMPER_GAIN, INFLUENCE
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
            the DLS answer within the bounds was used); ``"overflow"`` (task errors so large,
            e.g. a target 1e300 away, that the step's equations overflow: the step is the point
            of the bounds nearest 0); ``"shortened"`` (``dls``: the
            task-space part of the step was scaled down or dropped by `shorten`, beyond a fold
            of the workspace).
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


SHORTEN_HALVINGS = 12
"""Halvings of the range-space part of a ``dls`` step before it is dropped (see `shorten`)."""


def shorten(
    m: Mechanism, problem: DiffIKProblem, dq: np.ndarray, tasks: Sequence[Task], rebuild: Any
) -> tuple[np.ndarray, int]:
    """Shorten a step that leaves the region where the task's linear model holds.

    ``dq`` is split into its part ``dq_r = P dq`` in the row space of the priority-0 task rows
    ``A = W J`` (``P = A^+ A``) and the null-space rest. The linear model predicts that ``dq_r``
    reduces the weighted primary error ``E = ||W e||^2`` by ``pred = E - ||W e + A dq_r||^2``;
    the step ``s dq_r + dq_n`` is kept for the largest ``s = 2^-k`` whose actual reduction
    (evaluated at ``q + s dq_r``) is at least ``pred(s) / 2``, else ``s = 0``. This is the
    acceptance test of a trust region, applied per step: beyond a fold of the workspace (a
    stretched arm and a target out of reach) the damped step overshoots through the
    singularity, the actual reduction is negative, and the step shrinks instead of flipping the
    elbow at hundreds of rad/s; at a stretched arm the range step is 0 and the arm stays put.
    The null-space part (secondary tasks) is not scaled: its effect on the primary error is of
    second order and corrected by the next step.

    Args:
        m: the mechanism.
        problem: the step's problem at ``q``.
        dq: the step (within ``[lb, ub]``).
        tasks: the tasks, in the problem's order.
        rebuild: ``q -> DiffIKProblem`` at another configuration (same tasks, targets, limits).

    Returns:
        The (possibly shortened) step, clipped into ``[lb, ub]``, and the halvings made
        (``SHORTEN_HALVINGS + 1`` when the range part was dropped).
    """
    rows = problem.levels()[0]
    gains = [np.full(s.stop - s.start, t.gain) for s, t in zip(problem.slices, tasks, strict=True)]
    alpha = np.concatenate(gains)[rows]
    we = -problem.target[rows] / alpha
    a = problem.jacobian[rows]
    dq_r = np.linalg.pinv(a, rcond=1e-10) @ (a @ dq)
    dq_n = dq - dq_r
    e0 = float(we @ we)
    if not math.isfinite(e0):  # errors so large that their square overflows: no model to test
        return dq, 0
    lo, hi = np.minimum(m.lower, problem.q), np.maximum(m.upper, problem.q)
    for k in range(SHORTEN_HALVINGS + 1):
        s = 0.5**k
        step_r = s * dq_r
        predicted = we + a @ step_r
        pred = e0 - float(predicted @ predicted)
        if pred <= 1e-14 * e0 or pred <= 1e-30:  # nothing to gain along the range space
            return np.clip(step_r + dq_n, problem.lb, problem.ub), k
        new = rebuild(np.clip(problem.q + step_r, lo, hi))
        we_new = -new.target[rows] / alpha
        if e0 - float(we_new @ we_new) >= 0.5 * pred:
            return np.clip(step_r + dq_n, problem.lb, problem.ub), k
    return np.clip(dq_n, problem.lb, problem.ub), SHORTEN_HALVINGS + 1


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
    support: Any = None,
    com_margin: float = 0.0,
    world: Any = None,
    self_collision: bool | None = None,
    margin: float = 0.0,
    influence: float = INFLUENCE,
    collision_gain: float = DAMPER_GAIN,
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
        support: the world x-y support polygon, counter-clockwise ``(k, 2)`` (``method="qp"``
            only): static balance as the QP's inequality rows, the linearized ground projection of
            the centre of mass inside every edge by ``com_margin`` after the step
            ([`build_qp`][optik.diffik.build_qp]); feet held in place are frame tasks (or
            `optik.solve_ik`'s ``contacts``).
        com_margin: the balance margin (m, ``>= 0``; only with ``support``).
        world: obstacles ([`optik.World`][optik.World], ``method="qp"`` only): velocity dampers
            (`optik.diffik.collision`) as inequality rows for every pair closer than
            ``influence``, each losing at most ``collision_gain`` of its distance above
            ``margin`` per step.
        self_collision: dampers for the robot's own pairs too (None: True when ``world`` is given).
        margin: the clearance (m) the dampers keep.
        influence: the distance (m) below which a pair gets a damper.
        collision_gain: ``gamma`` in ``(0, 1]``.
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
    if support is not None and method != "qp":
        raise InvalidArgumentError(
            "support", f"balance rows are QP inequalities: method 'qp' takes support=, not {method!r}"
        )
    if (world is not None or self_collision) and method != "qp":
        raise InvalidArgumentError(
            "world", f"collision dampers are QP inequalities: method 'qp' takes world=, not {method!r}"
        )
    problem = build_qp(
        m,
        q,
        tasks,
        dt,
        limits,
        v_prev=v_prev,
        damping=qp_damping,
        closure_gain=closure_gain,
        support=support,
        com_margin=com_margin,
        world=world,
        self_collision=self_collision,
        margin=margin,
        influence=influence,
        collision_gain=collision_gain,
    )
    status, message, used = "ok", "", None
    if not all(np.isfinite(a).all() for a in (problem.H, problem.c, problem.jacobian, problem.target)):
        # finite task errors whose products overflow (a target 1e300 away): no step to take
        dq = np.clip(np.zeros(problem.n), problem.lb, problem.ub)
        status, message = "overflow", "the task errors overflow the step's equations; no step taken"
    elif method == "qp":
        used = default_solver() if solver is None else solver
        out = solve_qp(problem, used, **options)
        if out.dq is not None:
            dq = np.clip(out.dq, problem.lb, problem.ub)
        else:
            dq, _, _ = _dls(problem, "dls", {})
            status = f"qp_{out.status}_fallback"
            message = f"QP {out.status} ({out.detail}); used the DLS step within the bounds"
            if problem.G.shape[0]:
                message += " (which does not hold the inequality rows: balance, collision dampers)"
    else:
        if damping is not None:
            options = {**options, "damping": damping}
        dq, n_sat, scale = _dls(problem, method, options)
        if n_sat or scale < 1.0:
            status = "saturated"
            message = f"{n_sat} coordinate(s) held at a bound, task velocity scaled by {scale:.3g}"
        if method == "dls" and not m.is_closed:
            task_list = [tasks] if isinstance(tasks, Task) else list(tasks)

            def rebuild(q_trial: np.ndarray) -> DiffIKProblem:
                return build_qp(
                    m,
                    q_trial,
                    task_list,
                    dt,
                    limits,
                    v_prev=v_prev,
                    damping=qp_damping,
                    closure_gain=closure_gain,
                )

            dq, halvings = shorten(m, problem, dq, task_list, rebuild)
            if halvings:
                status = "shortened"
                kept = "dropped" if halvings > SHORTEN_HALVINGS else f"scaled by 2^-{halvings}"
                message = (
                    f"the task-space part of the step was {kept}: the full step would not reduce the task "
                    "error as its linear model predicts (beyond a fold of the workspace, e.g. an "
                    "unreachable target)" + (f"; {message}" if message else "")
                )
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
