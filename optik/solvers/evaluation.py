"""Compiled evaluation of the success check (position, orientation and closure errors).

[`optik.solvers.base.evaluate`][optik.solvers.base.evaluate] computes the errors through CasADi's Python
interface (about 0.1 ms per call); the methods that iterate in compiled code call this compiled twin of the
same definitions ([`optik.problem.IKProblem.error_expressions`][optik.problem.IKProblem.error_expressions])
instead, both to stop their iterations and to check their final answer in
[`make_result`][optik.solvers.base.make_result].
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import casadi as ca
import numpy as np

from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.native import NativeFunction, native_functions
from optik.problem import IKProblem, build_ik_problem, target_parameters

ErrorFn = Callable[[np.ndarray], tuple[float, float, float]]
"""``q -> (position error, orientation error, closure error)``."""


def error_function(problem: IKProblem) -> ca.Function:
    """``(q, target) -> (position error, orientation error, closure error)`` of the success check
    ([`IKProblem.error_expressions`][optik.IKProblem.error_expressions]), as a CasADi function."""
    outs = [ca.densify(v) for v in problem.error_expressions()]
    return ca.Function("optik_ik_errors", [problem.q, problem.target], outs)


_ERRORS: PerMechanism[dict[tuple, tuple[NativeFunction, threading.Lock]]] = PerMechanism()


def _native_errors(
    m: Mechanism, task: str, frame: str | None, compile: bool | str
) -> tuple[NativeFunction, threading.Lock]:
    """The shared error function and the lock that serializes its buffers (built once per
    mechanism, task, frame and ``compile``; they live as long as the mechanism)."""
    per = _ERRORS.setdefault(m, {})
    key = (task, frame, compile)
    found = per.get(key)
    if found is None:
        fn = native_functions([error_function(build_ik_problem(m, task, frame))], compile)[0]
        found = per.setdefault(key, (fn, threading.Lock()))
    return found


def errors_against(
    m: Mechanism, task: str, frame: str | None, target: np.ndarray, compile: bool | str = "auto"
) -> ErrorFn:
    """A fast ``q -> (position, orientation, closure)`` error function for one target (the
    compiled function is shared per mechanism, task and frame; calls from several threads, as
    `optik.batch` makes them, take turns on its buffers)."""
    fn, lock = _native_errors(m, task, frame, compile)
    params = target_parameters(target)

    def errors(q: np.ndarray) -> tuple[float, float, float]:
        with lock:
            fn.inputs[0][:] = q
            fn.inputs[1][:] = params
            pos, ori, clo = fn()
            return float(pos[0]), float(ori[0]), float(clo[0])

    return errors
