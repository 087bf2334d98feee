"""Method ``"closed_form"``: the analytic IK of a catalog mechanism, branch nearest ``q0``.

[`optik.closed_form.ik`][optik.closed_form.ik] returns every branch (angles shifted by multiples of 2 pi into
the limits where possible); this method keeps those within the joint limits and answers the one nearest the
start ``q0`` (max-norm, angles modulo 2 pi). It applies when the mechanism's catalog kind has a registered
closed form and the task is the mechanism's own task space. No branch within the limits gives
``success=False`` with a message that says whether the target is out of reach or only out of the limits (then
the nearest branch, clipped into the limits, is returned).

The request's target is validated once by [`optik.solve_ik`][optik.solve_ik]; this method goes straight to
the branches ([`optik.closed_form.registry.branches`][optik.closed_form.registry.branches], computed once for
both cases) and evaluates the answer with the mechanism's compiled FK / closure functions.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from optik import closed_form
from optik.closed_form import registry
from optik.closed_form.derived import DerivedRows
from optik.errors import SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.results import IKResult
from optik.solvers.base import (
    IKRequest,
    Tolerances,
    evaluate,
    joint_distance,
    make_result,
    method_options,
    register_method,
    task_errors,
)
from optik.spatial import wrap_angle


def closed_form_applies(m: Mechanism, task: str) -> bool:
    """True when ``m`` has a registered closed-form IK for its own task space ``task``."""
    return closed_form.has_ik(m) and task == m.task


def nearest(m: Mechanism, qs: list[np.ndarray], q0: np.ndarray) -> np.ndarray:
    """The configuration of ``qs`` nearest ``q0`` (see
    [`joint_distance`][optik.solvers.closed.joint_distance])."""
    return min(qs, key=lambda q: joint_distance(m, q, q0))


def row_distance(mask: tuple[bool, ...], row: list[float], start: list[float]) -> float:
    """[`joint_distance`][optik.solvers.base.joint_distance] of two rows of floats (``mask``:
    the angle coordinates, [`registry.angle_mask`][optik.closed_form.registry.angle_mask])."""
    pi = math.pi
    worst = 0.0
    for a, b, ang in zip(row, start, mask, strict=True):
        d = a - b
        if ang and not -pi < d <= pi:  # within (-pi, pi] wrapping changes d by rounding only
            d = wrap_angle(d)
        if d < 0.0:
            d = -d
        if d > worst:
            worst = d
    return worst


def _nearest_row(m: Mechanism, rows: list[list[float]], q0: np.ndarray) -> np.ndarray:
    """[`nearest`][optik.solvers.closed.nearest] over rows of floats (the first of equally near
    ones), as an array."""
    if len(rows) > 1:
        mask = registry.angle_mask(m)
        start = q0.tolist()
        rows = [min(rows, key=lambda row: row_distance(mask, row, start))]
    return np.array(rows[0])


class _Evaluator:
    """FK of one frame and the closure residual of a mechanism, evaluated by CasADi on
    preallocated buffers (``Function.buffer``: about 1 us per call instead of about 40 us per
    call through CasADi's Python interface). The same expressions as ``m.fk`` / ``m.closure``.
    Guarded by a lock: a concurrent caller that finds it busy falls back to ``evaluate``."""

    def __init__(self, m: Mechanism, frame: str | None) -> None:
        outs = [ca.densify(m.frame_expr(frame))]
        if m.is_closed:
            outs.append(ca.densify(m.closure_expr))
        f = ca.Function("closed_form_check", [m.q_sym], outs)
        self.q = np.zeros(m.n_q)
        self.pose = np.zeros(16)  # column-major 4x4
        self.closure = np.zeros(m.n_closure) if m.is_closed else None
        self.buffer, self.call = f.buffer()
        self.buffer.set_arg(0, memoryview(self.q))
        self.buffer.set_res(0, memoryview(self.pose))
        if self.closure is not None:
            self.buffer.set_res(1, memoryview(self.closure))
        self.lock = threading.Lock()


_EVALUATORS: PerMechanism[dict[str | None, _Evaluator]] = PerMechanism()


def _evaluator(m: Mechanism, frame: str | None) -> _Evaluator:
    per_frame = _EVALUATORS.setdefault(m, {})
    if frame not in per_frame:
        per_frame[frame] = _Evaluator(m, frame)
    return per_frame[frame]


def _compiled_errors(request: IKRequest) -> Callable[[np.ndarray], tuple[float, float, float]]:
    """``q -> (position, orientation, closure)`` errors exactly as
    [`optik.solvers.base.evaluate`][optik.solvers.base.evaluate] computes them, with the FK and closure
    residual from `_Evaluator` (``q`` is the validated, clipped answer: no re-validation)."""
    m, task, target = request.mechanism, request.task, request.target
    ev = _evaluator(m, request.frame)

    def errors(q: np.ndarray) -> tuple[float, float, float]:
        if not ev.lock.acquire(blocking=False):
            e = evaluate(m, q, target, task, request.frame)
            return e.position, e.orientation, e.closure
        try:
            ev.q[:] = q
            ev.call()
            pose = ev.pose.reshape(4, 4, order="F").copy()
            clo = float(np.max(np.abs(ev.closure))) if ev.closure is not None else 0.0
        finally:
            ev.lock.release()
        pos, ori = task_errors(task, pose, target)
        return pos, ori, clo

    return errors


BINDINGS: dict[
    int, tuple[weakref.ref, int, Callable[..., Any], Callable[..., Any] | None, Callable[..., Any] | None]
] = {}
"""``id(m) -> (weak reference to m, registry generation, the driver's Python binding, its
binding over many targets, its binding of the solutions within the limits alone)``."""


_TOL = Tolerances.from_arg(None)
"""The default tolerances (the compiled driver is used where its FK check is within them)."""


def binding_of(m: Mechanism) -> Callable[..., Any] | None:
    """`compiled_binding` of ``m`` through `BINDINGS` (a dictionary lookup once it is loaded)."""
    entry = BINDINGS.get(id(m))
    if entry is not None and entry[0]() is m and entry[1] == registry.generation():
        return entry[2]
    return compiled_binding(m)


def many_binding_of(m: Mechanism) -> Callable[..., Any] | None:
    """The binding over many targets of ``m``'s compiled driver
    (``AllSolutionsKernel.many`` of `optik.closed_form.ik_all`), when
    `binding_of` has one; else None."""
    return _other_binding(m, 3)


def rows_binding_of(m: Mechanism) -> Callable[..., Any] | None:
    """The binding of the solutions within the limits alone of ``m``'s compiled driver
    (``AllSolutionsKernel.rows`` of `optik.closed_form.ik_all`), when `binding_of` has one;
    else None."""
    return _other_binding(m, 4)


def _other_binding(m: Mechanism, slot: int) -> Callable[..., Any] | None:
    if binding_of(m) is None:
        return None
    entry = BINDINGS.get(id(m))
    return entry[slot] if entry is not None else None


def compile_closed_form(m: Mechanism) -> None:
    """Build (or load from the cache) the compiled driver of ``m``'s derived closed form now and
    wait for it (`optik.closed_form.DerivedIK.compile`), so that `binding_of` has it; nothing
    for other closed forms. A batch is worth the wait: a single call answers from numpy while
    the driver builds in the background."""
    rows = registry.ik_solver(m)
    if type(rows) is DerivedRows:
        rows.solver.compile()


def compiled_binding(m: Mechanism) -> Callable[..., Any] | None:
    """The Python binding of the compiled driver of ``m``'s derived closed form
    ([`optik.closed_form.ik_all`][optik.closed_form.ik_all]), kept in `BINDINGS` once it is
    loaded; None while it builds, without one, or when ``m``'s closed form is not a derived one
    that the default tolerances admit. ``binding(T, q0, lower, upper, True)`` gives the same
    solutions, errors and order as the general closed-form paths, or None / False where they
    must answer: a target or ``q0`` that is not a float64 array of its shape or not valid (it then raises
    the named error), a candidate to polish or two close candidates (the numpy path decides)."""
    rows = registry.ik_solver(m)
    if type(rows) is not DerivedRows or m.task != "pose" or rows.solver.check_position > _TOL.position:
        return None
    driver = rows.solver.driver()
    if driver is None or driver.fast is None:
        return None
    key = id(m)
    alive = weakref.ref(m, lambda _, key=key: BINDINGS.pop(key, None))
    BINDINGS[key] = (alive, registry.generation(), driver.fast, driver.many, driver.rows)
    return driver.fast


def solve_closed_form(request: IKRequest) -> IKResult:
    """All closed-form branches, then the one within limits nearest ``q0`` (no options)."""
    method_options(request, {})
    m = request.mechanism
    fast = binding_of(m)
    if fast is not None:  # the solutions within the limits nearest q0 first, in one compiled call
        try:
            got = fast(request.target, request.q0, m.lower, m.upper, True)
        except RuntimeError as exc:  # the generated code reported an error
            raise SolverUnavailableError(str(exc)) from None
        if got and len(got[0]):  # None or False: every branch below decides
            return make_result(request, got[0][0].copy(), "closed_form", 0, errors=_compiled_errors(request))
    every = registry.branches(m, request.target)
    errors = _compiled_errors(request)
    inside = registry.within_limits(m, every)
    if inside:
        return make_result(request, _nearest_row(m, inside, request.q0), "closed_form", 0, errors=errors)
    if isinstance(every, registry.Uncertified):  # no word on reachability from an incomplete search
        res = make_result(
            request,
            _nearest_row(m, every, request.q0) if every else request.q0,
            "closed_form",
            0,
            status="not_found",
            message=f"the closed form found {len(every)} branch(es), none within the joint limits, and is "
            f"not certified complete ({every.reason}): the target may still be reachable",
            errors=errors,
        )
        res.extra["uncertified"] = every.reason or "no reason given"
        return res
    if every:
        return make_result(
            request,
            _nearest_row(m, every, request.q0),
            "closed_form",
            0,
            status="outside_limits",
            message=f"the target is reachable by {len(every)} closed-form branch(es), none within the "
            "joint limits; returned the branch nearest q0 clipped into the limits",
            errors=errors,
        )
    return make_result(
        request,
        request.q0,
        "closed_form",
        0,
        status="unreachable",
        message="the target is out of reach: the closed form has no real solution; returned q0",
        errors=errors,
    )


register_method(
    "closed_form",
    solve_closed_form,
    closed_form_applies,
    description="analytic IK of a catalog mechanism, branch within limits nearest q0",
)
