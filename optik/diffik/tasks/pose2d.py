"""Planar pose task ``(x, y, phi)``."""

from __future__ import annotations

from typing import Any

import numpy as np

from optik.checks import as_vector, real_array
from optik.diffik.tasks.frame_rows import PoseRowsTask
from optik.targets import Pose2D, target_transform


class Pose2DTask(PoseRowsTask):
    """Drive a frame of a planar mechanism to ``(x, y, phi)``: ``e = [x - x*, y - y*, wrap(phi - phi*)]``.

    The heading row is the z component of ``log(R R*^T)``, which for rotations about z is the
    wrapped heading difference; its Jacobian row is the z row of the angular Jacobian.

    Args:
        frame: frame name (None: the end effector).
        target: [`Pose2D`][optik.Pose2D], ``(x, y, phi)`` or a 4x4 transform in the x-y plane.
        position_cost: weight of the x and y rows; orientation_cost: of the heading row.
        gain, lm_damping, priority: see [`Task`][optik.diffik.Task].
    """

    rows = (0, 1, 5)
    kind = "pose2d"

    def to_transform(self, target: Any) -> np.ndarray:
        if isinstance(target, Pose2D):
            return target.as_transform()
        arr = real_array(target, "target")
        if arr.shape == (4, 4):
            return target_transform(arr)
        return Pose2D(*as_vector(target, "target", 3)).as_transform()
