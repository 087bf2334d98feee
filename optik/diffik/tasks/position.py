"""Position task of a frame (all or some of x, y, z)."""

from __future__ import annotations

from typing import Any

import numpy as np

from optik import spatial
from optik.checks import as_name, as_vector, real_array
from optik.diffik.tasks.frame_rows import FrameRowsTask
from optik.errors import InvalidArgumentError
from optik.targets import Position


class PositionTask(FrameRowsTask):
    """Drive the origin of a frame to a point: ``e = p - p*`` restricted to ``axes``.

    Args:
        frame: frame name (None: the end effector).
        target: 3-vector (2-vector for planar), [`Position`][optik.Position] or a 4x4 transform
            (its translation is used).
        cost: weight of each position row (scalar or one per axis).
        axes: the coordinates to control, e.g. ``"xyz"`` or ``"xy"`` for planar mechanisms.
        gain, lm_damping, priority: see [`Task`][optik.diffik.Task].
    """

    kind = "position"

    def __init__(
        self,
        frame: str | None = None,
        target: Any = None,
        cost: Any = 1.0,
        axes: str = "xyz",
        gain: float = 1.0,
        lm_damping: float = 0.0,
        priority: int = 0,
    ) -> None:
        if not as_name(axes, "axes") or any(a not in "xyz" for a in axes) or len(set(axes)) != len(axes):
            raise InvalidArgumentError("axes", f"expected distinct letters of 'xyz', got {axes!r}")
        self.rows = tuple("xyz".index(a) for a in axes)
        super().__init__(frame, target, cost, gain, lm_damping, priority)

    def to_transform(self, target: Any) -> np.ndarray:
        if isinstance(target, Position):
            return target.as_transform()
        arr = real_array(target, "target")
        if arr.shape == (4, 4):
            return spatial.translation(*as_vector(arr[:3, 3], "target", 3))
        return Position(as_vector(target, "target", None)).as_transform()
