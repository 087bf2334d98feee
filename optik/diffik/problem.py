"""``build_qp``: the quadratic program of one differential-IK step, as an inspectable object.

With the step ``dq = v dt`` (Pink's convention; ``v`` is returned), tasks ``k`` with error
``e_k``, Jacobian ``J_k``, costs ``W_k = diag(cost_k)``, gain ``alpha_k`` and LM damping
``lambda_k``, limits giving ``lb <= dq <= ub`` and, for closed chains, the closure ``c(q)``:

```text
minimise    1/2 dq^T H dq + c^T dq
H = sum_k (W_k J_k)^T (W_k J_k) + mu I,   mu = damping + sum_k lambda_k ||alpha_k W_k e_k||^2
c = sum_k (W_k J_k)^T (alpha_k W_k e_k)
subject to  lb <= dq <= ub,   J_c dq = -gain_c c(q),   G dq <= h
```

``G dq <= h`` are inequality rows: static balance (``support=`` polygon with the unit outward
edge normals ``N`` and offsets ``b``, `optik.solvers.balance.support_halfplanes`) keeps the
linearized ground projection of the centre of mass inside by ``com_margin``,
``N (c_xy(q) + J_com,xy(q) dq) <= b - com_margin``, so ``G = N J_com,xy`` and
``h = b - com_margin - N c_xy(q)`` (none without ``support``).

which is ``1/2 sum_k ||W_k (J_k dq + alpha_k e_k)||^2 + mu/2 ||dq||^2`` up to a constant. Every
term is one compiled CasADi function per mechanism and task structure (see
`optik.diffik._codegen`): a new target or cost changes only parameter values.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_float, as_vector
from optik.diffik._codegen import CompiledFunction
from optik.diffik.base import Limit, Task, intersect
from optik.diffik.collision import DAMPER_GAIN, INFLUENCE, damper_rows
from optik.diffik.limits import ClosureConstraint, ConfigurationLimit, VelocityLimit
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.native import in_background
from optik.solvers.balance import support_halfplanes


@dataclass
class DiffIKProblem:
    """The QP of one step and the task data the other methods use (all numpy).

    Attributes:
        H, c: QP objective ``1/2 dq^T H dq + c^T dq`` (``n x n``, ``n``).
        lb, ub: bounds on ``dq`` from the limits (already intersected).
        A, b: equality ``A dq = b`` (loop closures; ``0 x n`` for open chains).
        jacobian: stacked weighted task Jacobians ``W J`` (rows of all tasks).
        target: stacked weighted task targets ``-alpha W e`` (so the task rows ask
            ``jacobian @ dq = target``).
        errors: stacked raw task errors ``e``.
        closure: closure residual ``c(q)``.
        mu: total Tikhonov + LM damping in ``H``.
        slices: rows of each task in the stacked arrays.
        priorities: priority of each task.
        q: the configuration; dt: the time step.
        G, h: inequality rows ``G dq <= h`` (static balance, then collision dampers; ``0 x n``
            without them).
    """

    H: np.ndarray
    c: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    A: np.ndarray
    b: np.ndarray
    jacobian: np.ndarray
    target: np.ndarray
    errors: np.ndarray
    closure: np.ndarray
    mu: float
    slices: list[slice]
    priorities: list[int]
    q: np.ndarray
    dt: float
    cache: Any = field(default=None, repr=False)
    G: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    h: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n(self) -> int:
        """Number of coordinates."""
        return int(self.q.shape[0])

    def task_errors(self) -> list[np.ndarray]:
        """Raw error vector of each task, in task order."""
        return [self.errors[s] for s in self.slices]

    def levels(self) -> list[np.ndarray]:
        """Row indices of each priority level (highest priority first)."""
        rows = []
        for level in sorted(set(self.priorities)):
            idx = [
                np.arange(s.start, s.stop)
                for s, p in zip(self.slices, self.priorities, strict=True)
                if p == level
            ]
            rows.append(np.concatenate(idx))
        return rows

    def objective(self, dq: np.ndarray) -> float:
        """``1/2 dq^T H dq + c^T dq``."""
        return float(0.5 * dq @ self.H @ dq + self.c @ dq)


def stack_casadi(
    m: Mechanism,
    tasks: Sequence[Task],
    limits: Sequence[Limit],
    closure: ClosureConstraint | None,
    geometry: ca.SX | None = None,
) -> ca.Function:
    """The CasADi function ``(q, p, dt, v_prev) -> (H, c, lb, ub, A, b, W J, -alpha W e, e, c(q),
    mu)`` of one task structure (`StackFunction`). ``geometry``: symbols the model's expressions
    depend on besides ``q`` (the chain of `optik.diffik.generic_stack`), appended to ``p``."""
    n = m.n_q
    q = m.q_sym
    dt = ca.SX.sym("dt")
    v_prev = ca.SX.sym("v_prev", n)
    pieces: list[ca.SX] = []
    rows_j, rows_t, rows_e = [], [], []
    mu = ca.SX(0)
    for k, task in enumerate(tasks):
        pt = ca.SX.sym(f"p{k}", task.n_parameters(m))
        w = ca.SX.sym(f"w{k}", task.dim)
        gain = ca.SX.sym(f"g{k}")
        lm = ca.SX.sym(f"lm{k}")
        pieces += [pt, w, gain, lm]
        e, jac = task.expressions(m, q, pt)
        target = -gain * w * e
        rows_j.append(ca.diag(w) @ jac)
        rows_t.append(target)
        rows_e.append(e)
        mu = mu + lm * ca.dot(target, target)
    lb: Any = ca.SX.zeros(n) - 1e20
    ub: Any = ca.SX.zeros(n) + 1e20
    for i, limit in enumerate(limits):
        pl = ca.SX.sym(f"l{i}", limit.parameters(m).shape[0])
        pieces.append(pl)
        lo, hi = limit.bounds(m, q, pl, dt, v_prev)
        lb, ub = intersect(lb, ub, lo, hi)
    damping = ca.SX.sym("damping")
    pieces.append(damping)
    if geometry is not None:
        pieces.append(geometry)
    mu = mu + damping
    jw = ca.vertcat(*rows_j)
    tw = ca.vertcat(*rows_t)
    hess = ca.mtimes(jw.T, jw) + mu * ca.SX.eye(n)
    lin = -ca.mtimes(jw.T, tw)
    if closure is not None and m.is_closed:
        cres, jc, bc = closure.expressions(m, q)
    else:
        cres, jc, bc = ca.SX(0, 1), ca.SX(0, n), ca.SX(0, 1)
    p = ca.vertcat(*pieces)
    outs = [hess, lin, lb, ub, jc, bc, jw, tw, ca.vertcat(*rows_e), cres, mu]
    return ca.Function("diffik_stack", [q, p, dt, v_prev], outs)


def task_slices(dims: Sequence[int]) -> tuple[list[slice], np.ndarray]:
    """The rows of each task (of ``dims`` rows each) in the stacked arrays, and the first row of each."""
    bounds = np.cumsum([0, *dims])
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)], bounds[:-1]


class StackFunction:
    """Compiled evaluation of every task, limit and closure term of one task structure.

    Inputs ``(q, p, dt, v_prev)``; ``p`` concatenates, per task, its parameters, costs, gain and
    LM damping, then each limit's parameters, then the Tikhonov damping.
    """

    def __init__(
        self, m: Mechanism, tasks: Sequence[Task], limits: Sequence[Limit], closure: ClosureConstraint | None
    ) -> None:
        f = stack_casadi(m, tasks, limits, closure)
        self.function = CompiledFunction(f)
        self.n_closure = int(f.size1_out(4))
        self.dims = [t.dim for t in tasks]
        self.slices, self.starts = task_slices(self.dims)
        self._local = threading.local()

    @property
    def backends(self) -> dict[str, Any]:
        """QP backend objects that keep state between steps (OSQP workspace, cvxpy problem):
        each thread has its own, so concurrent steps never share a solver's workspace."""
        found = getattr(self._local, "backends", None)
        if found is None:
            found = self._local.backends = {}
        return found

    def __call__(
        self, q: np.ndarray, p: list[np.ndarray], dt: float, v_prev: np.ndarray
    ) -> tuple[np.ndarray, ...]:
        """Evaluate at ``q`` with the parameter pieces ``p`` (concatenated here, in one copy)."""
        return self.function.call_flat(np.concatenate([q, *p, np.array([dt]), v_prev]))


_STACKS: PerMechanism[dict[tuple, StackFunction]] = PerMechanism()
_FIRST_STACKS: list[Callable[[Mechanism, Sequence[Task], Sequence[Limit]], StackFunction | None]] = []


def register_first_stack(
    find: Callable[[Mechanism, Sequence[Task], Sequence[Limit]], StackFunction | None],
) -> None:
    """Let `stack_function` answer with ``find(m, tasks, limits)`` (when not None) while the stack
    of ``m`` is not compiled yet, and build that one in the background meanwhile
    (`optik.diffik.generic_stack` registers itself on import)."""
    _FIRST_STACKS.append(find)


_STARTED: PerMechanism[set[tuple]] = PerMechanism()  # stacks being built in the background


def normalize_limits(m: Mechanism, limits: Sequence[Limit] | None) -> list[Limit]:
    """The limits of a step, sorted by rank, with a
    [`ConfigurationLimit`][optik.diffik.problem.ConfigurationLimit] always present.

    ``None`` means the mechanism's velocity limits (when ``m.params`` has them) and its position
    limits.
    """
    if limits is None:  # cached: the default limits' parameters are computed once
        cached = _DEFAULT_LIMITS.get(m)
        if cached is None:
            found = [VelocityLimit.of(m)] if "velocity_limits" in m.params else []
            cached = _DEFAULT_LIMITS[m] = [*found, ConfigurationLimit()]
        return cached
    else:
        chosen = _as_list(limits, "limits", "Limit")
        for lim in chosen:
            if not isinstance(lim, Limit):
                raise InvalidArgumentError("limits", f"expected Limit objects, got {type(lim).__name__}")
    if not any(isinstance(lim, ConfigurationLimit) for lim in chosen):
        chosen.append(ConfigurationLimit())
    return sorted(chosen, key=lambda lim: lim.rank)


_ZEROS: dict[int, np.ndarray] = {}
_DEFAULT_LIMITS: PerMechanism[list[Limit]] = PerMechanism()


MIN_DT = 1e-9
"""Shortest time step (s): ``v = dq / dt`` of a shorter one can overflow."""


def _positive_float(value: Any, name: str, strict: bool = False) -> float:
    """``value`` as a float ``>= 0`` (``> 0`` when ``strict``), else an error naming ``name``."""
    if type(value) is float and math.isfinite(value) and (value > 0 or (value == 0 and not strict)):
        return value
    return as_float(value, name, 0.0, strict=strict)


def _as_list(items: Any, name: str, kind: str) -> list:
    """``items`` as a list (else [`InvalidArgumentError`][optik.InvalidArgumentError] naming ``name``)."""
    if isinstance(items, (str, bytes)) or not isinstance(items, Iterable):
        raise InvalidArgumentError(name, f"expected a sequence of {kind} objects, got {type(items).__name__}")
    return list(items)


def _check_tasks(tasks: Sequence[Task]) -> list[Task]:
    if isinstance(tasks, Task):
        tasks = [tasks]
    out = _as_list(tasks, "tasks", "Task")
    if not out:
        raise InvalidArgumentError("tasks", "need at least one task")
    for t in out:
        if not isinstance(t, Task):
            raise InvalidArgumentError("tasks", f"expected Task objects, got {type(t).__name__}")
    return out


def stack_function(
    m: Mechanism, tasks: Sequence[Task], limits: Sequence[Limit], closure_gain: float
) -> StackFunction:
    """The compiled [`StackFunction`][optik.diffik.problem.StackFunction] of a task structure (built once,
    then cached)."""
    key = (tuple(t.key() for t in tasks), tuple(lim.key() for lim in limits), closure_gain)
    per_m = _STACKS.get(m)
    if per_m is None:
        per_m = _STACKS[m] = {}
    stack = per_m.get(key)
    if stack is None or not stack.function.compiled:
        generic = next((s for f in _FIRST_STACKS if (s := f(m, tasks, limits)) is not None), None)
        if generic is not None:  # until the stack of m is compiled (built in the background)
            started = _STARTED.setdefault(m, set())
            if stack is None and key not in started:
                started.add(key)
                task_list, lims = list(tasks), list(limits)

                def build() -> None:
                    per_m[key] = StackFunction(m, task_list, lims, ClosureConstraint(closure_gain))

                in_background(build)
            return generic
    if stack is None:
        stack = per_m[key] = StackFunction(m, tasks, limits, ClosureConstraint(closure_gain))
    return stack


def build_qp(
    m: Mechanism,
    q: Any,
    tasks: Sequence[Task] | Task,
    dt: float,
    limits: Sequence[Limit] | None = None,
    *,
    v_prev: Any = None,
    damping: float = 1e-12,
    closure_gain: float = 1.0,
    support: Any = None,
    com_margin: float = 0.0,
    world: Any = None,
    self_collision: bool | None = None,
    margin: float = 0.0,
    influence: float = INFLUENCE,
    collision_gain: float = DAMPER_GAIN,
) -> DiffIKProblem:
    """The QP of one differential-IK step at ``q`` (see the module docstring for the formulas).

    Args:
        m: the mechanism.
        q: current coordinates (may lie outside the limits; the bounds then lead back in).
        tasks: the tasks (a single task is accepted).
        dt: time step (s), at least `MIN_DT`.
        limits: limits on the step (default: the mechanism's velocity limits if known, and its
            position limits; a [`ConfigurationLimit`][optik.diffik.problem.ConfigurationLimit] is always
            added).
        v_prev: previous joint velocity for [`AccelerationLimit`][optik.diffik.AccelerationLimit] (default
            zero).
        damping: Tikhonov regularisation ``mu`` (``>= 0``).
        closure_gain: gain of the loop-closure constraint (closed chains).
        support: the world x-y support polygon, counter-clockwise ``(k, 2)``: the balance rows
            ``G dq <= h`` of the module docstring (the mechanism needs masses).
        com_margin: the balance margin (m, ``>= 0``; only with ``support``).
        world: obstacles ([`optik.World`][optik.World]); with it or ``self_collision=True`` the
            velocity dampers of `optik.diffik.collision` join ``G dq <= h``: every pair closer
            than ``influence`` may lose at most ``collision_gain`` of its distance above
            ``margin`` per step.
        self_collision: dampers for the robot's own pairs too (None: True when ``world`` is given).
        margin: the clearance the dampers keep (m).
        influence: the distance (m) below which a pair gets a damper.
        collision_gain: ``gamma`` in ``(0, 1]``.

    Returns:
        The [`DiffIKProblem`][optik.diffik.problem.DiffIKProblem].

    Raises:
        OptikError: a subclass naming the bad argument (q, tasks, dt, limits, v_prev, damping, a
            task's target or frame).
    """
    qq = m.check_q(q)  # raises the error naming q
    task_list = _check_tasks(tasks)
    step = as_float(dt, "dt", MIN_DT)
    lims = normalize_limits(m, limits)
    vp = _ZEROS.setdefault(m.n_q, np.zeros(m.n_q)) if v_prev is None else as_vector(v_prev, "v_prev", m.n_q)
    stack = stack_function(m, task_list, lims, _positive_float(closure_gain, "closure_gain"))
    parts: list[np.ndarray] = []
    for t in task_list:
        parts += [t.parameters(m), t.cost, np.array([t.gain, t.lm_damping])]
    parts += [lim.parameters(m) for lim in lims]
    parts.append(np.array([_positive_float(damping, "damping")]))
    h, c, lb, ub, a, b, jw, tw, e, cres, mu = stack(qq, parts, step, vp)
    rows = jw.shape[0]
    g_rows, h_rows = balance_rows(m, qq, support, com_margin)
    own = (world is not None) if self_collision is None else bool(self_collision)
    if world is not None or own:
        g_c, h_c, _ = damper_rows(m, qq, world, own, margin, influence, collision_gain)
        if h_rows.size:
            g_rows, h_rows = np.vstack([g_rows, g_c]), np.concatenate([h_rows, h_c])
        else:
            g_rows, h_rows = g_c, h_c
    return DiffIKProblem(
        H=h.reshape(m.n_q, m.n_q),
        c=c,
        lb=lb,
        ub=ub,
        A=a.reshape(stack.n_closure, m.n_q),
        b=b,
        jacobian=jw.reshape(rows, m.n_q),
        target=tw,
        errors=e,
        closure=cres,
        mu=float(mu[0]),
        slices=stack.slices,
        priorities=[t.priority for t in task_list],
        q=qq,
        dt=step,
        cache=stack,
        G=g_rows,
        h=h_rows,
    )


def balance_rows(m: Mechanism, q: np.ndarray, support: Any, com_margin: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(G, h)``: the linearized balance rows ``G dq <= h`` at ``q`` (module docstring; ``0 x n``
    without ``support``).

    Raises:
        InvalidArgumentError: a malformed ``support`` or ``com_margin``, or a margin without a polygon.
        ModelError: the mechanism has no mass.
    """
    margin = as_float(com_margin, "com_margin", 0.0)
    if support is None:
        if margin != 0.0:
            raise InvalidArgumentError("com_margin", "a balance margin needs a support polygon (support=...)")
        return np.zeros((0, m.n_q)), np.zeros(0)
    normals, b = support_halfplanes(support)
    com, jac = m.com_function(q)
    com, jac = np.asarray(com).reshape(-1), np.asarray(jac)
    return normals @ jac[:2], b - margin - normals @ com[:2]
