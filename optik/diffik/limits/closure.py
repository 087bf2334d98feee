"""Loop-closure constraint of closed chains."""

from __future__ import annotations

import casadi as ca

from optik.diffik.base import positive
from optik.mechanism import Mechanism


class ClosureConstraint:
    """Keep the loops closed: ``J_c dq = -gain c(q)`` with ``J_c = dc/dq``.

    With ``gain = 1`` the step also removes the closure drift of the previous steps (a Newton
    step on ``c(q) = 0``). Added automatically by [`optik.diffik.build_qp`][optik.diffik.build_qp] for
    mechanisms with loops; an equality constraint of the QP and the top level of the DLS and priority methods.

    Args:
        gain: fraction of the residual removed per step, ``> 0``.
    """

    def __init__(self, gain: float = 1.0) -> None:
        self.gain = positive(gain, "closure_gain")

    def expressions(self, m: Mechanism, q: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Symbolic ``(c, J_c, b)`` with the right-hand side ``b = -gain c``."""
        c = m.closure_expr
        jc = ca.jacobian(c, q)
        return c, jc, -self.gain * c
