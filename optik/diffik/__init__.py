"""Differential inverse kinematics: tasks, limits, one step by QP / DLS / pseudo-inverse /
strict priority, path tracking, and iterated differential IK as the ``"dls"`` and ``"qp"``
methods of [`optik.solve_ik`][optik.solve_ik] (registered on import).
"""

from optik.diffik import generic_stack as _generic_stack  # noqa: F401  # loaded with the package: the first step finds it
from optik.diffik import ik as _ik
from optik.diffik.base import Limit, Task
from optik.diffik.limits import AccelerationLimit, ClosureConstraint, ConfigurationLimit, VelocityLimit
from optik.diffik.linalg import damped_pinv
from optik.diffik.paths import circle_path, line_path, polyline_path
from optik.diffik.problem import DiffIKProblem, build_qp
from optik.diffik.qp import default_solver, solve_qp
from optik.diffik.step import METHODS, StepResult, step
from optik.diffik.tasks import (
    FrameTask,
    JointLimitTask,
    ManipulabilityTask,
    OrientationTask,
    Pose2DTask,
    PositionTask,
    PostureTask,
)
from optik.diffik.track import TrackResult, track, tracking_task

__all__ = [
    "METHODS",
    "AccelerationLimit",
    "ClosureConstraint",
    "ConfigurationLimit",
    "DiffIKProblem",
    "FrameTask",
    "JointLimitTask",
    "Limit",
    "ManipulabilityTask",
    "OrientationTask",
    "Pose2DTask",
    "PositionTask",
    "PostureTask",
    "StepResult",
    "Task",
    "TrackResult",
    "VelocityLimit",
    "build_qp",
    "circle_path",
    "damped_pinv",
    "default_solver",
    "line_path",
    "polyline_path",
    "solve_qp",
    "step",
    "track",
    "tracking_task",
]

_ik.register()
