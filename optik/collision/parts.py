"""Parts: the coal objects of robot links and world objects, each with a bounding sphere.

A `Shape` becomes one `Part` (a point cloud one per point); the bounding sphere lets a query
skip the pairs that cannot be the closest (`optik.collision.check`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optik.collision.shapes import Shape, coal_objects, shape_vertices

__all__ = ["Part", "bounding_sphere", "parts_of"]


def bounding_sphere(shape: Shape) -> tuple[np.ndarray, float]:
    """A sphere ``(centre, radius)`` containing the shape (centre of the vertices' box)."""
    v, r = shape_vertices(shape)
    centre = (v.min(axis=0) + v.max(axis=0)) / 2
    return centre, float(np.max(np.linalg.norm(v - centre, axis=1)) + r)


@dataclass(frozen=True, eq=False)
class Part:
    """One coal object of a robot link or a world object.

    Attributes:
        name: the link or the world object it belongs to.
        shape: its geometry (a point cloud's part is one of its spheres).
        offset: 4x4 pose in the link frame (robot) or the base frame (world).
        geometry: the coal object.
        centre: centre of a bounding sphere in the frame of ``offset``'s parent.
        radius: that sphere's radius.
    """

    name: str
    shape: Shape
    offset: np.ndarray
    geometry: Any = field(repr=False)
    centre: np.ndarray = field(repr=False)
    radius: float


def parts_of(name: str, shape: Shape, pose: np.ndarray) -> list[Part]:
    """The coal parts of a shape placed at ``pose`` (one per point of a point cloud)."""
    out = []
    if shape.kind == "points":
        r = shape.size[0]
        for geom, off in coal_objects(shape):
            t = pose @ off
            out.append(Part(name, Shape("sphere", (r,)), t, geom, t[:3, 3].copy(), r))
        return out
    ((geom, off),) = coal_objects(shape)
    t = pose @ off
    c, r = bounding_sphere(shape)
    out.append(Part(name, shape, t, geom, t[:3, :3] @ c + t[:3, 3], r))
    return out
