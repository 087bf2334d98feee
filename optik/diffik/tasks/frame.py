"""Full-pose task of a frame."""

from __future__ import annotations

from optik.diffik.tasks.frame_rows import PoseRowsTask


class FrameTask(PoseRowsTask):
    """Drive a frame to a target pose: ``e = [p - p*; log(R R*^T)]`` (6 rows, base frame).

    Args:
        frame: frame name (None: the end effector).
        target: 4x4 transform (or [`Pose2D`][optik.Pose2D]); may be set later with
            `set_target`.
        position_cost: weight of the three position rows (per metre).
        orientation_cost: weight of the three rotation rows (per radian).
        gain: fraction of the error removed per step, in ``(0, 1]``.
        lm_damping: Levenberg-Marquardt damping (see [`Task`][optik.diffik.Task]).
        priority: hierarchy level (0 highest).

    The Jacobian is ``[J_v; J_l^{-1}(e_w) J_w]``: the geometric Jacobian with the exact
    derivative of the rotation vector.
    """

    rows = (0, 1, 2, 3, 4, 5)
    kind = "frame"
