"""``AllSolutions``: every IK solution of one target as one array, built once per mechanism.

`optik.solve_ik_all` answers with an ``optik.results.IKSolutions`` and takes every option of the
search, which a loop over many single targets pays for on every call (about 1.3 us of its
arguments and result against about 3 us of arithmetic for a UR arm). ``AllSolutions(m)`` is the
counterpart of a compiled CasADi function: it is built once (waiting for the compiled driver of
``m``'s derived closed form, `optik.closed_form.ik_all`), and a call

``ik(T, q0) -> q (K, n)``

hands the target straight to that driver's binding (``AllSolutionsKernel.rows``), which reads a
float64 ``(4, 4)`` array of any strides, validates it as `optik.checks.as_transform` does, and
returns the solutions within the joint limits, nearest ``q0`` first, as one new array: the rows of
``solve_ik_all(m, T, q0).q``, bit for bit. Everything else goes through `optik.solve_ik_all`
itself (the same answer, as an array): a target of another type or layout, an invalid target
or ``q0`` (its named error), the rare target whose candidates need the numpy path (one to
polish, two close ones, one at a limit), a mechanism without a compiled derived closed form
(another closed form or the numerical multi-start), no C compiler.

Thread-safe: the driver keeps its memory on the stack and the object holds no buffer.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.solvers.all import solve_ik_all
from optik.solvers.closed import compile_closed_form, rows_binding_of


class AllSolutions:
    """Every IK solution within the joint limits of one target, as one ``(K, n)`` array.

    ``ik = optik.AllSolutions(m)`` then ``q = ik(T)`` gives ``solve_ik_all(m, T).q`` (always of
    shape ``(K, n)``, ``K = 0`` when the target is unreachable); ``q, outside = ik(T,
    outside=True)`` also gives the solutions left out for the joint limits (``(L, n)``, what
    ``solve_ik_all(m, T).outside_limits`` lists).

    Args:
        m: the mechanism. The object answers with the closed form ``m`` has when it is made
            (a closed form registered later is not seen; make a new one).

    Raises:
        InvalidArgumentError: ``m`` is not an ``optik.Mechanism``.
    """

    __slots__ = ("_lower", "_rows", "_upper", "mechanism")

    def __init__(self, m: Mechanism) -> None:
        if not isinstance(m, Mechanism):
            raise InvalidArgumentError("m", f"expected an optik Mechanism, got {type(m).__name__}")
        compile_closed_form(m)  # a derived closed form's driver, built (or loaded) now
        self.mechanism = m
        self._lower, self._upper = m.lower, m.upper
        self._rows = rows_binding_of(m)

    @property
    def compiled(self) -> bool:
        """True when calls go to the compiled driver (False: every call is `optik.solve_ik_all`)."""
        return self._rows is not None

    def __call__(
        self, target: Any, q0: Any = None, *, outside: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """The solutions of ``target`` within the joint limits, nearest ``q0`` first.

        Args:
            target: the target (a 4x4 transform; any target `optik.solve_ik_all` takes).
            q0: the solutions are ordered by their max-norm distance to it, angles modulo
                ``2 pi`` (None: the middle of the limits, ``Mechanism.mid_q``).
            outside: also return the solutions outside the joint limits.

        Returns:
            ``q (K, n)``, a new array; with ``outside``, ``(q, q_outside (L, n))``.

        Raises:
            OptikError: malformed ``target`` or ``q0`` (the argument named), as `optik.solve_ik_all`.
        """
        if self._rows is not None:
            try:
                got = self._rows(target, q0, self._lower, self._upper, outside)
            except RuntimeError as exc:  # the generated code reported an error
                raise SolverUnavailableError(str(exc)) from None
            if got is not None and got is not False:
                return got
        sols = solve_ik_all(self.mechanism, target, q0)
        q = sols.q
        return (q, np.array(sols.outside_limits).reshape(-1, q.shape[1])) if outside else q
