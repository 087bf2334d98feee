"""`check` and `check_many`: exact collision queries of a mechanism at ``q``, with coal.

The pairs checked are the robot's self-collision pairs (`optik.collision.robot`, when
``self_collision``) and every robot part against every world object. Each pair's signed
distance (negative: penetration depth) comes from coal (`optik.collision.distance`). To stay
exact and fast, every pair first gets a lower bound of its distance from models that contain the
parts (`optik.collision.screen`: the robot's spheres, bounding spheres and capsules, each
obstacle's rounded box; one compiled call for all pairs, a second one where the first's coarse
world bounds leave many pairs: `search`), the pairs are taken in increasing order of it, and the
search stops once the bound exceeds the smallest distance found, the margin and 0: no pair left out can
be the closest, closer than the margin, or touching. The witness points are read from coal only
for the pairs reported. A part no joint moves (`RobotGeometry.fixed_parts`: the Panda's base
link) is as far from each object at every ``q``: its coal entries are kept per world version once
found, their distance taken as their bound (the Panda's base on its table was the least coarse
bound, so coal's first query, at nearly every configuration). `ClearTest` is the search's first
decision with ``stop`` (no bound under the margin: clear, no coal query) as a C check that a
compiled solve runs on its answer in its own C call (`optik.solvers.collision_free.CollisionCall`).

``in_collision`` is True when some pair is closer than ``margin`` or touches (distance
``<= 0``): at ``margin=0`` it means contact or penetration; with a margin, a clearance below
it. `CollisionReport.min_distance` is the smallest signed distance over the pairs checked
(``inf`` when there is no pair at all).
"""

from __future__ import annotations

import ctypes
import threading
import weakref
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from optik.checks import as_batch, as_bool, as_float
from optik.collision.distance import signed_request
from optik.collision.parts import Part
from optik.collision.robot import RobotGeometry, robot_geometry
from optik.collision.screen import screen
from optik.collision.shapes import coal_module
from optik.collision.world import World, WorldState, state_of
from optik.mechanism import Mechanism

__all__ = [
    "ClearTest",
    "CollisionBatch",
    "CollisionPair",
    "CollisionReport",
    "Search",
    "check",
    "check_many",
    "report_at",
    "search",
    "world_parts",
]


@dataclass(frozen=True)
class CollisionPair:
    """Two parts and their signed distance.

    Attributes:
        a: the robot link.
        b: the other robot link, or the world object.
        distance: signed distance (m; negative: penetration depth).
        point_a: witness point on ``a`` (base frame).
        point_b: witness point on ``b`` (base frame).
        world: True when ``b`` is a world object.
    """

    a: str
    b: str
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray
    world: bool


@dataclass(frozen=True)
class CollisionReport:
    """The answer of `check` at one configuration.

    Attributes:
        in_collision: some pair is closer than ``margin`` or touches.
        min_distance: smallest signed distance over the pairs (``inf``: no pair).
        pair: names of the closest pair (None: no pair).
        witness: its witness points ``(on a, on b)`` (None: no pair).
        close_pairs: every pair closer than the margin or touching, closest first.
        margin: the margin of the query.
        checked: pairs whose exact distance was computed.
        candidates: pairs considered (the rest are further than their bound).
    """

    in_collision: bool
    min_distance: float
    pair: tuple[str, str] | None
    witness: tuple[np.ndarray, np.ndarray] | None
    close_pairs: tuple[CollisionPair, ...]
    margin: float
    checked: int
    candidates: int

    @property
    def closest(self) -> CollisionPair | None:
        """The closest pair as a `CollisionPair` (None: no pair)."""
        if self.pair is None or self.witness is None:
            return None
        world = bool(self.close_pairs and self.close_pairs[0].b == self.pair[1] and self.close_pairs[0].world)
        return CollisionPair(self.pair[0], self.pair[1], self.min_distance, *self.witness, world)


@dataclass(frozen=True)
class CollisionBatch:
    """The answers of `check_many`.

    Attributes:
        in_collision: ``(N,)`` bools.
        min_distance: ``(N,)`` smallest signed distances.
        reports: one `CollisionReport` per configuration.
    """

    in_collision: np.ndarray
    min_distance: np.ndarray
    reports: tuple[CollisionReport, ...]


_SLACK = 1e-9
"""Rounding room (m) of the screening bounds: a pair is skipped only when its bound is above the
search's limit by more (a touching pair, distance 0, is never skipped on a bound of 1e-17)."""


def world_parts(world: World | None) -> tuple[Part, ...]:
    """The coal parts of a world as it is now (built once per world version)."""
    return state_of(world).parts


Entry = tuple[float, int, int, bool, Any]
"""A pair checked by coal: ``(signed distance, a, b, on_world, coal's DistanceResult)``."""


class Search(NamedTuple):
    """What the search of the module docstring found at one configuration, before any report
    object is made (`report_at` makes them; a solve reads the nearest pair alone).

    Attributes:
        nearest: ``(distance, a, b, on_world, coal result)`` of the closest pair (None: no pair):
            ``a`` a robot part index, ``b`` a part index or (``on_world``) a world part index.
        close: every entry closer than the margin or touching, in the order found.
        checked: pairs whose exact distance was computed.
        candidates: pairs considered.
        refined: the world bounds were refined (see `search`).
    """

    nearest: Entry | None
    close: list[Entry]
    checked: int
    candidates: int
    refined: bool

    @property
    def in_collision(self) -> bool:
        """Some pair is closer than the margin or touches."""
        return bool(self.close)

    def names(self, geo: RobotGeometry, world: WorldState) -> tuple[str, str] | None:
        """The names of the closest pair (None: no pair)."""
        e = self.nearest
        if e is None:
            return None
        return geo.parts[e[1]].name, (world.parts[e[2]] if e[3] else geo.parts[e[2]]).name


REFINE = 4
"""World pairs left under the search's limit after an exact distance above which the coarse world
bounds (each part's bounding sphere, `optik.collision.screen`) are refined by the sphere model's
(self pairs left do not count: the refinement cannot skip them; the Panda's folded answers, their
elbow near its shoulder, left 4 to 13 self pairs and 1 or 2 world pairs, and the refinement cost
more than the rest of the search). On the Panda in clutter (8 boxes) the coarse call took 16 us,
the fine one 40 us and a coal query 2-5 us (same run); 4 is a round choice, not tuned: either way
the answer is the same."""


_LOCAL = threading.local()


def _transforms(geo: RobotGeometry, coal: Any) -> list[Any]:
    """This thread's coal transforms of ``geo``'s parts, one per part, reused by every search on
    the thread (each sets those it reads: setting one costs a third of making one)."""
    per = getattr(_LOCAL, "transforms", None)
    if per is None:
        per = _LOCAL.transforms = weakref.WeakKeyDictionary()
    got = per.get(geo)
    if got is None:
        got = per[geo] = [coal.Transform3s() for _ in geo.parts]
    return got


_Known = dict[tuple[int, int], Entry]
_FIXED: weakref.WeakKeyDictionary[RobotGeometry, weakref.WeakKeyDictionary[WorldState, _Known]]
_FIXED = weakref.WeakKeyDictionary()
"""Per geometry and world version: the coal entries of the pairs of a fixed part
(`RobotGeometry.fixed_parts`) and a world part found so far, by ``(part, world part)``: the same
at every ``q``. Each dict is replaced, never changed (a reader holds a consistent one)."""
_FIXED_LOCK = threading.Lock()


def _fixed_entries(geo: RobotGeometry, world: WorldState) -> _Known:
    """The known entries of ``geo``'s fixed parts against ``world`` (see `_FIXED`)."""
    per = _FIXED.get(geo)
    got = None if per is None else per.get(world)
    return {} if got is None else got


_FIXED_VERSION = 0
"""Incremented at each change of `_FIXED` (a `ClearTest` reads its entries again after one)."""


def _keep_fixed(geo: RobotGeometry, world: WorldState, entry: Entry) -> None:
    """Add a fixed part's entry to `_FIXED`."""
    global _FIXED_VERSION
    with _FIXED_LOCK:
        per = _FIXED.setdefault(geo, weakref.WeakKeyDictionary())
        per[world] = {**per.get(world, {}), (entry[1], entry[2]): entry}
        _FIXED_VERSION += 1


def _under(lb: np.ndarray, limit: float) -> tuple[list[int], int]:
    """The indices of the bounds ``lb <= limit`` in increasing order of bound (stable: ties in
    index order), and 0 (the search's position in them)."""
    idx = (lb <= limit).nonzero()[0]
    if len(idx) > 1:
        idx = idx[lb[idx].argsort(kind="stable")]
    return idx.tolist(), 0


def search(
    geo: RobotGeometry,
    q: np.ndarray,
    world: WorldState,
    margin: float,
    self_collision: bool,
    stop: bool = False,
    outputs: list[np.ndarray] | None = None,
) -> Search:
    """The search of the module docstring at checked coordinates ``q`` against one version of a
    world (`World.state`): each pair's screening bound, then coal on the pairs in increasing order
    of it until the bound exceeds ``max(margin, 0, nearest found)``.

    The bounds come from one compiled call with the coarse world rows (`optik.collision.screen`);
    when more than `REFINE` world pairs are still under the limit after an exact distance, a second call
    gives the sphere model's world rows and each world bound becomes the larger of the two (both
    are lower bounds), the search going on over the pairs not yet checked. The nearest entry's
    distance is exact (coal's), and so is the set of pairs closer than ``margin`` or touching: a
    pair skipped has a bound above both.

    With ``stop``, the search only decides whether some pair is closer than ``margin`` or
    touches (what accepting or rejecting an answer needs): the limit stays ``max(margin, 0)``
    (a pair's distance above it no longer lowers it, nor does the search look for the nearest
    pair beyond it) and the search ends at the first close pair. ``in_collision`` is then exact,
    ``close`` holds that pair alone and ``nearest`` is the nearest pair checked (None when no
    bound is under the limit; its distance is the smallest only when it is close). On the Panda's
    clear answers in clutter (1000 benchmark targets) it checked 0.70 pairs with coal instead of 1.90.

    ``outputs``: the coarse screen's outputs at ``q`` made already (`ClearTest.outputs` after a
    test of ``q`` against this world), read instead of a new screen call.
    """
    n_obj, n_parts = len(world.parts), len(geo.parts)
    n_self = len(geo.self_pairs) if self_collision else 0
    poses, lb = screen(geo, world.capacity, coarse=True).pair_bounds(q, world.slots, n_obj, n_self, outputs)
    fixed = geo.fixed_parts if n_obj else frozenset()
    known = _fixed_entries(geo, world) if fixed else {}
    for (a, b), e in known.items():  # their exact distance is the tightest bound
        lb[n_self + b * n_parts + a] = e[0]
    floor = max(margin, 0.0)  # pairs below it are reported, and the nearest always is
    limit = floor + _SLACK if stop else np.inf  # else max(floor, nearest found) + _SLACK once found
    # the pairs in increasing order of bound: the least first, then, once a pair's distance sets
    # the limit (it only decreases), those under it alone (the rest of a full sort is never read)
    if stop:
        order, i = _under(lb, limit)
        if not order:  # clear by the bounds alone, no coal query (3 in 4 clear answers in clutter)
            return Search(None, [], 0, int(lb.size), False)
    else:
        order, i = [int(lb.argmin())] if lb.size else [], 0
    coal = coal_module()
    distance, request, parts, others = coal.distance, signed_request(), geo.parts, world.parts
    tfs = _transforms(geo, coal)
    rotations, origins = poses[:, :9].reshape(-1, 3, 3), poses[:, 9:]
    placed: set[int] = set()  # the parts whose transform is set for this q

    def tf(k: int) -> Any:
        t = tfs[k]
        if k not in placed:
            t.setRotation(rotations[k])
            t.setTranslation(origins[k])
            placed.add(k)
        return t

    best: Entry | None = None
    close: list[Entry] = []
    done: set[int] = set()
    done_world = 0
    refined = False
    while i < len(order):
        k = order[i]
        i += 1
        if lb[k] > limit:
            break
        if k in done:  # checked before the bounds were refined
            continue
        on_world = k >= n_self
        if on_world:
            b, a = divmod(k - n_self, n_parts)
            entry = known.get((a, b))
            if entry is None:
                res = coal.DistanceResult()
                tf_b = world.transforms[b]
                d = float(distance(parts[a].geometry, tf(a), others[b].geometry, tf_b, request, res))
                entry = (d, a, b, True, res)
                if a in fixed:
                    _keep_fixed(geo, world, entry)
            d = entry[0]
        else:
            a, b = geo.pair_list[k]
            res = coal.DistanceResult()
            d = float(distance(parts[a].geometry, tf(a), parts[b].geometry, tf(b), request, res))
            entry = (d, a, b, False, res)
        done.add(k)
        done_world += on_world
        if best is None or d < best[0]:
            best = entry
            if not stop:
                limit = max(floor, d) + _SLACK
        if d < margin or d <= 0:
            close.append(entry)
            if stop:
                break
        if len(done) == 1 and not stop:
            order, i = _under(lb, limit)
        # world pairs left under the limit (counted only when the pairs under it could hold more
        # than REFINE: order holds every pair under the limit of when it was made, a larger one)
        if (
            n_obj
            and not refined
            and len(order) - done_world > REFINE
            and int(np.count_nonzero(lb[n_self:] <= limit)) - done_world > REFINE
        ):
            refined = True
            fine = screen(geo, world.capacity).bounds(q, world.slots, n_obj)[1]
            np.maximum(lb[n_self:], fine.T.ravel(), out=lb[n_self:])
            order, i = _under(lb, limit)
    return Search(best, close, len(done), int(lb.size), refined)


_P = ctypes.c_void_p


class ClearTest:
    """`search` with ``stop`` up to its first decision, as a C check (``optik_screen_clear`` of
    `optik.collision.screen`): whether no screening bound is under the limit ``max(margin, 0)``
    (plus `_SLACK`), the answer that makes the search return clear with no coal query. For one
    thread, geometry, world version, margin and ``self_collision``.

    The bounds are the search's: the coarse screen call at ``q``, its first ``n_self``
    self-pair rows and its world rows of the world's objects, each fixed part's row against an
    object replaced by its known exact distance (`_FIXED`, read again whenever it has changed).
    `address` is the check's block for ``optik_lm_call_checked`` of
    ``optik/solvers/lm_chunk.c`` (`optik.solvers.lm.LMCall` runs it on its answer in the same C
    call); after a call `verdict` is 1 (clear: `search` would find no pair), 0 (some bound under
    the limit: the search decides) or, when the check did not run, what it was before.

    Args:
        geo: the robot geometry.
        world: one version of the world.
        margin: the clearance (m).
        self_collision: the self-collision pairs are checked.
        clear: `optik.collision.screen.Screen.clear_function` of the coarse screen of ``geo``
            and the world's capacity.
    """

    def __init__(
        self,
        geo: RobotGeometry,
        world: WorldState,
        margin: float,
        self_collision: bool,
        clear: tuple[int, int, int],
    ) -> None:
        self.geo, self.world = geo, world
        n_obj, n_parts = len(world.parts), len(geo.parts)
        n_self = len(geo.self_pairs) if self_collision else 0
        self.n_rows = n_obj * n_parts
        self.known, self.use = np.zeros(self.n_rows), np.zeros(self.n_rows)
        self.limit = np.array([max(margin, 0.0) + _SLACK])
        self.verdict = np.zeros(1, dtype=np.int64)
        fn, n_iw, n_w = clear
        outs = [np.zeros(12 * n_parts), np.zeros(world.capacity * n_parts), np.zeros(len(geo.self_pairs))]
        work = [np.zeros(n_iw, dtype=np.int64), np.zeros(n_w)]
        self.outputs = outs
        """The screen's outputs (poses, world, self) at the last ``q`` tested (`search` reads them)."""
        self._work = work  # the memory the block points at, kept alive
        bufs = [world.slots, self.known, self.use, self.limit, *outs, *work, self.verdict]
        addresses = [b.ctypes.data for b in bufs]
        self.block = (_P * 13)(fn, addresses[0], n_self, self.n_rows, *addresses[1:])
        self._address = ctypes.addressof(self.block)
        self._version = -1

    @property
    def address(self) -> int:
        """The block's address, the known entries of the fixed parts read again when `_FIXED`
        has changed since the last read."""
        if self._version != _FIXED_VERSION:
            self._version = _FIXED_VERSION
            n_parts = len(self.geo.parts)
            self.use[:] = 0.0
            if self.n_rows and self.geo.fixed_parts:
                for (a, b), e in _fixed_entries(self.geo, self.world).items():
                    self.known[b * n_parts + a], self.use[b * n_parts + a] = e[0], 1.0
        return self._address


def report_at(
    geo: RobotGeometry, q: np.ndarray, world: WorldState, margin: float, self_collision: bool
) -> CollisionReport:
    """The `CollisionReport` of ``geo`` at checked coordinates ``q`` against one version of a
    world (`World.state`): the `search` of the module docstring."""
    found = search(geo, q, world, margin, self_collision)

    def pair(e: Entry) -> CollisionPair:
        d, a, b, on_world, res = e
        other = world.parts[b].name if on_world else geo.parts[b].name
        witness = np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2())
        return CollisionPair(geo.parts[a].name, other, d, *witness, on_world)

    nearest = None if found.nearest is None else pair(found.nearest)
    return CollisionReport(
        in_collision=found.in_collision,
        min_distance=np.inf if nearest is None else nearest.distance,
        pair=None if nearest is None else (nearest.a, nearest.b),
        witness=None if nearest is None else (nearest.point_a, nearest.point_b),
        close_pairs=tuple(pair(e) for e in sorted(found.close, key=lambda e: e[0])),
        margin=margin,
        checked=found.checked,
        candidates=found.candidates,
    )


def check(
    m: Mechanism, q: Any, world: World | None = None, margin: float = 0.0, self_collision: bool = True
) -> CollisionReport:
    """Exact collision query of ``m`` at ``q`` against itself and ``world`` (see the module docstring).

    Args:
        m: a mechanism with collision geometry (`optik.collision.robot.robot_geometry`).
        q: coordinates ``(n_q,)``.
        world: obstacles (None: self-collision only).
        margin: clearance (m, >= 0) below which a pair counts as colliding.
        self_collision: check the robot's own link pairs.

    Raises:
        InvalidArgumentError: ``m`` without collision geometry, a bad ``q``, ``world`` or ``margin``.
        MissingExtraError: coal is not installed.
    """
    geo = robot_geometry(m)
    qv = m.check_q(q)
    collide = as_bool(self_collision, "self_collision")
    return report_at(geo, qv, state_of(world), as_float(margin, "margin", 0.0), collide)


def check_many(
    m: Mechanism, Q: Any, world: World | None = None, margin: float = 0.0, self_collision: bool = True
) -> CollisionBatch:
    """`check` at every row of ``Q`` (``(N, n_q)``), against one snapshot of ``world``."""
    geo = robot_geometry(m)
    qb, _ = as_batch(Q, "Q", m.n_q)
    state = state_of(world)
    mg = as_float(margin, "margin", 0.0)
    collide = as_bool(self_collision, "self_collision")
    reports = tuple(report_at(geo, q, state, mg, collide) for q in qb)
    return CollisionBatch(
        np.array([r.in_collision for r in reports], dtype=bool),
        np.array([r.min_distance for r in reports], dtype=float),
        reports,
    )
