"""Iterated differential IK as position IK: the ``"dls"`` and ``"qp"`` methods of
[`optik.solve_ik`][optik.solve_ik].

From ``q0``, repeat ``q <- q + dq`` with the step of [`optik.diffik.step`][optik.diffik.step] at ``dt = 1``
and gain 1 (a Gauss-Newton step on the task error; with adaptive damping the DLS step is the exact Newton step
away from singularities, so convergence is quadratic near a regular solution), inside the joint limits
([`ConfigurationLimit`][optik.diffik.ik.ConfigurationLimit]) and, for closed chains, with the loop closures as
the top level / equality constraint. The error is checked before each step; after ``stall_iterations`` steps
without a 1 % improvement, or ``max_iterations`` steps from one start, the method restarts from a random
configuration within the limits (``request.rng``). It returns within the request's time limit (plus one step)
with the best configuration found; compiling the task function on the first request of a mechanism and task
space (cached afterwards) does not count against the limit. Several frame targets (a ``{frame: target}`` dict)
are one frame task each, stacked with equal weight in the same step; the error checked is the largest over
the frames.

Options (``solve_ik(..., method="dls", max_iterations=..., ...)``): ``max_iterations`` (per
start, default 100), ``stall_iterations`` (default 10), ``damping`` and ``threshold`` (DLS: the step
uses the damping ``min(damping, ||e||)``, Levenberg-Marquardt damping proportional to the error, so
that there is none at the solution and convergence stays quadratic at a solution close to a
singularity, where the adaptive damping alone converged linearly: 14 iterations instead of failing
within 1 s on a seed 6R target with ``s5 = 0.03``) or
``solver`` (QP backend) and ``lm_damping`` (QP, default [`LM_DAMPING`][optik.diffik.ik.LM_DAMPING]: the QP
Hessian gets ``lm_damping ||e||^2 I``, which shortens the Gauss-Newton steps far from the target and vanishes
at it; 40/40 Panda targets within 50 ms instead of 35/40 without). ``solve_ik(..., support=polygon,
com_margin=..., method="qp")`` passes ``support`` and ``com_margin`` here (`optik.solvers.balance`): each
step's QP then has the balance rows of [`build_qp`][optik.diffik.build_qp], and an iterate counts as solved
only with its centre of mass inside by the margin.
"""

from __future__ import annotations

import time

import numpy as np

from optik.diffik.base import positive
from optik.diffik.limits import ConfigurationLimit
from optik.diffik.problem import normalize_limits, stack_function
from optik.diffik.step import DLS_DAMPING, step
from optik.diffik.track import tracking_task
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.results import IKResult
from optik.solvers.balance import BALANCE_TOL
from optik.solvers.base import IKRequest, make_result, positive_int, register_method

_OPTIONS = {
    "dls": {"max_iterations", "stall_iterations", "damping", "threshold"},
    "qp": {"max_iterations", "stall_iterations", "solver", "lm_damping", "support", "com_margin"},
}
"""Options each method reads; any other option is an error (never silently ignored)."""

LM_DAMPING = 0.1
"""Default Levenberg-Marquardt damping of the task in ``method="qp"`` (large steps far from the
target are damped, ``mu = lambda ||e||^2``; none at the solution)."""


def _int_option(options: dict, name: str, default: int) -> int:
    return positive_int(options.get(name, default), name)


def _errors_of(rows: tuple[int, ...], e: np.ndarray) -> tuple[float, float]:
    """Position and orientation error from the frame task's error rows (``e`` of the rows ``rows``
    of the 6-row pose error)."""
    pos = [i for i, r in enumerate(rows) if r < 3]
    ori = [i for i, r in enumerate(rows) if r >= 3]
    return float(np.linalg.norm(e[pos])) if pos else 0.0, float(np.linalg.norm(e[ori])) if ori else 0.0


def iterate(request: IKRequest, method: str) -> IKResult:
    """Iterated differential IK for one request (see the module docstring)."""
    m: Mechanism = request.mechanism
    opts = dict(request.options)
    unknown = set(opts) - _OPTIONS[method]
    if unknown:
        raise InvalidArgumentError("options", f"unknown options for method {method!r}: {sorted(unknown)}")
    max_iter = _int_option(opts, "max_iterations", 100)
    stall = _int_option(opts, "stall_iterations", 10)
    step_opts = {k: opts[k] for k in ("damping", "threshold", "support", "com_margin") if k in opts}
    solver = opts.get("solver")
    tasks = []
    for frame, space, target in request.frame_targets():  # one frame task per target
        task = tracking_task(m, space, frame)
        task.set_target(target)
        if method == "qp":
            task.lm_damping = positive(opts.get("lm_damping", LM_DAMPING), "lm_damping")
        tasks.append(task)
    limits = [ConfigurationLimit()]
    build_start = time.perf_counter()
    stack_function(m, tasks, normalize_limits(m, limits), 1.0)  # compiled once per structure
    request.exclude_setup(build_start)  # a first build does not count against the time limit
    tol = request.tol
    q = request.q0.copy()
    best_q, best_err = q.copy(), np.inf
    iterations = restarts = since_start = since_better = 0
    last_err = np.inf
    lam_max = positive(step_opts.get("damping", DLS_DAMPING), "damping")
    e_norm = np.inf
    while True:
        if method == "dls":  # damping lambda = min(lambda_max, |e|): none at the solution
            step_opts["damping"] = min(lam_max, e_norm)
        res = step(m, q, tasks, 1.0, "qp" if method == "qp" else "dls", solver, limits, **step_opts)
        e = res.problem.errors
        e_norm = float(np.linalg.norm(e))
        per_task = [_errors_of(t.rows, et) for t, et in zip(tasks, res.problem.task_errors(), strict=True)]
        pos, ori = max(p for p, _ in per_task), max(o for _, o in per_task)
        inside = bool(np.all(q >= m.lower) and np.all(q <= m.upper))
        if res.problem.h.size:  # balance rows: h = b - margin - N c_xy(q) >= 0 inside
            inside = inside and float(np.min(res.problem.h)) >= -BALANCE_TOL
        err = max(pos / tol.position, ori / tol.orientation, res.closure_error / tol.closure)
        if inside and err < best_err:
            best_q, best_err = q.copy(), err
        if inside and err <= 1.0:
            return make_result(request, q, method, iterations, restarts)
        if request.remaining() <= 0:
            return make_result(
                request, best_q, method, iterations, restarts, status="time_limit" if best_err > 1 else None
            )
        since_better = 0 if err < 0.99 * last_err else since_better + 1
        last_err = min(last_err, err)
        if since_better >= stall or since_start >= max_iter:
            q = m.random_q(seed=request.rng)
            restarts += 1
            since_start = since_better = 0
            last_err = np.inf
            continue
        q = res.q
        iterations += 1
        since_start += 1


def solve_dls(request: IKRequest) -> IKResult:
    """``method="dls"``: iterated damped least squares (adaptive damping)."""
    return iterate(request, "dls")


def solve_qp(request: IKRequest) -> IKResult:
    """``method="qp"``: iterated QP steps (default backend, see
    [`optik.diffik.default_solver`][optik.diffik.default_solver])."""
    return iterate(request, "qp")


def register() -> None:
    """Register ``"dls"`` and ``"qp"`` with
    [`optik.solvers.base.register_method`][optik.solvers.base.register_method]."""
    register_method(
        "dls",
        solve_dls,
        description="iterated differential IK, damped least squares with adaptive damping and restarts",
        multi_target=True,
    )
    register_method(
        "qp",
        solve_qp,
        description="iterated differential IK, one QP per step (joint limits as bounds) with restarts",
        multi_target=True,
    )
