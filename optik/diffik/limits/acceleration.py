"""Joint acceleration limits (need the previous velocity)."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from optik.diffik.base import Limit, per_coordinate, rate_limits
from optik.mechanism import Mechanism


class AccelerationLimit(Limit):
    """``|v - v_prev| <= a_max dt``, i.e. ``(v_prev - a_max dt) dt <= dq <= (v_prev + a_max dt) dt``.

    ``v_prev`` is the previous step's velocity (``step(..., v_prev=...)``; zero when not given,
    [`optik.diffik.track`][optik.diffik.track] passes it). This limit ranks after the position limits: when
    braking within ``a_max`` cannot stop a joint before its position limit, the position limit
    wins (see [`Limit`][optik.diffik.Limit]).

    Args:
        a_max: maximum acceleration per coordinate (scalar or ``n_q`` values, ``> 0``).
    """

    rank = 2

    def __init__(self, a_max: Any) -> None:
        self.a_max = rate_limits(a_max, "a_max", "accelerations")

    def key(self) -> tuple:
        return ("acceleration",)

    def parameters(self, m: Mechanism) -> np.ndarray:
        return self._parameters_of(m, lambda: per_coordinate(self.a_max, "a_max", m))

    def bounds(self, m: Mechanism, q: ca.SX, p: ca.SX, dt: ca.SX, v_prev: ca.SX) -> tuple[ca.SX, ca.SX]:
        return (v_prev - p * dt) * dt, (v_prev + p * dt) * dt
