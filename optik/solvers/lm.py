"""Method ``"lm"``: bounded Levenberg-Marquardt with random restarts, compiled to C.

The residual is ``e(q) = [w_p r_p; w_o r_o; w_c c(q)]``: the task residual of
[`optik.problem`][optik.problem] with the loop closures of a closed chain appended as heavily weighted rows.
One iteration at ``q`` with gradient ``g = J^T e`` and Gauss-Newton matrix ``A = J^T J``:

1. *Active set*: coordinate ``i`` is frozen when it sits on a bound and the descent direction
   ``-g_i`` points outside (``q_i = lo_i, g_i > 0`` or ``q_i = hi_i, g_i < 0``); ``D`` is the
   diagonal 0/1 matrix of the free coordinates.
2. *Step*: ``(D A D + mu I + (I - D)) dq = -D g + k mu D (q_ref - q)``, solved by Cholesky on
   the lower triangle (`optik.solvers.lm_kernel`). The last term is a
   null-space posture pull: for ``mu -> 0`` it vanishes in the range of ``J^T`` and keeps moving
   along the null space of ``J`` toward ``q_ref`` (gain ``k = posture_gain``, 0 by default).
3. *Projection and acceptance*: ``q+ = clip(q + dq, lo, hi)``; accepted when
   ``|e(q+)|^2 < |e(q)|^2``, then ``mu <- max(mu / 3, 1e-12)``, else ``mu <- min(4 mu, 1e8)``.

Each target's whole multi-start loop runs in generated C (`optik.solvers.lm_kernel`):
the tolerances and the time limit are checked after every iteration; a start is abandoned when
a block of ``block`` iterations reduces the cost by less than the factor ``stall`` or after
``max_iter`` iterations, and the next start is drawn uniformly within the limits from a
generator seeded with the request's seed (`optik.solvers.lm_kernel.target_seeds` gives
the seeds of a batch, so `optik.solve_ik_batch` answers as this method does). The answer
is the first start that meets the tolerances, or the lowest cost configuration seen when the
time limit or ``max_restarts`` ends the search.

Later `optik.solve_ik` calls with options already validated once go through a prepared call,
`LMCall`: one C call that checks the target and ``q0``, solves and judges the answer, with the
same results as `solve_lm` (``docs/solvers/lm.md``, "Prepared calls").

Options (``solve_ik(..., method="lm", **options)``):

* ``block`` (5): iterations per stall test. (2 with ``stall`` 0.8 takes about 3-20 % fewer
  iterations on the Panda, the iiwa14 and the robots table's arms, but abandons slow starts that
  would converge: on random general 6R arms the multi-start ``solve_ik_all`` found 2.46 instead
  of 3.08 solutions per target and ``solve_ik`` failed more often, so 5 and 0.7 stay.)
* ``max_iter`` (100): iterations per start before restarting.
* ``mu0`` (0.1): initial damping (0.1 takes 10-25 % fewer iterations than 1e-2 on the Panda,
  iiwa14, Puma 560, seed 6R and planar 3R arms, from the mid-limit seed and from random starts).
* ``stall`` (0.7): restart when a block's cost exceeds ``stall`` times the previous block's.
* ``posture_gain`` (0.0): gain ``k`` of the null-space pull toward ``q_ref``.
* ``q_ref`` (mid-limit): reference posture for that pull.
* ``weights`` ((1, 1)): task weights ``(w_p, w_o)``.
* ``closure_weight`` (100.0): weight ``w_c`` of the loop-closure rows.
* ``max_restarts`` (None): cap on restarts (None: until success or the time limit).
* ``compile`` ("auto"): compile to C when a compiler exists (see `optik.native.NativeFunction`).
"""

from __future__ import annotations

import dataclasses
import threading
import time
from typing import Any

import numpy as np

from optik.checks import as_vector
from optik.errors import InvalidArgumentError, OptikError, SolverUnavailableError
from optik.native import compiler
from optik.problem import target_parameters
from optik.results import IKResult
from optik.solvers import generic_chain
from optik.solvers.base import (
    IKRequest,
    PreparedCache,
    make_result,
    method_options,
    positive_int,
    register_method,
    rotation_vectors_canonical,
)
from optik.solvers.lm_kernel import STATUS, LMKernel, OneTarget, Settings, kernel
from optik.solvers.options import check_floats, check_max_restarts

DEFAULTS: dict[str, Any] = {
    "block": 5,
    "max_iter": 100,
    "mu0": 0.1,
    "stall": 0.7,
    "posture_gain": 0.0,
    "q_ref": None,
    "weights": (1.0, 1.0),
    "closure_weight": 100.0,
    "max_restarts": None,
    "compile": "auto",
}
"""Default options of ``"lm"``."""

_STOP_MARGIN = 0.5
"""A start stops once its errors are below this fraction of the tolerances (so that the final
check, done on the wrapped and clipped answer, passes with room)."""


def lm_settings(request: IKRequest) -> tuple[Settings, float, bool | str]:
    """The validated options of a request as kernel settings, with the closure weight and the
    ``compile`` option.

    Raises:
        InvalidArgumentError: an unknown option or a bad value (named).
    """
    opts = method_options(request, DEFAULTS)
    check_floats(opts, "stall", "posture_gain", "closure_weight", strict=("mu0",))
    max_restarts = check_max_restarts(opts["max_restarts"])
    m, tol = request.mechanism, request.tol
    block = positive_int(opts["block"], "block")
    max_blocks = max(1, positive_int(opts["max_iter"], "max_iter") // block)
    weights = as_vector(opts["weights"], "weights", 2)
    if np.any(weights < 0):
        raise InvalidArgumentError("weights", f"must be >= 0, got {weights}")
    settings = Settings(
        block=block,
        max_iter=max_blocks * block,
        max_restarts=-1 if max_restarts is None else max_restarts,
        time_limit=request.time_limit,
        mu0=float(opts["mu0"]),
        stall=float(opts["stall"]),
        stop=(_STOP_MARGIN * tol.position, _STOP_MARGIN * tol.orientation, _STOP_MARGIN * tol.closure),
        gain=float(opts["posture_gain"]),
        weights=(float(weights[0]), float(weights[1])),
        q_ref=m.mid_q() if opts["q_ref"] is None else m.check_q(opts["q_ref"], "q_ref"),
    )
    return settings, float(opts["closure_weight"]), opts["compile"]


def request_seed(seed: int | np.random.Generator | None) -> int:
    """The kernel's seed of a request: the int itself (None: 0, as for every method), or one
    drawn from a Generator."""
    if seed is None:
        return 0
    if isinstance(seed, int | np.integer):  # first: np.random is imported on first use (20 ms)
        return int(seed)
    if isinstance(seed, np.random.Generator):
        return int(seed.integers(0, 2**63))
    return int(seed)


_PREPARED: PreparedCache[tuple[LMKernel, np.ndarray]] = PreparedCache()
"""Per mechanism: the validated requests (`prepare_kernel`)."""


def prepare_kernel(request: IKRequest, build: bool = True) -> tuple[LMKernel, np.ndarray] | None:
    """The kernel and the driver's ``conf`` of a request, cached per mechanism, task, frame,
    tolerances and option values when those are hashable (validation costs more than a solve);
    None when not cached and ``build`` is False."""
    key = _PREPARED.key(request)
    hit = _PREPARED.get(request.mechanism, key)
    if hit is None and not build:
        return None
    if hit is None:
        settings, closure_weight, compile = lm_settings(request)
        setup = time.perf_counter()
        k = kernel(request.mechanism, request.task, request.frame, closure_weight, compile)
        request.exclude_setup(setup)
        hit = _PREPARED.put(request.mechanism, key, (k, settings.conf(request.mechanism)))
    return hit


def solve_lm(request: IKRequest) -> IKResult:
    """Solve an IK request by bounded LM with random restarts (see the module docstring); until
    the kernel of the mechanism is compiled, by the generic chain kernel where it applies
    (`optik.solvers.generic_chain`)."""
    seed = request_seed(request.seed) & (2**64 - 1)
    prepared = prepare_kernel(request, build=False)
    if prepared is None or not prepared[0].compiled:
        settings, closure_weight, compile = lm_settings(request)
        first = generic_chain.solve_first(
            request, settings, closure_weight, compile, prepare_kernel, seed, lm_result
        )
        if first is not None:
            return first
    k, base = prepared or prepare_kernel(request)  # type: ignore[misc]  # built when None
    conf = base.copy()
    conf[3] = max(request.remaining(), 0.0)
    params = target_parameters(request.target)
    q, err, iterations, restarts, code = k.run_one(params, request.q0, seed, conf)
    return lm_result(request, k, q, err, iterations, restarts, code, params)


_MASK = 2**64 - 1


def lm_result(
    request: IKRequest,
    k: LMKernel,
    q: np.ndarray,
    err: tuple[float, float, float],
    iterations: int,
    restarts: int,
    code: int,
    params: np.ndarray | None = None,
) -> IKResult:
    """The result of a kernel run by `optik.solvers.base.make_result`, which wraps and clips
    ``q`` and judges it: with the kernel's errors ``err`` of ``q`` when that leaves ``q``
    unchanged, else the errors of the final ``q`` evaluated again (against ``params``, the
    request's target parameters, computed when not given)."""
    answer = q.tolist()

    def errors(qq: np.ndarray) -> tuple[float, float, float]:
        """The kernel's own check, as the batch's."""
        if qq.tolist() == answer:
            return err
        return k.final_errors(qq, target_parameters(request.target) if params is None else params)

    status = None if code == 0 else STATUS[code]
    return make_result(request, q, "lm", iterations, restarts, status, errors=errors)


_F64 = np.dtype(np.float64)


class LMCall:
    """The prepared call of ``lm`` (a `optik.solvers.base.PreparedCall`): the later calls
    of `optik.solve_ik` with the options of ``request`` (time limit, tolerances, method options,
    task and frame, all validated once) solve through one C call, ``optik_lm_call`` of
    ``lm_chunk.c``, which checks the target transform as `optik.checks.as_transform` does and
    ``q0`` for finiteness, runs the solve as `solve_lm` does and says whether the answer is
    canonical (within the limits and within the bands of `optik.solvers.base.wrap_bands`, which
    `optik.solvers.lm_kernel.Settings.conf` carries: ``(-pi, pi)`` for an angle whose limits span a
    turn or more, the whole line for a shorter one, such as the Panda's joint 6 up to 3.75, which is
    its own wrap anywhere within them; the norms of the rotation vectors of a free base or
    spherical joint are checked here, by `optik.solvers.base.rotation_vectors_canonical`; as
    `optik.solvers.base.make_result` checks them). A canonical answer that
    meets the tolerances is the result as it is (what `optik.solvers.base.make_result` makes of
    it); any other answer goes through `lm_result`. It returns None, before solving, for input
    it does not take (a ``q0`` that `optik.Mechanism.check_q` refuses, a seed other than an int
    ``>= 0``, a Generator or None, a target the C check refuses: the general path then raises
    the named error, a Generator seed having given its one draw) and while the kernel is not
    built or its library is being built (the kernel is built by the general path, by `solve_lm`
    or in the background by `optik.solvers.generic_chain`, and found here). A ``q0`` other than
    a float64 vector is converted by `optik.Mechanism.check_q` as the general path converts it.
    Thread-safe: buffers per thread.

    A caller may hand a check of the answer to the same C call (``check``: the address of its
    block, see ``optik_lm_call_checked`` in ``lm_chunk.c``): it runs on an answer that meets the
    tolerances and is canonical, the answer this call returns as it is, and writes its verdict
    where its block says (`optik.collision.check.ClearTest`). It is not run for a mechanism with
    rotation vectors (their norms are checked here, after the C call).
    """

    def __init__(self, request: IKRequest) -> None:
        self._prepared: tuple[LMKernel, np.ndarray] | None = None
        self._entry: Any = None
        """The kernel's ``optik_lm_call`` once loaded (`optik.solvers.lm_kernel.LMKernel.call_entry`)."""
        self._checked: Any = None
        """Its ``optik_lm_call_checked`` (`optik.solvers.lm_kernel.LMKernel.checked_entry`)."""
        self.request = request
        m = request.mechanism
        self._mid = m.mid_q()
        self._shape = (m.n_q,)
        self._rotation_vectors = bool(m.spherical_slices)
        tol = request.tol
        self._tol = (tol.position, tol.orientation, tol.closure)
        self._local = threading.local()

    @property
    def kernel(self) -> LMKernel | None:
        """The kernel once it is built (None before)."""
        if self._prepared is None:
            self._prepared = prepare_kernel(self.request, build=False)
        return None if self._prepared is None else self._prepared[0]

    def _buffers(self, k: LMKernel, conf: np.ndarray) -> OneTarget:
        one = self._local.one = OneTarget(len(self._mid), k.n_target, len(conf))
        one.conf[:] = conf
        one.tol[:] = self._tol
        return one

    def __call__(
        self, start: float, target: np.ndarray, q0: Any, seed: Any, check: int | None = None
    ) -> IKResult | None:
        """Solve for ``target`` from ``q0`` (None: mid-limit) with restart seed ``seed``, and run
        the check at address ``check`` on an answer kept as it is (see the class); None when this
        call is left to the general path (see the class)."""
        call = self._entry
        if call is None:
            k = self.kernel
            call = self._entry = None if k is None else k.call_entry()
            if call is None:
                return None
        if target.dtype != _F64 or target.shape != (4, 4):
            return None
        if q0 is None:
            q0 = self._mid
        elif type(q0) is not np.ndarray or q0.dtype != _F64 or q0.shape != self._shape:
            try:
                q0 = self.request.mechanism.check_q(q0, "q0")  # the general path's conversion
            except OptikError:
                return None  # the general path names it (after checking the target)
        if seed is None:
            s = 0
        elif (type(seed) is int and seed >= 0) or isinstance(seed, np.random.Generator):
            s = request_seed(seed) & _MASK  # one draw from a Generator, as `solve_lm` makes
        else:
            return None
        prepared = self._prepared
        one = getattr(self._local, "one", None) or self._buffers(*prepared)
        one.transform[:] = target
        one.q0[:] = q0
        one.seed[0] = s
        one.conf[3] = max(self.request.time_limit - (time.perf_counter() - start), 0.0)
        if check is None or self._rotation_vectors:
            rc = call(one.call_args)
        else:
            checked = self._checked
            if checked is None:
                checked = self._checked = prepared[0].checked_entry()
            one.checked_args[9] = check
            rc = checked(one.checked_args)
        if rc != 0:
            if rc in (2, 3):  # the target or q0 failed the check: the general path names it
                return None
            raise SolverUnavailableError("optik_lm_call: evaluation of the generated code failed")
        iterations, restarts, code, canonical = one.counts.tolist()
        pos, ori, clo = one.errors.tolist()
        q = one.q.copy()
        if canonical and self._rotation_vectors:
            canonical = rotation_vectors_canonical(self.request.mechanism, q.tolist())
        tp, to, tc = self._tol
        if canonical and pos <= tp and ori <= to and clo <= tc:
            # the fields in order: q, success, the three errors, limits_ok, iterations, solve_time,
            # method, status, message, restarts
            elapsed = time.perf_counter() - start
            return IKResult(q, True, pos, ori, clo, True, iterations, elapsed, "lm", "solved", "", restarts)
        request = dataclasses.replace(
            self.request,
            target=target,
            q0=q0,
            seed=seed,
            options=dict(self.request.options),
            start=start,
            setup_time=0.0,
        )
        return lm_result(request, prepared[0], q, (pos, ori, clo), iterations, restarts, code)


def prepare_lm(request: IKRequest) -> LMCall | None:
    """The `LMCall` of a request, None for several frame targets or without a C library
    (``compile=False``, no compiler)."""
    if request.multi_target or lm_settings(request)[2] is False or compiler() is None:
        return None
    return LMCall(request)


register_method(
    "lm",
    solve_lm,
    description="bounded Levenberg-Marquardt compiled to C, random restarts until the time limit",
    multi_target=True,
    prepare=prepare_lm,
)
