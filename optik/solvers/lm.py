"""Method ``"lm"``: bounded Levenberg-Marquardt with random restarts, compiled to C.

The residual is ``e(q) = [w_p r_p; w_o r_o; w_c c(q)]``: the task residual of
[`optik.problem`][optik.problem] with the loop closures of a closed chain appended as heavily weighted rows.
One iteration at ``q`` with gradient ``g = J^T e`` and Gauss-Newton matrix ``A = J^T J``:

1. *Active set*: coordinate ``i`` is frozen when it sits on a bound and the descent direction
   ``-g_i`` points outside (``q_i = lo_i, g_i > 0`` or ``q_i = hi_i, g_i < 0``); ``D`` is the
   diagonal 0/1 matrix of the free coordinates.
2. *Step*: ``(D A D + mu I + (I - D)) dq = -D g + k mu D (q_ref - q)``. The last term is a
   null-space posture pull: for ``mu -> 0`` it vanishes in the range of ``J^T`` and keeps moving
   along the null space of ``J`` toward ``q_ref`` (gain ``k = posture_gain``, 0 by default).
3. *Projection and acceptance*: ``q+ = clip(q + dq, lo, hi)``; accepted when
   ``|e(q+)|^2 < |e(q)|^2``, then ``mu <- max(mu / 3, 1e-12)``, else ``mu <- min(4 mu, 1e8)``.

Iterations are grouped into blocks of ``block`` iterations, one CasADi function generated as C,
compiled with gcc and called through ``ctypes`` ([`optik.solvers.native`][optik.solvers.native]), so Python
runs once per block. Between blocks the driver checks the tolerances and the time limit; a start is abandoned
when a block reduces the cost by less than the factor ``stall`` or after ``max_iter`` iterations, and the next
start is drawn uniformly within the limits from the request's generator. The answer is the first start that
meets the tolerances, or the lowest cost configuration seen when the time limit ends the search.

Options (``solve_ik(..., method="lm", **options)``):

* ``block`` (5): iterations per compiled call.
* ``max_iter`` (100): iterations per start before restarting.
* ``mu0`` (1e-2): initial damping.
* ``stall`` (0.7): restart when a block's cost exceeds ``stall`` times the previous block's.
* ``posture_gain`` (0.0): gain ``k`` of the null-space pull toward ``q_ref``.
* ``q_ref`` (mid-limit): reference posture for that pull.
* ``weights`` ((1, 1)): task weights ``(w_p, w_o)``.
* ``closure_weight`` (100.0): weight ``w_c`` of the loop-closure rows.
* ``max_restarts`` (None): cap on restarts (None: until success or the time limit).
* ``compile`` ("auto"): compile to C when a compiler exists (see
  [`NativeFunction`][optik.solvers.lm.NativeFunction]).
"""

from __future__ import annotations

import time
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_vector
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.problem import IKProblem, build_ik_problem, target_parameters
from optik.results import IKResult
from optik.solvers.base import (
    IKRequest,
    make_result,
    method_options,
    positive_int,
    register_method,
    restart_stop,
    start_points,
)
from optik.solvers.evaluation import error_function, errors_against
from optik.solvers.native import NativeFunction, native_functions
from optik.solvers.options import check_floats, check_max_restarts

DEFAULTS: dict[str, Any] = {
    "block": 5,
    "max_iter": 100,
    "mu0": 1e-2,
    "stall": 0.7,
    "posture_gain": 0.0,
    "q_ref": None,
    "weights": (1.0, 1.0),
    "closure_weight": 100.0,
    "max_restarts": None,
    "compile": "auto",
}
"""Default options of ``"lm"``."""

_MU_MIN, _MU_MAX = 1e-12, 1e8
_STOP_MARGIN = 0.5
"""A start stops once its errors are below this fraction of the tolerances (so that the final
check, done on the wrapped and clipped answer, passes with room)."""


def lm_step_function(problem: IKProblem, closure_weight: float) -> ca.Function:
    """One bounded LM iteration ``(q, mu, target, weights, q_ref, gain) -> (q+, mu+, cost+)``
    (see the module docstring), as an ``SX`` function."""
    m = problem.mechanism
    q = problem.q
    lo, hi = problem.lower, problem.upper
    closure = closure_weight if m.is_closed else None
    e = problem.weighted_residual(closure)
    residual = ca.Function("e", [q, problem.target, problem.weights], [e])
    mu, gain = ca.SX.sym("mu"), ca.SX.sym("gain")
    jac = ca.jacobian(e, q)
    g = ca.mtimes(jac.T, e)
    free = 1 - ca.logic_or(ca.logic_and(q <= lo, g > 0), ca.logic_and(q >= hi, g < 0))
    d = ca.diag(free)
    lhs = ca.mtimes([d, ca.mtimes(jac.T, jac), d]) + mu * ca.SX.eye(m.n_q) + ca.diag(1 - free)
    rhs = free * (-g + gain * mu * (problem.q_ref - q))
    q_new = ca.fmin(ca.fmax(q + ca.solve(lhs, rhs), lo), hi)
    cost = 0.5 * ca.sumsqr(e)
    cost_new = 0.5 * ca.sumsqr(residual(q_new, problem.target, problem.weights))
    accept = cost_new < cost
    return ca.Function(
        "lm_step",
        [q, mu, problem.target, problem.weights, problem.q_ref, gain],
        [
            ca.if_else(accept, q_new, q),
            ca.if_else(accept, ca.fmax(mu / 3, _MU_MIN), ca.fmin(mu * 4, _MU_MAX)),
            ca.if_else(accept, cost_new, cost),
        ],
    )


def lm_block_function(problem: IKProblem, closure_weight: float, block: int) -> ca.Function:
    """``block`` LM iterations in one function, followed by the errors of the final ``q``.

    Inputs ``(q, mu, target, weights, q_ref, gain)``; outputs ``(q, mu, cost, position error,
    orientation error, closure error)``, the errors of the final ``q`` as
    [`error_function`][optik.solvers.lm.error_function] defines them.
    """
    m = problem.mechanism
    step = lm_step_function(problem, closure_weight)
    errors = error_function(problem)
    q = ca.MX.sym("q", m.n_q)
    mu = ca.MX.sym("mu")
    target = ca.MX.sym("target", 12)
    weights = ca.MX.sym("weights", 2)
    q_ref = ca.MX.sym("q_ref", m.n_q)
    gain = ca.MX.sym("gain")
    qk, muk, cost = q, mu, ca.MX(0)
    for _ in range(block):
        qk, muk, cost = step(qk, muk, target, weights, q_ref, gain)
    pos, ori, clo = errors(qk, target)
    outs = [ca.densify(v) for v in (qk, muk, cost, pos, ori, clo)]
    return ca.Function("optik_lm_block", [q, mu, target, weights, q_ref, gain], outs)


@lru_cache(maxsize=64)
def _native_block(
    m: Mechanism, task: str, frame: str | None, closure_weight: float, block: int, compile: bool | str
) -> NativeFunction:
    problem = build_ik_problem(m, task, frame)
    return native_functions([lm_block_function(problem, closure_weight, block)], compile)[0]


def solve_lm(request: IKRequest) -> IKResult:
    """Solve an IK request by bounded LM with random restarts (see the module docstring)."""
    opts = method_options(request, DEFAULTS)
    check_floats(opts, "stall", "posture_gain", "closure_weight", strict=("mu0",))
    opts["max_restarts"] = check_max_restarts(opts["max_restarts"])
    m, tol = request.mechanism, request.tol
    block = positive_int(opts["block"], "block")
    max_blocks = max(1, positive_int(opts["max_iter"], "max_iter") // block)
    weights = as_vector(opts["weights"], "weights", 2)
    if np.any(weights < 0):
        raise InvalidArgumentError("weights", f"must be >= 0, got {weights}")
    setup = time.perf_counter()
    fn = _native_block(m, request.task, request.frame, float(opts["closure_weight"]), block, opts["compile"])
    errors = errors_against(m, request.task, request.frame, request.target, opts["compile"])
    request.exclude_setup(setup)
    ins = fn.inputs
    ins[2][:] = target_parameters(request.target)
    ins[3][:] = weights
    ins[4][:] = m.mid_q() if opts["q_ref"] is None else m.check_q(opts["q_ref"], "q_ref")
    ins[5][0] = float(opts["posture_gain"])
    deadline = request.start + request.time_limit
    max_restarts = opts["max_restarts"]
    best_q, best_cost = request.q0.copy(), np.inf
    iterations, restarts = 0, -1
    starts = start_points(request)
    while True:
        restarts += 1
        ins[0][:] = next(starts)
        ins[1][0] = float(opts["mu0"])
        previous = np.inf
        for _ in range(max_blocks):
            q, mu, cost, pos, ori, clo = fn()
            iterations += block
            c = float(cost[0])
            if c < best_cost:
                best_q, best_cost = q.copy(), c
            if (
                pos[0] <= _STOP_MARGIN * tol.position
                and ori[0] <= _STOP_MARGIN * tol.orientation
                and clo[0] <= _STOP_MARGIN * tol.closure
            ):
                return make_result(request, q, "lm", iterations, restarts, errors=errors)
            if time.perf_counter() >= deadline or c > float(opts["stall"]) * previous:
                break
            previous = c
            ins[0][:] = q
            ins[1][0] = mu[0]
        stop = restart_stop(deadline, restarts, max_restarts)
        if stop is not None:
            return make_result(request, best_q, "lm", iterations, restarts, stop, errors=errors)


register_method(
    "lm",
    solve_lm,
    description="bounded Levenberg-Marquardt compiled to C, random restarts until the time limit",
)
