"""Posture task: a joint-space target."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_vector
from optik.diffik.base import Task
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism


class PostureTask(Task):
    """Drive the coordinates to a target posture: ``e = q - q*``, ``J = I``.

    Usually a low-cost regulariser next to a frame task: it fixes the redundant (null-space)
    motion of a redundant arm.

    Args:
        target: target coordinates ``q*`` (one value per coordinate).
        cost: weight per coordinate (scalar or one value per coordinate).
        gain, lm_damping, priority: see [`Task`][optik.diffik.Task].
    """

    def __init__(
        self,
        target: Any,
        cost: Any = 1e-3,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        priority: int = 0,
    ) -> None:
        self.target = as_vector(target, "target", None)
        self.dim = int(self.target.shape[0])
        super().__init__(cost, gain, lm_damping, priority)

    def set_target(self, target: Any) -> None:
        """Set the target posture (same length)."""
        self.target = as_vector(target, "target", self.dim)

    def key(self) -> tuple:
        return ("posture", self.dim)

    def parameters(self, m: Mechanism) -> np.ndarray:
        if self.dim != m.n_q:
            raise InvalidArgumentError("target", f"expected {m.n_q} coordinates, got {self.dim}")
        return self.target

    def expressions(self, m: Mechanism, q: ca.SX, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        return q - p, ca.SX.eye(m.n_q)
