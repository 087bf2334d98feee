"""What every IK method shares: the request, tolerances, result evaluation and a method registry.

A method is a function ``solve(request) -> IKResult`` registered under a name with
[`register_method`][optik.solvers.base.register_method]. [`optik.solve_ik`][optik.solve_ik] validates the
user's input once, builds an [`IKRequest`][optik.solvers.base.IKRequest] and dispatches to the method. Methods
registered from layers below the solvers (e.g. [`optik.diffik`][optik.diffik], which registers ``"dls"`` and
``"qp"``) plug in the same way, so the import direction stays one way.
"""

from __future__ import annotations

import math
import operator
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Generic, TypeVar

import casadi as ca
import numpy as np

from optik import spatial
from optik.checks import as_float, as_name, as_rng, as_vector, check_seed
from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import LRU, PerMechanism
from optik.problem import Frames, Tasks, frame_tasks
from optik.results import IKResult
from optik.targets import Pose2D, Position, target_transform


@dataclass(frozen=True)
class Tolerances:
    """Success tolerances (the defaults of the docs' Concepts page, Conventions).

    Attributes:
        position: max position error (m).
        orientation: max orientation error (rad).
        closure: max loop-closure residual (max-norm).
    """

    position: float = 1e-6
    orientation: float = 1e-6
    closure: float = 1e-9

    def __post_init__(self) -> None:
        """Each tolerance must be a finite number > 0 (0 can never be met by floating point,
        and the methods divide by the tolerances to scale their stopping tests).

        Raises:
            InvalidArgumentError: naming the field (``position``, ``orientation``, ``closure``).
        """
        for name in ("position", "orientation", "closure"):
            object.__setattr__(self, name, as_float(getattr(self, name), name, 0.0, strict=True))

    @classmethod
    def from_arg(cls, tol: float | Tolerances | None) -> Tolerances:
        """``None`` -> defaults; a float sets position and orientation tolerances."""
        if tol is None:
            return _DEFAULT_TOL if cls is Tolerances else cls()
        if isinstance(tol, Tolerances):
            return tol
        if type(tol) is float and cls is Tolerances:  # frozen: one shared instance per value
            hit = _FLOAT_TOL.get(tol)  # NaN is never found: it is validated (and refused) below
            if hit is not None:
                return hit
        t = as_float(tol, "tol", 0.0, strict=True)
        made = cls(position=t, orientation=t)
        if type(tol) is float and cls is Tolerances:
            if len(_FLOAT_TOL) >= 64:
                _FLOAT_TOL.clear()
            _FLOAT_TOL[tol] = made
        return made


_DEFAULT_TOL = Tolerances()  # frozen: one shared instance for the common ``tol=None``
_FLOAT_TOL: dict[float, Tolerances] = {}  # ``tol`` given as a float: validated once per value

SETUP_THRESHOLD = 1e-3
"""Seconds above which a method's setup counts as a first-time build (see
[`IKRequest.exclude_setup`][optik.solvers.base.IKRequest.exclude_setup])."""


@dataclass
class IKRequest:
    """A validated IK request, as methods receive it.

    Attributes:
        mechanism: the model.
        target: 4x4 target transform of ``frame`` (``(k, 4, 4)``: one per frame of ``frame``).
        task: task space: ``"pose"``, ``"position"``, ``"orientation"``, ``"pose2d"``, ``"position2d"``
            (a tuple, one per frame, for several targets).
        frame: task frame name (None: end effector), or a tuple of ``k >= 2`` frame names when
            several frame targets are solved at once (`multi_target`).
        q0: start configuration (mid-limit when the user gave none).
        time_limit: wall-time budget (s); every method must return within it (plus one iteration).
        tol: success tolerances.
        seed: seed or Generator of the restarts; `rng` makes the generator on first use
            (creating one costs ~20 us, more than many solves).
        options: method-specific options.
        start: ``time.perf_counter()`` when the request was made (moved forward by
            `exclude_setup`).
        setup_time: one-time build time excluded from the time limit (s).
    """

    mechanism: Mechanism
    target: np.ndarray
    task: Tasks
    frame: Frames
    q0: np.ndarray
    time_limit: float
    tol: Tolerances
    seed: int | np.random.Generator | None = None
    options: dict[str, Any] = field(default_factory=dict)
    start: float = field(default_factory=time.perf_counter)
    setup_time: float = 0.0

    @property
    def multi_target(self) -> bool:
        """True when the request holds several frame targets (``frame`` is a tuple)."""
        return isinstance(self.frame, tuple)

    def frame_targets(self) -> tuple[tuple[str | None, str, np.ndarray], ...]:
        """``((frame, task, 4x4 target), ...)``: one triple per frame target."""
        targets = self.target if self.multi_target else self.target[None]
        return tuple(
            (f, t, tt) for (f, t), tt in zip(frame_tasks(self.frame, self.task), targets, strict=True)
        )

    @cached_property
    def rng(self) -> np.random.Generator:
        """The random generator for restarts (from `seed`)."""
        return as_rng(self.seed)

    def exclude_setup(self, since: float) -> None:
        """Exclude a one-time build from the time limit and from the reported solve time.

        Methods call this after fetching their cached problem / compiled code. When the time
        since ``since`` (a ``perf_counter`` value) exceeds
        [`SETUP_THRESHOLD`][optik.solvers.base.SETUP_THRESHOLD] it was a first-time build (construction, code
        generation, compilation), which must not fail the first call on a new mechanism: it is added to
        `start` and reported as ``IKResult.extra["setup_time"]``. Cached lookups (microseconds) stay
        counted."""
        spent = time.perf_counter() - since
        if spent > SETUP_THRESHOLD:
            self.start += spent
            self.setup_time += spent

    def elapsed(self) -> float:
        """Seconds since the request was made."""
        return time.perf_counter() - self.start

    def remaining(self) -> float:
        """Seconds left of the time limit."""
        return self.time_limit - self.elapsed()


@dataclass(frozen=True)
class Errors:
    """Errors of a configuration against a request."""

    position: float
    orientation: float
    closure: float
    limits_ok: bool

    def ok(self, tol: Tolerances) -> bool:
        """All tolerances met and limits satisfied exactly."""
        return (
            self.position <= tol.position
            and self.orientation <= tol.orientation
            and self.closure <= tol.closure
            and self.limits_ok
        )


def task_errors(task: str, pose: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """Position and orientation error of ``pose`` against ``target`` in a task space.

    ``pose``/``position``: Euclidean distance of the origins; ``pose2d``/``position2d``: of their
    x-y coordinates. ``pose``/``orientation``: geodesic angle ``angle(R^T R*)``; ``pose2d``:
    ``|wrap(phi - phi*)|`` of the headings about z.
    """
    # plain floats on the 4x4s (numpy per-call overhead dominates at this size)
    (a00, a01, a02, ax), (a10, a11, a12, ay), (a20, a21, a22, az), _ = pose.tolist()
    (b00, b01, b02, bx), (b10, b11, b12, by), (b20, b21, b22, bz), _ = target.tolist()
    planar = task in ("pose2d", "position2d")
    pos = math.hypot(ax - bx, ay - by) if planar else math.hypot(ax - bx, ay - by, az - bz)
    if task in ("position", "position2d"):
        return pos, 0.0
    if task == "orientation":
        pos = 0.0
    if task == "pose2d":
        phi = math.atan2(a10, a00) - math.atan2(b10, b00)
        return pos, abs(_wrap_angle(phi))
    # angle(R_a^T R_b): trace and skew part of M = R_a^T R_b, M_ij = col_i(R_a) . col_j(R_b)
    tr = (
        (a00 * b00 + a10 * b10 + a20 * b20)
        + (a01 * b01 + a11 * b11 + a21 * b21)
        + (a02 * b02 + a12 * b12 + a22 * b22)
    )
    sx = (a02 * b01 + a12 * b11 + a22 * b21) - (a01 * b02 + a11 * b12 + a21 * b22)
    sy = (a00 * b02 + a10 * b12 + a20 * b22) - (a02 * b00 + a12 * b10 + a22 * b20)
    sz = (a01 * b00 + a11 * b10 + a21 * b20) - (a00 * b01 + a10 * b11 + a20 * b21)
    return pos, math.atan2(0.5 * math.sqrt(sx * sx + sy * sy + sz * sz), 0.5 * (tr - 1.0))


_TWO_PI = 2.0 * math.pi
_HALF_TURN = math.pi - 1e-9


def _wrap_angle(a: float) -> float:
    """[`optik.spatial.wrap_angle`][optik.spatial.wrap_angle] of one float: into ``(-pi, pi]``."""
    w = (a + math.pi) % _TWO_PI - math.pi
    return w + _TWO_PI if w <= -math.pi else w


_BANDS: PerMechanism[tuple[list[float], list[float], list[float], list[float]]] = PerMechanism()


def wrap_bands(m: Mechanism) -> tuple[list[float], list[float], list[float], list[float]]:
    """``m``'s limits and, per coordinate, the open interval ``(a, b)`` of the values within the
    limits that [`Mechanism.wrap`][optik.Mechanism.wrap] returns as they are (`is_canonical`),
    as plain float lists (cached per mechanism).

    An angle whose limits span ``2 pi`` or more (less a rounding margin) gets ``(-pi, pi)``; one
    whose limits span less gets the whole line: a value ``x`` within them has no other turn
    ``x + 2 pi k`` within them, so `optik.spatial.wrap_to_limits` keeps ``x`` (its rule 2: the
    Panda's joint 6, limits ``[-0.0175, 3.7525]``, beyond pi on a sixth of its range). A rotation
    vector coordinate gets ``(-pi, pi)`` (its norm is checked too: `rotation_vectors_canonical`),
    every other coordinate (prismatic: `wrap` does not touch it) the whole line.
    """
    hit = _BANDS.get(m)
    if hit is not None:
        return hit
    lower, upper = m.lower.tolist(), m.upper.tolist()
    angle = np.asarray(m.revolute_mask, dtype=bool)
    rotation = np.zeros(m.n_q, dtype=bool)
    for sl in m.spherical_slices:
        rotation[sl] = True
    short = m.upper - m.lower < _TWO_PI - 1e-9  # an unbounded angle spans inf: not short
    free = (angle & short) | ~(angle | rotation)
    a = np.where(free, -np.inf, -math.pi).tolist()
    b = np.where(free, np.inf, math.pi).tolist()
    return _BANDS.setdefault(m, (lower, upper, a, b))


def is_canonical(m: Mechanism, q: list[float]) -> bool:
    """Whether ``q`` (a plain float list of ``n_q`` entries) lies within ``m``'s limits and is
    its own [`Mechanism.wrap`][optik.Mechanism.wrap] (`wrap_bands`, `rotation_vectors_canonical`):
    a result may keep it as it is. NaN is not canonical."""
    lower, upper, a, b = wrap_bands(m)
    le, lt = operator.le, operator.lt
    if not (all(map(le, lower, q)) and all(map(le, q, upper))):
        return False
    if not (all(map(lt, a, q)) and all(map(lt, q, b))):
        return False
    return not m.spherical_slices or rotation_vectors_canonical(m, q)


def rotation_vectors_canonical(m: Mechanism, q: list[float]) -> bool:
    """Whether every rotation vector of ``q`` (a plain float list of ``n_q`` entries: the
    spherical joints' coordinates and the free joints' last three) has norm ``< pi - 1e-9``, so
    that [`Mechanism.wrap`][optik.Mechanism.wrap] leaves it as it is."""
    # a margin below pi: a vector this near the half-turn goes through `Mechanism.wrap`, whose
    # norm (nested hypot) may round differently
    return all(math.hypot(*q[sl]) < _HALF_TURN for sl in m.spherical_slices)


def evaluate(m: Mechanism, q: np.ndarray, target: np.ndarray, task: str, frame: str | None) -> Errors:
    """Position, orientation and closure errors of ``q``, and whether it is within limits."""
    pos, ori = task_errors(task, m.fk(q, frame), target)
    closure = float(np.max(np.abs(m.closure(q)))) if m.is_closed else 0.0
    limits_ok = bool((q >= m.lower).all() and (q <= m.upper).all())
    return Errors(pos, ori, closure, limits_ok)


def make_result(
    request: IKRequest,
    q: np.ndarray,
    method: str,
    iterations: int,
    restarts: int = 0,
    status: str | None = None,
    message: str = "",
    errors: Callable[[np.ndarray], tuple[float, float, float]] | None = None,
) -> IKResult:
    """An [`IKResult`][optik.IKResult] for ``q``: errors evaluated here, success judged by the tolerances.

    ``q`` is clipped into the limits first (a method must never report a violating answer).
    Status and success always agree: a result that meets the tolerances is ``"solved"`` (with
    no message) whatever the method's stop reason, since the final, wrapped and clipped ``q``
    decides, not the method's own bookkeeping; a failed result has the method's ``status``,
    default ``"not_converged"``.

    Args:
        errors: optional faster evaluation ``q -> (position, orientation, closure)`` errors with
            the definitions of [`evaluate`][optik.solvers.base.evaluate] (e.g. compiled code); it is applied
            to the final, wrapped and clipped ``q``. Default: [`evaluate`][optik.solvers.base.evaluate].
    """
    m = request.mechanism
    if type(q) is not np.ndarray or q.dtype != np.float64:
        q = np.asarray(q, dtype=float)
    if request.multi_target:
        qq, err, frame_errors = _multi_target_errors(request, q)
        return _result(request, qq, err, method, iterations, restarts, status, message, frame_errors)
    lower, upper = m.lower, m.upper
    # already wrapped and within limits: m.wrap would return q itself (`is_canonical`)
    if q.shape == lower.shape:
        # plain-float comparisons (NaN compares False, as in numpy): cheaper than four ufuncs
        ql = q.tolist()
        wrapped = is_canonical(m, ql)
        le = operator.le
        inside = wrapped or (all(map(le, lower.tolist(), ql)) and all(map(le, ql, upper.tolist())))
    else:
        inside = bool((q >= lower).all() and (q <= upper).all())
        wrapped = inside and bool((np.abs(q) < np.pi).all()) and not m.spherical_slices
    if wrapped:
        qq = q.copy()
    else:
        qq = np.clip(m.wrap(q), lower, upper)
        # clipped into the limits unless NaN slipped through (then the check fails)
        inside = bool((qq >= lower).all() and (qq <= upper).all())
    if errors is None:
        if qq.shape == (m.n_q,) and math.isfinite(sum(qq.tolist())):
            # qq is a finite float vector of n_q entries: FK without re-validating it
            pose = np.asarray(m.fk_function(request.frame)(qq))
            pos, ori = task_errors(request.task, pose, request.target)
            clo = float(np.max(np.abs(m.closure(qq)))) if m.is_closed else 0.0
            err = Errors(pos, ori, clo, inside)
        else:
            err = evaluate(m, qq, request.target, request.task, request.frame)
    else:
        pos, ori, clo = errors(qq)
        err = Errors(float(pos), float(ori), float(clo), inside)
    return _result(request, qq, err, method, iterations, restarts, status, message, {})


def _result(
    request: IKRequest,
    qq: np.ndarray,
    err: Errors,
    method: str,
    iterations: int,
    restarts: int,
    status: str | None,
    message: str,
    frame_errors: dict[str, tuple[float, float]],
) -> IKResult:
    """The [`IKResult`][optik.IKResult] of a final ``qq`` and its errors (status and message as
    [`make_result`][optik.solvers.base.make_result] describes)."""
    success = err.ok(request.tol)
    if success:
        status, message = "solved", ""
    elif status is None or status == "solved":
        status = "not_converged"
    if not success and not message:
        if frame_errors:
            each = ", ".join(f"{f}: {p:.3g} m, {o:.3g} rad" for f, (p, o) in frame_errors.items())
            errors_text, what = f"errors per frame {each}", "the targets may be unreachable together"
        else:
            errors_text = f"position error {err.position:.3g} m, orientation error {err.orientation:.3g} rad"
            what = "the target may be unreachable"
        message = (
            f"tolerances not met within the time limit ({request.time_limit:g} s): {errors_text}, "
            f"closure {err.closure:.3g}; {what} within the joint limits"
        )
    return IKResult(
        q=qq,
        success=success,
        position_error=err.position,
        orientation_error=err.orientation,
        closure_error=err.closure,
        limits_ok=err.limits_ok,
        iterations=iterations,
        solve_time=request.elapsed(),
        method=method,
        status=status,
        message=message,
        restarts=restarts,
        extra={"setup_time": request.setup_time} if request.setup_time else {},
        frame_errors=frame_errors,
    )


_FRAMES_FK: PerMechanism[dict[tuple[str | None, ...], ca.Function]] = PerMechanism()


def frames_fk_function(m: Mechanism, frames: tuple[str | None, ...]) -> ca.Function:
    """``q -> [T_1(q), ..., T_k(q)]`` (``4 x 4k``) of several frames in one call (built once per
    mechanism and frames): the success check of a several-target request makes one call instead of
    one per frame (each CasADi call costs tens of microseconds, the evaluation a few)."""
    per = _FRAMES_FK.setdefault(m, {})
    found = per.get(frames)
    if found is None:
        expr = ca.horzcat(*(m.frame_expr(m.ee if f is None else f) for f in frames))
        found = per.setdefault(frames, ca.Function("fk_frames", [m.q_sym], [expr]))
    return found


def _multi_target_errors(request: IKRequest, q: np.ndarray) -> tuple[np.ndarray, Errors, dict]:
    """``(q, errors, frame_errors)`` of a several-target request: ``q`` wrapped and clipped, each
    frame's errors from its own FK, the overall position and orientation errors the largest."""
    m = request.mechanism
    finite = bool(np.all(np.isfinite(q)))
    qq = np.clip(m.wrap(q), m.lower, m.upper) if finite else q
    inside = bool((qq >= m.lower).all() and (qq <= m.upper).all())
    if finite:
        triples = request.frame_targets()
        poses = np.asarray(frames_fk_function(m, tuple(f for f, _, _ in triples))(qq))
        frame_errors = {
            f: task_errors(task, poses[:, 4 * i : 4 * i + 4], t) for i, (f, task, t) in enumerate(triples)
        }
        clo = float(np.max(np.abs(m.closure(qq)))) if m.is_closed else 0.0
    else:
        frame_errors = {f: (math.inf, math.inf) for f, _, _ in request.frame_targets()}
        clo = math.inf
    pos, ori = max(p for p, _ in frame_errors.values()), max(o for _, o in frame_errors.values())
    return qq, Errors(pos, ori, clo, inside), frame_errors


BRANCH_TOL = 1e-4
"""Two solutions are the same branch when their joint vectors differ by less than this
(the same-branch rule; angles compared modulo 2 pi)."""


V = TypeVar("V")


class PreparedCache(Generic[V]):
    """What a method prepares from a request's settings (a compiled kernel and its driver's
    ``conf``: validation and setup cost more than a solve), per mechanism and per key
    ``(task, frame, tol, sorted options, *extra)``.

    Thread-safe; at most ``size`` keys per mechanism, the least recently used dropped (option
    values drawn anew per call cannot grow it without end). A request with an unhashable option
    value (an array ``q_ref``) has no key and is prepared every time.
    """

    def __init__(self, size: int = 256) -> None:
        self.size = size
        self._per: PerMechanism[LRU[tuple[Any, ...], V]] = PerMechanism()

    @staticmethod
    def key(request: IKRequest, *extra: Any) -> tuple[Any, ...] | None:
        """The cache key of ``request`` (with ``extra`` appended), None when it is unhashable."""
        key = (request.task, request.frame, request.tol, tuple(sorted(request.options.items())), *extra)
        try:
            hash(key)
        except TypeError:
            return None
        return key

    def _entries(self, m: Mechanism) -> LRU[tuple[Any, ...], V]:
        entries = self._per.get(m)
        return self._per.setdefault(m, LRU(self.size)) if entries is None else entries

    def get(self, m: Mechanism, key: tuple[Any, ...] | None) -> V | None:
        """The entry of ``key`` for ``m`` (None when absent or ``key`` is None)."""
        return None if key is None else self._entries(m).get(key)

    def put(self, m: Mechanism, key: tuple[Any, ...] | None, value: V) -> V:
        """Store ``value`` under ``key`` for ``m`` (not when ``key`` is None); the entry kept
        (another thread's when it stored first)."""
        return value if key is None else self._entries(m).setdefault(key, value)


def joint_distance(m: Mechanism, qa: np.ndarray, qb: np.ndarray) -> float:
    """Max-norm of ``qa - qb`` with angular coordinates compared modulo 2 pi."""
    d = np.asarray(qa, dtype=float) - np.asarray(qb, dtype=float)
    ang = m.revolute_mask
    d[ang] = spatial.wrap_angle(d[ang])
    return float(np.max(np.abs(d))) if d.size else 0.0


def positive_int(value: Any, name: str) -> int:
    """``value`` as an integer >= 1 (else [`InvalidArgumentError`][optik.InvalidArgumentError] naming
    ``name``)."""
    if type(value) is int and value >= 1:  # the common case, without the generic validation
        return value
    v = float(as_vector(value, name, 1)[0])
    if v < 1 or v != int(v):
        raise InvalidArgumentError(name, f"expected a positive integer, got {value!r}")
    return int(v)


def method_options(request: IKRequest, defaults: dict[str, Any]) -> dict[str, Any]:
    """The request's options merged over a method's ``defaults``.

    Raises:
        InvalidArgumentError: an option the method does not know (named, with the known ones).
    """
    unknown = sorted(set(request.options) - set(defaults))
    if unknown:
        raise InvalidArgumentError(
            unknown[0], f"unknown option for this method; known options: {sorted(defaults)}"
        )
    return {**defaults, **request.options}


def start_points(request: IKRequest) -> Iterator[np.ndarray]:
    """Multi-start sequence: ``q0`` first, then points drawn uniformly within the limits (the
    mechanism's ``sampling_bounds`` for unbounded joints) from the request's generator
    (endless; the caller stops on success or at the time limit)."""
    m = request.mechanism
    yield request.q0.copy()
    while True:
        yield m.random_q(seed=request.rng)


def restart_stop(deadline: float, restarts: int, max_restarts: int | None) -> str | None:
    """Why a multi-start loop stops after a failed start (``"time_limit"`` or ``"max_restarts"``),
    or None to start again."""
    if time.perf_counter() >= deadline:
        return "time_limit"
    if max_restarts is not None and restarts >= int(max_restarts):
        return "max_restarts"
    return None


IKMethod = Callable[[IKRequest], IKResult]

PreparedCall = Callable[[float, np.ndarray, Any, Any], "IKResult | None"]
"""``(start, target, q0, seed) -> IKResult or None``: a method's solve of later calls that
differ from a first request only by the target (a float64 4x4 array), ``q0`` and ``seed``, with
``start`` the ``perf_counter()`` of the call. It validates what it takes (the same checks and
outcomes as `make_request` and the method) and returns None, before solving, when it cannot
answer a call (input that may be invalid, code not yet compiled): `optik.solve_ik` then takes its
general path, which raises the named error or solves."""


@dataclass(frozen=True)
class MethodInfo:
    """A registered method: its solve function, a predicate saying whether it applies, whether
    it solves several frame targets at once (``multi_target``), and optionally ``prepare``:
    ``request -> PreparedCall or None`` (None: this request's options have no prepared call)."""

    name: str
    solve: IKMethod
    applies: Callable[[Mechanism, str], bool]
    description: str
    multi_target: bool = False
    prepare: Callable[[IKRequest], PreparedCall | None] | None = None


_METHODS: dict[str, MethodInfo] = {}
_REGISTRATIONS = 0  # calls of register_method (see registrations)


def register_method(
    name: str,
    solve: IKMethod,
    applies: Callable[[Mechanism, str], bool] = lambda m, task: True,
    description: str = "",
    multi_target: bool = False,
    prepare: Callable[[IKRequest], PreparedCall | None] | None = None,
) -> None:
    """Register an IK method under ``name`` (replacing a previous registration).

    ``multi_target=True`` says that ``solve`` handles requests with several frame targets
    (`IKRequest.multi_target`; ``applies`` is then called with the tuple of task spaces).
    ``prepare`` makes the `PreparedCall` of a request, which `optik.solve_ik` keeps and uses for
    the later calls with the same options."""
    global _REGISTRATIONS
    _METHODS[name] = MethodInfo(name, solve, applies, description, multi_target, prepare)
    _REGISTRATIONS += 1


def registrations() -> int:
    """How many times `register_method` has been called: part of the key of
    `optik.solve_ik`'s prepared calls, so that none made before a method is registered again is
    used after."""
    return _REGISTRATIONS


def methods() -> dict[str, MethodInfo]:
    """The registered methods by name."""
    return dict(_METHODS)


def get_method(name: str) -> MethodInfo:
    """The method registered under ``name``.

    Raises:
        SolverUnavailableError: unknown name (the message lists the known ones).
    """
    if as_name(name, "method") not in _METHODS:
        raise SolverUnavailableError(f"unknown IK method {name!r}; available: {sorted(_METHODS)}")
    return _METHODS[name]


def default_task(m: Mechanism, target: Any) -> str:
    """Task implied by the target type: [`Pose2D`][optik.Pose2D] -> ``pose2d``; [`Position`][optik.Position]
    -> ``position2d`` (planar) or ``position``; a 4x4 transform -> the mechanism's own task."""
    if isinstance(target, Pose2D):
        return "pose2d"
    if isinstance(target, Position):
        return "position2d" if m.planar else "position"
    return m.task


def _frame_targets(
    m: Mechanism, targets: Mapping[Any, Any], task: Any, frame: Any
) -> tuple[np.ndarray, Tasks, Frames]:
    """``(targets, tasks, frames)`` of a ``{frame: target}`` request: one 4x4 and a tuple of
    task spaces and frames for two or more frames, the plain single-target request for one."""
    if frame is not None:
        raise InvalidArgumentError(
            "frame", "give frame=None with a {frame: target} dict (its keys are the frames)"
        )
    if not targets:
        raise InvalidArgumentError("target", "an empty {frame: target} dict")
    frames = tuple(targets)
    for f in frames:
        if not isinstance(f, str):
            raise InvalidArgumentError("target", f"the keys of a target dict are frame names, got {f!r}")
        m._frame(f)
    if isinstance(task, Mapping):
        if set(task) != set(frames):
            raise InvalidArgumentError("task", f"give one task space per frame of the target: {list(frames)}")
        tasks = tuple(m._task(task[f]) for f in frames)
    else:
        tasks = tuple(m._task(default_task(m, targets[f]) if task is None else task) for f in frames)
    stack = np.array([target_transform(targets[f], f"target[{f!r}]") for f in frames])
    if len(frames) == 1:
        return stack[0], tasks[0], frames[0]
    return stack, tasks, frames


def make_request(
    m: Mechanism,
    target: Any,
    q0: Any = None,
    task: str | Mapping[str, str] | None = None,
    frame: str | None = None,
    time_limit: float | None = None,
    tol: float | Tolerances | None = None,
    seed: int | np.random.Generator | None = None,
    options: dict[str, Any] | None = None,
) -> IKRequest:
    """Validate user input and build an [`IKRequest`][optik.solvers.base.IKRequest].

    ``target`` may be a ``{frame: target}`` dict (several frame targets at once, ``frame=None``);
    ``task`` is then one task space for every frame, a ``{frame: task}`` dict, or None (each
    frame's task from its target's type).

    Raises:
        OptikError: a subclass naming the bad argument (target, q0, task, frame, time_limit, tol, seed).
    """
    start = time.perf_counter()
    if isinstance(target, Mapping):
        t, tk, frame = _frame_targets(m, target, task, frame)
    else:
        t = target_transform(target)
        tk = m._task(default_task(m, target) if task is None else task)  # raises on an unknown task
        m._frame(frame)  # raises UnknownFrameError naming the frame
    q_start = m.mid_q() if q0 is None else m.check_q(q0, "q0")
    check_seed(seed)  # now (the generator itself is made on first use)
    if time_limit is None:
        limit = 0.1
    elif type(time_limit) is float and math.isfinite(time_limit):
        limit = time_limit
    else:
        limit = float(as_vector(time_limit, "time_limit", 1)[0])
    if limit <= 0:
        raise InvalidArgumentError("time_limit", f"must be > 0 seconds, got {limit}")
    return IKRequest(
        mechanism=m,
        target=t,
        task=tk,
        frame=frame,
        q0=q_start,
        time_limit=limit,
        tol=Tolerances.from_arg(tol),
        seed=seed,
        options=dict(options or {}),
        start=start,
    )
