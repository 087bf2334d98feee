"""Collision-aware IK: ``solve_ik(m, T, world=W, self_collision=True, margin=0.01)``.

Two methods take the constraints, from the conservative sphere and capsule model of
`optik.collision.spheres` (``d_k(q)``: lower bounds of the signed distances of the robot to the
world, one row per moving sphere and world slot, and to itself, one row per capsule pair),
required to stay above ``b = margin + buffer`` (``buffer`` option, default 2 mm, the room
between the model and the exact check):

* ``lm``: the rows ``max(0, b - d_k(q))`` join the loop-closure rows of a second compiled
  Levenberg-Marquardt kernel (`optik.solvers.collision_kernel`, its world and self rows loops
  in the generated C, run by `optik.solvers.lm_kernel`'s driver, weight ``closure_weight``): a squared
  hinge penalty that is zero wherever the model is clear, so a start stops only when the task
  is met *and* every row is zero. Each round runs the unconstrained kernel (with its restarts)
  until the pose is met; when the exact check finds that answer colliding, the next round starts
  from a new random configuration (rejection, cheap), and at round ``plain_rounds`` (option,
  default `PLAIN_ROUNDS`) the constrained kernel first starts from the colliding answer (one
  start, once per call: it slides the arm out along the self-motion while keeping the pose),
  until the time limit. Once: where the capsules are much fatter than the meshes the model keeps
  the pose's clear answers out, and a further start only costs time. TALOS (`optik benchmark
  collision_self`): every one of its 100 targets' own clear configurations violates some capsule
  pair the kernel models (the right gripper against the right thigh: capsules -0.21 m apart
  where coal finds -0.05 m), each start of the 754-pair kernel stalls in a few milliseconds
  still colliding, and a slide at every round solved 96/100 at 2.6-2.8 ms mean against 100/100
  at 0.84-0.89 ms for one slide a call (50 ms limit, same run, load 2.2). No slide at all when
  the kernel has no active row (an empty world, and no self pair kept by
  `optik.collision.spheres.separable_pairs`, as on TALOS since no sample clears its capsules
  together).
* ``nlp``: IPOPT with the inequality constraints ``d_k(q) >= b`` (and the loop closures),
  objective as `optik.IKProblem`'s, multi-start until the time limit. An iteration callback
  (`ClearStop`) stops a start at the first iterate that meets the pose tolerances with every
  model row satisfied (``d_k(q) >= b``), as the plain ``nlp`` stops at tolerance. An empty world
  gives no world rows (its slots' rows would be constants, and IPOPT's iteration costs grow with
  the rows: on the dual Panda 1104 of them tripled it, to about 30 ms). The Hessian is the exact
  one: IPOPT's limited-memory approximation and a Gauss-Newton Hessian without the rows'
  curvature took 3 to 5 times more iterations there and solved fewer targets in the time limit.
  IPOPT's functions (``f``, ``g``, their derivatives, the Hessian) are
  `optik.solvers.collision_nlp`'s, built from one row function mapped over the pairs and the
  (sphere, slot) rows, and compiled to C in the background (`optik.native`; CasADi's evaluator
  until then, and for good without a compiler or with the option ``compile=False``). The time
  limit: the callback stops a start at its first iterate past the deadline, and no restart
  begins with less time left than the last start took before its first iterate. Dual Panda, an
  IPOPT iteration (CPU time, loaded machine): 11.6 ms with the rows as one expression in the
  evaluator, 3.5 ms now (the Hessian 0.6 ms of it; the rest is IPOPT's linear algebra, see
  `MUMPS_ORDER`).

The world is read once per call (`optik.World.state`: one version, so a `World.move` during the
solve changes neither the slots nor the exact check of this call) and handed to the generated
code as parameter values (`optik.collision.slots`), and so is the bound ``b`` with the flags of the
self pairs the capsules can keep that far apart (`optik.collision.spheres.separable_pairs`; the
others are left to the exact check): the code is cached per mechanism, task, frame and slot
capacity, so a moved, added or removed object or a new margin builds nothing new. The first
build of a key is made once, under a lock (a second thread waits for it).

Later calls of `optik.solve_ik` with a 4x4 target and the options of a first call (``lm``) go
through its `CollisionCall`: the first round is ``lm``'s own prepared C call, its answer judged
by the exact check (`optik.collision.check.search`, no report objects), whose first decision (no
screening bound under the margin: clear without a coal query, 3 in 4 of the Panda's answers in
clutter) runs in that same C call (`optik.collision.check.ClearTest`); the rounds go on from it
when it is not clear. The answers are the general path's.

**Success** is decided by the exact check (`optik.collision.check` at ``margin``) of the final
answer, after the tolerances: a start whose answer the check finds closer than the margin is
rejected and the search goes on from a new random start until the time limit. The result
carries ``min_distance`` and ``collision_pair`` (the closest pair at ``q``); a failure says
which pair blocked when the pose was reached but the answer collides. Its ``solve_time`` is set
last, after the exact check of the answer returned (on every path: the prepared call, ``lm``'s
rounds, ``nlp``), so it is the wall time of the whole call; the full search that a clear answer's
``min_distance`` makes when first read (`optik.results.LazyDistanceResult`) is the reader's.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from typing import Any

import casadi as ca
import numpy as np

from optik import native
from optik.checks import as_float
from optik.collision.check import ClearTest, Search, search
from optik.collision.robot import robot_geometry
from optik.collision.screen import screen
from optik.collision.slots import SLOT_SIZE
from optik.collision.spheres import capsule_gaps
from optik.collision.world import World, WorldState, state_of
from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.problem import IKProblem, build_ik_problem, target_parameters
from optik.results import IKResult, LazyDistanceResult
from optik.solvers.base import IKRequest, PreparedCache, make_result, positive_int
from optik.solvers.collision_kernel import bound_parameters, constrained_functions
from optik.solvers.collision_nlp import NLPFunctions, nlp_functions
from optik.solvers.evaluation import ErrorFn, errors_against
from optik.solvers.iteration_stop import IterationStop
from optik.solvers.lm import LMCall, lm_result, lm_settings, prepare_kernel, prepare_lm, request_seed
from optik.solvers.lm_kernel import LMKernel

__all__ = [
    "METHODS",
    "CollisionCall",
    "compiled_kernels",
    "prepare_collision_free",
    "solve_collision_free",
]

METHODS = ("lm", "nlp")
"""Methods that take collision constraints."""

_OWN_OPTIONS = {"buffer": 0.002}
"""Options of the collision-aware solve itself (the rest go to the method)."""

PLAIN_ROUNDS = 8
"""Default of the ``lm`` option ``plain_rounds``: rounds of the unconstrained kernel whose answers
collide before the constrained kernel starts from one. Rejection is cheap (Panda: about 0.1 ms a
round, exact check included) and the constrained kernel about 2 ms a start; on 400 targets each
of the clutter and the self-collision benchmark scenes (10 ms limit, CPU time, same run),
starting it after the first colliding round solved 398 and 395 at 0.20 and 0.40 ms mean, after
four 399 and 399 at 0.15 and 0.20 ms, after eight 400 (clutter) at 0.13 ms."""


_CACHE: dict[tuple[Any, ...], Any] = {}
_CACHE_MAX = 32
_LOCK = threading.Lock()
_BUILDING: dict[tuple[Any, ...], threading.Lock] = {}


def _cached(key: tuple[Any, ...], build: Any) -> Any:
    """The cached value of ``key``, built by ``build()`` once: a second thread asking for a key
    being built waits for that build instead of starting its own."""
    with _LOCK:
        hit = _CACHE.get(key)
        if hit is not None:
            return hit
        building = _BUILDING.setdefault(key, threading.Lock())
    with building:
        with _LOCK:
            hit = _CACHE.get(key)
        if hit is None:
            hit = build()
            with _LOCK:
                if len(_CACHE) >= _CACHE_MAX:
                    _CACHE.clear()
                _CACHE[key] = hit
                _BUILDING.pop(key, None)
    return hit


def compiled_kernels() -> dict[str, bool]:
    """``{mechanism name: compiled}`` of the constrained ``lm`` kernels built so far (False: still
    answering through CasADi's evaluator while the C compiler runs)."""
    with _LOCK:
        hits = [(key[1].name, v) for key, v in _CACHE.items() if key[0] == "lm"]
    return {name: kernel.compiled for name, kernel in hits}


def _split_options(request: IKRequest, method: str) -> tuple[IKRequest, float, int]:
    """The request without the collision-aware solve's own options, ``buffer`` and (``lm``)
    ``plain_rounds``, and their values."""
    opts = dict(request.options)
    buffer = as_float(opts.pop("buffer", _OWN_OPTIONS["buffer"]), "buffer", 0.0)
    rounds = positive_int(opts.pop("plain_rounds", PLAIN_ROUNDS), "plain_rounds") if method == "lm" else 0
    return dataclasses.replace(request, options=opts), buffer, rounds


class _Exact:
    """The exact check of a solve's answers (`optik.collision.check.search` at ``margin``) against
    the one world version the solve read."""

    def __init__(self, m: Mechanism, world: WorldState, self_collision: bool, margin: float) -> None:
        self.geo, self.world = robot_geometry(m), world
        self.self_collision, self.margin = self_collision, margin
        # the screens the search may ask for, built here on first use (tens of ms: the solvers
        # make their _Exact within the setup they exclude from the time limit), not inside a timed
        # check (the finer one is asked for only when many world pairs stay close)
        screen(self.geo, world.capacity, coarse=True)
        if world.parts:
            screen(self.geo, world.capacity)

    def finish(self, res: IKResult, stop: bool = False, outputs: list[np.ndarray] | None = None) -> IKResult:
        """``res`` judged by the exact check as well (see the module docstring), with the distance
        and the names of the closest pair of its ``q``; with ``stop``, the search only decides
        (`optik.collision.check.search`): an answer that collides is rejected at its first close
        pair (`complete` makes the distance, the pair and the message exact for the answer
        returned), a clear success is a `LazyDistanceResult` whose distance and pair the full
        search makes when they are first read. ``outputs``: the coarse screen's at ``res.q``, made
        already (`optik.collision.check.search`)."""
        found = search(self.geo, res.q, self.world, self.margin, self.self_collision, stop, outputs)
        if stop and res.success and not found.in_collision:
            return self.clear(res)
        return self._judged(res, found, res.success, False)

    def clear(self, res: IKResult) -> LazyDistanceResult:
        """A success ``res`` the search with ``stop`` finds clear, as `finish` returns it: its
        distance and pair made by the full search when first read."""
        q = res.q.copy()  # the q judged, whatever a caller later does to the result's array
        return LazyDistanceResult(res, lambda: self._nearest(q))

    def _nearest(self, q: np.ndarray) -> tuple[float, tuple[str, str] | None]:
        """The exact smallest distance at ``q`` and the names of its pair (the full search)."""
        found = search(self.geo, q, self.world, self.margin, self.self_collision)
        return np.inf if found.nearest is None else found.nearest[0], found.names(self.geo, self.world)

    def complete(self, res: IKResult) -> IKResult:
        """The answer a solve returns, judged by `finish` with ``stop``, judged in full when it
        failed (a success is clear: its distance and pair are the full search's, made when read)."""
        if res.success:
            return res
        found = search(self.geo, res.q, self.world, self.margin, self.self_collision)
        return self._judged(res, found, res.status == "in_collision", True)

    def _judged(self, res: IKResult, found: Search, reached: bool, full: bool) -> IKResult:
        """``res`` with the distance and pair of ``found``; when some pair is close, its message
        names the closest close pair, and when the pose is ``reached`` it fails as
        ``"in_collision"`` (an answer that failed otherwise, e.g. at the time limit, keeps its
        status and, when ``found`` is a full search, says which pair its configuration also
        brings too close)."""
        res.min_distance = np.inf if found.nearest is None else found.nearest[0]
        res.collision_pair = found.names(self.geo, self.world)
        if found.in_collision:
            d, a, b, on_world, _ = min(found.close, key=lambda e: e[0])
            other = (self.world.parts[b] if on_world else self.geo.parts[b]).name
            pair = f"{self.geo.parts[a].name!r} and {other!r} are {d:.4g} m apart (margin {self.margin:g} m)"
            if reached:
                res.success, res.status = False, "in_collision"
                res.message = f"the pose is reached but {pair}"
            elif full:
                res.message = f"{res.message}; in its configuration {pair}"
        return res


_PREPARED: PreparedCache[tuple[LMKernel, LMKernel, np.ndarray]] = PreparedCache()
"""Per mechanism: the validated settings of a request (`_kernels`)."""


def _kernels(
    request: IKRequest, capacity: int, self_collision: bool
) -> tuple[LMKernel, LMKernel, np.ndarray]:
    """The unconstrained kernel of a request (``lm``'s own, `optik.solvers.lm.prepare_kernel`), the
    constrained one and the driver's ``conf``, the validated settings cached per request key
    (validation costs more than a solve)."""
    m = request.mechanism
    key = _PREPARED.key(request, capacity, self_collision)
    hit = _PREPARED.get(m, key)
    if hit is not None:
        return hit
    plain, conf = prepare_kernel(request)  # type: ignore[misc]  # built: never None
    _, closure_weight, compile = lm_settings(request)

    def build() -> LMKernel:
        problem = build_ik_problem(m, request.task, request.frame)
        geo = robot_geometry(m)
        functions = constrained_functions(problem, geo, capacity, self_collision, closure_weight)
        if self_collision:
            capsule_gaps(geo)  # what the solves' bound_parameters read: built here, not in a solve
        return LMKernel(m, request.task, request.frame, closure_weight, compile, functions=functions)

    constrained = _cached(
        ("lm", m, request.task, request.frame, closure_weight, compile, capacity, self_collision), build
    )
    return _PREPARED.put(m, key, (plain, constrained, conf))


_SEEDS = 2**63 - 1
"""Mask of the round seeds of the collision-aware ``lm``."""


def _solve_lm(
    request: IKRequest,
    world: WorldState,
    self_collision: bool,
    margin: float,
    buffer: float,
    plain_rounds: int,
    first: IKResult | None = None,
) -> IKResult:
    """The rounds of the module docstring; ``first``: the first round's answer already judged by
    the exact check (`CollisionCall`), the rounds going on from it."""
    m = request.mechanism
    setup = time.perf_counter()
    plain, constrained, base = _kernels(request, world.capacity, self_collision)
    exact = _Exact(m, world, self_collision, margin)
    request.exclude_setup(setup)
    conf = base.copy()
    pose = target_parameters(request.target)
    seed = request_seed(request.seed) & _SEEDS
    rng: np.random.Generator | None = None  # the random starts of rounds 2, 3, ...
    res, rounds = first, int(first is not None)
    iterations, restarts = (0, -1) if first is None else (first.iterations, first.restarts)

    slid = False  # the constrained kernel starts once a call

    def slide(res: IKResult) -> IKResult:
        """From a colliding answer (at round ``plain_rounds`` or the first after it), the
        constrained kernel (one start, once per call; none when no row of it is active: an empty
        world and no self pair kept), its answer judged by the pose errors alone (its own
        closure error holds the model's hinges)."""
        nonlocal iterations, slid
        if slid or res.status != "in_collision" or rounds < plain_rounds or request.remaining() <= 0:
            return res
        slid = True
        bounds = bound_parameters(exact.geo, self_collision, margin + buffer)
        if not world.parts and not bounds[1:].any():
            return res
        once = conf.copy()
        once[2], once[3] = 0, request.remaining()
        params = np.concatenate([pose, world.slots, bounds])
        q, _, it, _, code = constrained.run_one(params, res.q, seed, once)
        iterations += it
        err = plain.final_errors(q, pose)
        res = lm_result(request, plain, q, err, iterations, restarts, code, pose)
        return exact.finish(res, stop=True)

    if res is not None:
        res = slide(res)
    while res is None or (not res.success and request.remaining() > 0):
        q0 = request.q0
        if res is not None:  # a new round from a new random configuration
            seed = (seed * 6364136223846793005 + 1442695040888963407) & _SEEDS
            rng = np.random.default_rng(seed) if rng is None else rng
            q0 = m.random_q(seed=rng)
        rounds += 1
        # the unconstrained kernel (its own restarts) until the pose is met ...
        conf[3] = max(request.remaining(), 0.0)
        q, err, it, starts, code = plain.run_one(pose, q0, seed, conf)
        iterations += it
        restarts += starts + 1
        # ... then, when that answer collides, perhaps the constrained kernel from it
        res = lm_result(request, plain, q, err, iterations, restarts, code, pose)
        res = slide(exact.finish(res, stop=True))  # a rejected answer's search stops early
    res = exact.complete(res)
    if not res.success and res.status in ("not_converged", "max_restarts"):
        res.status = "time_limit"  # the rounds end only at a success or at the time limit
    res.solve_time = request.elapsed()  # the exact checks included
    return res


class CollisionCall:
    """The prepared call of the collision-aware ``lm`` (see `optik.solvers.base.PreparedCall`,
    with the world as a fifth argument): the later calls of `optik.solve_ik` with the options of a
    first request (time limit, tolerances, options, margin and ``self_collision`` validated once).

    The first round is ``lm``'s own prepared call (`optik.solvers.lm.LMCall`: one C call, the
    unconstrained kernel from ``q0`` with the seed), whose answer the exact check judges against
    the world read once here (`optik.World.state`); a clear answer is the result (its
    ``solve_time`` from ``start`` to the end of that check), any other goes
    on through the rounds of `_solve_lm` from it (same answers as the general path: the same
    kernel, seed and rounds). It returns None before solving, for the general path to take the
    call, when ``lm``'s call does (input it does not take, code not built) and for a seed that
    is not None or an int in ``[0, 2^63)`` (a Generator's draw would be taken twice), a world that
    is not an `optik.World` or None (the general path names it).

    The exact check's first decision runs in that same C call once the coarse screen is
    compiled (`optik.collision.check.ClearTest`, one per thread and world version): an answer
    kept as it is whose screening bounds are all above the margin is clear with no Python
    search (3 in 4 of the Panda's clutter answers); any other answer is judged by the search,
    as before. Same answers either way: the test is the search's own first step.

    Args:
        request: the first, validated request (its collision options ``buffer`` and
            ``plain_rounds`` split off: `_split_options`).
        plain: ``lm``'s prepared call of ``request``.
        self_collision, margin, buffer, plain_rounds: the validated collision settings.
    """

    def __init__(
        self,
        request: IKRequest,
        plain: LMCall,
        self_collision: bool,
        margin: float,
        buffer: float,
        plain_rounds: int,
    ) -> None:
        self.request, self.plain = request, plain
        self.settings = (self_collision, margin, buffer, plain_rounds)
        self._local = threading.local()  # this thread's (_Exact, ClearTest or None) of a world version

    def _judges(self, state: WorldState) -> tuple[_Exact, ClearTest | None]:
        """This thread's exact check of ``state`` and its `ClearTest` (None until the coarse
        screen is compiled), made again for another world version."""
        got = getattr(self._local, "judges", None)
        if got is not None and got[0].world is state and got[1] is not None:
            return got
        self_collision, margin, _, _ = self.settings
        exact = _Exact(self.request.mechanism, state, self_collision, margin)
        clear = screen(exact.geo, state.capacity, coarse=True).clear_function()
        test = None if clear is None else ClearTest(exact.geo, state, margin, self_collision, clear)
        got = self._local.judges = (exact, test)
        return got

    def __call__(self, start: float, target: np.ndarray, q0: Any, seed: Any, world: Any) -> IKResult | None:
        """Solve for ``target`` from ``q0`` (None: mid-limit) with seed ``seed`` clear of ``world``;
        None when the call is left to the general path (see the class)."""
        if not (seed is None or (type(seed) is int and 0 <= seed <= _SEEDS)):
            return None
        if world is not None and not isinstance(world, World):
            return None
        state = state_of(world)
        exact, test = self._judges(state)
        if test is None:
            res = self.plain(start, target, q0, seed)
        else:
            test.verdict[0] = -1
            res = self.plain(start, target, q0, seed, test.address)
        if res is None:
            return None
        verdict = -1 if test is None else test.verdict[0]
        if verdict == 1:  # a success the bounds alone find clear
            res = exact.clear(res)
        else:  # the search decides (from the test's screen outputs at res.q when it ran)
            res = exact.finish(res, stop=True, outputs=None if verdict == -1 else test.outputs)
        if res.success:
            res.solve_time = time.perf_counter() - start  # the exact check included
            return res
        self_collision, margin, buffer, plain_rounds = self.settings
        m = self.request.mechanism
        request = dataclasses.replace(
            self.request,
            target=target,
            q0=m.mid_q() if q0 is None else m.check_q(q0, "q0"),  # taken by the first round: valid
            seed=seed,
            options=dict(self.request.options),
            start=start,
            setup_time=0.0,
        )
        return _solve_lm(request, state, self_collision, margin, buffer, plain_rounds, first=res)


class ClearStop(IterationStop):
    """Iteration callback of the collision-aware IPOPT: stops at the deadline, or at the first
    iterate whose pose errors are within the tolerances (`errors` against `goal`: position,
    orientation, closure) and whose constraint rows after the ``n_closure`` loop closures are all
    ``>= 0`` (the sphere and capsule model clear by the bound).

    Args:
        n_x, n_g, n_p: the NLP's sizes; n_closure: its leading equality rows.
    """

    def __init__(self, n_x: int, n_g: int, n_p: int, n_closure: int) -> None:
        self.n_closure = n_closure
        self.errors: ErrorFn | None = None
        self.goal = (0.0, 0.0, 0.0)
        self.first: float | None = None  # perf_counter of the solve's first callback (None: none yet)
        self.last, self.calls = 0.0, 0  # ... of its latest one, and how many there were
        IterationStop.__init__(self, n_x, n_g, n_p, "optik_collision_stop")

    def seen(self) -> None:
        """Record a callback (the time IPOPT takes before its first iterate, and per iteration)."""
        self.last, self.calls = time.perf_counter(), self.calls + 1
        if self.first is None:
            self.first = self.last

    def start(self) -> float:
        """Forget the callbacks of the previous solve; the time now."""
        self.first, self.calls = None, 0
        return time.perf_counter()

    def needs(self, began: float) -> float:
        """Seconds the last solve (begun at ``began``) took to its first iterate and then one
        iteration (its mean): what a new start needs before it can leave its starting point."""
        if self.first is None:
            return 0.0
        step = (self.last - self.first) / (self.calls - 1) if self.calls > 1 else 0.0
        return self.first - began + step

    def eval_buffer(self, arg: list[memoryview], res: list[memoryview]) -> int:
        """`IterationStop.eval_buffer` with the constraint values ``g`` (the solver's output 2)."""
        self.seen()
        x = np.frombuffer(arg[0], dtype=float).copy()
        g = np.frombuffer(arg[2], dtype=float)
        np.frombuffer(res[0], dtype=float)[0] = float(self.clear(x, g) or self.check(x))
        return 0

    def eval(self, arg: list[Any]) -> list[int]:
        self.seen()
        x = np.array(arg[0].nonzeros())
        return [int(self.clear(x, np.array(arg[2].nonzeros())) or self.check(x))]

    def clear(self, x: np.ndarray, g: np.ndarray) -> bool:
        """Whether ``x`` meets the tolerances with every model row ``g[n_closure:] >= 0``."""
        if self.errors is None or not np.all(g[self.n_closure :] >= 0.0):
            return False
        return all(e <= t for e, t in zip(self.errors(x), self.goal, strict=True))


MUMPS_ORDER = 0
"""MUMPS's fill-reducing ordering of IPOPT's KKT systems here (``mumps_pivot_order``: 0 is AMD,
IPOPT's default 7 lets MUMPS choose). With the hundreds of inequality rows of these NLPs the
linear algebra, not the functions, took most of an iteration once those were compiled: Panda
clutter (564 rows), 100 iterations from mid-limit to a pose out of reach, CPU time per iteration
2.55-2.57 ms with the default against 1.32-1.36 ms with AMD (1.34-1.35 with AMF, 2.6-3.0 with
PORD, METIS or QAMD); dual Panda (376 rows) 2.7-3.2 against 2.55-2.7 ms. An ordering changes only
the rounding of the steps: the reference targets took the same iterations and restarts."""


class _IpoptPool:
    """IPOPT instances of one constrained problem, one per concurrent solve (nlpsol instances
    are not safe to share between threads), each with its `IterationStop` callback (the
    deadline of the solve running on it) that also stops at a clear answer within the tolerances
    (`ClearStop`).

    The NLP's functions are `optik.solvers.collision_nlp`'s (small mapped pieces), compiled into
    one library by `optik.native.library` in the background: until it is loaded the instances
    evaluate them in CasADi's virtual machine, then new instances call the compiled code
    (``casadi.external``) and the idle ones of the evaluator are dropped.

    Args:
        problem: the pose problem.
        functions: its collision-aware NLP (`optik.solvers.collision_nlp.nlp_functions`).
        max_iter: IPOPT's iterations per start.
        compile: `optik.native.library`'s ``compile`` option.
    """

    def __init__(
        self, problem: IKProblem, functions: NLPFunctions, max_iter: int, compile: bool | str
    ) -> None:
        self.problem, self.functions = problem, functions
        n_g, n_c = functions.g.size1_out(0), functions.n_closure
        self.sizes = (functions.f.size1_in(0), n_g, functions.f.size1_in(1))
        self.lbg = ca.DM(np.zeros(n_g))
        self.ubg = ca.DM(np.concatenate([np.zeros(n_c), np.full(n_g - n_c, np.inf)]))
        self.options = {
            "print_time": False,
            "ipopt": {
                "print_level": 0,
                "sb": "yes",
                "max_iter": max_iter,
                "tol": 1e-14,
                "acceptable_iter": 0,
                "mumps_pivot_order": MUMPS_ORDER,
            },
        }
        self.library = native.library(functions.all(), compile)
        self._compiled: list[ca.Function] | None = None
        self._free: list[tuple[Any, ClearStop, bool]] = []
        self._lock = threading.Lock()

    def _loaded(self) -> list[ca.Function] | None:
        """The compiled functions once the library is ready (None before, and without one)."""
        if self._compiled is None and self.library is not None and self.library.state == "ready":
            # finite differences only let nlpsol build its gradient of the Lagrangian (``nlp_grad``,
            # for multipliers nothing reads, never evaluated): the derivatives IPOPT calls are ours
            path, fd = str(self.library.path), {"enable_fd": True}
            self._compiled = [ca.external(f.name(), path, fd) for f in self.functions.all()]
        return self._compiled

    @property
    def compiled(self) -> bool:
        """Whether new instances call the compiled functions."""
        return self._loaded() is not None

    def take(self) -> tuple[Any, ClearStop, bool]:
        """An idle ``(nlpsol, its callback, compiled)``, or a new one (compiled once it can be)."""
        compiled = self._loaded()
        with self._lock:
            if compiled is not None:  # the evaluator's instances are not taken again
                self._free = [t for t in self._free if t[2]]
            if self._free:
                return self._free.pop()
        f, g, grad_f, jac_g, hess_lag = compiled or self.functions.all()
        x, p = ca.MX.sym("x", self.sizes[0]), ca.MX.sym("p", self.sizes[2])
        nlp = {"x": x, "p": p, "f": f(x, p), "g": g(x, p)}
        stop = ClearStop(*self.sizes, self.functions.n_closure)
        options = {
            **self.options,
            "iteration_callback": stop,
            "error_on_fail": False,
            "calc_lam_p": False,  # multipliers nothing reads
            "calc_lam_x": False,
            "grad_f": grad_f,
            "jac_g": jac_g,
            "hess_lag": hess_lag,
        }
        return ca.nlpsol("optik_collision_ipopt", "ipopt", nlp, options), stop, compiled is not None

    def give(self, solver: tuple[Any, ClearStop, bool]) -> None:
        with self._lock:
            self._free.append(solver)


def _solve_nlp(
    request: IKRequest, world: WorldState, self_collision: bool, margin: float, buffer: float
) -> IKResult:
    m = request.mechanism
    opts = dict(request.options)
    max_iter = positive_int(opts.pop("max_iter", 200), "max_iter")
    posture = as_float(opts.pop("posture", 1e-9), "posture", 0.0)
    compile = native.check_compile(opts.pop("compile", "auto"))
    if opts:
        raise InvalidArgumentError(
            next(iter(opts)), "unknown option of the collision-aware nlp (max_iter, posture, buffer, compile)"
        )
    setup = time.perf_counter()
    # no world rows for an empty world: its slots' rows are constants, but IPOPT pays for each row
    capacity = world.capacity if world.parts else 0
    key = ("nlp", m, request.task, request.frame, capacity, self_collision, max_iter, compile)

    def build() -> _IpoptPool:
        base = build_ik_problem(m, request.task, request.frame)
        functions = nlp_functions(base, robot_geometry(m), capacity, self_collision)
        return _IpoptPool(base, functions, max_iter, compile)

    pool = _cached(key, build)
    taken = pool.take()
    solver, stop, _ = taken
    bounds = bound_parameters(robot_geometry(m), self_collision, margin + buffer)
    exact = _Exact(m, world, self_collision, margin)
    request.exclude_setup(setup)
    task = pool.problem.parameter_values(request.target, posture=posture)
    params = ca.DM(np.concatenate([task, world.slots[: capacity * SLOT_SIZE], bounds]))
    limits = {"lbx": ca.DM(m.lower), "ubx": ca.DM(m.upper), "lbg": pool.lbg, "ubg": pool.ubg}

    rng = request.rng
    q0, iterations, restarts = request.q0, 0, -1
    stop.deadline = request.start + request.time_limit  # after exclude_setup: the build is not counted
    stop.errors = errors_against(m, request.task, request.frame, request.target)
    stop.goal = (request.tol.position, request.tol.orientation, request.tol.closure)
    try:
        while True:
            restarts += 1
            began = stop.start()
            sol = solver.call({"x0": ca.DM(q0), "p": params, **limits})
            iterations += int(solver.stats().get("iter_count", 0))
            # a new start given less time than IPOPT's work to its first iterate (set-up, first
            # evaluations and factorization) and one iteration would end at its starting point, late
            over = request.remaining() <= stop.needs(began)
            q = np.asarray(sol["x"]).ravel()
            res = exact.finish(
                make_result(request, q, "nlp", iterations, restarts, "time_limit" if over else None)
            )
            if res.success or over:
                res.solve_time = request.elapsed()  # the exact check included
                return res
            q0 = m.random_q(seed=rng)
    finally:
        pool.give(taken)


def prepare_collision_free(
    request: IKRequest, method: str | None, self_collision: bool, margin: Any
) -> CollisionCall | None:
    """The `CollisionCall` of a request solved once by `solve_collision_free` (its input valid),
    None for the ``nlp`` method or where ``lm`` has no prepared call (`optik.solvers.lm.prepare_lm`)."""
    if method not in (None, "lm"):
        return None
    plain_request, buffer, rounds = _split_options(request, "lm")
    plain = prepare_lm(plain_request)
    if plain is None:
        return None
    mg = as_float(margin, "margin", 0.0)
    return CollisionCall(plain_request, plain, bool(self_collision), mg, buffer, rounds)


def solve_collision_free(
    request: IKRequest, method: str, world: Any, self_collision: bool, margin: Any
) -> IKResult:
    """Solve a request with collision constraints (see the module docstring).

    Raises:
        InvalidArgumentError: a bad ``world`` or ``margin``, or an unknown option.
        SolverUnavailableError: a method without collision constraints.
    """
    if method not in METHODS:
        raise SolverUnavailableError(
            f"method {method!r} takes no collision constraints; use one of {METHODS}"
        )
    state = state_of(world)  # the one version of the world this solve reads
    mg = as_float(margin, "margin", 0.0)
    request, buffer, rounds = _split_options(request, method)
    if method == "lm":
        return _solve_lm(request, state, bool(self_collision), mg, buffer, rounds)
    return _solve_nlp(request, state, bool(self_collision), mg, buffer)
