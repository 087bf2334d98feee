"""The Robotics Toolbox for Python (``pip install roboticstoolbox-python``): its C++ ``ik_LM``.

The URDF is read by ``Robot.URDF(path)`` and the chain is ``robot.ets(start=base_link,
end=tip_link)``; ``ETS.ik_LM(T, q0, tol=tol_E, joint_limits=True)`` runs Levenberg-Marquardt
(Chan's damping) with random restarts (``slimit`` searches of ``ilimit`` iterations) and rejects
answers outside the URDF limits. It stops at ``E = e^T e / 2 <= tol_E`` with
``tol_E = residual_bound(tol)`` (`optik.harness.peers.rules`). It has no wall-time limit: the
iteration and search caps bound it, and the benchmark counts the measured time.
"""

from __future__ import annotations

import warnings

import numpy as np

from optik.harness.peers.base import Peer, PeerUnavailable
from optik.harness.peers.rules import residual_bound
from optik.solvers import Tolerances


class RoboticsToolbox(Peer):
    """``ETS.ik_LM`` of ``roboticstoolbox`` with joint limits on (its defaults: 30 iterations per
    search, 100 searches)."""

    name = "rtb_lm"
    package = "roboticstoolbox"

    def load(self) -> int:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                robot = self.lib.Robot.URDF(str(self.urdf))
                self._ets = robot.ets(start=self.base_link, end=self.tip_link)
            except Exception as exc:  # the toolbox's URDF reader raises many kinds
                raise PeerUnavailable(
                    f"rtb_lm: cannot read the chain {self.base_link} -> {self.tip_link}: {exc}"
                ) from None
        return self._ets.n

    def fk(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(self._ets.eval(np.asarray(q, dtype=float)))

    def attempt(
        self, q0: np.ndarray, target: np.ndarray, time_limit: float, tol: Tolerances
    ) -> tuple[np.ndarray, bool]:
        sol = self._ets.ik_LM(
            target, q0=np.asarray(q0, dtype=float), tol=residual_bound(tol), joint_limits=True
        )
        return np.asarray(sol.q, dtype=float), bool(sol.success)
