"""Forward kinematics of closed chains: one assembly mode ([`solve_fk`][optik.solve_fk]) or all
([`solve_fk_all`][optik.solve_fk_all]).

With the actuated coordinates ``a`` fixed, the passive coordinates ``x`` solve the loop closure
``c(x; a) = 0`` (``m.closure``). There may be more equations than unknowns (the doggy with four
leg angles: 2 closure equations, 1 passive angle) or as many (five-bar, 3-RPR, Stewart-Gough);
the solver is Levenberg-Marquardt on ``min |c(x; a)|^2``,

``(J^T J + mu diag(J^T J) + mu_0 I) dx = -J^T c``,  ``J = dc/dx``,

which is Newton's method when ``J`` is square and well conditioned and least squares otherwise;
success means ``max |c| <= tol`` *and* every coordinate within its limits (angles shifted by
2 pi into the limits first). The closure and its passive Jacobian are one CasADi function per
mechanism, built on first use and cached.

*Tracking.* When ``q0`` closes its loops and the closure is square (as many equations as
passive coordinates, so every actuator value on the way has a mode to follow),
[`solve_fk`][optik.solve_fk] moves the actuated coordinates from ``q0``'s values to ``a`` along a straight
line in steps (halved whenever Newton needs more than a few iterations or a passive coordinate
jumps), so it returns the assembly mode reached continuously from ``q0``: the one "nearest"
``q0``. Otherwise Levenberg-Marquardt starts from ``q0`` (mid-limit when None) directly; if it
fails, up to ``max_restarts`` seeded random restarts follow (within the time limit).

*All modes.* [`solve_fk_all`][optik.solve_fk_all] uses the registered closed form when the mechanism has one
([`optik.closed_form.parallel`][optik.closed_form.parallel]: five-bar, slider-crank, 3-RPR, doggy,
Stewart-Gough by homotopy continuation) and otherwise a seeded multi-start: random passive coordinates within
the limits, Levenberg-Marquardt, de-duplication by the branch rule (coordinates differ by ``< 1e-4``, angles
modulo 2 pi), stopping after ``patience`` consecutive starts that found no new mode (or at the time limit).

*Outcomes.* Inputs that cannot assemble give ``success=False`` with the least-squares
configuration, its residual and a message. Every result reports the condition number of ``J``
at the answer; above ``singular_condition`` the message flags a (near) singularity of the
assembly, where two modes merge.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from optik import closed_form, spatial
from optik.checks import as_bool, as_rng, as_vector
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.results import FKModes, FKResult
from optik.solvers.base import BRANCH_TOL, Tolerances, joint_distance, positive_int
from optik.solvers.conditions import condition_numbers

DEFAULT_TIME_LIMIT = 1.0
"""Default wall-time budget of [`solve_fk`][optik.solve_fk] and of the multi-start in
[`solve_fk_all`][optik.solve_fk_all] (s)."""

SINGULAR_CONDITION = 1e4
"""Condition number of ``dc/dx`` above which a result is flagged as near a singularity."""


BATCH = 16
"""Starts solved together (one mapped CasADi call per iteration) by the multi-start."""


@dataclass
class _Compiled:
    """Per-mechanism data of the FK solvers (built once)."""

    closure: ca.Function  # q -> (c, dc/dx)
    act: np.ndarray
    pas: np.ndarray
    act_angular: np.ndarray  # mask over act: revolute-type actuated coordinates
    mapped: dict[int, ca.Function] = field(default_factory=dict)
    modes: _ModeCheck | None = None

    def evaluate(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closure ``c`` (``(N, m)``) and passive Jacobian (``(N, m, p)``) at the rows of ``qs``."""
        n = len(qs)
        if n == 1:
            c, jac = self.closure(qs[0])
            return np.asarray(c).reshape(1, -1), np.asarray(jac)[None]
        if n not in self.mapped:
            self.mapped[n] = self.closure.map(n)
        c, jac = self.mapped[n](qs.T)
        rows, cols = self.closure.size1_out(1), self.closure.size2_out(1)
        return np.asarray(c).T, np.asarray(jac).reshape(rows, n, cols).transpose(1, 0, 2)


class _ModeCheck:
    """The check of closed-form assembly modes: ``q -> (closure, passive Jacobian, end-effector
    pose)`` at ``K`` rows in one evaluation of CasADi's virtual machine (the function mapped over
    ``K`` columns) on preallocated buffers (``Function.buffer``: no conversion to ``DM`` and
    back), one set per ``K``, guarded by a lock."""

    def __init__(self, m: Mechanism, closure: ca.Function) -> None:
        q = m.q_sym
        c, jac = closure(q)
        # transposed: CasADi writes column-major, so the buffers hold J and T row-major
        self.function = ca.Function(
            "fk_mode", [q], [ca.densify(c), ca.densify(jac.T), ca.densify(m.frame_expr(m.ee).T)]
        )
        self.n_q, self.shape = m.n_q, jac.shape
        self._buffers: dict[int, tuple[Any, ...]] = {}
        self.lock = threading.Lock()

    def _buffer(self, k: int) -> tuple[Any, ...]:
        """``(call, q (k, n), c (k, m), jac (k, m, p), pose (k, 4, 4))`` of the map over ``k``
        rows (the outputs of one row after the other)."""
        if k not in self._buffers:
            f = self.function if k == 1 else self.function.map(k)
            rows, cols = self.shape
            arrays = (
                np.zeros((k, self.n_q)),
                np.zeros((k, rows)),
                np.zeros((k, rows, cols)),
                np.zeros((k, 4, 4)),
            )
            buffer, call = f.buffer()
            buffer.set_arg(0, memoryview(arrays[0].reshape(-1)))
            for i, out in enumerate(arrays[1:]):
                buffer.set_res(i, memoryview(out.reshape(-1)))
            self._buffers[k] = (buffer, call, *arrays)
        return self._buffers[k][1:]

    def __call__(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(c (K, m), dc/dx (K, m, p), T (K, 4, 4))`` at the rows of ``qs (K, n)``, copies."""
        with self.lock:
            call, q, c, jac, pose = self._buffer(len(qs))
            q[:] = qs
            call()
            return c.copy(), jac.copy(), pose.copy()


_CACHE: PerMechanism[_Compiled] = PerMechanism()
_TWO_PI = 2 * math.pi


def _compiled(m: Mechanism) -> _Compiled:
    if m not in _CACHE:
        q = m.q_sym
        pas = m.passive_indices
        c = m.closure_expr
        jac = ca.jacobian(c, q[[int(i) for i in pas]]) if len(pas) else ca.SX(c.shape[0], 0)
        f = ca.Function("fk_closure", [q], [c, jac])
        cm = _Compiled(f, m.actuated_indices, pas, m.revolute_mask[m.actuated_indices])
        cm.modes = _ModeCheck(m, f)
        _CACHE[m] = cm
    return _CACHE[m]


def same_mode(m: Mechanism, q1: np.ndarray, q2: np.ndarray, tol: float = BRANCH_TOL) -> bool:
    """The same-branch rule: every coordinate differs by ``< tol`` (angles modulo 2 pi)."""
    return joint_distance(m, q1, q2) < tol


@dataclass
class _Solve:
    """Outcome of Levenberg-Marquardt runs on a batch of starts."""

    q: np.ndarray  # (N, n_q)
    residual: np.ndarray  # (N,) max-norm of the closure
    iterations: int


def _levenberg_marquardt(cm: _Compiled, qs: np.ndarray, tol: float, max_iter: int, deadline: float) -> _Solve:
    """Minimize ``|c(x)|^2`` over the passive ``x`` from each row of ``qs`` (actuated kept).

    All rows advance together; each keeps its own damping ``mu`` (divided by 10 after a step
    that lowers the cost, multiplied by 10 otherwise). A row stops when ``max |c| <= tol / 1000``
    (the answer is judged against ``tol``; the margin buys digits near singularities, where the
    residual is quadratic in the error) or when its damping exceeds ``1e12`` (a least-squares
    minimum: the inputs may not assemble).
    """
    q = np.array(qs, dtype=float, ndmin=2)
    c, jac = cm.evaluate(q)
    cost = np.sum(c * c, axis=1)
    mu = np.full(len(q), 1e-8)
    aim = tol * 1e-3
    active = np.max(np.abs(c), axis=1, initial=0.0) > aim
    it = 0
    while it < max_iter and np.any(active) and time.perf_counter() < deadline:
        it += 1
        idx = np.flatnonzero(active)
        jt = np.swapaxes(jac[idx], 1, 2)
        jtj = jt @ jac[idx]
        g = np.einsum("nij,nj->ni", jt, c[idx])
        diag = np.diagonal(jtj, axis1=1, axis2=2)
        scale = diag + 1e-12 * (1 + np.max(diag, axis=1, keepdims=True, initial=0.0))
        lhs = jtj + mu[idx, None, None] * (scale[:, :, None] * np.eye(jtj.shape[1]))
        try:
            dx = np.linalg.solve(lhs, -g[..., None])[..., 0]
        except np.linalg.LinAlgError:
            dx = np.stack([np.linalg.lstsq(a, -b, rcond=None)[0] for a, b in zip(lhs, g, strict=True)])
        trial = q[idx].copy()
        trial[:, cm.pas] += dx
        c_t, jac_t = cm.evaluate(trial)
        cost_t = np.sum(c_t * c_t, axis=1)
        better = np.isfinite(cost_t) & (cost_t < cost[idx])
        up = idx[better]
        q[up], c[up], jac[up], cost[up] = trial[better], c_t[better], jac_t[better], cost_t[better]
        mu[up] = np.maximum(mu[up] / 10, 1e-12)
        mu[idx[~better]] *= 10
        active = (np.max(np.abs(c), axis=1, initial=0.0) > aim) & (mu < 1e12)
    return _Solve(q, np.max(np.abs(c), axis=1, initial=0.0), it)


def _residual_and_condition(cm: _Compiled, q: np.ndarray) -> tuple[float, float]:
    """Max-norm of the closure and condition number of ``dc/dx`` at ``q`` (one evaluation)."""
    c, jac = cm.evaluate(q[None])
    return _measures(c[0], jac[0])


def _measures(c: np.ndarray, jac: np.ndarray) -> tuple[float, float]:
    """Max-norm of the closure ``c`` and condition number of its passive Jacobian ``jac``."""
    return float(np.max(np.abs(c), initial=0.0)), _conditions(jac[None])[0]


def _conditions(jacs: np.ndarray) -> list[float]:
    """`_measures`' condition numbers of a stack of passive Jacobians ``(K, m, p)``
    (`condition_numbers`: one call for the stack)."""
    if not len(jacs):
        return []
    if jacs[0].size == 0:
        return [1.0] * len(jacs)
    return condition_numbers(jacs)


def _distinct(m: Mechanism, qs: np.ndarray) -> list[int]:
    """Indices of the rows of ``qs`` that are new modes, in order: each is kept unless it is the
    same mode (`same_mode`) as a row kept before it. On floats: two modes usually differ in
    their first coordinate already, where the comparison of a pair stops."""
    rows, angular = qs.tolist(), m.revolute_mask.tolist()
    kept: list[int] = []
    for i, row in enumerate(rows):
        if not any(_same_row(row, rows[j], angular) for j in kept):
            kept.append(i)
    return kept


def _same_row(a: list[float], b: list[float], angular: list[bool]) -> bool:
    """`same_mode` on float rows: every ``|a_i - b_i| < BRANCH_TOL``, angles by the float rule of
    `spatial.wrap_angle` (its end fix only flips a sign)."""
    for x, y, wrap in zip(a, b, angular, strict=True):
        d = (x - y + math.pi) % _TWO_PI - math.pi if wrap else x - y
        if not abs(d) < BRANCH_TOL:
            return False
    return True


def _closure_tol(tol: float | Tolerances | None) -> float:
    if tol is None:
        return Tolerances().closure
    if isinstance(tol, Tolerances):
        return tol.closure
    t = float(as_vector(tol, "tol", 1)[0])
    if t <= 0:
        raise InvalidArgumentError("tol", f"must be > 0, got {t}")
    return t


def _positive(value: float, name: str) -> float:
    v = float(as_vector(value, name, 1)[0])
    if v <= 0:
        raise InvalidArgumentError(name, f"must be > 0, got {v}")
    return v


def _violations(m: Mechanism, q: np.ndarray) -> list[str]:
    """Names of the coordinates of ``q`` outside their limits."""
    inside = (m.lower <= q) & (q <= m.upper)
    if inside.all():
        return []  # the usual case, at the cost of three array operations
    return [m.coordinate_names[i] for i in np.flatnonzero(~inside).tolist()]


def _actuated_out(m: Mechanism, a: np.ndarray) -> str:
    """``"rho1 = 2.7 > 2.5, ..."`` for the actuated values outside their limits (``""`` if none)."""
    idx = m.actuated_indices
    lo, hi = m.lower[idx], m.upper[idx]
    if np.all((lo <= a) & (a <= hi)):
        return ""  # the usual case, at the cost of one comparison
    names = [m.coordinate_names[i] for i in idx]
    parts = [
        f"{n} = {v:.6g} {'<' if v < low else '>'} {low if v < low else up:.6g}"
        for n, v, low, up in zip(names, a.tolist(), lo, hi, strict=True)
        if not low <= v <= up
    ]
    return ", ".join(parts)


def _result(
    m: Mechanism,
    cm: _Compiled,
    q: np.ndarray,
    tol: float,
    start: float,
    singular_condition: float,
    note: str = "",
    measured: tuple[float, float, np.ndarray] | None = None,
    **extra: Any,
) -> FKResult:
    """An [`FKResult`][optik.FKResult] for ``q``: residual, success, limits (which coordinates
    are out), condition number, message. ``measured``: ``(residual, condition, pose)`` at
    ``q`` when already known (``q`` is then wrapped already: `Mechanism.wrap` leaves it)."""
    if measured is None:
        qq = m.wrap(q)
        residual, cond = _residual_and_condition(cm, qq)
        pose = m.fk(qq)
    else:
        qq = q
        residual, cond, pose = measured
    closed = residual <= tol
    bad = _violations(m, qq)
    messages = [note] if note else []
    if not closed:
        messages.append(
            f"the actuated values cannot assemble (or no assembly was found): least-squares closure "
            f"residual {residual:.3g} > tol {tol:.3g}"
        )
    actuated_out = _actuated_out(m, qq[cm.act]) if bad else ""  # within every limit: none out
    if actuated_out:
        messages.append(f"the actuated values are outside their limits: {actuated_out}")
    if bad:
        messages.append(f"the {'assembly' if closed else 'configuration'} violates the joint limits of {bad}")
    singular = cond > singular_condition
    if singular:
        messages.append(
            f"near a singularity: condition number {cond:.3g} of the closure Jacobian with respect "
            "to the passive coordinates"
        )
    return FKResult(
        pose=pose,
        q=qq,
        success=bool(closed and not bad),
        residual=float(residual),
        solve_time=time.perf_counter() - start,
        condition_number=cond,
        message="; ".join(messages),
        extra={"singular": singular, **extra},
        limits_ok=not bad,
        limits_violated=tuple(bad),
    )


def _count(value: Any, name: str) -> int:
    """``value`` as an integer >= 0 (else [`InvalidArgumentError`][optik.InvalidArgumentError] naming
    ``name``)."""
    return positive_int(float(as_vector(value, name, 1)[0]) + 1, name) - 1


def _check_inputs(m: Mechanism, actuated: Any) -> np.ndarray:
    if not m.is_closed:
        raise InvalidArgumentError("m", f"mechanism {m.name!r} has no loop closure; use m.fk(q)")
    return as_vector(actuated, "actuated", len(m.actuated_indices))


def _continuation(
    cm: _Compiled, q0: np.ndarray, a: np.ndarray, tol: float, deadline: float, max_jump: float
) -> _Solve | None:
    """Move the actuated values of a closed ``q0`` to ``a`` in steps, Newton at each step
    (angles the short way round).

    A step is accepted when Newton converges within 6 iterations and no passive coordinate
    moves by more than ``max_jump``; otherwise it is halved. Returns None when the step falls
    below ``1e-6`` of the way (a singularity or a non-assemblable stretch lies on the line).
    """
    a0 = q0[cm.act].copy()
    step = a - a0
    step[cm.act_angular] = spatial.wrap_angle(step[cm.act_angular])  # the short way round
    q, s, ds, total = q0.copy(), 0.0, 1.0, 0
    residual = np.zeros(1)
    while s < 1.0:
        if time.perf_counter() > deadline or ds < 1e-6:
            return None
        s_try = min(1.0, s + ds)
        trial = q.copy()
        trial[cm.act] = a0 + s_try * step
        sol = _levenberg_marquardt(cm, trial, tol, 6, deadline)
        total += sol.iterations
        if sol.residual[0] <= tol and np.max(np.abs(sol.q[0, cm.pas] - q[cm.pas]), initial=0.0) <= max_jump:
            q, s, residual = sol.q[0], s_try, sol.residual
            ds *= 2
        else:
            ds /= 2
    q[cm.act] = a  # equal to the tracked values up to multiples of 2 pi
    return _Solve(q[None], residual, total)


def solve_fk(
    m: Mechanism,
    actuated: Any,
    q0: Any = None,
    *,
    time_limit: float = DEFAULT_TIME_LIMIT,
    tol: float | Tolerances | None = None,
    seed: int | np.random.Generator | None = None,
    max_iter: int = 50,
    max_jump: float = 0.5,
    max_restarts: int = 20,
    singular_condition: float = SINGULAR_CONDITION,
) -> FKResult:
    """Forward kinematics: the assembly mode of a closed chain for given actuated coordinates.

    Args:
        m: a mechanism with loop closures.
        actuated: values of the actuated coordinates, in the order of ``m.actuated_indices``.
        q0: start / reference configuration (default: mid-limit). When it closes its loops the
            answer is the assembly mode reached continuously from it (see module docstring).
        time_limit: wall-time budget (s), restarts included.
        tol: closure tolerance (max-norm; a float or [`Tolerances`][optik.Tolerances], default 1e-9).
        seed: seed or Generator of the random restarts used when the first attempt fails.
        max_iter: Levenberg-Marquardt iterations per attempt.
        max_jump: largest change of a passive coordinate in one continuation step.
        max_restarts: random restarts after a failed first attempt (fewer if time runs out).
        singular_condition: condition number above which the result is flagged as singular.

    Returns:
        [`FKResult`][optik.FKResult]; non-assemblable inputs give ``success=False``, the least-squares
        configuration, its ``residual`` and a message.

    Raises:
        OptikError: malformed input (named argument), or a mechanism without loops.
    """
    start = time.perf_counter()
    a = _check_inputs(m, actuated)
    limit = _positive(time_limit, "time_limit")
    tol_c = _closure_tol(tol)
    max_iter = positive_int(max_iter, "max_iter")
    max_jump = _positive(max_jump, "max_jump")
    max_restarts = _count(max_restarts, "max_restarts")
    singular_condition = _positive(singular_condition, "singular_condition")
    deadline = start + limit
    cm = _compiled(m)
    q_start = m.mid_q() if q0 is None else m.check_q(q0, "q0").copy()
    best: _Solve | None = None
    note = ""
    square = m.n_closure == len(cm.pas)
    if square and q0 is not None and np.max(np.abs(m.closure(q_start)), initial=0.0) <= 1e-6:
        best = _continuation(cm, q_start, a, tol_c, deadline, max_jump)
        note = "" if best is not None else "continuation from q0 stopped (singularity on the way?)"
    if best is None or best.residual[0] > tol_c:
        trial = q_start.copy()
        trial[cm.act] = a
        sol = _levenberg_marquardt(cm, trial, tol_c, max_iter, deadline)
        best = sol if best is None or sol.residual[0] < best.residual[0] else best
    rng = as_rng(seed)
    restarts = 0
    while best.residual[0] > tol_c and restarts < max_restarts and time.perf_counter() < deadline:
        restarts += 1
        trial = m.random_q(seed=rng)
        trial[cm.act] = a
        sol = _levenberg_marquardt(cm, trial, tol_c, max_iter, deadline)
        if sol.residual[0] < best.residual[0]:
            best = sol
    if restarts and best.residual[0] <= tol_c:
        note = f"found after {restarts} random restart(s): not necessarily the mode nearest q0"
    return _result(m, cm, best.q[0], tol_c, start, singular_condition, note, restarts=restarts)


def solve_fk_all(
    m: Mechanism,
    actuated: Any,
    *,
    within_limits: bool = True,
    method: str | None = None,
    time_limit: float | None = None,
    tol: float | Tolerances | None = None,
    seed: int | np.random.Generator | None = None,
    patience: int = 64,
    max_iter: int = 50,
    singular_condition: float = SINGULAR_CONDITION,
) -> FKModes:
    """Every real assembly mode for given actuated coordinates.

    Args:
        m: a mechanism with loop closures.
        actuated: values of the actuated coordinates, in the order of ``m.actuated_indices``.
        within_limits: keep only the modes within every joint limit; the others are counted
            and kept on the result's ``dropped`` list, with the reason in its ``message``.
            ``False``: every real mode comes back, each with ``limits_ok`` and
            ``limits_violated`` (``success`` stays False for a mode outside the limits).
        method: ``"closed_form"`` (needs a registered closed form), ``"numeric"`` (multi-start), or
            None: the closed form when registered, else numeric.
        time_limit: wall-time budget (s) of the multi-start and of the closed forms that can
            run long (the Stewart-Gough homotopy, which warns when completeness is not certified
            in time). None: 1 s for the multi-start (`DEFAULT_TIME_LIMIT`), the closed form's own
            default (5 s for the homotopy, whose median is tens of milliseconds).
        tol: closure tolerance (max-norm, default 1e-9).
        seed: seed or Generator of the multi-start.
        patience: the multi-start stops after this many consecutive starts without a new mode.
        max_iter: Levenberg-Marquardt iterations per start.
        singular_condition: condition number above which a mode is flagged as singular.

    Returns:
        [`FKModes`][optik.FKModes]: a list with one [`FKResult`][optik.FKResult] per distinct
        mode (within the limits unless ``within_limits=False``), its ``dropped`` modes and a
        ``message`` that says why modes are missing: inputs that cannot assemble (``[]``; use
        [`solve_fk`][optik.solve_fk] for the least-squares residual), actuated values outside their
        limits, passive joints out of range.

    Raises:
        OptikError: malformed input, unknown method, or ``"closed_form"`` without a closed form.
    """
    start = time.perf_counter()
    a = _check_inputs(m, actuated)
    tol_c = _closure_tol(tol)
    limit = DEFAULT_TIME_LIMIT if time_limit is None else _positive(time_limit, "time_limit")
    patience = positive_int(patience, "patience")
    max_iter = positive_int(max_iter, "max_iter")
    singular_condition = _positive(singular_condition, "singular_condition")
    if method not in (None, "closed_form", "numeric"):
        raise InvalidArgumentError("method", f"unknown FK method {method!r}; use 'closed_form' or 'numeric'")
    within_limits = as_bool(within_limits, "within_limits")
    cm = _compiled(m)
    use_closed = method == "closed_form" or (method is None and closed_form.has_fk(m))
    if use_closed:
        remaining = None if time_limit is None else max(limit - (time.perf_counter() - start), 1e-3)
        rows = closed_form.fk(m, a, respect_limits=False, time_limit=remaining)  # wrapped (m.wrap)
        found, measured = _closed_modes(m, cm, rows, tol_c, max_iter, start + limit)
        label = "closed_form"
    else:
        rng = as_rng(seed)
        found: list[np.ndarray] = []
        measured: list[tuple[float, float, np.ndarray] | None] = []
        idle = 0
        while idle < patience and time.perf_counter() - start < limit:
            trials = m.random_q(BATCH, seed=rng)
            trials[:, cm.act] = a
            sol = _levenberg_marquardt(cm, trials, tol_c, max_iter, start + limit)
            for q_raw, res in zip(sol.q, sol.residual, strict=True):
                q = m.wrap(q_raw)
                if res <= tol_c and not any(same_mode(m, q, f) for f in found):
                    found.append(q)
                    measured.append(None)
                    idle = 0
                else:
                    idle += 1
        label = "numeric"
    kept, dropped, unclosed = [], [], 0
    for q, known in zip(found, measured, strict=True):
        res = _result(m, cm, q, tol_c, start, singular_condition, measured=known, method=label)
        if res.residual > tol_c:
            unclosed += 1  # not a mode: a closed-form candidate that the polish could not close
            continue
        (kept if res.limits_ok or not within_limits else dropped).append(res)
    return FKModes(kept, dropped, _modes_message(m, a, kept, dropped, unclosed))


def _closed_modes(
    m: Mechanism, cm: _Compiled, rows: list[np.ndarray], tol: float, max_iter: int, deadline: float
) -> tuple[list[np.ndarray], list[tuple[float, float, np.ndarray] | None]]:
    """The distinct modes among closed-form ``rows`` (wrapped) and, for each, its ``(residual,
    condition number, pose)`` from one check evaluation of all rows, or None for a row that was
    polished by Levenberg-Marquardt (its residual exceeded ``tol / 1000``: the closed form lost
    digits, e.g. near a singularity; `_result` measures it again)."""
    if not rows:
        return [], []
    qs = np.array(rows)
    c, jac, poses = cm.modes(qs)  # type: ignore[misc]
    residuals = np.max(np.abs(c), axis=1, initial=0.0).tolist()
    measured: list[tuple[float, float, np.ndarray] | None] = [
        (res, cond, pose) for res, cond, pose in zip(residuals, _conditions(jac), poses, strict=True)
    ]
    for i, res in enumerate(residuals):
        if res > tol * 1e-3:
            qs[i], measured[i] = _levenberg_marquardt(cm, qs[i], tol, max_iter, deadline).q[0], None
    kept = _distinct(m, qs)
    return [qs[i] for i in kept], [measured[i] for i in kept]


def _modes_message(
    m: Mechanism, a: np.ndarray, kept: list[FKResult], dropped: list[FKResult], unclosed: int
) -> str:
    """Why `solve_fk_all` returned what it did (``""`` when nothing is missing)."""
    parts = []
    if unclosed:
        parts.append(f"{unclosed} closed-form candidate(s) left out: their closure residual exceeds tol")
    actuated_out = _actuated_out(m, a)
    if actuated_out:
        parts.append(f"the actuated values are outside their limits: {actuated_out}")
    if dropped:
        names = sorted({n for r in dropped for n in r.limits_violated})
        parts.append(
            f"{len(dropped)} assembly mode(s) left out because they violate the joint limits of {names} "
            "(solve_fk_all(..., within_limits=False) returns them)"
        )
    if not kept and not dropped:
        parts.append("the actuated values cannot assemble: no real assembly mode")
    return "; ".join(parts)
