"""Manipulability task: move away from singular configurations."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_vector
from optik.diffik.base import Task, positive
from optik.errors import InvalidArgumentError
from optik.mechanism import TASK_ROWS, Mechanism


class ManipulabilityTask(Task):
    """Raise Yoshikawa's manipulability ``w(q) = sqrt(det(J_t J_t^T))`` towards a target value.

    ``J_t`` is the geometric Jacobian of ``frame`` restricted to the rows of ``space``. The scalar
    error is ``e = w(q) - w*`` with ``J = grad w`` (symbolic), so a step asks for
    ``grad w . dq = -alpha (w - w*)``: ``w`` grows while below ``w*``. As a low-priority task of
    a redundant arm it moves the arm's self-motion away from singularities.

    Args:
        frame: frame name (None: the end effector).
        target: the manipulability ``w*`` to reach (``> 0``).
        space: task space of ``J_t``: ``"pose"``, ``"position"``, ``"pose2d"``, ``"position2d"``.
        cost, gain, lm_damping, priority: see :class:`~optik.diffik.Task`.
    """

    dim = 1

    def __init__(
        self,
        frame: str | None = None,
        target: float = 1.0,
        space: str = "position",
        cost: Any = 1e-2,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        priority: int = 0,
    ) -> None:
        if space not in TASK_ROWS:
            raise InvalidArgumentError(
                "space", f"unknown task space {space!r}; use one of {sorted(TASK_ROWS)}"
            )
        super().__init__(cost, gain, lm_damping, priority)
        self.frame = frame
        self.space = space
        self.set_target(target)

    def set_target(self, target: float) -> None:
        """Set ``w*`` (``> 0``)."""
        t = positive(target, "target")
        if t <= 0:
            raise InvalidArgumentError("target", "must be > 0")
        self.target = t

    def key(self) -> tuple:
        return ("manipulability", self.frame, self.space)

    def parameters(self, m: Mechanism) -> np.ndarray:
        m._frame(self.frame)
        return as_vector(self.target, "target", 1)

    def expressions(self, m: Mechanism, q: ca.SX, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        jt = m.jacobian_expr(self.frame)[list(TASK_ROWS[self.space]), :]
        w = ca.sqrt(ca.fmax(ca.det(ca.mtimes(jt, jt.T)), 1e-12))
        return w - p[0], ca.jacobian(w, q)
