"""`check` and `check_many`: exact collision queries of a mechanism at ``q``, with coal.

The pairs checked are the robot's self-collision pairs (`optik.collision.robot`, when
``self_collision``) and every robot part against every world object. Each pair's signed
distance (negative: penetration depth) comes from coal (`optik.collision.distance`). To stay
exact and fast, pairs are taken in increasing order of the lower bound
``|c_a - c_b| - r_a - r_b`` of their bounding spheres, and the search stops once that bound
exceeds the smallest distance found, the margin and 0: no pair left out can be the closest,
closer than the margin, or touching.

``in_collision`` is True when some pair is closer than ``margin`` or touches (distance
``<= 0``): at ``margin=0`` it means contact or penetration; with a margin, a clearance below
it. `CollisionReport.min_distance` is the smallest signed distance over the pairs checked
(``inf`` when there is no pair at all).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from optik.checks import as_batch, as_bool, as_float
from optik.collision.distance import coal_transform, placed_distance
from optik.collision.parts import Part
from optik.collision.robot import RobotGeometry, robot_geometry
from optik.collision.world import World
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism

__all__ = ["CollisionBatch", "CollisionPair", "CollisionReport", "check", "check_many", "world_parts"]


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


def world_parts(world: World | None) -> tuple[Part, ...]:
    """The coal parts of a world as it is now (built once per world version)."""
    if world is None:
        return ()
    if not isinstance(world, World):
        raise InvalidArgumentError("world", f"expected an optik.World or None, got {type(world).__name__}")
    return world.parts()


def _bounds(
    geo: RobotGeometry, links: np.ndarray, obstacles: Sequence[Part], self_collision: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Candidate pairs ``(i, j)`` (``j >= P`` indexes ``obstacles[j - P]``) with their bounds,
    from the link poses ``links``."""
    t = links[geo.part_link]
    centres = np.einsum("pij,pj->pi", t[:, :3, :3], np.stack([p.centre for p in geo.parts])) + t[:, :3, 3]
    radii = np.array([p.radius for p in geo.parts])
    n = len(geo.parts)
    blocks_i, blocks_j = [], []
    if self_collision and len(geo.self_pairs):
        blocks_i.append(geo.self_pairs[:, 0])
        blocks_j.append(geo.self_pairs[:, 1])
    if obstacles:
        ii, jj = np.meshgrid(np.arange(n), np.arange(len(obstacles)), indexing="ij")
        blocks_i.append(ii.ravel())
        blocks_j.append(jj.ravel() + n)
    if not blocks_i:
        empty = np.zeros(0, dtype=int)
        return empty, empty, np.zeros(0)
    i, j = np.concatenate(blocks_i), np.concatenate(blocks_j)
    all_c = np.concatenate([centres, np.array([o.centre for o in obstacles]).reshape(-1, 3)])
    all_r = np.concatenate([radii, np.array([o.radius for o in obstacles])])
    lb = np.linalg.norm(all_c[i] - all_c[j], axis=1) - all_r[i] - all_r[j]
    return i, j, lb


def _report(
    geo: RobotGeometry, q: np.ndarray, obstacles: Sequence[Part], margin: float, self_collision: bool
) -> CollisionReport:
    links = geo.link_poses(q)
    poses = geo.part_poses(q, links)
    i, j, lb = _bounds(geo, links, obstacles, self_collision)
    n = len(geo.parts)
    best: CollisionPair | None = None
    close: list[CollisionPair] = []
    checked = 0
    tfs: dict[int, Any] = {}  # coal transforms by part index (obstacles after the robot's), made once

    def tf(index: int, pose: np.ndarray) -> Any:
        got = tfs.get(index)
        if got is None:
            got = tfs[index] = coal_transform(pose)
        return got

    for k in np.argsort(lb, kind="stable"):
        if lb[k] > max(margin, 0.0, best.distance if best is not None else np.inf):
            break
        a, b = int(i[k]), int(j[k])
        world = b >= n
        part_b, pose_b = (obstacles[b - n], obstacles[b - n].offset) if world else (geo.parts[b], poses[b])
        d, pa, pb = placed_distance(geo.parts[a], tf(a, poses[a]), part_b, tf(b, pose_b))
        checked += 1
        pair = CollisionPair(geo.parts[a].name, part_b.name, d, pa, pb, world)
        if best is None or d < best.distance:
            best = pair
        if d < margin or d <= 0:
            close.append(pair)
    close.sort(key=lambda p: p.distance)
    return CollisionReport(
        in_collision=bool(close),
        min_distance=np.inf if best is None else best.distance,
        pair=None if best is None else (best.a, best.b),
        witness=None if best is None else (best.point_a, best.point_b),
        close_pairs=tuple(close),
        margin=margin,
        checked=checked,
        candidates=len(lb),
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
    return _report(geo, qv, world_parts(world), as_float(margin, "margin", 0.0), collide)


def check_many(
    m: Mechanism, Q: Any, world: World | None = None, margin: float = 0.0, self_collision: bool = True
) -> CollisionBatch:
    """`check` at every row of ``Q`` (``(N, n_q)``), against one snapshot of ``world``."""
    geo = robot_geometry(m)
    qb, _ = as_batch(Q, "Q", m.n_q)
    obstacles = world_parts(world)
    mg = as_float(margin, "margin", 0.0)
    collide = as_bool(self_collision, "self_collision")
    reports = tuple(_report(geo, q, obstacles, mg, collide) for q in qb)
    return CollisionBatch(
        np.array([r.in_collision for r in reports], dtype=bool),
        np.array([r.min_distance for r in reports], dtype=float),
        reports,
    )
