"""ikpy (``pip install ikpy``): a scipy least-squares fit of the forward kinematics.

The chain is read with ``Chain.from_urdf_file(urdf, base_elements=[base_link])``; its link list
has an inactive origin link and the URDF's fixed joints, so optik's coordinates map to the
revolute/prismatic links (the active mask). ikpy has no wall-time limit: ``max_iter`` bounds the
optimizer instead, and the harness counts the measured time.
"""

from __future__ import annotations

import warnings

import numpy as np

from optik.harness.peers.base import Peer
from optik.solvers import Tolerances

MAX_ITER = 200
"""Optimizer iterations per call (ikpy's only budget)."""


class IKPy(Peer):
    """ikpy's ``inverse_kinematics_frame`` with ``orientation_mode="all"``."""

    name = "ikpy"
    package = "ikpy.chain"

    def load(self) -> int:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            probe = self.lib.Chain.from_urdf_file(str(self.urdf), base_elements=[self.base_link])
            mask = [link.joint_type != "fixed" for link in probe.links]
            self._chain = self.lib.Chain.from_urdf_file(
                str(self.urdf), base_elements=[self.base_link], active_links_mask=mask
            )
        self._active = np.flatnonzero(mask)
        self._size = len(mask)
        return len(self._active)

    def _full(self, q: np.ndarray) -> np.ndarray:
        full = np.zeros(self._size)
        full[self._active] = q
        return full

    def fk(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(self._chain.forward_kinematics(self._full(q)))

    def attempt(
        self, q0: np.ndarray, target: np.ndarray, time_limit: float, tol: Tolerances
    ) -> tuple[np.ndarray, bool]:
        """ikpy has no success flag: ``found`` is always True (the referee judges)."""
        full = self._full(q0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = self._chain.inverse_kinematics_frame(
                target, initial_position=full, orientation_mode="all", max_iter=MAX_ITER
            )
        return np.asarray(out)[self._active], True
