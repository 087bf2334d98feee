"""Method ``"lm"``: bounded Levenberg-Marquardt with random restarts, compiled to C.

The residual is ``e(q) = [w_p r_p; w_o r_o; w_c c(q)]``: the task residual of
[`optik.problem`][optik.problem] with the loop closures of a closed chain appended as heavily weighted rows.
One iteration at ``q`` with gradient ``g = J^T e`` and Gauss-Newton matrix ``A = J^T J``:

1. *Active set*: coordinate ``i`` is frozen when it sits on a bound and the descent direction
   ``-g_i`` points outside (``q_i = lo_i, g_i > 0`` or ``q_i = hi_i, g_i < 0``); ``D`` is the
   diagonal 0/1 matrix of the free coordinates.
2. *Step*: ``(D A D + mu I + (I - D)) dq = -D g + k mu D (q_ref - q)``. The last term is a
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

Options (``solve_ik(..., method="lm", **options)``):

* ``block`` (5): iterations per stall test.
* ``max_iter`` (100): iterations per start before restarting.
* ``mu0`` (0.1): initial damping (0.1 takes 10-25 % fewer iterations than 1e-2 on the Panda,
  iiwa14, Puma 560, seed 6R and planar 3R arms, from the mid-limit seed and from random starts).
* ``stall`` (0.7): restart when a block's cost exceeds ``stall`` times the previous block's.
* ``posture_gain`` (0.0): gain ``k`` of the null-space pull toward ``q_ref``.
* ``q_ref`` (mid-limit): reference posture for that pull.
* ``weights`` ((1, 1)): task weights ``(w_p, w_o)``.
* ``closure_weight`` (100.0): weight ``w_c`` of the loop-closure rows.
* ``max_restarts`` (None): cap on restarts (None: until success or the time limit).
* ``compile`` ("auto"): compile to C when a compiler exists (see `optik.solvers.native.NativeFunction`).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from optik.checks import as_vector
from optik.errors import InvalidArgumentError
from optik.mechanism.memo import PerMechanism
from optik.problem import target_parameters
from optik.results import IKResult
from optik.solvers import generic_chain
from optik.solvers.base import IKRequest, make_result, method_options, positive_int, register_method
from optik.solvers.lm_kernel import STATUS, LMKernel, Settings, kernel
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


_PREPARED: PerMechanism[dict[tuple[Any, ...], tuple[LMKernel, np.ndarray]]] = PerMechanism()
_PREPARED_MAX = 256
"""Prepared requests kept per mechanism (all are dropped past it: option values drawn anew per call)."""


def _prepare(request: IKRequest, build: bool = True) -> tuple[LMKernel, np.ndarray] | None:
    """The kernel and the driver's ``conf`` of a request, cached per mechanism, task, frame,
    tolerances and option values when those are hashable (validation costs more than a solve);
    None when not cached and ``build`` is False."""
    try:
        key: tuple[Any, ...] | None = (
            request.task,
            request.frame,
            request.tol,
            tuple(sorted(request.options.items())),
        )
        prepared = _PREPARED.setdefault(request.mechanism, {})
        hit = prepared.get(key)  # type: ignore[arg-type]
    except TypeError:  # an unhashable option value (an array q_ref): validate every time
        key, hit = None, None
    if hit is None and not build:
        return None
    if hit is None:
        settings, closure_weight, compile = lm_settings(request)
        setup = time.perf_counter()
        k = kernel(request.mechanism, request.task, request.frame, closure_weight, compile)
        request.exclude_setup(setup)
        hit = (k, settings.conf(request.mechanism))
        if key is not None:
            if len(prepared) >= _PREPARED_MAX:
                prepared.clear()
            prepared[key] = hit
    return hit


def solve_lm(request: IKRequest) -> IKResult:
    """Solve an IK request by bounded LM with random restarts (see the module docstring); until
    the kernel of the mechanism is compiled, by the generic chain kernel where it applies
    (`optik.solvers.generic_chain`)."""
    seed = request_seed(request.seed) & (2**64 - 1)
    prepared = _prepare(request, build=False)
    if prepared is None or not prepared[0].compiled:
        settings, closure_weight, compile = lm_settings(request)
        first = generic_chain.solve_first(request, settings, closure_weight, compile, _prepare, seed)
        if first is not None:
            return first
    k, base = prepared or _prepare(request)  # type: ignore[misc]  # built when None
    conf = base.copy()
    conf[3] = max(request.remaining(), 0.0)
    params = target_parameters(request.target)
    q, err, iterations, restarts, code = k.run_one(params, request.q0, seed, conf)
    answer = q.tolist()

    def errors(qq: np.ndarray) -> tuple[float, float, float]:
        """The kernel's own check, as the batch's: the errors it computed for its answer when
        wrapping and clipping left that unchanged, else evaluated again."""
        return err if qq.tolist() == answer else k.final_errors(qq, params)

    status = None if code == 0 else STATUS[code]
    return make_result(request, q, "lm", iterations, restarts, status, errors=errors)


register_method(
    "lm",
    solve_lm,
    description="bounded Levenberg-Marquardt compiled to C, random restarts until the time limit",
    multi_target=True,
)
