"""``solve_ik_all``: every distinct IK solution, by a closed form or by numerical multi-start.

* **Closed form** (``method="closed_form"``, or ``method=None`` when the mechanism has one for
  its own task: a catalog closed form or one derived from the model's structure, see
  ``optik.closed_form.derived``): every branch is computed, each passing the FK check (a
  branch that fails it is polished, then dropped if it still fails, and counted). A closed form is
  complete, so it answers alone: no numerical search follows. For an arm whose closed form is
  derived, the plain call ``solve_ik_all(m, T[, q0])`` is one call into compiled C
  (``optik.closed_form.ik_all``: candidates, checks, 2 pi shift, limit split and order in one
  go), with the same answer as the general path.
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

import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from optik import native
from optik.checks import as_bool, as_name, as_vector
from optik.closed_form import registry, search_1d
from optik.closed_form.derived import derive_locked, locked_axes
from optik.closed_form.general_6r import General6R, solve_general_6r
from optik.collision.check import check_many
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
from optik.solvers.closed import _compiled_errors, binding_of, closed_form_applies
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
    fixed: Mapping[str, float] | None = None,
    world: Any = None,
    self_collision: bool | None = None,
    margin: float = 0.0,
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
            has one for the task, else ``"lm"`` where it applies, else ``"nlp"``; when the
            closed form is not certified complete and finds no solution within the limits, the
            numerical search answers within the time left (its ``uncertified_reason`` says so).
        task: task space (default from the target and the mechanism).
        frame: task frame (default: the end effector).
        time_limit: wall-time budget of the whole search (s): the numerical search checks it
            after every iteration; a closed form has no iteration to stop and runs to completion
            (the general 6R solver takes about 0.6 ms on a generic arm whatever the limit:
            ``docs/reliability.md``, "Time limits").
        tol: success tolerances.
        seed: seed or Generator of the starts.
        patience: stop after this many consecutive starts without a new solution.
        max_solutions: stop after this many solutions.
        closed_form: with ``method=None``, False skips the closed form (numerical search only).
        fixed: coordinates locked at given values, ``{name: value}`` (e.g. one joint of a 7-DOF
            arm): the solutions of the remaining joints, by what a standalone arm of the 6R chain
            they leave would get: its derived closed form when its structure allows (Panda, iiwa
            with one joint locked), else the general 6R solver where it covers the geometry, else
            the 1-D search (both with their certificate or its absence); else by the numerical
            search with those coordinates' limits pinned to the values. Sample the
            self-motion of a redundant arm by sweeping the value (`self_motion`).
        world: obstacles ([`optik.World`][optik.World]); with it or ``self_collision=True`` each
            solution is checked exactly (`optik.collision.check_many` at ``margin``): the
            collision-free ones are returned, with their ``min_distance`` and ``collision_pair``,
            the others are in ``in_collision``.
        self_collision: check the robot against itself too (None: True when ``world`` is given).
        margin: the clearance (m) a solution needs.
        **options: options of the numerical method (the closed form takes none).

    Returns:
        An ``optik.results.IKSolutions`` (a list of successful results, one per solution,
        nearest ``q0`` first; empty when none was found, e.g. an unreachable target), with the
        solutions left out for the joint limits in ``outside_limits``.

    Raises:
        OptikError: malformed input (named argument), unknown or inapplicable method, an option
            the method does not know.
    """
    own = (world is not None) if self_collision is None else as_bool(self_collision, "self_collision")
    if world is not None or own:
        found = solve_ik_all(
            m, target, q0, method, task=task, frame=frame, time_limit=time_limit, tol=tol, seed=seed,
            patience=patience, max_solutions=max_solutions, closed_form=closed_form, fixed=fixed, **options,
        )  # fmt: skip
        return _collision_free(m, found, world, own, margin)
    start = time.perf_counter()
    if (  # the plain call on an arm with a derived closed form: one compiled call (binding_of)
        (method is None or (type(method) is str and method == "closed_form"))
        and closed_form is True
        and fixed is None
        and task is None
        and frame is None
        and tol is None
        and seed is None
        and not options
        and type(patience) is int
        and type(max_solutions) is int
        and patience > 0
        and max_solutions > 0
        and (time_limit is None or (type(time_limit) is float and 0.0 < time_limit < math.inf))
    ):
        fast = binding_of(m)
        try:
            got = None if fast is None else fast(target, q0, m.lower, m.upper, True)
        except RuntimeError as exc:  # the generated code reported an error
            raise SolverUnavailableError(str(exc)) from None
        if got:  # None or False: the general path decides
            return IKSolutions.from_arrays(*got, "closed_form", time.perf_counter() - start)
    request = make_request(m, target, q0, task, frame, time_limit, tol, seed, options)
    if request.multi_target:
        raise InvalidArgumentError(
            "target", "solve_ik_all takes one frame target; several frame targets at once: optik.solve_ik"
        )
    patience = positive_int(patience, "patience")
    max_solutions = positive_int(max_solutions, "max_solutions")
    if method is not None:
        as_name(method, "method")
    closed_form = as_bool(closed_form, "closed_form")
    with native.deadline(request.start + request.time_limit):  # no wait for a C build past it
        return _dispatch(request, method, fixed, patience, max_solutions, closed_form)


def _collision_free(
    m: Mechanism, found: IKSolutions, world: Any, self_collision: bool, margin: Any
) -> IKSolutions:
    """``found`` split by the exact check at ``margin``: the clear solutions, the others in
    ``in_collision`` (each marked failed, with the pair that blocks)."""
    results = list(found)
    q = np.array([r.q for r in results]).reshape(len(results), m.n_q)
    batch = check_many(m, q, world, margin, self_collision)
    clear, hit = [], []
    for r, report in zip(results, batch.reports, strict=True):
        r.min_distance, r.collision_pair = report.min_distance, report.pair
        if report.in_collision:
            pair = report.close_pairs[0]
            r.success, r.status = False, "in_collision"
            r.message = (
                f"{pair.a!r} and {pair.b!r} are {pair.distance:.4g} m apart (margin {report.margin:g} m)"
            )
            hit.append(r)
        else:
            clear.append(r)
    out = IKSolutions(
        clear, found.outside_limits, found.failed_check, found.method, found.uncertified_reason, m.n_q
    )
    out.in_collision = hit
    return out


def _dispatch(
    request: IKRequest,
    method: str | None,
    fixed: Any,
    patience: int,
    max_solutions: int,
    closed_form: bool,
) -> IKSolutions:
    """The search of `solve_ik_all` for a validated request: locked joints, the closed form,
    or the numerical multi-start."""
    m, frame = request.mechanism, request.frame
    if fixed is not None:
        return _locked_all(request, _locks(m, fixed), method, patience, max_solutions)
    applies = closed_form_applies(m, request.task) and frame in (None, m.ee)
    if method == "closed_form":
        if not applies:
            raise SolverUnavailableError(
                f"method 'closed_form' does not apply to {m.name!r} with task {request.task!r}"
                + ("" if frame in (None, m.ee) else f" and frame {frame!r}")
            )
        return _closed_form_all(request)
    if method is None and closed_form and applies:
        found = _closed_form_all(request)
        if len(found) or found.certified:
            return found
        # an uncertified closed form with nothing within the limits: the numerical search decides
        name = pick_method(m, request.task, NUMERIC_ORDER)
        numeric = _numeric_all(request, name, patience, max_solutions, request.q0)
        numeric.uncertified_reason += f"; the closed form found none ({found.uncertified_reason})"
        return numeric
    name = method or pick_method(m, request.task, NUMERIC_ORDER)
    return _numeric_all(request, name, patience, max_solutions, request.q0)


def _closed_form_all(request: IKRequest) -> IKSolutions:
    """Every closed-form branch within limits, each FK-checked (polished or dropped), sorted by
    the distance to ``q0``."""
    _no_options(request)
    return _from_rows(request, registry.branches(request.mechanism, request.target))


def _no_options(request: IKRequest) -> None:
    if request.options:
        name = sorted(request.options)[0]
        raise InvalidArgumentError(name, "unknown option for method 'closed_form'; it takes no options")


def _from_rows(request: IKRequest, rows: list[list[float]]) -> IKSolutions:
    """Results of closed-form rows (wrapped): the ones within limits, checked by the
    mechanism's compiled FK, nearest ``q0`` first.

    Lean on purpose (one closed-form call per target is the hot path of branch selection):
    results are built directly from the compiled FK check (``closed._compiled_errors``) instead
    of the generic [`make_result`][optik.solvers.base.make_result], which only the rare branch
    that needs polishing goes through."""
    m = request.mechanism
    clipped = [registry.clip_to_limits(m, r) for r in rows]
    inside = [c for c in clipped if c is not None]
    outside = [np.array(r) for r, c in zip(rows, clipped, strict=True) if c is None]
    checked = {}
    if isinstance(rows, registry.CheckedRows) and request.task == m.task == "pose" and not m.is_closed:
        checked = {id(row): err for row, err in zip(rows, rows.errors, strict=True)}
    errors = _compiled_errors(request)
    tol = request.tol
    if len(inside) > 1:  # nearest q0 first: joint_distance of every row at once
        d = np.asarray(inside) - request.q0
        ang = m.revolute_mask
        d[:, ang] = (d[:, ang] + np.pi) % (2.0 * np.pi) - np.pi
        order = np.argsort(np.abs(d).max(axis=1), kind="stable").tolist()
        inside = [inside[k] for k in order]
    kept: list[IKResult] = []
    failed = 0
    for row in inside:
        q = np.array(row)
        pos, ori, clo = (*checked[id(row)], 0.0) if id(row) in checked else errors(q)
        if pos <= tol.position and ori <= tol.orientation and clo <= tol.closure:
            kept.append(IKResult(q, True, pos, ori, clo, True, 0, request.elapsed(), "closed_form", "solved"))
            continue
        res = make_result(request, polish(m, request, q)[0], "closed_form", 0)
        if res.success:
            kept.append(res)
        else:
            failed += 1
    reason = (rows.reason or "no reason given") if isinstance(rows, registry.Uncertified) else ""
    return IKSolutions(kept, outside, failed, "closed_form", reason, m.n_q)


def _locks(m: Mechanism, fixed: Mapping[str, float]) -> dict[int, float]:
    """``fixed`` as ``{coordinate index: value}``, checked (known names, finite values within
    the limits)."""
    if not isinstance(fixed, Mapping) or not fixed:
        raise InvalidArgumentError(
            "fixed", f"expected a non-empty mapping {{coordinate name: value}}, got {fixed!r}"
        )
    locks: dict[int, float] = {}
    for name, value in fixed.items():
        if name not in m.coordinate_names:
            raise InvalidArgumentError(
                "fixed", f"unknown coordinate {name!r}; known: {list(m.coordinate_names)}"
            )
        k = m.coordinate_names.index(name)
        v = float(as_vector(value, "fixed", 1)[0])
        if not m.lower[k] <= v <= m.upper[k]:
            raise InvalidArgumentError(
                "fixed", f"{name} = {v} is outside its limits [{m.lower[k]}, {m.upper[k]}]"
            )
        locks[k] = v
    return locks


def _locked_all(
    request: IKRequest, locks: dict[int, float], method: str | None, patience: int, max_solutions: int
) -> IKSolutions:
    """Solutions with the coordinates ``locks`` fixed: the derived closed form of the remaining
    6R chain, else the numerical search with those limits pinned."""
    m = request.mechanism
    found = None
    if method in (None, "closed_form") and request.task == "pose" and request.frame in (None, m.ee):
        found = _locked_closed_form(m, locks, request.target)
    if found is not None:
        _no_options(request)
        free = [k for k in range(m.n_q) if k not in locks]
        rows = []
        for sol in found:
            row = [0.0] * m.n_q
            for k, v in zip(free, sol, strict=True):
                row[k] = v
            rows.append(row)
        rows = registry.wrap_rows(m, rows)
        for row in rows:  # exactly the locked values (within limits: checked)
            for k, v in locks.items():
                row[k] = v
        if isinstance(found, registry.Uncertified):
            rows = registry.Uncertified(rows, found.reason)
        return _from_rows(request, rows)
    if method == "closed_form":
        raise SolverUnavailableError(
            f"method 'closed_form' does not apply to {m.name!r} with "
            f"{sorted(m.coordinate_names[k] for k in locks)} locked: the remaining chain has no "
            "closed form for this task and frame"
        )
    lower, upper = m.lower.copy(), m.upper.copy()
    for k, v in locks.items():
        lower[k] = upper[k] = v
    pinned = m.with_limits(lower=lower, upper=upper)
    q0 = np.clip(request.q0, lower, upper)
    r = request
    sub = make_request(pinned, r.target, q0, r.task, r.frame, r.time_limit, r.tol, r.seed, r.options)
    name = method or pick_method(pinned, request.task, NUMERIC_ORDER)
    return _numeric_all(sub, name, patience, max_solutions, request.q0)


def _locked_closed_form(
    m: Mechanism, locks: dict[int, float], target: np.ndarray
) -> list[list[float]] | None:
    """The closed-form solutions of the free joints with ``locks`` fixed, by what a standalone
    arm of the remaining 6R chain's geometry would get: its derived closed form, else the
    general 6R solver where it covers the geometry (an `registry.Uncertified` list when the
    count check fails), else the 1-D search (uncertified); None when none applies."""
    solver = derive_locked(m, locks)
    if solver is not None:
        q, ok = solver.solve(target)
        return q[0][ok[0]].tolist()
    axes = locked_axes(m, locks)
    if axes is None:
        return None
    arm = General6R.from_axes(axes)
    if arm.covered:
        sols = solve_general_6r(arm, target)
        return sols.q.tolist() if sols.count_ok else registry.Uncertified(sols.q.tolist(), sols.reason)
    family = search_1d.family_of(axes)
    if family is None:
        return None
    got = search_1d.Search1D(axes, family).solve(target[None])[0]
    return registry.Uncertified(got.q.tolist(), got.reason)


def self_motion(m: Mechanism, target: Any, joint: str, values: Any, **options: Any) -> list[IKSolutions]:
    """Samples of the self-motion of a redundant arm: ``solve_ik_all(m, target, fixed={joint: v})``
    for each ``v`` of ``values`` (e.g. ``np.linspace(lower, upper, 50)`` of that joint).

    Each sample holds the solutions with the joint at that value (for a 7-DOF arm with a
    decomposable 6R remainder: every analytic branch); following one branch over the samples
    traces one self-motion manifold.

    Args:
        m: the mechanism.
        target: the target.
        joint: the swept coordinate's name.
        values: its sample values (within its limits).
        **options: further arguments of `solve_ik_all`.

    Returns:
        One [`IKSolutions`][optik.results.IKSolutions] per value, in order.
    """
    vals = as_vector(values, "values")
    return [solve_ik_all(m, target, fixed={joint: float(v)}, **options) for v in vals]


def _numeric_all(
    request: IKRequest, name: str, patience: int, max_solutions: int, near: np.ndarray
) -> IKSolutions:
    """Single starts of method ``name`` until ``patience`` starts in a row add nothing; the
    solutions nearest ``near`` first."""
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
    kept = sorted((r for r, _ in found), key=lambda r: joint_distance(m, r.q, near))
    why = f"found by the numerical multi-start ({name}), which does not prove that no solution is missing"
    return IKSolutions(kept, method=name, uncertified_reason=why, n_q=m.n_q)


def _polished(request: IKRequest, res: IKResult, q: np.ndarray) -> IKResult:
    """``res`` with ``q`` replaced by its polished value (errors re-evaluated), when that still
    meets the tolerances; else ``res`` unchanged."""
    better = make_result(request, q, res.method, res.iterations, res.restarts, res.status, res.message)
    if not better.success:
        return res
    better.solve_time = res.solve_time
    return better
