"""``solve_ik_all``: distinct IK branches by closed forms plus numerical multi-start.

Branches are collected in two ways:

1. where the catalog registers a closed form for the mechanism's own task, every closed-form
   branch within the joint limits (exact, so nothing is missed there);
2. a numerical method (``"lm"`` where it applies, else ``"nlp"``) is run from the start ``q0``
   and then from points drawn uniformly within the limits, one start per call (no restarts
   inside a call); each successful answer that is not the same branch as one already found
   (same-branch rule: joint vectors within [`BRANCH_TOL`][optik.solvers.base.BRANCH_TOL], angles modulo
   2 pi) is added.

The search stops after ``patience`` consecutive starts without a new branch, after
``max_solutions`` branches (redundant arms have infinitely many solutions), or at the time limit.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from optik import closed_form as analytic
from optik.mechanism import Mechanism
from optik.results import IKResult
from optik.solvers.api import pick_method, solve_ik
from optik.solvers.base import (
    BRANCH_TOL,
    Tolerances,
    joint_distance,
    make_request,
    make_result,
    positive_int,
)
from optik.solvers.closed import closed_form_applies

NUMERIC_ORDER = ("lm", "nlp")
"""Numerical methods ``solve_ik_all`` may use, in order of preference."""


def solve_ik_all(
    m: Mechanism,
    target: Any,
    q0: Any = None,
    method: str | None = None,
    *,
    task: str | None = None,
    frame: str | None = None,
    time_limit: float | None = 1.0,
    tol: float | Tolerances | None = None,
    seed: int | np.random.Generator | None = None,
    patience: int = 50,
    max_solutions: int = 64,
    closed_form: bool = True,
    **options: Any,
) -> list[IKResult]:
    """Every distinct IK branch found within the joint limits.

    Args:
        m: the mechanism.
        target: 4x4 transform, [`Pose2D`][optik.Pose2D] or [`Position`][optik.Position].
        q0: first start of the numerical search (default mid-limit); results are sorted by their
            distance to it.
        method: numerical method for the multi-start (default ``"lm"`` where it applies,
            else ``"nlp"``).
        task: task space (default from the target and the mechanism).
        frame: task frame (default: the end effector).
        time_limit: wall-time budget of the whole search (s).
        tol: success tolerances.
        seed: seed or Generator of the starts.
        patience: stop after this many consecutive starts without a new branch.
        max_solutions: stop after this many branches.
        closed_form: include the closed-form branches where the catalog has a closed form.
        **options: options of the numerical method.

    Returns:
        Successful results, one per branch, nearest ``q0`` first; ``[]`` when none was found
        (e.g. an unreachable target).

    Raises:
        OptikError: malformed input (named argument), unknown or inapplicable method.
    """
    request = make_request(m, target, q0, task, frame, time_limit, tol, seed, options)
    patience = positive_int(patience, "patience")
    max_solutions = positive_int(max_solutions, "max_solutions")
    found: list[IKResult] = []
    if closed_form and closed_form_applies(m, request.task):
        for q in analytic.ik(m, request.target, respect_limits=True):
            res = make_result(request, q, "closed_form", 0)
            if res.success and not _known(m, res.q, found):
                found.append(res)
    name = method or pick_method(m, request.task, NUMERIC_ORDER)
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
            frame=frame,
            time_limit=remaining,
            tol=request.tol,
            seed=rng,
            max_restarts=0,
            **options,
        )
        if res.success and not _known(m, res.q, found):
            found.append(res)
            misses = 0
        else:
            misses += 1
        start = rng.uniform(m.lower, m.upper)
    return sorted(found, key=lambda r: joint_distance(m, r.q, request.q0))


def _known(m: Mechanism, q: np.ndarray, found: list[IKResult]) -> bool:
    return any(joint_distance(m, q, r.q) < BRANCH_TOL for r in found)
