"""Joint position limits as a bound on the step."""

from __future__ import annotations

import casadi as ca
import numpy as np

from optik.checks import as_float
from optik.diffik.base import BIG, Limit
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism


class ConfigurationLimit(Limit):
    """``lower <= q + dq <= upper``, i.e. ``gain (lower - q) <= dq <= gain (upper - q)``.

    Starting outside the limits (``q_i < lower_i``) the bound on that side becomes
    ``dq_i >= lower_i - q_i > 0`` with gain 1: the step must bring the coordinate back in at once,
    and since velocity limits rank before this limit (see [`Limit`][optik.diffik.Limit]) a
    coordinate that cannot get back within one step moves towards the limits at full speed. The QP
    therefore stays feasible and the motion returns inside the limits.

    Args:
        gain: fraction of the distance to a limit that one step may cover, in ``(0, 1]``
            (Pink uses 0.5; 1 lets a task reach a target that lies on a limit).
    """

    rank = 1

    def __init__(self, gain: float = 1.0) -> None:
        g = as_float(gain, "gain", 0.0, strict=True)
        if g > 1:
            raise InvalidArgumentError("gain", f"must be in (0, 1], got {gain}")
        self.gain = g

    def key(self) -> tuple:
        return ("configuration",)

    def parameters(self, m: Mechanism) -> np.ndarray:
        return self._parameters_of(
            m, lambda: np.concatenate([np.clip(m.lower, -BIG, BIG), np.clip(m.upper, -BIG, BIG), [self.gain]])
        )

    def bounds(self, m: Mechanism, q: ca.SX, p: ca.SX, dt: ca.SX, v_prev: ca.SX) -> tuple[ca.SX, ca.SX]:
        n = m.n_q
        lo, hi, g = p[:n], p[n : 2 * n], p[2 * n]
        lb = ca.if_else(q < lo, lo - q, g * (lo - q))
        ub = ca.if_else(q > hi, hi - q, g * (hi - q))
        return lb, ub
