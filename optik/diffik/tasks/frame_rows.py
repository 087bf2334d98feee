"""Shared implementation of the frame tasks: rows of the pose error of one frame."""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np

from optik.checks import as_name
from optik.diffik.base import Task, frame_error_expr, positive
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.targets import target_transform


class FrameRowsTask(Task):
    """Rows of ``e = [p - p*; log(R R*^T)]`` (base frame) of one frame against a target pose.

    Subclasses fix `rows` (0-2 position, 3-5 rotation vector) and convert their target
    argument into a 4x4 transform.
    """

    rows: tuple[int, ...] = (0, 1, 2, 3, 4, 5)
    kind: ClassVar[str] = "frame"

    def __init__(
        self,
        frame: str | None = None,
        target: Any = None,
        cost: Any = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        priority: int = 0,
    ) -> None:
        self.dim = len(self.rows)
        super().__init__(cost, gain, lm_damping, priority)
        self.frame = None if frame is None else as_name(frame, "frame")
        self.target: np.ndarray | None = None
        if target is not None:
            self.set_target(target)

    def to_transform(self, target: Any) -> np.ndarray:
        """The 4x4 transform of a target argument (overridden by subclasses)."""
        return target_transform(target)

    def set_target(self, target: Any) -> None:
        """Set the target (same types as the constructor); does not recompile anything."""
        self.target = self.to_transform(target)

    def key(self) -> tuple:
        return (self.kind, self.frame, self.rows)

    def parameters(self, m: Mechanism) -> np.ndarray:
        if self.target is None:
            raise InvalidArgumentError("target", f"{type(self).__name__} has no target; call set_target()")
        m._frame(self.frame)  # raises UnknownFrameError naming the frame
        return self.target.reshape(-1, order="F")

    def n_parameters(self, m: Mechanism) -> int:
        return 16

    def expressions(self, m: Mechanism, q: ca.SX, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        e, jac = frame_error_expr(m, self.frame, ca.reshape(p, 4, 4))
        rows = list(self.rows)
        return e[rows], jac[rows, :]


class PoseRowsTask(FrameRowsTask):
    """Frame rows weighted by two costs: ``position_cost`` on rows 0-2, ``orientation_cost`` on 3-5."""

    def __init__(
        self,
        frame: str | None = None,
        target: Any = None,
        position_cost: float = 1.0,
        orientation_cost: float = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        priority: int = 0,
    ) -> None:
        pc = positive(position_cost, "position_cost")
        oc = positive(orientation_cost, "orientation_cost")
        cost = [pc if row < 3 else oc for row in self.rows]
        super().__init__(frame, target, cost, gain, lm_damping, priority)
