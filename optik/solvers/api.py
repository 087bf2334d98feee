"""``solve_ik``: one entry point in front of every registered IK method."""

from __future__ import annotations

from typing import Any

import numpy as np

from optik.collision import World
from optik.errors import SolverUnavailableError
from optik.mechanism import Mechanism
from optik.results import IKResult
from optik.solvers.base import Tolerances, get_method, make_request, methods
from optik.solvers.collision_free import solve_collision_free

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
            available (closed form where the catalog has one, else ``"lm"``).
        task: task space (default from the target type and the mechanism); with a target dict,
            one space for every frame or a ``{frame: task}`` dict.
        frame: task frame (default: the end effector); None with a target dict.
        time_limit: wall-time budget in seconds (default 0.1).
        tol: tolerances (float: position and orientation) or [`Tolerances`][optik.Tolerances].
        seed: seed or Generator for restarts.
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
        configuration found and a message.

    Raises:
        OptikError: malformed input (named argument), unknown or inapplicable method.
    """
    request = make_request(m, target, q0, task, frame, time_limit, tol, seed, options)
    if world is not None or self_collision:
        own = True if self_collision is None else bool(self_collision)
        return solve_collision_free(request, method or "lm", world, own, margin)
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
    return info.solve(request)
