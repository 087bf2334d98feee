"""TRAC-IK (``pip install pytracik``): KDL Newton iterations raced against an SQP, with restarts.

``TRAC_IK(base, tip, urdf_xml, timeout, eps, solve_type)``; ``ik(solver, q0, x, y, z, qx, qy,
qz, qw)`` returns ``[found, q...]``. Its ``eps`` bounds each component of the Cartesian twist
error, so ``eps = min(position, orientation) / 2`` keeps the Euclidean errors within optik's
tolerances. The timeout is fixed at construction, so one solver is kept per time limit.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from optik.harness.peers.base import Peer
from optik.mechanism import Mechanism
from optik.solvers import Tolerances


class TracIK(Peer):
    """TRAC-IK through the ``pytracik`` bindings (solve type ``Speed``)."""

    name = "trac_ik"
    package = "pytracik"

    def __init__(self, mechanism: Mechanism, urdf: Path, base_link: str, tip_link: str) -> None:
        super().__init__(mechanism, urdf, base_link, tip_link)
        self._lib = self.import_package()
        self._xml = self.urdf.read_text(encoding="utf-8")
        self._solvers: dict[tuple[float, float], Any] = {}
        self.check_joints(self._lib.get_num_joints(self._solver(0.01, 1e-6)))

    def _solver(self, time_limit: float, eps: float) -> Any:
        key = (time_limit, eps)
        if key not in self._solvers:
            self._solvers[key] = self._lib.TRAC_IK(
                self.base_link, self.tip_link, self._xml, time_limit, eps, self._lib.SolveType.Speed
            )
        return self._solvers[key]

    def fk(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(self._lib.fk(self._solver(0.01, 1e-6), np.asarray(q, dtype=float)))

    def solve(self, q0: np.ndarray, target: np.ndarray, time_limit: float, tol: Tolerances) -> np.ndarray:
        solver = self._solver(time_limit, 0.5 * min(tol.position, tol.orientation))
        qx, qy, qz, qw = Rotation.from_matrix(target[:3, :3]).as_quat()
        x, y, z = target[:3, 3]
        out = np.asarray(self._lib.ik(solver, np.asarray(q0, dtype=float), x, y, z, qx, qy, qz, qw))
        return out[1:] if out[0] > 0 else np.asarray(q0, dtype=float)
