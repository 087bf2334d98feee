"""Joint-limit avoidance task."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from optik.checks import MAX_COORDINATES, as_int
from optik.diffik.base import Task
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism


class JointLimitTask(Task):
    """Keep away from the joint limits: ``e_i = s_i^k``, ``s_i = (q_i - m_i) / h_i``.

    ``m_i`` is the mid-limit and ``h_i`` the half range of coordinate ``i`` (coordinates with an
    infinite limit get ``e_i = 0``). With the odd exponent ``k`` the error is negligible in the
    middle of the range and grows steeply near a limit, so as a low-cost (or low-priority) task it
    pushes only the joints that come close to a limit. ``J = diag(k s_i^(k-1) / h_i)``.

    Args:
        n_q: number of coordinates of the mechanism it will be used with.
        cost: weight per coordinate (scalar or ``n_q`` values).
        exponent: odd integer ``k >= 1`` (``k = 1`` is a posture task to mid-limit, normalised).
        gain, lm_damping, priority: see [`Task`][optik.diffik.Task].
    """

    def __init__(
        self,
        n_q: int,
        cost: Any = 1e-2,
        exponent: int = 3,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        priority: int = 0,
    ) -> None:
        k = as_int(exponent, "exponent", 1)
        if k % 2 == 0:
            raise InvalidArgumentError("exponent", f"must be an odd integer >= 1, got {exponent!r}")
        self.dim = as_int(n_q, "n_q", 1, MAX_COORDINATES)
        self.exponent = k
        super().__init__(cost, gain, lm_damping, priority)

    def key(self) -> tuple:
        return ("joint_limit", self.dim, self.exponent)

    def parameters(self, m: Mechanism) -> np.ndarray:
        self._check_coordinates(m)
        finite = np.isfinite(m.lower) & np.isfinite(m.upper) & (m.upper > m.lower)
        mid = np.where(finite, 0.5 * (m.lower + m.upper), 0.0)
        inv_half = np.where(finite, 2.0 / np.where(finite, m.upper - m.lower, 1.0), 0.0)
        return np.concatenate([mid, inv_half])

    def expressions(self, m: Mechanism, q: ca.SX, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        n, k = m.n_q, self.exponent
        s = (q - p[:n]) * p[n:]
        return s**k, ca.diag(k * s ** (k - 1) * p[n:])
