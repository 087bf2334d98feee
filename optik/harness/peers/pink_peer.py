"""Pink (``pip install pin-pink``): differential IK on pinocchio, iterated to a pose.

Each step solves Pink's QP ``min_v |J v - e / dt|^2 (+ damping)`` under the URDF's position and
velocity limits, and integrates ``q <- q (+) v dt``; iterations stop at half the tolerances (the
common rule of `optik.harness.peers.rules`) or at the time limit, or when the QP has no solution.
The QP backend is ``daqp`` when installed, else ``osqp``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from optik.harness.peers.base import Peer, PeerUnavailable
from optik.harness.peers.rules import HALF
from optik.solvers import Tolerances

DT = 1.0
"""Integration step (s); with unit task gain one step removes the linearized error."""


class Pink(Peer):
    """Pink ``FrameTask`` on the tip link, solved step by step until converged or out of time."""

    name = "pink"
    package = "pink"

    def load(self) -> int:
        try:
            import pinocchio as pin
            import qpsolvers
        except ImportError as exc:
            raise PeerUnavailable(f"pink: {exc}") from None
        self._pin = pin
        self._model = pin.buildModelFromUrdf(str(self.urdf))
        if not self._model.existFrame(self.tip_link):
            raise PeerUnavailable(f"pink: the URDF has no frame {self.tip_link!r}")
        self._data = self._model.createData()
        self._task = self.lib.tasks.FrameTask(self.tip_link, position_cost=1.0, orientation_cost=1.0)
        backends = qpsolvers.available_solvers
        self._qp = "daqp" if "daqp" in backends else "osqp"
        return self._model.nq

    def fk(self, q: np.ndarray) -> np.ndarray:
        conf = self.lib.Configuration(self._model, self._data, np.asarray(q, dtype=float).copy())
        return np.asarray(conf.get_transform_frame_to_world(self.tip_link).homogeneous)

    def attempt(
        self, q0: np.ndarray, target: np.ndarray, time_limit: float, tol: Tolerances
    ) -> tuple[np.ndarray, bool]:
        """``found``: the loop stopped at half the tolerances (by Pink's FK)."""
        start = time.perf_counter()
        pin = self._pin
        conf: Any = self.lib.Configuration(self._model, self._data, np.asarray(q0, dtype=float).copy())
        self._task.set_target(pin.SE3(target[:3, :3].copy(), target[:3, 3].copy()))
        found = False
        while time.perf_counter() - start < time_limit:
            pose = conf.get_transform_frame_to_world(self.tip_link)
            dp = np.linalg.norm(pose.translation - target[:3, 3])
            dr = np.linalg.norm(pin.log3(pose.rotation.T @ target[:3, :3]))
            if dp <= HALF * tol.position and dr <= HALF * tol.orientation:
                found = True
                break
            try:
                v = self.lib.solve_ik(conf, [self._task], DT, solver=self._qp, safety_break=False)
            except self.lib.exceptions.NoSolutionFound:  # infeasible QP: stop where we are
                break
            conf.integrate_inplace(v, DT)
        return np.asarray(conf.q, dtype=float).copy(), found
