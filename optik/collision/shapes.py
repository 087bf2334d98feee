"""Collision shapes: the primitives, meshes and point clouds of robots and worlds, and their coal objects.

A `Shape` is a geometry in its own frame:

| kind | size | the solid |
|---|---|---|
| ``"box"`` | ``(x, y, z)`` edge lengths | centred at the origin, edges along the axes |
| ``"sphere"`` | ``(r,)`` | centred at the origin |
| ``"cylinder"`` | ``(r, length)`` | axis along z, centred at the origin |
| ``"capsule"`` | ``(r, length)`` | the points within ``r`` of the z segment of that length |
| ``"mesh"`` | ``(sx, sy, sz)`` scale (< 0: mirror) | the **convex hull** of the file's vertices (scaled) |
| ``"points"`` | ``(r,)`` | a sphere of radius ``r`` around each of the ``points`` (``(N, 3)``) |

Meshes are taken as their convex hulls: robots' collision meshes are convex already (URDF
packages ship hulls for this reason) and a hull contains the mesh, so a configuration the check
calls free is free. The coal object of a shape (`coal_objects`) is built once and shared: coal's
queries only read it. coal is the optional extra ``collision`` (`coal_module` names it when
missing).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from optik.errors import InvalidArgumentError, MissingExtraError

__all__ = ["KINDS", "Shape", "coal_module", "coal_objects", "shape_vertices"]

KINDS = ("box", "sphere", "cylinder", "capsule", "mesh", "points")
"""Shape kinds."""

_SIZES = {"box": 3, "sphere": 1, "cylinder": 2, "capsule": 2, "mesh": 3, "points": 1}


@dataclass(frozen=True, eq=False)
class Shape:
    """One collision geometry in its own frame (see the module docstring for each kind).

    Attributes:
        kind: one of `KINDS`.
        size: the dimensions of the kind (the scale of a mesh).
        path: the mesh file (meshes only).
        points: ``(N, 3)`` sphere centres (point clouds only).
    """

    kind: str
    size: tuple[float, ...]
    path: Path | None = None
    points: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InvalidArgumentError("kind", f"unknown shape {self.kind!r}; use one of {KINDS}")
        size = np.asarray(self.size, dtype=float)
        if size.shape != (_SIZES[self.kind],) or not np.all(np.isfinite(size)):
            n = _SIZES[self.kind]
            raise InvalidArgumentError("size", f"a {self.kind} needs {n} finite numbers, got {self.size}")
        low = size == 0 if self.kind == "mesh" else size <= 0  # a negative mesh scale mirrors it
        if self.kind == "capsule":  # a capsule of length 0 is a sphere
            low[1] = size[1] < 0
        if np.any(low):
            rule = "nonzero" if self.kind == "mesh" else "positive"
            raise InvalidArgumentError("size", f"{self.kind} dimensions must be {rule}, got {self.size}")
        object.__setattr__(self, "size", tuple(float(v) for v in size))
        if self.kind == "mesh" and (self.path is None or not Path(self.path).is_file()):
            raise InvalidArgumentError("path", f"no mesh file {self.path!s}")
        if self.kind == "points":
            pts = np.asarray(self.points, dtype=float)
            if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
                raise InvalidArgumentError("xyz", f"expected finite (N, 3) points, got shape {pts.shape}")
            object.__setattr__(self, "points", pts.copy())


def coal_module() -> Any:
    """The ``coal`` module.

    Raises:
        MissingExtraError: coal is not installed (``pip install optik[collision]``).
    """
    try:
        import coal
    except ImportError as exc:  # pragma: no cover - coal comes with the test environment's pin
        raise MissingExtraError(
            "collision checks need coal: pip install 'optik[collision]' (or pip install coal)"
        ) from exc
    return coal


_MESHES: dict[tuple[str, tuple[float, ...]], Any] = {}
_MESH_LOCK = threading.Lock()


def _convex_mesh(path: Path, scale: tuple[float, ...]) -> Any:
    """The coal convex hull of a mesh file, loaded once per file and scale."""
    key = (str(Path(path).resolve()), tuple(scale))
    with _MESH_LOCK:
        hit = _MESHES.get(key)
        if hit is None:
            coal = coal_module()
            bvh = coal.MeshLoader().load(key[0], np.asarray(scale, dtype=float))
            bvh.buildConvexHull(True, "Qt")
            hit = _MESHES[key] = bvh.convex
        return hit


def coal_objects(shape: Shape) -> list[tuple[Any, np.ndarray]]:
    """The coal geometries of a shape with their 4x4 offsets in the shape's frame (one object,
    at the identity, except for a point cloud: one sphere per point)."""
    coal = coal_module()
    s = shape.size
    if shape.kind == "box":
        return [(coal.Box(*s), np.eye(4))]
    if shape.kind == "sphere":
        return [(coal.Sphere(s[0]), np.eye(4))]
    if shape.kind == "cylinder":
        return [(coal.Cylinder(s[0], s[1]), np.eye(4))]
    if shape.kind == "capsule":
        return [(coal.Capsule(s[0], s[1]), np.eye(4))]
    if shape.kind == "mesh":
        assert shape.path is not None  # checked in __post_init__
        return [(_convex_mesh(shape.path, s), np.eye(4))]
    out = []
    for p in shape.points:  # type: ignore[union-attr]
        offset = np.eye(4)
        offset[:3, 3] = p
        out.append((coal.Sphere(s[0]), offset))
    return out


def shape_vertices(shape: Shape, segments: int = 16) -> tuple[np.ndarray, float]:
    """Points ``V`` and a radius ``r`` such that the shape lies within the union of the balls of
    radius ``r`` around the convex hull of ``V`` (for conservative fits).

    A box gives its 8 corners and ``r = 0``; a sphere its centre and its radius; a capsule the
    two end centres and its radius; a cylinder the vertices of its two end polygons of
    ``segments`` sides circumscribing the end circles (radius ``r / cos(pi / segments)``) and
    ``r = 0``; a mesh the vertices of its hull; a point cloud its points and radius.
    """
    s = shape.size
    if shape.kind == "box":
        h = np.asarray(s) / 2
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
        return corners * h, 0.0
    if shape.kind == "sphere":
        return np.zeros((1, 3)), float(s[0])
    if shape.kind == "capsule":
        return np.array([[0.0, 0.0, -s[1] / 2], [0.0, 0.0, s[1] / 2]]), float(s[0])
    if shape.kind == "cylinder":
        a = 2 * np.pi * np.arange(segments) / segments
        rr = s[0] / np.cos(np.pi / segments)
        ring = np.stack([rr * np.cos(a), rr * np.sin(a), np.zeros(segments)], axis=1)
        lo, hi = ring.copy(), ring.copy()
        lo[:, 2], hi[:, 2] = -s[1] / 2, s[1] / 2
        return np.concatenate([lo, hi]), 0.0
    if shape.kind == "mesh":
        hull = coal_objects(shape)[0][0]
        return np.array(hull.points(), dtype=float).reshape(-1, 3), 0.0
    return np.asarray(shape.points, dtype=float), float(s[0])
