"""``track``: follow a sequence of target poses with differential IK, step by step."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optik.checks import as_float, as_transform, real_array
from optik.diffik.base import Limit, Task
from optik.diffik.problem import MIN_DT
from optik.diffik.step import StepResult, step
from optik.diffik.tasks import FrameTask, OrientationTask, Pose2DTask, PositionTask
from optik.diffik.tasks.frame_rows import FrameRowsTask
from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError
from optik.mechanism import Mechanism
from optik.solvers.base import default_task, task_errors
from optik.targets import Pose2D, Position


@dataclass
class TrackResult:
    """A tracked path.

    Attributes:
        t: times of the configurations (``N + 1``; ``t[0] = 0``).
        q: configurations (``(N + 1) x n``); ``q[k + 1]`` is the answer to target ``k``.
        v: joint velocities (``N x n``).
        position_error, orientation_error: error of ``q[k + 1]`` against target ``k`` in the
            tracking task's space (``N``).
        limit_margin: ``min_i min(q_i - lower_i, upper_i - q_i)`` per configuration (``N + 1``;
            negative outside the limits).
        manipulability: Yoshikawa's measure of the task Jacobian per configuration (``N + 1``).
        closure_error: loop-closure residual (max-norm) per configuration (``N + 1``).
        status: step status per step; solve_time: wall time of each step.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    limit_margin: np.ndarray
    manipulability: np.ndarray
    closure_error: np.ndarray
    status: list[str] = field(default_factory=list)
    solve_time: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def max_speed(self) -> float:
        """Largest joint speed ``max |v|`` along the path."""
        return float(np.max(np.abs(self.v))) if self.v.size else 0.0

    @property
    def within_limits(self) -> bool:
        """Every configuration within the limits."""
        return bool(np.all(self.limit_margin >= 0))


def tracking_task(m: Mechanism, space: str | None = None, frame: str | None = None) -> FrameRowsTask:
    """The frame task of a task space: ``"pose"`` -> [`FrameTask`][optik.diffik.track.FrameTask],
    ``"position"`` / ``"position2d"`` -> [`PositionTask`][optik.diffik.track.PositionTask] (``xyz`` / ``xy``),
    ``"pose2d"`` -> [`Pose2DTask`][optik.diffik.track.Pose2DTask] (``None``: the mechanism's own task space),
    ``"orientation"`` -> [`OrientationTask`][optik.diffik.track.OrientationTask]."""
    s = m.task if space is None else space
    if s == "pose":
        return FrameTask(frame)
    if s == "pose2d":
        return Pose2DTask(frame)
    if s in ("position", "position2d"):
        return PositionTask(frame, axes="xyz" if s == "position" else "xy")
    if s == "orientation":
        return OrientationTask(frame)
    raise InvalidArgumentError("space", f"unknown task space {s!r}")


def path_targets(m: Mechanism, path: Any) -> tuple[np.ndarray, str]:
    """The ``(N, 4, 4)`` target transforms of a path and the task space they imply.

    A path is what [`solve_ik`][optik.solve_ik] accepts as a target, one per step: a sequence of
    `Pose2D` (task ``"pose2d"``) or of `Position`, an ``(N, 3)`` or
    ``(N, 2)`` array of points (task ``"position"``, ``"position2d"`` for planar mechanisms), or
    ``(N, 4, 4)`` transforms, each a proper rigid transform (the mechanism's own task).

    Raises:
        InvalidArgumentError: an empty path, mixed target types, another shape, or an invalid
            target (named ``path[k]``).
    """
    if isinstance(path, (str, bytes)) or not isinstance(path, Sequence | np.ndarray) or len(path) == 0:
        raise InvalidArgumentError("path", f"expected a non-empty sequence of targets, got {path!r:.80}")
    kinds = {type(p) for p in path if isinstance(p, (Pose2D, Position))}
    if kinds:
        if len(kinds) > 1 or not all(isinstance(p, (Pose2D, Position)) for p in path):
            raise InvalidArgumentError("path", "mixes target types; use one of Pose2D, Position, 4x4")
        return np.stack([p.as_transform() for p in path]), default_task(m, path[0])
    a = real_array(path, "path")
    if a.ndim == 2 and a.shape[1] in (2, 3):
        if not np.isfinite(a).all():
            raise NonFiniteError("path", "contains NaN or infinity")
        return np.stack([Position(p).as_transform() for p in a]), default_task(m, Position(a[0]))
    if a.ndim != 3 or a.shape[1:] != (4, 4):
        raise ShapeError("path", f"expected (N, 4, 4) poses or (N, 3) points, got shape {a.shape}")
    return np.stack([as_transform(t, f"path[{k}]") for k, t in enumerate(a)]), m.task


def _margin(m: Mechanism, q: np.ndarray) -> float:
    return float(np.min(np.minimum(q - m.lower, m.upper - q)))


def track(
    m: Mechanism,
    q0: Any,
    path: Any,
    dt: float,
    method: str = "qp",
    solver: str | None = None,
    *,
    space: str | None = None,
    frame: str | None = None,
    tasks: Sequence[Task] = (),
    limits: Sequence[Limit] | None = None,
    **options: Any,
) -> TrackResult:
    """Track a path: at step ``k`` the frame task's target is ``path[k]`` and one
    [`step`][optik.diffik.track.step] of length ``dt`` moves the mechanism (gain 1: the step asks for the
    whole way to the sample, which is the feed-forward velocity of the path plus the correction of the current
    error).

    Args:
        m: the mechanism.
        q0: start configuration (may lie slightly outside the limits: the steps bring it back).
        path: one target per step: ``(N, 4, 4)`` poses (see [`optik.diffik.paths`][optik.diffik.paths]),
            a sequence of `Pose2D` or `Position`, or ``(N, 3)`` points (see
            [`path_targets`][optik.diffik.track.path_targets]).
        dt: control period (s).
        method, solver: see [`step`][optik.diffik.track.step].
        space: task space of the tracked frame (default: the one the targets imply, as in
            [`solve_ik`][optik.solve_ik]).
        frame: tracked frame (default: the end effector).
        tasks: extra tasks (posture, manipulability...), kept for every step.
        limits: see [`step`][optik.diffik.track.step]; acceleration limits get the previous velocity.
        **options: passed to [`step`][optik.diffik.track.step].

    Returns:
        The [`TrackResult`][optik.diffik.track.TrackResult].
    """
    targets, implied = path_targets(m, path)
    q = m.check_q(q0, "q0")
    dt = as_float(dt, "dt", MIN_DT)
    space_name = implied if space is None else space
    main = tracking_task(m, space_name, frame)
    all_tasks = [main, *tasks]
    n_steps = len(targets)
    qs = np.zeros((n_steps + 1, m.n_q))
    vs = np.zeros((n_steps, m.n_q))
    pos_err = np.zeros(n_steps)
    ori_err = np.zeros(n_steps)
    times = np.zeros(n_steps)
    statuses: list[str] = []
    qs[0] = q
    v_prev = np.zeros(m.n_q)
    for k, target in enumerate(targets):
        main.set_target(target)
        t0 = time.perf_counter()
        res: StepResult = step(m, q, all_tasks, dt, method, solver, limits, v_prev=v_prev, **options)
        times[k] = time.perf_counter() - t0
        q, v_prev = res.q, res.v
        qs[k + 1], vs[k] = q, res.v
        statuses.append(res.status)
        pos_err[k], ori_err[k] = task_errors(space_name, m.fk(q, frame), main.target)
    manip = np.array([m.manipulability(qk, frame, space_name) for qk in qs])
    closure = np.array([np.max(np.abs(m.closure(qk))) if m.is_closed else 0.0 for qk in qs])
    return TrackResult(
        t=np.arange(n_steps + 1) * dt,
        q=qs,
        v=vs,
        position_error=pos_err,
        orientation_error=ori_err,
        limit_margin=np.array([_margin(m, qk) for qk in qs]),
        manipulability=manip,
        closure_error=closure,
        status=statuses,
        solve_time=times,
    )
