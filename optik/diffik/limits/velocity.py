"""Joint velocity limits."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from optik.diffik.base import Limit, per_coordinate, rate_limits
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism


class VelocityLimit(Limit):
    """``|v_i| <= v_max_i``, i.e. ``-v_max dt <= dq <= v_max dt``.

    Args:
        v_max: maximum speed per coordinate (scalar or ``n_q`` values, ``> 0``; ``inf`` allowed).
    """

    rank = 0

    def __init__(self, v_max: Any) -> None:
        self.v_max = rate_limits(v_max, "v_max", "speeds")

    @classmethod
    def of(cls, m: Mechanism) -> VelocityLimit:
        """The mechanism's own velocity limits (``m.params["velocity_limits"]``).

        Raises:
            InvalidArgumentError: the mechanism has none.
        """
        if "velocity_limits" not in m.params:
            raise InvalidArgumentError("m", f"{m.name!r} has no params['velocity_limits']")
        return cls(m.params["velocity_limits"])

    def key(self) -> tuple:
        return ("velocity",)

    def parameters(self, m: Mechanism) -> np.ndarray:
        return self._parameters_of(m, lambda: per_coordinate(self.v_max, "v_max", m))

    def bounds(self, m: Mechanism, q: ca.SX, p: ca.SX, dt: ca.SX, v_prev: ca.SX) -> tuple[ca.SX, ca.SX]:
        return -p * dt, p * dt
