"""Joint velocity limits."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_vector
from optik.diffik.base import BIG, Limit
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism


class VelocityLimit(Limit):
    """``|v_i| <= v_max_i``, i.e. ``-v_max dt <= dq <= v_max dt``.

    Args:
        v_max: maximum speed per coordinate (scalar or ``n_q`` values, ``> 0``; ``inf`` allowed).
    """

    rank = 0

    def __init__(self, v_max: Any) -> None:
        v = np.asarray(v_max, dtype=float).reshape(-1)
        if v.size == 0 or np.any(np.isnan(v)) or np.any(v <= 0):
            raise InvalidArgumentError("v_max", f"speeds must be > 0, got {v}")
        self.v_max = v
        self._cached: tuple[Mechanism, np.ndarray] | None = None

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
        if self._cached is not None and self._cached[0] is m:
            return self._cached[1]
        v = np.broadcast_to(self.v_max, (m.n_q,)) if self.v_max.size == 1 else self.v_max
        if v.shape[0] != m.n_q:
            raise InvalidArgumentError("v_max", f"expected {m.n_q} values, got {v.shape[0]}")
        self._cached = (m, as_vector(np.minimum(v, BIG), "v_max", m.n_q))
        return self._cached[1]

    def bounds(self, m: Mechanism, q: ca.SX, p: ca.SX, dt: ca.SX, v_prev: ca.SX) -> tuple[ca.SX, ca.SX]:
        return -p * dt, p * dt
