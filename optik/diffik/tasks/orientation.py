"""Orientation task of a frame."""

from __future__ import annotations

from typing import Any

import numpy as np

from optik import spatial
from optik.checks import as_transform, real_array
from optik.diffik.tasks.frame_rows import FrameRowsTask
from optik.targets import Pose2D


class OrientationTask(FrameRowsTask):
    """Drive the orientation of a frame to a target: ``e = log(R R*^T)`` (3 rows, base frame).

    Args:
        frame: frame name (None: the end effector).
        target: 3x3 rotation, 4x4 transform or `Pose2D` (its rotation is used).
        cost: weight of each rotation row (per radian).
        gain, lm_damping, priority: see [`Task`][optik.diffik.Task].
    """

    rows = (3, 4, 5)
    kind = "orientation"

    def to_transform(self, target: Any) -> np.ndarray:
        if isinstance(target, Pose2D):
            target = target.as_transform()
        arr = real_array(target, "target")
        if arr.shape == (3, 3):
            return as_transform(spatial.transform(arr), "target")
        return as_transform(spatial.transform(as_transform(arr, "target")[:3, :3]), "target")
