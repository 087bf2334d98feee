"""The compiled chunk kernel of method ``"lm"``: whole multi-start solves of many targets in C.

One LM iteration (`lm_iteration_function`, the algorithm of `optik.solvers.lm`) and
the success check's errors (`optik.solvers.evaluation.error_function`) are generated as C
by CasADi and compiled together with optik's driver ``lm_chunk.c``, which runs, for each target
of a chunk, the whole multi-start loop: iterations, stop test, stall test, restarts and the time
limit, checked after every iteration. Python calls the driver once per chunk through ``ctypes``,
which releases the GIL, so threads solve chunks on every core (`optik.batch`) and
`optik.solve_ik` runs a chunk of one target: both give the same answer for the same seed.

Restarts are drawn from a splitmix64 stream seeded with the target's seed:
``u = (x >> 11) 2^-53`` in ``[0, 1)`` and ``q_j = lo_j + (hi_j - lo_j) u`` per coordinate, over the
mechanism's ``sampling_bounds`` (its limits where finite).
`target_seeds` derives the seed of target ``i`` of a batch from the batch seed: the
``(i + 1)``-th output of splitmix64 started at that seed, shifted right by one bit. Without a C
compiler (or with ``compile=False``) `LMKernel.run` runs the same loop in Python over
CasADi's evaluator, with the same generator (same answers, slower).
"""

from __future__ import annotations

import ctypes
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import ORTHO_DIAG, ORTHO_OFF
from optik.errors import InvalidArgumentError, ShapeError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.native import NativeFunction, driver_source, library
from optik.problem import IKProblem, build_ik_problem
from optik.solvers.base import wrap_bands
from optik.solvers.evaluation import error_function

DRIVER = Path(__file__).with_name("lm_chunk.c")
"""optik's C driver of the chunk loop."""

STATUS = {0: "converged", 1: "time_limit", 2: "max_restarts"}
"""Kernel status codes: stop thresholds met, time limit, restart cap."""

MU_MIN, MU_MAX = 1e-12, 1e8
"""Bounds of the LM damping."""

_GOLDEN = 0x9E3779B97F4A7C15
_MIX1, _MIX2 = 0xBF58476D1CE4E5B9, 0x94D049BB133111EB
_MASK = (1 << 64) - 1
_STEP, _ERRORS = "optik_lm_step", "optik_ik_errors"


def lm_iteration_function(
    problem: IKProblem, closure_weight: float, inequalities: ca.SX | None = None
) -> ca.Function:
    """One bounded LM iteration with the errors of the trial point, as an ``SX`` function.

    ``(q, mu, target, weights, q_ref, gain, lo, hi) -> (q+, mu+, cost+, accepted, position error,
    orientation error, closure error)``: the step of `optik.solvers.lm` from ``q``, the
    projected trial point ``q_t = clip(q + dq, lo, hi)``, accepted when its cost
    ``|e(q_t)|^2 / 2`` is below that of ``q``; the errors are those of ``q_t`` (the driver keeps
    the previous ones when the trial is rejected). The limits ``lo, hi`` are inputs (infinite
    entries: unbounded), so one compiled kernel serves every limits of one geometry. ``problem``
    may be any object with the attributes and methods of `IKProblem` that are read here
    (`optik.solvers.generic_chain.ChainProblem`: a chain whose geometry is in the target).

    ``inequalities``: rows ``g(q) <= 0`` whose hinges ``max(0, g)`` are the last ``k`` rows of
    ``problem.closure`` (static balance, `optik.solvers.balance`). A hinge has no gradient
    where it is inactive, so a plain Gauss-Newton step from inside overshoots across the
    boundary and is rejected again and again while ``mu`` grows. The step is therefore taken
    twice, for a working set ``A`` of rows treated as the equations ``w_c g_i = 0`` (their
    linearization, onto the boundary): first ``A_1 = {i : g_i > 0}`` (the hinges' own
    Gauss-Newton step), then ``A_2 = A_1 + {i : g_i + J_g,i dq_1 > 0}`` (the rows the first step
    would cross), the step taken. With ``M_0 = D J_t^T J_t D + mu I + (I - D)`` of the other rows
    ``J_t`` (free set ``D`` from the whole gradient), ``U = D J_g^T``, ``S = w_c^2 diag(A)`` and
    ``r_0`` the other rows' right-hand side, the step of a working set solves
    ``(M_0 + U S U^T) dq = r_0 - U S g``; by the Woodbury identity, with
    ``M_0 [X_0, Y] = [r_0, U]`` solved once (``M_0`` keeps the other rows' sparsity: the balance
    rows couple every joint) and ``B = X_0 - Y S g``,
    ``dq = B - Y S (I + U^T Y S)^-1 U^T B``: a ``k x k`` solve per working set.
    """
    q = problem.q
    n = int(q.shape[0])
    lo, hi = ca.SX.sym("lower", n), ca.SX.sym("upper", n)
    e = problem.weighted_residual(closure_weight if problem.closure.shape[0] else None)
    at = ca.Function("at", [q, problem.target, problem.weights], [e, *problem.error_expressions()])
    mu, gain = ca.SX.sym("mu"), ca.SX.sym("gain")
    jac = ca.jacobian(e, q)
    grad = ca.mtimes(jac.T, e)
    free = 1 - ca.logic_or(ca.logic_and(q <= lo, grad > 0), ca.logic_and(q >= hi, grad < 0))
    k = 0 if inequalities is None else int(inequalities.shape[0])
    top = e.shape[0] - k  # the rows other than the hinges
    jt = jac[:top, :]
    cols = [jt[:, j] for j in range(n)]
    diag = [mu + 1 - free[i] for i in range(n)]
    lhs = [  # the lower triangle of D J_t^T J_t D + mu I + (I - D), row by row
        [free[i] * free[j] * ca.dot(cols[i], cols[j]) + (diag[i] if i == j else 0) for j in range(i + 1)]
        for i in range(n)
    ]
    rhs = free * (-(ca.mtimes(jt.T, e[:top]) if k else grad) + gain * mu * (problem.q_ref - q))
    if not k:
        dq = _cholesky_solve(lhs, rhs)
    else:
        g = inequalities
        u = ca.mtimes(ca.diag(free), ca.jacobian(g, q).T)  # D J_g^T
        xy = _cholesky_solve(lhs, ca.horzcat(rhs, u))
        x0, y = xy[:, 0], xy[:, 1:]

        def working_step(active: ca.SX) -> ca.SX:
            s = ca.diag(closure_weight**2 * active)
            b = x0 - ca.mtimes([y, s, g])
            small = ca.SX.eye(k) + ca.mtimes([u.T, y, s])
            return b - ca.mtimes([y, s, ca.solve(small, ca.mtimes(u.T, b))])

        violated = g > 0
        dq1 = working_step(violated)
        dq = working_step(ca.logic_or(violated, g + ca.mtimes(u.T, dq1) > 0))
    q_trial = ca.fmin(ca.fmax(q + dq, lo), hi)
    e_trial, pos, ori, clo = at(q_trial, problem.target, problem.weights)
    outs = accept_or_keep(q, q_trial, mu, e, e_trial, [pos, ori, clo])
    ins = [q, mu, problem.target, problem.weights, problem.q_ref, gain, lo, hi]
    # common subexpressions merged (the same operations, so the same values): 5 % fewer instructions
    return ca.Function(_STEP, ins, ca.cse([ca.densify(v) for v in outs]))


def accept_or_keep(
    q: ca.SX, q_trial: ca.SX, mu: ca.SX, e: ca.SX, e_trial: ca.SX, errors: list[ca.SX]
) -> list[ca.SX]:
    """The outputs of one LM iteration, ``[q', mu', cost', accepted, *errors]``: the trial point
    is taken when it lowers the cost ``|e|^2 / 2`` (``cost_trial < cost``; then ``mu' =
    max(mu / 3, MU_MIN)``), else ``q`` is kept (``mu' = min(4 mu, MU_MAX)``); ``cost'`` is the
    cost at ``q'``; ``errors`` are the trial point's (the driver's stop test reads them)."""
    cost, cost_trial = 0.5 * ca.sumsqr(e), 0.5 * ca.sumsqr(e_trial)
    accept = cost_trial < cost
    return [
        ca.if_else(accept, q_trial, q),
        ca.if_else(accept, ca.fmax(mu / 3, MU_MIN), ca.fmin(mu * 4, MU_MAX)),
        ca.if_else(accept, cost_trial, cost),
        accept,
        *errors,
    ]


def conf_length(n_q: int) -> int:
    """Length of `Settings.conf` for ``n_q`` coordinates: 12 scalars, then per coordinate the
    sampling bounds, ``q_ref``, the limits and the bands of `optik.solvers.base.wrap_bands`."""
    return 12 + 7 * n_q


def driver_defines(n_q: int, n_target: int, sz_arg: int = 8, sz_res: int = 7) -> str:
    """The C definitions ``lm_chunk.c`` is compiled with (after the generated functions
    `lm_iteration_function` and `optik.solvers.evaluation.error_function`): ``n_q`` coordinates,
    ``n_target`` target parameters per target, and the length of the argument and result
    pointer arrays (the functions' ``sz_arg()`` and ``sz_res()``, at least 8 and 7: a function
    that calls others uses the entries past its own as scratch)."""
    return (
        f"\n#define OPTIK_SZ_ARG {max(8, sz_arg)}\n#define OPTIK_SZ_RES {max(7, sz_res)}"
        f"\n#define OPTIK_NQ {n_q}\n#define OPTIK_NT {n_target}\n"
        f"#define OPTIK_STEP {_STEP}\n#define OPTIK_STEP_WORK {_STEP}_work\n"
        f"#define OPTIK_ERRORS {_ERRORS}\n#define OPTIK_ERRORS_WORK {_ERRORS}_work\n"
        f"#define OPTIK_ORTHO_DIAG {ORTHO_DIAG!r}\n#define OPTIK_ORTHO_OFF {ORTHO_OFF!r}\n"
    )


def _cholesky_solve(lower: list[list[ca.SX]], b: ca.SX) -> ca.SX:
    """``x = A^-1 b`` (``b`` a vector, or a matrix of right-hand sides on one factorization) for a
    symmetric positive definite ``A`` given by its lower triangle (``lower[i][j] = A_ij``, ``j <=
    i``), by Cholesky ``A = L L^T`` and two triangular solves: about n^3 / 6 multiply-adds and n
    square roots, where CasADi's general ``solve`` (a QR) takes several times more operations, and
    ``J^T J`` is formed on one triangle (the LM matrix, with ``mu > 0`` on its diagonal, is positive
    definite; where rounding loses definiteness the step is NaN, which the projection maps onto a
    bound or leaves NaN, and the acceptance test keeps only a trial point of lower cost either way,
    NaN comparing false)."""
    n = len(lower)
    chol: list[list[ca.SX]] = [[] for _ in range(n)]
    inv_diag: list[ca.SX] = []
    for j in range(n):
        for i in range(j, n):
            s = lower[i][j] - sum((chol[i][k] * chol[j][k] for k in range(j)), ca.SX(0))
            if i == j:
                chol[j].append(ca.sqrt(s))
                inv_diag.append(1 / chol[j][j])
            else:
                chol[i].append(s * inv_diag[j])
    y: list[ca.SX] = []
    for i in range(n):  # L y = b
        y.append((b[i, :] - sum((chol[i][k] * y[k] for k in range(i)), ca.SX(0))) * inv_diag[i])
    x: list[ca.SX] = [ca.SX(0)] * n
    for i in reversed(range(n)):  # L^T x = y
        x[i] = (y[i] - sum((chol[k][i] * x[k] for k in range(i + 1, n)), ca.SX(0))) * inv_diag[i]
    return ca.vertcat(*x)


def target_seeds(seed: int, start: int, count: int) -> np.ndarray:
    """Seeds of targets ``start .. start + count - 1`` of a batch seeded with ``seed`` (uint64,
    each below 2^63): splitmix64 outputs ``start + 1 ..`` of the stream started at ``seed``."""
    index = np.arange(start + 1, start + count + 1, dtype=np.uint64)
    z = np.uint64(seed & _MASK) + np.uint64(_GOLDEN) * index
    z = (z ^ (z >> np.uint64(30))) * np.uint64(_MIX1)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(_MIX2)
    return (z ^ (z >> np.uint64(31))) >> np.uint64(1)


@dataclass(frozen=True)
class Settings:
    """The kernel's options (see `optik.solvers.lm`), one set for every target of a call.

    Attributes:
        block: iterations per stall test.
        max_iter: iterations per start.
        max_restarts: restart cap (-1: none).
        time_limit: seconds per target.
        mu0: initial damping.
        stall: a start stops when a block ends above ``stall`` times the previous block's cost.
        stop: position, orientation and closure errors below which a target is done.
        gain: null-space posture gain.
        weights: task weights ``(w_p, w_o)``.
        q_ref: posture reference.
    """

    block: int
    max_iter: int
    max_restarts: int
    time_limit: float
    mu0: float
    stall: float
    stop: tuple[float, float, float]
    gain: float
    weights: tuple[float, float]
    q_ref: np.ndarray

    def conf(self, m: Mechanism) -> np.ndarray:
        """The driver's ``conf`` vector (layout in ``lm_chunk.c``): the scalars, the sampling
        bounds, ``q_ref``, the limits of ``m`` that the steps project onto and the open bands
        ``(a, b)`` of `optik.solvers.base.wrap_bands`, within which an answer is its own wrap (the
        canonical test of ``optik_lm_call``)."""
        scalars = [self.block, self.max_iter, self.max_restarts, self.time_limit, self.mu0, self.stall]
        scalars += [*self.stop, self.gain, *self.weights]
        lo, hi = m.sampling_bounds  # restarts are drawn over finite bounds (one turn when unbounded)
        _, _, a, b = wrap_bands(m)
        return np.concatenate([scalars, lo, hi, self.q_ref, m.lower, m.upper, a, b]).astype(float)


@dataclass
class Output:
    """Per-target outputs of a kernel run (``N`` targets, ``n`` coordinates).

    Attributes:
        q: answers ``(N, n)``: the converged start, else the lowest-cost point seen.
        errors: position, orientation and closure errors of ``q`` ``(N, 3)``.
        iterations: LM iterations summed over the starts.
        restarts: starts after the first.
        status: codes of `STATUS`.
        solve_time: seconds per target, measured in the kernel.
    """

    q: np.ndarray
    errors: np.ndarray
    iterations: np.ndarray
    restarts: np.ndarray
    status: np.ndarray
    solve_time: np.ndarray


_P = ctypes.c_void_p


class OneTarget:
    """One thread's buffers of a one-target run, and the packed argument arrays of the driver's
    ``optik_lm_packed``, ``optik_lm_call`` and ``optik_lm_call_checked`` pointing at them (the
    addresses are taken once: reading ``ndarray.ctypes.data`` costs microseconds per array, more
    than a whole solve's iterations)."""

    def __init__(self, nq: int, nt: int, n_conf: int) -> None:
        self.target, self.q0, self.conf = np.zeros(nt), np.zeros(nq), np.zeros(n_conf)
        self.seed = np.zeros(1, dtype=np.uint64)
        self.q, self.errors, self.time = np.zeros(nq), np.zeros(3), np.zeros(1)
        self.counts = np.zeros(4, dtype=np.int64)  # iterations, restarts, status, canonical
        self.transform = np.zeros((4, 4))
        c = self.counts.ctypes.data
        bufs = (self.target, self.q0, self.seed, self.conf, self.q, self.errors)
        self.args = (_P * 11)(1, *[b.ctypes.data for b in bufs], c, c + 8, c + 16, self.time.ctypes.data)
        bufs = (self.transform, self.q0, self.seed, self.conf, self.q, self.errors, self.counts, self.time)
        self.call_args = (_P * 8)(*[b.ctypes.data for b in bufs])
        """The argument array of ``optik_lm_call`` (a 4x4 transform in place of the parameters)."""
        self.tol = np.zeros(3)
        self.checked_args = (_P * 10)(*self.call_args, self.tol.ctypes.data, None)
        """The argument array of ``optik_lm_call_checked``: ``call_args``, the tolerances `tol`
        and, set per call, the address of the check's block (``lm_chunk.c``)."""


class LMKernel:
    """The chunk kernel of one mechanism, task, frame and closure weight (thread-safe).

    Args:
        m: the mechanism.
        task: task space.
        frame: task frame (None: end effector).
        closure_weight: weight of the loop-closure rows.
        compile: as in `optik.native.library` (False: the Python loop; ``"auto"``: the
            Python loop until the library built in the background is loaded).
        problem: the problem to solve (default: `optik.problem.build_ik_problem` of ``m``,
            ``task``, ``frame``); its ``closure`` rows are the weighted rows of the residual and
            the closure error of the stop test.
        inequalities: rows ``g(q) <= 0`` whose hinges end ``problem.closure`` (see
            `lm_iteration_function`).
        functions: the step and error functions themselves, with the signatures of
            `lm_iteration_function` and `optik.solvers.evaluation.error_function` (named
            ``optik_lm_step`` and ``optik_ik_errors``; default: those of ``problem``): the
            collision-aware kernel builds its own (`optik.solvers.collision_kernel`).
    """

    def __init__(
        self,
        m: Mechanism,
        task: str,
        frame: str | None,
        closure_weight: float,
        compile: bool | str,
        problem: IKProblem | None = None,
        inequalities: ca.SX | None = None,
        functions: tuple[ca.Function, ca.Function] | None = None,
    ) -> None:
        if functions is None:
            problem = build_ik_problem(m, task, frame) if problem is None else problem
            functions = lm_iteration_function(problem, closure_weight, inequalities), error_function(problem)
        self.mechanism = m
        self.step, self.errors = functions
        self.n_target = int(self.step.size1_in(2))
        """Target parameters per target (12 per frame target)."""
        self.n_conf = conf_length(m.n_q)
        """Length of `Settings.conf` (`conf_length`)."""
        driver = driver_source(DRIVER, compile)
        sizes = max(self.step.sz_arg(), self.errors.sz_arg()), max(self.step.sz_res(), self.errors.sz_res())
        self.library = (
            None
            if driver is None
            else library(
                [self.step, self.errors], compile, driver_defines(m.n_q, self.n_target, *sizes) + driver
            )
        )
        self._fn: Any = None
        self._packed: Any = None
        self._call: Any = None
        self._checked: Any = None
        self._local = threading.local()  # per-thread error evaluators and one-target buffers

    def final_errors(self, q: np.ndarray, target: np.ndarray) -> tuple[float, float, float]:
        """Position, orientation and closure errors of ``q`` against target parameters
        ``target`` (12,), by the kernel's own error function (compiled once the driver is):
        the check of answers changed after the kernel (wrapped into canonical angles)."""
        fn = getattr(self._local, "errors", None)
        if fn is None:
            fn = self._local.errors = NativeFunction(self.errors, self.library)
        fn.inputs[0][:] = q
        fn.inputs[1][:] = target
        pos, ori, clo = fn()
        return float(pos[0]), float(ori[0]), float(clo[0])

    @property
    def compiled(self) -> bool:
        """True when `run` calls the compiled driver (False while it is being built)."""
        return self._driver() is not None

    def _driver(self) -> Any:
        """The driver's entry point once the library is loaded, else None."""
        if self._fn is None and self.library is not None:
            lib = self.library.get()
            if lib is not None:
                fn = lib.optik_lm_chunk
                fn.argtypes = [ctypes.c_longlong] + [_P] * 10
                fn.restype = ctypes.c_int
                self._fn = fn
        return self._fn

    def call_entry(self) -> Any:
        """The driver's ``optik_lm_call`` (one whole ``solve_ik`` call: `optik.solvers.lm.LMCall`)
        once the library is loaded, else None (it is never waited for)."""
        call = self._call
        if call is None and self.library is not None and self.library.state == "ready" and self._driver():
            call = self.library.get().optik_lm_call  # type: ignore[union-attr]
            call.argtypes, call.restype = [_P], ctypes.c_int
            self._call = call
        return call

    def checked_entry(self) -> Any:
        """The driver's ``optik_lm_call_checked`` (`call_entry` and a check of its answer in the
        same call) once the library is loaded, else None."""
        call = self._checked
        if call is None and self.call_entry() is not None:
            call = self.library.get().optik_lm_call_checked  # type: ignore[union-attr]
            call.argtypes, call.restype = [_P], ctypes.c_int
            self._checked = call
        return call

    def run_one(
        self, target: np.ndarray, q0: np.ndarray, seed: int, conf: np.ndarray
    ) -> tuple[np.ndarray, tuple[float, float, float], int, int, int]:
        """`run` for one target with the least per-call work (the path of `optik.solve_ik`):
        the same driver on this thread's preallocated buffers, through one packed argument.

        Args:
            target: target parameters ``(12,)`` (``(12 k,)`` for ``k`` frame targets).
            q0: the first start ``(n,)``.
            seed: the restart seed (below 2^64).
            conf: `Settings.conf`.

        Returns:
            ``(q, (position, orientation, closure) errors of q, iterations, restarts, status)``.
        """
        packed = self._packed
        if packed is None and self._driver() is not None:
            packed = self._packed = self.library.get().optik_lm_packed  # type: ignore[union-attr]
            packed.argtypes, packed.restype = [_P], ctypes.c_int
        if packed is None:
            seeds = np.array([seed], dtype=np.uint64)
            out = self.run(target[None], q0[None], seeds, conf)
            e = out.errors[0].tolist()
            counts = int(out.iterations[0]), int(out.restarts[0]), int(out.status[0])
            return out.q[0], (e[0], e[1], e[2]), *counts
        one = getattr(self._local, "one", None)
        if one is None:
            one = self._local.one = OneTarget(self.mechanism.n_q, len(target), len(conf))
        one.target[:] = target
        one.q0[:] = q0
        one.seed[0] = seed
        one.conf[:] = conf
        if packed(one.args) != 0:
            raise SolverUnavailableError("optik_lm_chunk: evaluation of the generated code failed")
        e = one.errors.tolist()
        it, restarts, status, _ = one.counts.tolist()
        return one.q.copy(), (e[0], e[1], e[2]), it, restarts, status

    def run(self, targets: np.ndarray, q0: np.ndarray, seeds: np.ndarray, conf: np.ndarray) -> Output:
        """Solve ``N`` targets.

        Args:
            targets: target parameters ``(N, 12)``, ``(N, 12 k)`` for ``k`` frame targets each
                (`optik.problem.target_parameters`).
            q0: first start of each target ``(N, n)``.
            seeds: restart seeds (uint64, ``(N,)``).
            conf: `Settings.conf`.
        """
        n, nq = self._check_run(targets, q0, seeds, conf)
        out = Output(
            np.empty((n, nq)),
            np.empty((n, 3)),
            np.empty(n, dtype=np.int64),
            np.empty(n, dtype=np.int64),
            np.empty(n, dtype=np.int64),
            np.empty(n),
        )
        fn = self._driver()
        if fn is None:
            start = time.perf_counter()
            self._run_python(targets, q0, seeds, conf, out)
            if self.library is not None:  # still building: account the time (see optik.native)
                self.library.evaluated(time.perf_counter() - start)
            return out
        pairs = ((targets, float), (q0, float), (seeds, np.uint64))
        ins = [np.ascontiguousarray(a, dtype=t) for a, t in pairs]
        conf = np.ascontiguousarray(conf, dtype=float)
        bufs = [*ins, conf, out.q, out.errors, out.iterations, out.restarts, out.status, out.solve_time]
        if fn(n, *[b.ctypes.data for b in bufs]) != 0:
            raise SolverUnavailableError("optik_lm_chunk: evaluation of the generated code failed")
        return out

    def _check_run(self, targets: Any, q0: Any, seeds: Any, conf: Any) -> tuple[int, int]:
        """``(N, n)`` once the arrays that `run` hands to C are checked (shapes and kinds; the
        driver reads and writes by these sizes, so a wrong array would be read out of bounds).

        Raises:
            ShapeError: an array of another shape than ``targets (N, n_target)``, ``q0 (N, n)``,
                ``seeds (N,)``, ``conf (n_conf,)``.
            InvalidArgumentError: ``seeds`` not of unsigned or non-negative integers, or another
                array not of real numbers.
        """
        nq = self.mechanism.n_q
        n = np.shape(targets)[0] if np.ndim(targets) == 2 else -1
        expected = (
            ("targets", targets, (n, self.n_target), "biuf"),
            ("q0", q0, (n, nq), "biuf"),
            ("seeds", seeds, (n,), "ui"),
            ("conf", conf, (self.n_conf,), "biuf"),
        )
        for name, value, shape, kinds in expected:
            arr = np.asarray(value)
            if arr.shape != shape or n < 0:
                want = f"(N, {self.n_target})" if name == "targets" else str(shape)
                raise ShapeError(name, f"expected shape {want}, got {arr.shape}")
            negative = arr.dtype.kind == "i" and name == "seeds" and bool((arr < 0).any())
            if arr.dtype.kind not in kinds or negative:
                what = "integers >= 0" if name == "seeds" else "real numbers"
                raise InvalidArgumentError(name, f"expected {what}, got {arr.dtype} {arr.ravel()[:3]}")
        return n, nq

    def _run_python(
        self, targets: np.ndarray, q0: np.ndarray, seeds: np.ndarray, conf: np.ndarray, out: Output
    ) -> None:
        """The loop of ``lm_chunk.c`` in Python over CasADi's evaluator (no compiler)."""
        nq = self.mechanism.n_q
        step, errors = NativeFunction(self.step), NativeFunction(self.errors)
        block, max_iter, max_restarts = int(conf[0]), int(conf[1]), int(conf[2])
        time_limit, mu0, stall = conf[3], conf[4], conf[5]
        stop = conf[6:9]
        lo, hi = conf[12 : 12 + nq], conf[12 + nq : 12 + 2 * nq]
        step.inputs[3][:] = conf[10:12]
        step.inputs[4][:] = conf[12 + 2 * nq : 12 + 3 * nq]
        step.inputs[5][0] = conf[9]
        step.inputs[6][:] = conf[12 + 3 * nq : 12 + 4 * nq]
        step.inputs[7][:] = conf[12 + 4 * nq : 12 + 5 * nq]

        def check(q: np.ndarray, target: np.ndarray) -> np.ndarray:
            errors.inputs[0][:] = q
            errors.inputs[1][:] = target
            return np.array([float(v[0]) for v in errors()])

        for t, target in enumerate(targets):
            t0 = time.perf_counter()
            deadline = t0 + time_limit
            state = int(seeds[t])
            step.inputs[2][:] = target
            best, best_cost = q0[t].copy(), np.inf
            iterations, restarts, status, answer = 0, -1, 0, None
            while answer is None:
                restarts += 1
                if restarts == 0:
                    q = q0[t].copy()
                else:
                    u = np.empty(nq)
                    for j in range(nq):
                        state = (state + _GOLDEN) & _MASK
                        z = ((state ^ (state >> 30)) * _MIX1) & _MASK
                        z = ((z ^ (z >> 27)) * _MIX2) & _MASK
                        u[j] = ((z ^ (z >> 31)) >> 11) * 2.0**-53
                    q = lo + (hi - lo) * u
                err = check(q, target)
                if (err <= stop).all():
                    answer = q
                    break
                mu, previous, out_of_time = mu0, np.inf, False
                for k in range(1, max_iter + 1):
                    step.inputs[0][:] = q
                    step.inputs[1][0] = mu
                    q_new, mu_new, cost, accept, *trial = step()
                    iterations += 1
                    q, mu, c = q_new.copy(), float(mu_new[0]), float(cost[0])
                    if accept[0] != 0.0:
                        err = np.array([float(v[0]) for v in trial])
                    if c < best_cost:
                        best, best_cost = q.copy(), c
                    if (err <= stop).all():
                        answer = q
                        break
                    if time.perf_counter() >= deadline:
                        out_of_time = True
                        break
                    if k % block == 0:
                        if c > stall * previous:
                            break
                        previous = c
                if answer is not None:
                    break
                if out_of_time or time.perf_counter() >= deadline:
                    status, answer = 1, best
                elif 0 <= max_restarts <= restarts:
                    status, answer = 2, best
            out.q[t] = answer
            out.errors[t] = check(answer, target)
            out.iterations[t], out.restarts[t], out.status[t] = iterations, restarts, status
            out.solve_time[t] = time.perf_counter() - t0


_KERNELS: PerMechanism[dict[tuple, LMKernel]] = PerMechanism()


def cached_kernel(
    m: Mechanism, task: str, frame: str | None, closure_weight: float, compile: bool | str
) -> LMKernel | None:
    """The `kernel` of these arguments when it was built already, else None (builds nothing)."""
    per = _KERNELS.get(m.geometry)
    return None if per is None else per.get((task, frame, closure_weight, compile))


def kernel(
    m: Mechanism, task: str, frame: str | None, closure_weight: float, compile: bool | str
) -> LMKernel:
    """The `LMKernel` of a mechanism, task, frame and closure weight (built once per
    [`Mechanism.geometry`][optik.Mechanism.geometry]: copies that differ only by their limits
    share it, the limits being inputs of `Settings.conf`; it lives as long as that geometry)."""
    g = m.geometry
    per = _KERNELS.setdefault(g, {})
    key = (task, frame, closure_weight, compile)
    found = per.get(key)
    if found is None:
        found = per.setdefault(key, LMKernel(g, task, frame, closure_weight, compile))
    return found
