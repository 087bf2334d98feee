"""Manipulability task: move away from singular configurations by gradient ascent."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from optik.checks import MAX_COORDINATES, as_int, as_name
from optik.diffik.base import Task
from optik.mechanism import TASK_ROWS, Mechanism


class ManipulabilityTask(Task):
    """Climb Yoshikawa's manipulability ``w(q) = sqrt(det(J_t J_t^T))`` by gradient ascent.

    ``J_t`` is the geometric Jacobian of ``frame`` restricted to the rows of ``space``. The task
    asks for the joint step ``dq = alpha grad w(q)`` (the gradient projection method of Liegeois
    and Yoshikawa): its error is ``e = -grad w(q)`` with ``J = I`` (the Jacobian of the step with
    the gradient frozen at the current ``q``). The requested step vanishes at a maximum of ``w``
    and never blows up, unlike driving the scalar ``w`` to a target. As a low-priority task (or
    with a low cost) of a redundant arm it moves the self-motion away from singularities.

    Args:
        n_q: number of coordinates of the mechanism it will be used with.
        frame: frame name (None: the end effector).
        space: task space of ``J_t``: ``"pose"``, ``"position"``, ``"orientation"``, ``"pose2d"``,
            ``"position2d"``.
        cost: weight per coordinate (scalar or ``n_q`` values).
        gain: ascent step ``alpha`` (rad per unit of ``grad w``), in ``(0, 1]``.
        lm_damping, priority: see [`Task`][optik.diffik.Task].
    """

    def __init__(
        self,
        n_q: int,
        frame: str | None = None,
        space: str = "position",
        cost: Any = 1.0,
        gain: float = 0.05,
        lm_damping: float = 0.0,
        priority: int = 0,
    ) -> None:
        as_name(space, "space", TASK_ROWS)
        self.dim = as_int(n_q, "n_q", 1, MAX_COORDINATES)
        super().__init__(cost, gain, lm_damping, priority)
        self.frame = None if frame is None else as_name(frame, "frame")
        self.space = space

    def key(self) -> tuple:
        return ("manipulability", self.dim, self.frame, self.space)

    def parameters(self, m: Mechanism) -> np.ndarray:
        self._check_coordinates(m)
        m._frame(self.frame)  # raises UnknownFrameError naming the frame
        return np.zeros(0)

    def expressions(self, m: Mechanism, q: ca.SX, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        jt = m.jacobian_expr(self.frame)[list(TASK_ROWS[self.space]), :]
        w = ca.sqrt(ca.fmax(ca.det(ca.mtimes(jt, jt.T)), 1e-24))
        return -ca.jacobian(w, q).T, ca.SX.eye(m.n_q)
