"""``solve_ik``: one entry point in front of every registered IK method."""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from optik import native
from optik.closed_form import registry
from optik.collision import World
from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.results import IKResult
from optik.solvers.balance import auto_support, merge_contacts, solve_balance
from optik.solvers.base import (
    IKRequest,
    MethodInfo,
    PreparedCall,
    Tolerances,
    get_method,
    make_request,
    methods,
    registrations,
)
from optik.solvers.collision_free import CollisionCall, prepare_collision_free, solve_collision_free

DEFAULT_ORDER = ("closed_form", "lm", "nlp")
"""Preference of ``method=None``: the first registered method that applies."""


MULTI_TARGET_ORDER = ("lm", "nlp")
"""Preference of ``method=None`` for several frame targets at once."""


def pick_method(
    m: Mechanism,
    task: str | tuple[str, ...],
    order: tuple[str, ...] = DEFAULT_ORDER,
    multi_target: bool = False,
) -> str:
    """The first method of ``order`` that is registered and applies to a mechanism and task
    (and solves several frame targets at once, when ``multi_target``)."""
    known = methods()
    for name in order:
        if name in known and (known[name].multi_target or not multi_target) and known[name].applies(m, task):
            return name
    raise SolverUnavailableError(f"no IK method applies to {m.name!r} with task {task!r}")


def solve_ik(
    m: Mechanism,
    target: Any,
    q0: Any = None,
    method: str | None = None,
    *,
    task: str | None = None,
    frame: str | None = None,
    time_limit: float | None = None,
    tol: float | Tolerances | None = None,
    seed: int | np.random.Generator | None = None,
    contacts: Any = None,
    support: Any = None,
    com_margin: float = 0.0,
    world: World | None = None,
    self_collision: bool | None = None,
    margin: float = 0.0,
    **options: Any,
) -> IKResult:
    """Inverse kinematics with joint limits (and loop closures for closed chains).

    Args:
        m: the mechanism.
        target: 4x4 transform, [`Pose2D`][optik.Pose2D] or [`Position`][optik.Position]; or a
            ``{frame: target}`` dict of several frame targets solved at once (e.g. both hands of a
            tree model), each a 4x4, `Pose2D` or `Position`, with ``lm``, ``nlp``, ``dls`` or ``qp``.
            The result's ``frame_errors`` then holds each frame's errors and ``position_error`` /
            ``orientation_error`` are their maxima; success needs every frame within tolerance.
        q0: start configuration (default: mid-limit).
        method: ``"closed_form"``, ``"lm"``, ``"nlp"``, ``"dls"``, ``"qp"``; None picks the best
            available (closed form where the catalog has one, else ``"lm"``; where the closed
            form is costly, ``"lm"`` first and the closed form only when it fails).
        task: task space (default from the target type and the mechanism); with a target dict,
            one space for every frame or a ``{frame: task}`` dict.
        frame: task frame (default: the end effector); None with a target dict.
        time_limit: wall-time budget in seconds (default 0.1).
        tol: tolerances (float: position and orientation) or [`Tolerances`][optik.Tolerances].
        seed: seed or Generator for restarts.
        contacts: ``{frame: 4x4 or Position}``: frames held in the world (flat contacts or point
            feet), extra targets that success needs too (`optik.solvers.balance`).
        support: the world x-y support polygon, counter-clockwise ``(k, 2)``, or ``"auto"``: the
            hull of the contacts' collision geometry projected onto the ground
            (`optik.solvers.balance.auto_support`); the centre of mass's ground projection must
            stay inside it by ``com_margin`` (methods ``"lm"``, the default then, ``"nlp"`` and
            ``"qp"``; the mechanism needs masses).
        com_margin: the balance margin (m, ``>= 0``; only with ``support``).
        world: obstacles ([`optik.World`][optik.World]) the answer must clear; with it or with
            ``self_collision=True`` the solve is collision-aware (``lm`` or ``nlp``, default ``lm``:
            see `optik.solvers.collision_free`), success needs the exact check at ``margin`` to pass
            and the result carries ``min_distance`` and ``collision_pair``.
        self_collision: keep the robot clear of itself (its allowed-collision matrix aside);
            None: True when ``world`` is given.
        margin: clearance (m) the exact check requires of a collision-aware answer.
        **options: method-specific options (see each method's documentation).

    Returns:
        An [`IKResult`][optik.IKResult]; unreachable targets give ``success=False`` with the closest
        configuration found and a message. With ``method=None``, a closed form that finds no
        branch within the limits and does not certify completeness (the 1-D search of arms
        special at both ends) does not decide: the numerical method answers, within the time
        left, and its message and ``extra["closed_form"]`` say what the closed form found.

    Raises:
        OptikError: malformed input (named argument), unknown or inapplicable method.
    """
    start = time.perf_counter()
    key = None
    collide = world is not None or bool(self_collision)
    plain = type(target) is np.ndarray and contacts is None and support is None and com_margin == 0.0
    if plain and isinstance(m, Mechanism):
        # a prepared call, if any (a collision-aware one takes the world: read once per call)
        where = (self_collision, type(margin), margin) if collide else None
        key = _call_key(method, task, frame, time_limit, tol, options, where)
        try:
            call = _CALLS.get(m, _NO_CALLS).get(key)
        except TypeError:  # an unhashable value: no prepared call
            key = call = None
        if call is not None:
            res = call(start, target, q0, seed, world) if collide else call(start, target, q0, seed)
            if res is not None:
                return res
    if isinstance(support, str):
        if support != "auto":
            raise InvalidArgumentError("support", f'expected a (k, 2) polygon or "auto", got {support!r}')
        support = auto_support(m, contacts)
    if contacts is not None:
        target, frame = merge_contacts(m, target, frame, contacts), None
    if support is None and com_margin != 0.0:
        raise InvalidArgumentError("com_margin", "a balance margin needs a support polygon (support=...)")
    request = make_request(m, target, q0, task, frame, time_limit, tol, seed, options)
    request.start = start
    if support is not None:
        with native.deadline(request.start + request.time_limit):
            return solve_balance(request, support, com_margin, method)
    if collide:
        own = True if self_collision is None else bool(self_collision)
        res = solve_collision_free(request, method or "lm", world, own, margin)
        if key is not None and key not in _CALLS.get(m, _NO_CALLS):
            _keep(m, key, prepare_collision_free(request, method, own, margin))
        return res
    multi = request.multi_target
    own_frame = not multi and request.frame in (None, m.ee)  # closed forms solve for the end effector only
    if method is None:
        order = DEFAULT_ORDER if own_frame else tuple(n for n in DEFAULT_ORDER if n != "closed_form")
        name = pick_method(m, request.task, MULTI_TARGET_ORDER if multi else order, multi)
    else:
        name = method
    info = get_method(name)
    if multi and not info.multi_target:
        able = sorted(k for k, v in methods().items() if v.multi_target)
        raise SolverUnavailableError(
            f"method {name!r} solves one frame target; several targets at once: method one of {able}"
        )
    if not info.applies(m, request.task) or (name == "closed_form" and not own_frame):
        raise SolverUnavailableError(
            f"method {name!r} does not apply to {m.name!r} with task {request.task!r}"
            + ("" if own_frame else f" and frame {request.frame!r}")
        )
    with native.deadline(request.start + request.time_limit):  # no wait for a C build past it
        if method is None and name == "closed_form" and registry.costly(m):
            return _numerical_first(request)
        if key is not None and key not in _CALLS.get(m, _NO_CALLS):
            _remember(m, key, info, request)
        res = info.solve(request)
        if method is None and name == "closed_form" and "uncertified" in res.extra:
            return _numerical_fallback(request, res)
        return res


_CALLS: PerMechanism[dict[tuple[Any, ...], PreparedCall | CollisionCall | None]] = PerMechanism()
"""The prepared calls of each mechanism by `_call_key` (None: the method has none); a
collision-aware key's call is a `optik.solvers.collision_free.CollisionCall`."""
_CALLS_MAX = 256
"""Prepared calls kept per mechanism (all are dropped past it: option values drawn anew per call)."""
_NO_CALLS: dict[tuple[Any, ...], PreparedCall | CollisionCall | None] = {}


def _call_key(
    method: Any,
    task: Any,
    frame: Any,
    time_limit: Any,
    tol: Any,
    options: dict[str, Any],
    collision: tuple[Any, ...] | None = None,
) -> tuple[Any, ...]:
    """The key of a call's prepared call: every argument but the target, ``q0``, the seed and
    the world (``collision``: ``(self_collision, type(margin), margin)`` of a collision-aware
    call, None for the others), with the type of each value (``True == 1``, yet an option may
    take one and refuse the other) and the count of method registrations
    (`optik.solvers.base.registrations`). Hashing it raises TypeError when a value is unhashable
    (no prepared call then): the caller's lookup is the one hash."""
    opts = tuple((k, type(v), v) for k, v in options.items()) if options else ()
    return (
        registrations(),
        method,
        task,
        frame,
        type(time_limit),
        time_limit,
        type(tol),
        tol,
        opts,
        collision,
    )


def _remember(m: Mechanism, key: tuple[Any, ...], info: MethodInfo, request: IKRequest) -> None:
    """Keep the prepared call of a validated single-target ``request`` (made by the method's
    ``prepare``; None when it has none) for the later calls of `solve_ik` with ``key``."""
    _keep(m, key, None if info.prepare is None else info.prepare(request))


def _keep(m: Mechanism, key: tuple[Any, ...], call: Any) -> None:
    """Keep ``call`` (None: there is none) for the later calls of `solve_ik` with ``key``."""
    calls = _CALLS.setdefault(m, {})
    if len(calls) >= _CALLS_MAX:
        calls.clear()
    calls[key] = call


NUMERICAL_SHARE = 0.5
"""Share of the time limit that ``method=None`` gives the numerical method first where the
closed form is costly (`_numerical_first`)."""


def _numerical_first(request: IKRequest) -> IKResult:
    """The default method where the closed form costs far more than a numerical solve (the
    general 6R solver: an eigenproblem and up to 16 polished candidates, about 0.6 ms per
    target on a generic arm, against about 0.1 ms for ``lm``): the next method of
    `DEFAULT_ORDER` with `NUMERICAL_SHARE` of the time limit; the closed form only when that
    fails. Its answer is taken when it finds a branch within the limits, or when it is certified
    complete (it then says why there is none: out of reach, or only outside the limits);
    otherwise the numerical answer stands, with the closed form's
    finding in its message and ``extra["closed_form"]``."""
    m = request.mechanism
    name = pick_method(m, request.task, tuple(n for n in DEFAULT_ORDER if n != "closed_form"))
    first = dataclasses.replace(request, time_limit=NUMERICAL_SHARE * request.time_limit)  # same start
    res = get_method(name).solve(first)
    if res.success:
        return res
    closed = get_method("closed_form").solve(request)
    if closed.success or "uncertified" not in closed.extra:
        note = f"{name} found no solution within {first.time_limit:g} s first"
        closed.message = f"{closed.message}; {note}" if closed.message else note
        closed.extra[name] = {"status": res.status, "message": res.message}
        return closed
    return _noted(res, closed)


def _numerical_fallback(request: IKRequest, closed: IKResult) -> IKResult:
    """The default method's answer when the closed form found nothing within the limits and
    does not certify completeness (the 1-D search, a general 6R solve whose count check
    failed): the next method of `DEFAULT_ORDER` that applies, within what is left of the time
    limit, with the closed form's finding in its message and ``extra["closed_form"]``."""
    m = request.mechanism
    name = pick_method(m, request.task, tuple(n for n in DEFAULT_ORDER if n != "closed_form"))
    # the same request: its start and time limit are the deadline, so the method gets exactly
    # what is left (a limit of `remaining()` from the same start would count the time spent twice)
    return _noted(get_method(name).solve(request), closed)


def _noted(res: IKResult, closed: IKResult) -> IKResult:
    """A numerical answer ``res`` with the finding of the uncertified closed form ``closed`` in
    its message and ``extra["closed_form"]``."""
    reason = closed.extra["uncertified"]
    note = f"the closed form (not certified complete: {reason}) found no branch within the limits"
    res.message = f"{res.message}; {note}" if res.message else note
    res.extra["closed_form"] = {"status": closed.status, "message": closed.message}
    return res
