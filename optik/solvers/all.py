"""``solve_ik_all``: every distinct IK solution, by a closed form or by numerical multi-start.

* **Closed form** (``method="closed_form"``, or ``method=None`` when the mechanism has one for
  its own task: a catalog closed form or one derived from the model's structure, see
  ``optik.closed_form.derived``): every branch is computed, each passing the FK check (a
  branch that fails it is polished, then dropped if it still fails, and counted). A closed form is
  complete, so it answers alone: no numerical search follows.
* **Numerical** (``method="lm"``, ``"nlp"``, ... or ``method=None`` without a closed form): the
  method runs from ``q0`` and then from points drawn uniformly within the limits, one start per
  call. Every successful answer is polished to full precision on the exact residual
  (``optik.solvers.polish.polish``) and kept when it is not the same solution as one already
  found, the distance being tied to the polished accuracy
  (``optik.solvers.polish.same_point_tol``). The search stops after ``patience`` consecutive
  starts without a new solution, after ``max_solutions`` (redundant arms have infinitely many) or
  at the time limit.

The method asked for is the method used: ``method="lm"`` never returns closed-form answers.
Solutions outside the joint limits are never returned; the returned
``optik.results.IKSolutions`` lists them in ``outside_limits`` and says how many in its
``message``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from optik.closed_form import registry
from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.results import IKResult, IKSolutions
from optik.solvers.api import pick_method, solve_ik
from optik.solvers.base import (
    IKRequest,
    joint_distance,
    make_request,
    make_result,
    positive_int,
)
from optik.solvers.closed import closed_form_applies
from optik.solvers.polish import polish, same_point_tol

NUMERIC_ORDER = ("lm", "nlp")
"""Numerical methods ``solve_ik_all`` may use, in order of preference."""
RESTARTING = ("lm", "nlp")
"""Methods with restarts inside a call; ``solve_ik_all`` sets their ``max_restarts`` to 0."""


def solve_ik_all(
    m: Mechanism,
    target: Any,
    q0: Any = None,
    method: str | None = None,
    *,
    task: str | None = None,
    frame: str | None = None,
    time_limit: float | None = 1.0,
    tol: Any = None,
    seed: int | np.random.Generator | None = None,
    patience: int = 50,
    max_solutions: int = 64,
    closed_form: bool = True,
    **options: Any,
) -> IKSolutions:
    """Every distinct IK solution within the joint limits.

    Args:
        m: the mechanism.
        target: 4x4 transform, [`Pose2D`][optik.Pose2D] or [`Position`][optik.Position].
        q0: first start of the numerical search (default mid-limit); results are sorted by their
            distance to it.
        method: ``"closed_form"`` (all analytic branches only), a numerical method for the
            multi-start (``"lm"``, ``"nlp"``, ...), or None: the closed form when the mechanism
            has one for the task, else ``"lm"`` where it applies, else ``"nlp"``.
        task: task space (default from the target and the mechanism).
        frame: task frame (default: the end effector).
        time_limit: wall-time budget of the whole search (s).
        tol: success tolerances.
        seed: seed or Generator of the starts.
        patience: stop after this many consecutive starts without a new solution.
        max_solutions: stop after this many solutions.
        closed_form: with ``method=None``, False skips the closed form (numerical search only).
        **options: options of the numerical method (the closed form takes none).

    Returns:
        An ``optik.results.IKSolutions`` (a list of successful results, one per solution,
        nearest ``q0`` first; empty when none was found, e.g. an unreachable target), with the
        solutions left out for the joint limits in ``outside_limits``.

    Raises:
        OptikError: malformed input (named argument), unknown or inapplicable method, an option
            the method does not know.
    """
    request = make_request(m, target, q0, task, frame, time_limit, tol, seed, options)
    patience = positive_int(patience, "patience")
    max_solutions = positive_int(max_solutions, "max_solutions")
    applies = closed_form_applies(m, request.task) and frame in (None, m.ee)
    if method == "closed_form":
        if not applies:
            raise SolverUnavailableError(
                f"method 'closed_form' does not apply to {m.name!r} with task {request.task!r}"
                + ("" if frame in (None, m.ee) else f" and frame {frame!r}")
            )
        found = _closed_form_all(request)
    elif method is None and closed_form and applies:
        found = _closed_form_all(request)
    else:
        name = method or pick_method(m, request.task, NUMERIC_ORDER)
        found = _numeric_all(request, name, patience, max_solutions)
    found.sort(key=lambda r: joint_distance(m, r.q, request.q0))
    return found


def _closed_form_all(request: IKRequest) -> IKSolutions:
    """Every closed-form branch within limits, each FK-checked (polished or dropped)."""
    if request.options:
        name = sorted(request.options)[0]
        raise InvalidArgumentError(name, "unknown option for method 'closed_form'; it takes no options")
    m = request.mechanism
    rows = registry.branches(m, request.target)
    inside = registry.within_limits(m, rows)
    outside = [np.array(r) for r in rows if r not in inside]
    kept: list[IKResult] = []
    failed = 0
    for row in inside:
        res = make_result(request, np.array(row), "closed_form", 0)
        if not res.success:
            q, _, _ = polish(m, request, res.q)
            res = make_result(request, q, "closed_form", 0)
            if not res.success:
                failed += 1
                continue
        kept.append(res)
    return IKSolutions(kept, outside, failed, "closed_form")


def _numeric_all(request: IKRequest, name: str, patience: int, max_solutions: int) -> IKSolutions:
    """Single starts of method ``name`` until ``patience`` starts in a row add nothing."""
    m = request.mechanism
    found: list[tuple[IKResult, float]] = []  # (result, same-point tolerance)
    misses = 0
    deadline = request.start + request.time_limit
    rng = request.rng
    start = request.q0
    while misses < patience and len(found) < max_solutions:
        remaining = deadline - time.perf_counter()
        if remaining <= 0:
            break
        res = solve_ik(
            m,
            request.target,
            start,
            name,
            task=request.task,
            frame=request.frame,
            time_limit=remaining,
            tol=request.tol,
            seed=rng,
            **({"max_restarts": 0} if name in RESTARTING else {}),
            **request.options,
        )
        start = m.random_q(seed=rng)
        if not res.success:
            misses += 1
            continue
        q, norm, sigma = polish(m, request, res.q)
        res = _polished(request, res, q)
        same = same_point_tol(norm, sigma)
        if any(joint_distance(m, res.q, r.q) < max(same, t) for r, t in found):
            misses += 1
            continue
        found.append((res, same))
        misses = 0
    return IKSolutions([r for r, _ in found], method=name)


def _polished(request: IKRequest, res: IKResult, q: np.ndarray) -> IKResult:
    """``res`` with ``q`` replaced by its polished value (errors re-evaluated), when that still
    meets the tolerances; else ``res`` unchanged."""
    better = make_result(request, q, res.method, res.iterations, res.restarts, res.status, res.message)
    if not better.success:
        return res
    better.solve_time = res.solve_time
    return better
