"""TRAC-IK (``pip install pytracik``): KDL Newton iterations raced against an SQP, with restarts.

``TRAC_IK(base, tip, urdf_xml, timeout, eps, solve_type)``; ``ik(solver, q0, x, y, z, qx, qy,
qz, qw)`` returns ``[found, q...]``. Its ``eps`` bounds each component of the Cartesian twist
error; it is [`twist_epsilon`][optik.harness.peers.rules.twist_epsilon] of the tolerances, the rule
of `optik.harness.peers.rules`. The timeout is fixed at construction, so one solver is kept per
time limit. ``pytracik`` reads the limits of a joint that has a ``<safety_controller>`` as
``[0, 0]``; such limits are replaced by the URDF's (``set_joint_limits``, as optik and Pinocchio
read them), so that every solver searches the same box.

KDL's URDF parser prints "The root link ... has an inertia specified in the URDF, but KDL does
not support a root link with an inertia" with C ``printf`` for every solver constructed from a
URDF whose root link has an ``<inertial>`` (the Panda's, TALOS's): `kdl_quiet` catches the
process's standard output at the file-descriptor level around the constructor, drops that
message and writes back whatever else was printed meanwhile.
"""

from __future__ import annotations

import ctypes
import os
import re
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from optik.harness.peers.base import Peer
from optik.harness.peers.rules import twist_epsilon
from optik.solvers import Tolerances

KDL_ROOT_INERTIA = re.compile(
    r"The root link \S+ has an inertia specified in the URDF, but KDL does not support"
)
"""KDL's message about a root link with an inertia (its ``%s`` is printed unformatted)."""

_FD_LOCK = threading.Lock()


@contextmanager
def kdl_quiet() -> Iterator[None]:
    """Standard output (file descriptor 1) into a temporary file while the block runs, then
    restored; the captured text goes back to ``sys.stdout`` without KDL's root-inertia lines
    (`KDL_ROOT_INERTIA`). C's buffers are flushed on both sides (``fflush(NULL)``), so nothing
    printed before or inside the block is lost or reordered."""
    libc = ctypes.CDLL(None)
    with _FD_LOCK, tempfile.TemporaryFile() as tmp:
        sys.stdout.flush()
        libc.fflush(None)
        saved = os.dup(1)
        os.dup2(tmp.fileno(), 1)
        try:
            yield
        finally:
            sys.stdout.flush()
            libc.fflush(None)
            os.dup2(saved, 1)
            os.close(saved)
        tmp.seek(0)
        text = tmp.read().decode("utf-8", errors="replace")
    kept = [line for line in text.splitlines(keepends=True) if not KDL_ROOT_INERTIA.search(line)]
    if kept:
        sys.stdout.write("".join(kept))
        sys.stdout.flush()


class TracIK(Peer):
    """TRAC-IK through the ``pytracik`` bindings (solve type ``Speed``)."""

    name = "trac_ik"
    package = "pytracik"

    def load(self) -> int:
        self._xml = self.urdf.read_text(encoding="utf-8")
        self._solvers: dict[tuple[float, float], Any] = {}
        return self.lib.get_num_joints(self._solver(0.01, 1e-6))

    def _solver(self, time_limit: float, eps: float) -> Any:
        key = (time_limit, eps)
        if key not in self._solvers:
            lib, m = self.lib, self.mechanism
            with kdl_quiet():
                solver = lib.TRAC_IK(
                    self.base_link, self.tip_link, self._xml, time_limit, eps, lib.SolveType.Speed
                )
            if lib.get_num_joints(solver) == m.n_q:
                lo = np.asarray(lib.get_joint_lower_bounds(solver), dtype=float)
                hi = np.asarray(lib.get_joint_upper_bounds(solver), dtype=float)
                finite = np.isfinite(m.lower) & np.isfinite(m.upper)
                gap = np.abs(np.where(finite, m.lower - lo, 0)) + np.abs(np.where(finite, m.upper - hi, 0))
                if np.any(gap > 1e-6):
                    lib.set_joint_limits(solver, np.where(finite, m.lower, lo), np.where(finite, m.upper, hi))
            self._solvers[key] = solver
        return self._solvers[key]

    def fk(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(self.lib.fk(self._solver(0.01, 1e-6), np.asarray(q, dtype=float)))

    def attempt(
        self, q0: np.ndarray, target: np.ndarray, time_limit: float, tol: Tolerances
    ) -> tuple[np.ndarray, bool]:
        solver = self._solver(time_limit, twist_epsilon(tol))
        qx, qy, qz, qw = Rotation.from_matrix(target[:3, :3]).as_quat()
        x, y, z = target[:3, 3]
        q0 = np.asarray(q0, dtype=float)
        out = np.asarray(self.lib.ik(solver, q0, x, y, z, qx, qy, qz, qw))
        return (out[1:], True) if out[0] > 0 else (q0, False)
