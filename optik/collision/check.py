"""`check` and `check_many`: exact collision queries of a mechanism at ``q``, with coal.

The pairs checked are the robot's self-collision pairs (`optik.collision.robot`, when
``self_collision``) and every robot part against every world object. Each pair's signed
distance (negative: penetration depth) comes from coal (`optik.collision.distance`). To stay
exact and fast, every pair first gets a lower bound of its distance from models that contain the
parts (`optik.collision.screen`: the robot's spheres and capsules, each obstacle's rounded box;
one compiled call for all pairs), the pairs are taken in increasing order of it, and the search
stops once the bound exceeds the smallest distance found, the margin and 0: no pair left out can
be the closest, closer than the margin, or touching. The witness points are read from coal only
for the pairs reported.

``in_collision`` is True when some pair is closer than ``margin`` or touches (distance
``<= 0``): at ``margin=0`` it means contact or penetration; with a margin, a clearance below
it. `CollisionReport.min_distance` is the smallest signed distance over the pairs checked
(``inf`` when there is no pair at all).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from optik.checks import as_batch, as_bool, as_float
from optik.collision.distance import coal_distance, signed_request
from optik.collision.parts import Part
from optik.collision.robot import RobotGeometry, robot_geometry
from optik.collision.screen import screen
from optik.collision.shapes import coal_module
from optik.collision.world import World, WorldState, state_of
from optik.mechanism import Mechanism

__all__ = [
    "CollisionBatch",
    "CollisionPair",
    "CollisionReport",
    "check",
    "check_many",
    "report_at",
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


def report_at(
    geo: RobotGeometry, q: np.ndarray, world: WorldState, margin: float, self_collision: bool
) -> CollisionReport:
    """The `CollisionReport` of ``geo`` at checked coordinates ``q`` against one version of a
    world (`World.state`): the search of the module docstring."""
    n_obj = len(world.parts)
    poses, to_world, own = screen(geo, world.capacity).bounds(q, world.slots, n_obj)
    n_self = len(geo.self_pairs) if self_collision else 0
    lb = np.concatenate([own[:n_self], to_world.ravel()])
    coal = coal_module()
    request = signed_request()
    tfs: dict[int, Any] = {}  # coal transforms of the robot's parts, made when first needed

    def tf(k: int) -> Any:
        got = tfs.get(k)
        if got is None:
            got = tfs[k] = coal.Transform3s(poses[k, :9].reshape(3, 3), poses[k, 9:])
        return got

    floor = max(margin, 0.0)  # pairs below it are reported, and the nearest always is
    best: tuple[float, int, int, bool, Any] | None = None
    close: list[tuple[float, int, int, bool, Any]] = []
    checked = 0
    bounds = lb.tolist()
    for k in np.argsort(lb, kind="stable").tolist():
        if best is not None and bounds[k] > max(floor, best[0]) + _SLACK:
            break
        if k < n_self:
            a, b = (int(v) for v in geo.self_pairs[k])
            found = coal_distance(geo.parts[a].geometry, tf(a), geo.parts[b].geometry, tf(b), request)
            entry = (found[0], a, b, False, found[1])
        else:
            a, b = divmod(k - n_self, n_obj)
            found = coal_distance(
                geo.parts[a].geometry, tf(a), world.parts[b].geometry, world.transforms[b], request
            )
            entry = (found[0], a, b, True, found[1])
        if best is None or entry[0] < best[0]:
            best = entry
        if entry[0] < margin or entry[0] <= 0:
            close.append(entry)
        checked += 1
    close.sort(key=lambda e: e[0])

    def pair(e: tuple[float, int, int, bool, Any]) -> CollisionPair:
        d, a, b, on_world, res = e
        other = world.parts[b].name if on_world else geo.parts[b].name
        witness = np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2())
        return CollisionPair(geo.parts[a].name, other, d, *witness, on_world)

    nearest = None if best is None else pair(best)
    return CollisionReport(
        in_collision=bool(close),
        min_distance=np.inf if nearest is None else nearest.distance,
        pair=None if nearest is None else (nearest.a, nearest.b),
        witness=None if nearest is None else (nearest.point_a, nearest.point_b),
        close_pairs=tuple(pair(e) for e in close),
        margin=margin,
        checked=checked,
        candidates=len(bounds),
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
