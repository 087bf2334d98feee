"""Velocity dampers: collision avoidance as inequality rows of the differential-IK QP.

For every pair (the robot against the world, and against itself) whose exact signed distance
``d`` (coal, `optik.collision.distance`) is below the *influence distance* ``d_i``, with witness
points ``p_a`` on the robot link ``a`` and ``p_b`` on ``b`` (a world object, or another link),
the distance changes to first order by

    delta d = n^T (J_a(p_a) - J_b(p_b)) dq,   n = (p_a - p_b) / |p_a - p_b|   (``-n`` when ``d < 0``)

with ``J_x(p) = J_v - [p - o_x]_x J_w`` the Jacobian of the point ``p`` fixed to link ``x``
(origin ``o_x``, geometric Jacobian ``[J_v; J_w]``; zero for a world object), so that
``n^T J_x(p) = n^T J_v + ((p - o_x) x n)^T J_w``. The damper of Faverjon and Tournassoud, in the
discrete form of a control barrier function, lets the distance shrink by at most the fraction
``gamma`` of its excess over the margin ``d_s`` per step:

    d + delta d >= d_s + (1 - gamma) (d - d_s)   <=>   -n^T (J_a - J_b) dq <= gamma (d - d_s),

one row ``G dq <= h`` per pair (pairs further than ``d_i`` give none: the QP is unchanged away
from obstacles). A pair already closer than the margin gets a row that pushes it out.

*Broad phase.* Only pairs that may be within ``d_i`` get an exact query: those whose screening
bound (`optik.collision.screen`: one compiled call for the part poses and a lower bound of every
pair's distance, from the spheres and capsules that contain the parts) is below ``d_i`` (the
bound is at most the distance, so a pair whose bound is not below ``d_i`` is not within it). The
screen is built for the smallest power of two of slots that holds the world's parts (the world's
own slot values, cut there), not the world's capacity: each slot costs a bound per sphere. Parts on
the base body get no world rows (their distance does not depend on ``q``: a row
``0 <= gamma (d - d_s)`` could only make the QP infeasible; the exact check still judges them).

*Pairs.* With the compiled code loaded, one compiled function (`screen_blocks`) gives the screen's
outputs and every moving body's ``[J^0; J_w]`` (below), and one C call
(`optik.diffik.damper_pairs`, compiled with it) computes the exact distance and witness points of
every pair whose bound is below ``d_i`` and the rows of those within ``d_i``, closest first. Without
it (no compiler, the build still running) or when that call cannot decide a pair (hulls that
overlap, a cylinder), coal answers every pair, through per-thread objects made once (a transform
per part, updated in place, one request and one result), and each pair within ``d_i`` writes its
witness points, the sign of ``d``, ``d`` and the bodies of its ends into the input buffers of a
second compiled function (`DamperKernel`), which computes every row in one call.

With
``J^0 = J_v + [o]_x J_w`` (the velocity of the point of the body at the base origin) the point
Jacobian is ``J^0 - [p]_x J_w``, so ``n^T J_x(p) = [n; p x n]^T [J^0; J_w]``, and since
``(p_a - p_b) x n = 0`` both ends share ``c = p_a x n``:

    G_pair = [n; c]^T (sigma_b [J^0; J_w]_b - sigma_a [J^0; J_w]_a),   h_pair = gamma (d - d_s),

with ``sigma`` the ``+-1`` selection of the two ends' bodies (none for an obstacle or the base).
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_float
from optik.collision.distance import signed_request
from optik.collision.robot import RobotGeometry, robot_geometry
from optik.collision.screen import Screen, screen, screen_function
from optik.collision.shapes import coal_module
from optik.collision.slots import SLOT_SIZE
from optik.collision.world import WorldState, state_of
from optik.diffik.damper_pairs import DRIVER, CompiledPairs
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.native import Library, NativeFunction, driver_source, library

__all__ = ["DAMPER_GAIN", "INFLUENCE", "DamperKernel", "damper_kernel", "damper_rows"]

INFLUENCE = 0.05
"""Default influence distance ``d_i`` (m)."""

DAMPER_GAIN = 0.5
"""Default ``gamma``: the fraction of the excess distance a step may use up."""

SLOTS = (1, 2, 4, 8)
"""Pair counts of the row functions compiled together when a kernel is made; a step takes the
smallest power of two that holds its candidate pairs (larger ones are built when first needed)."""

PAIR_SIZE = 8
"""Numbers per pair in the row function's input: ``p_a`` (3), ``p_b`` (3), the sign of ``d``, ``d``."""


def body_blocks(m: Mechanism, links: list[str]) -> list[ca.SX]:
    """``[J^0; J_w]`` (6 x n) of the body of each link: ``J^0 = J_v + [o]_x J_w``, the velocity of
    the body's point at the base origin (module docstring)."""
    blocks = []
    for link in links:
        jac, origin = m.jacobian_expr(link), m.frame_expr(link)[:3, 3]
        blocks.append(ca.vertcat(jac[:3, :] + ca.mtimes(ca.skew(origin), jac[3:, :]), jac[3:, :]))
    return blocks


def screen_blocks(geo: RobotGeometry, links: list[str], capacity: int) -> ca.Function:
    """``(q, slots) -> (poses, world, self, blocks)``: `optik.collision.screen.screen_function`'s
    outputs and the `body_blocks` of ``links`` (each column-major, one after the other): what
    `optik.diffik.damper_pairs`'s driver reads."""
    m = geo.mechanism
    blocks = ca.densify(ca.vertcat(ca.SX(0, 1), *(ca.vec(b) for b in body_blocks(m, links))))
    return screen_function(geo, capacity, blocks)


def row_function(m: Mechanism, links: list[str], slots: int) -> ca.Function:
    """``(q, pairs, sigma, (gamma, d_s)) -> rows``: the damper rows of ``slots`` pairs.

    ``pairs``: `PAIR_SIZE` numbers per pair (``p_a``, ``p_b``, ``s = +-1`` the sign of ``d``,
    ``d``); ``sigma``: ``len(links)`` numbers per pair, ``-1`` at the body of ``a``, ``+1`` at
    that of ``b`` (0 elsewhere; both 0 for the base body or an obstacle); ``rows``: ``n + 2``
    numbers per pair, the row ``G`` (module docstring, ``n = s (p_a - p_b) / |p_a - p_b|``),
    ``h`` and ``|p_a - p_b|``.
    """
    n_b = len(links)
    q = m.q_sym
    pairs, sigma = ca.SX.sym("pairs", PAIR_SIZE * slots), ca.SX.sym("sigma", n_b * slots)
    params = ca.SX.sym("params", 2)
    blocks = body_blocks(m, links)
    rows = []
    for k in range(slots):
        u = pairs[PAIR_SIZE * k : PAIR_SIZE * (k + 1)]
        p_a, delta = u[:3], u[:3] - u[3:6]
        length = ca.norm_2(delta)
        normal = delta * (u[6] / ca.fmax(length, 1e-300))  # touching pairs (length ~ 0) are dropped
        w = ca.vertcat(normal, ca.cross(p_a, normal)).T
        sel = sigma[n_b * k : n_b * (k + 1)]
        row = sum((sel[b] * ca.mtimes(w, blocks[b]) for b in range(n_b)), ca.SX.zeros(1, m.n_q))
        rows.append(ca.vertcat(row.T, params[0] * (u[7] - params[1]), length))
    return ca.Function(f"collision_damper_rows_{slots}", [q, pairs, sigma, params], [ca.vertcat(*rows)])


@dataclass(eq=False)
class DamperKernel:
    """What the dampers of one robot geometry evaluate at every step, built once.

    Attributes:
        mechanism: the mechanism.
        links: one link of each of the ``B`` moving bodies that carry parts.
        part_body: ``(P,)`` the body of each part (``B`` for the base body, which has no rows).
        blocked: ``(P, 1)`` ``inf`` for the parts on the base body (no world rows), else 0.
    """

    mechanism: Mechanism
    links: list[str]
    part_body: np.ndarray
    blocked: np.ndarray
    _functions: dict[int, tuple[ca.Function, Any]] = field(default_factory=dict, repr=False)
    _screens: dict[int, tuple[ca.Function, Library | None]] = field(default_factory=dict, repr=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def rows(self, slots: int) -> NativeFunction:
        """A new evaluator (for one thread) of the [`row_function`][optik.diffik.collision.row_function]
        of ``slots`` pairs (built at its first use, its C code in the background, CasADi's
        evaluator meanwhile)."""
        with self._lock:
            made = self._functions.get(slots)
            if made is None:
                f = row_function(self.mechanism, self.links, slots)
                made = self._functions[slots] = (f, library([f], "auto"))
        return NativeFunction(*made)

    def screen(self, geo: RobotGeometry, capacity: int) -> tuple[ca.Function, Library | None]:
        """`screen_blocks` of ``capacity`` slots and its library, with `optik.diffik.damper_pairs`'s
        driver (built at the first use, its C code in the background; None: no compiler, or the
        driver's source unreadable)."""
        with self._lock:
            made = self._screens.get(capacity)
            if made is None:
                f = screen_blocks(geo, self.links, capacity)
                source = driver_source(DRIVER)
                made = self._screens[capacity] = (f, library([f], "auto", source) if source else None)
        return made


def _kernel(geo: RobotGeometry) -> DamperKernel:
    m = geo.mechanism
    bodies: dict[str, str] = {}  # body -> its first link with parts
    for k in geo.part_link:
        link = geo.links[int(k)]
        body = m.frames[link][0]
        if body != m.base:
            bodies.setdefault(body, link)
    index = {body: i for i, body in enumerate(bodies)}
    links = list(bodies.values())
    part_body = np.array([index.get(m.frames[geo.links[int(k)]][0], len(links)) for k in geo.part_link])
    blocked = np.where(part_body < len(links), 0.0, np.inf)[:, None]
    kernel = DamperKernel(m, links, part_body, blocked)
    functions = [row_function(m, links, slots) for slots in SLOTS]
    lib = library(functions, "auto")  # one library, its C code building from now on
    kernel._functions.update({slots: (f, lib) for slots, f in zip(SLOTS, functions, strict=True)})
    return kernel


_KERNELS: weakref.WeakKeyDictionary[RobotGeometry, DamperKernel] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def damper_kernel(geo: RobotGeometry) -> DamperKernel:
    """The [`DamperKernel`][optik.diffik.collision.DamperKernel] of a geometry (built once, cached
    with it; its C code builds in the background, CasADi's evaluator answering meanwhile)."""
    with _LOCK:
        hit = _KERNELS.get(geo)
    if hit is None:
        hit = _kernel(geo)
        with _LOCK:
            hit = _KERNELS.setdefault(geo, hit)
    return hit


class _Queries:
    """One thread's objects for one geometry: its kernel and screens (looked up here without the
    shared caches' locks), a transform per part (set in place from the
    screen's poses), coal's distance functor of every self-collision pair (its solver made once;
    the same numbers as ``coal.distance``), one signed-distance request and one result (cleared
    before each query), and the last world state's geometries."""

    def __init__(self, geo: RobotGeometry) -> None:
        coal = coal_module()
        self.geo, self.kernel = geo, damper_kernel(geo)
        self._screens: dict[int, Screen] = {}
        self._screen_calls: dict[int, tuple[NativeFunction, list[WorldState | None]]] = {}
        self._compiled: dict[int, tuple[NativeFunction, CompiledPairs, list[WorldState | None]]] = {}
        self._rows: dict[int, tuple[NativeFunction, list[float]]] = {}  # with its (gamma, d_s) input
        self.transforms = [coal.Transform3s() for _ in geo.parts]
        self.set_rotation = [t.setRotation for t in self.transforms]
        self.set_translation = [t.setTranslation for t in self.transforms]
        self.geometries = [p.geometry for p in geo.parts]
        self.self_pairs = geo.self_pairs.tolist()
        g = self.geometries
        self.self_distance = [coal.ComputeDistance(g[i], g[j]) for i, j in self.self_pairs]
        self.body = geo_body = self.kernel.part_body.tolist()
        self.moving = [b < len(self.kernel.links) for b in geo_body]
        self.request = signed_request()
        result = coal.DistanceResult()
        self.distance, self.clear = coal.distance, result.clear
        self.result, self.point_a, self.point_b = result, result.getNearestPoint1, result.getNearestPoint2
        self.state: WorldState | None = None
        self.world_geometries: list[Any] = []

    def rows(self, slots: int, gamma: float, d_s: float) -> NativeFunction:
        """This thread's row evaluator of ``slots`` pairs (`DamperKernel.rows`), its parameter
        input set to ``(gamma, d_s)`` (written only when they change)."""
        hit = self._rows.get(slots)
        if hit is None:
            hit = self._rows[slots] = (self.kernel.rows(slots), [np.nan, np.nan])
        fn, params = hit
        if params[0] != gamma or params[1] != d_s:
            fn.inputs[3][:] = params[:] = gamma, d_s
        return fn

    def screen(self, capacity: int) -> Screen:
        """`optik.collision.screen.screen` of the geometry for ``capacity`` slots."""
        hit = self._screens.get(capacity)
        if hit is None:
            hit = self._screens[capacity] = screen(self.geo, capacity)
        return hit

    def screen_call(self, capacity: int, state: WorldState) -> NativeFunction:
        """This thread's evaluator of the screen for ``capacity`` slots, its slot input holding
        ``state``'s values (written only when the state changes)."""
        hit = self._screen_calls.get(capacity)
        if hit is None:
            hit = self._screen_calls[capacity] = (self.screen(capacity).evaluator(), [None])
        fn, written = hit
        if written[0] is not state:
            fn.inputs[1][:] = state.slots[: capacity * SLOT_SIZE]
            written[0] = state
        return fn

    def compiled(self, capacity: int, state: WorldState) -> tuple[NativeFunction, CompiledPairs] | None:
        """This thread's compiled `screen_blocks` of ``capacity`` slots (its slot input holding
        ``state``'s values) and driver call (`optik.diffik.damper_pairs`), or None while their
        library is not loaded (building, or no compiler)."""
        hit = self._compiled.get(capacity)
        if hit is None:
            f, lib = self.kernel.screen(self.geo, capacity)
            cdll = None if lib is None else lib.get()
            if cdll is None:
                return None
            n_b, n_q = len(self.kernel.links), self.geo.mechanism.n_q
            call = CompiledPairs(self.geo, cdll, self.moving, self.body, n_b, n_q)
            hit = self._compiled[capacity] = (NativeFunction(f, lib), call, [None])
        fn, call, written = hit
        if written[0] is not state:
            fn.inputs[1][:] = state.slots[: capacity * SLOT_SIZE]
            written[0] = state
        return fn, call

    def world(self, state: WorldState) -> list[Any]:
        """The coal geometries of ``state``'s parts (listed again only when the state changes)."""
        if state is not self.state:
            self.state, self.world_geometries = state, [p.geometry for p in state.parts]
        return self.world_geometries


_QUERIES = threading.local()


def _queries(m: Mechanism) -> _Queries:
    per = getattr(_QUERIES, "per", None)
    if per is None:
        per = _QUERIES.per = weakref.WeakKeyDictionary()
    hit = per.get(m)
    if hit is None:
        hit = per[m] = _Queries(robot_geometry(m))
    return hit


def damper_rows(
    m: Mechanism,
    q: np.ndarray,
    world: Any,
    self_collision: bool,
    margin: Any = 0.0,
    influence: Any = INFLUENCE,
    gain: Any = DAMPER_GAIN,
) -> tuple[np.ndarray, np.ndarray, float]:
    """``(G, h, d_min)``: the damper rows ``G dq <= h`` at ``q`` (module docstring), ordered by
    increasing distance, and the smallest exact distance of the pairs queried (``inf``: no pair's
    screening bound is below the influence distance).

    Raises:
        InvalidArgumentError: a negative ``margin``, an ``influence`` not above it, a ``gain``
            outside ``(0, 1]``, or a bad ``world``.
    """
    d_s = as_float(margin, "margin", 0.0)
    d_i = as_float(influence, "influence", 0.0)
    if not d_i > d_s:
        raise InvalidArgumentError("influence", f"must exceed the margin {d_s:g} m, got {d_i:g}")
    gamma = as_float(gain, "collision_gain")
    if not 0.0 < gamma <= 1.0:
        raise InvalidArgumentError("collision_gain", f"must be in (0, 1], got {gamma:g}")
    state = state_of(world)
    cq = _queries(m)
    n_obj = len(state.parts)
    capacity = 1 << max(n_obj - 1, 0).bit_length()  # the slots in use: every empty one costs a step time
    compiled = cq.compiled(capacity, state)
    if compiled is not None:
        fn, call = compiled
        fn.inputs[0][:] = q
        outputs = fn()
        call.bind(state, outputs)
        k = call(d_i, gamma, d_s, self_collision)
        if k >= 0:
            out = call.rows[: (m.n_q + 1) * k].reshape(k, m.n_q + 1).copy()  # off the thread's buffer
            return out[:, : m.n_q], out[:, m.n_q], float(call.d_min[0])
    else:
        fn = cq.screen_call(capacity, state)
        fn.inputs[0][:] = q
        outputs = fn()
    return _coal_rows(m, q, cq, state, outputs[:3], self_collision, d_i, gamma, d_s)


def _coal_rows(
    m: Mechanism,
    q: np.ndarray,
    cq: _Queries,
    state: WorldState,
    outputs: list[np.ndarray],
    self_collision: bool,
    d_i: float,
    gamma: float,
    d_s: float,
) -> tuple[np.ndarray, np.ndarray, float]:
    """`damper_rows` with coal's distances, from the screen's ``outputs``."""
    kernel = cq.kernel
    n_obj = len(state.parts)
    capacity = 1 << max(n_obj - 1, 0).bit_length()
    poses, to_world, own = cq.screen(capacity).reduce(outputs, n_obj)
    near = (to_world + kernel.blocked < d_i).ravel().nonzero()[0].tolist()  # part a * n_obj + object b
    n_world = len(near)
    if self_collision:
        near += (own < d_i).nonzero()[0].tolist()  # rows of geo.self_pairs
    if not near:
        return np.zeros((0, m.n_q)), np.zeros(0), np.inf
    slots = 1 << (len(near) - 1).bit_length()
    fn = cq.rows(slots, gamma, d_s)
    fn.inputs[0][:] = q
    pairs, sigma = fn.inputs[1], fn.inputs[2]
    sigma[:] = 0.0
    tfs, geometries, body, moving = cq.transforms, cq.geometries, cq.body, cq.moving
    distance, clear, request, result = cq.distance, cq.clear, cq.request, cq.result
    world_geometries, world_tfs, self_distance = cq.world(state), state.transforms, cq.self_distance
    placed = [False] * len(tfs)
    rotations, translations = poses[:, :9].reshape(-1, 3, 3), poses[:, 9:]  # row-major rotation, then origin
    n_b = len(kernel.links)
    dists: list[float] = []  # of the pairs within the influence distance, in slot order
    d_min = np.inf
    for r, i in enumerate(near):
        a, b = divmod(i, n_obj) if r < n_world else cq.self_pairs[i]
        if not placed[a]:
            cq.set_rotation[a](rotations[a])
            cq.set_translation[a](translations[a])
            placed[a] = True
        clear()
        if r < n_world:
            d = distance(geometries[a], tfs[a], world_geometries[b], world_tfs[b], request, result)
        else:
            if not placed[b]:
                cq.set_rotation[b](rotations[b])
                cq.set_translation[b](translations[b])
                placed[b] = True
            d = self_distance[i](tfs[a], tfs[b], request, result)
        if d < d_min:
            d_min = d
        if d < d_i:
            k = len(dists)
            at = PAIR_SIZE * k
            pairs[at : at + 3] = cq.point_a()
            pairs[at + 3 : at + 6] = cq.point_b()
            pairs[at + 6] = 1.0 if d >= 0 else -1.0
            pairs[at + 7] = d
            if moving[a]:
                sigma[n_b * k + body[a]] -= 1.0
            if r >= n_world and moving[b]:
                sigma[n_b * k + body[b]] += 1.0
            dists.append(d)
    if not dists:
        return np.zeros((0, m.n_q)), np.zeros(0), float(d_min)
    k = len(dists)
    order = sorted(range(k), key=dists.__getitem__)
    if order != list(range(k)):  # closest first, as the compiled call writes them
        pairs[: PAIR_SIZE * k] = pairs[: PAIR_SIZE * k].reshape(k, PAIR_SIZE)[order].ravel()
        sigma[: n_b * k] = sigma[: n_b * k].reshape(k, n_b)[order].ravel()
    return _rows_out(fn, slots, k, m.n_q, float(d_min))


def _rows_out(
    fn: NativeFunction, slots: int, k: int, n_q: int, d_min: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """``(G, h, d_min)`` of the row function ``fn`` of ``slots`` pairs whose first ``k`` are set."""
    out = fn()[0].reshape(slots, n_q + 2)[:k].copy()  # off the thread's buffer
    # touching at one point (|p_a - p_b| ~ 0) has no direction: no row (the check still decides success)
    if min(out[:, -1].tolist()) < 1e-12:
        out = out[out[:, -1] >= 1e-12]
    return out[:, :n_q], out[:, n_q], d_min
