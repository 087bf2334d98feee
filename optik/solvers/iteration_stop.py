"""`IterationStop`: an ``nlpsol`` iteration callback that asks the solver to stop at a deadline.

CasADi calls an ``iteration_callback`` after every iteration of IPOPT (its intermediate
callback) or ``sqpmethod`` with the solver's outputs (``x``, ``f``, ``g``, ``lam_x``, ``lam_g``,
``lam_p``); a nonzero answer stops the solve (IPOPT status ``User_Requested_Stop``). An
``nlpsol`` instance's options are fixed when it is built, so a per-call budget cannot be given
as IPOPT's ``max_wall_time``: the callback holds the call's `deadline` instead (a
``time.perf_counter`` value, set before each solve), which holds every start to the time limit
plus one iteration.
"""

from __future__ import annotations

import time
from typing import Any

import casadi as ca
import numpy as np

__all__ = ["IterationStop"]


class IterationStop(ca.Callback):
    """Iteration callback of one ``nlpsol`` instance (used by one solve at a time): stops the
    solver once ``time.perf_counter() >= deadline``; subclasses add their own reasons in
    `check`.

    Args:
        n_x: number of decision variables.
        n_g: number of constraints.
        n_p: number of parameters.
        name: the callback's CasADi name.
    """

    def __init__(self, n_x: int, n_g: int, n_p: int, name: str = "optik_iteration_stop") -> None:
        ca.Callback.__init__(self)
        self.n_x, self.n_g, self.n_p = n_x, n_g, n_p
        self.deadline = np.inf
        self.construct(name, {})

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "stop"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.n_x)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.n_g)
        return ca.Sparsity.dense(self.n_p)  # lam_p: the solver writes all of it

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg: list[memoryview], res: list[memoryview]) -> int:
        """The callback through CasADi's buffer protocol: the iterate as a view of the solver's
        memory, no ``DM`` conversions (half the cost of an IPOPT iteration on the Panda with
        `eval`)."""
        x = np.frombuffer(arg[0], dtype=float).copy()  # a copy: the buffer dies with the call
        np.frombuffer(res[0], dtype=float)[0] = float(self.check(x))
        return 0

    def eval(self, arg: list[Any]) -> list[int]:
        return [int(self.check(np.array(arg[0].nonzeros())))]

    def check(self, x: np.ndarray) -> bool:
        """Whether to stop the solver at the iterate ``x``: the deadline has passed."""
        return time.perf_counter() >= self.deadline
