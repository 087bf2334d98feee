"""Differential-IK tasks, one class per file (see [`optik.diffik.Task`][optik.diffik.Task])."""

from optik.diffik.tasks.frame import FrameTask
from optik.diffik.tasks.joint_limit import JointLimitTask
from optik.diffik.tasks.manipulability import ManipulabilityTask
from optik.diffik.tasks.orientation import OrientationTask
from optik.diffik.tasks.pose2d import Pose2DTask
from optik.diffik.tasks.position import PositionTask
from optik.diffik.tasks.posture import PostureTask

__all__ = [
    "FrameTask",
    "JointLimitTask",
    "ManipulabilityTask",
    "OrientationTask",
    "Pose2DTask",
    "PositionTask",
    "PostureTask",
]
