"""Exact distances between placed parts, through coal.

For two convex parts coal's GJK gives the distance and the nearest points when they are apart,
and EPA the penetration depth (as a negative distance) and the deepest points when they
overlap: the *signed distance*. Every call makes its own result object and reads one shared
request (`signed_request`), so the queries are safe from any thread (the geometries are only read).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np

from optik.collision.parts import Part
from optik.collision.shapes import coal_module

__all__ = [
    "Witness",
    "coal_distance",
    "coal_transform",
    "pair_distances",
    "placed_distance",
    "signed_distance",
    "signed_request",
]

Witness = tuple[float, np.ndarray, np.ndarray]
"""``(distance, point on a, point on b)`` in the base frame."""


def _transform(coal: Any, t: np.ndarray) -> Any:
    return coal.Transform3s(np.ascontiguousarray(t[:3, :3]), np.ascontiguousarray(t[:3, 3]))


def coal_transform(pose: np.ndarray) -> Any:
    """coal's ``Transform3s`` of a 4x4 pose."""
    return _transform(coal_module(), pose)


def signed_distance(a: Part, pose_a: np.ndarray, b: Part, pose_b: np.ndarray) -> Witness:
    """The signed distance of two parts at base-frame poses, with the witness points."""
    return placed_distance(a, coal_transform(pose_a), b, coal_transform(pose_b))


@functools.cache
def signed_request() -> Any:
    """coal's ``DistanceRequest`` for signed distances, one shared by every query of the process
    (coal only reads a request, from any thread; never change it)."""
    req = coal_module().DistanceRequest()
    req.enable_signed_distance = True
    return req


def coal_distance(a: Any, tf_a: Any, b: Any, tf_b: Any, request: Any) -> tuple[float, Any]:
    """The signed distance of coal geometries ``a`` and ``b`` at coal transforms, and coal's
    ``DistanceResult`` (its nearest points are the witnesses: read them only when needed)."""
    coal = coal_module()
    res = coal.DistanceResult()
    return float(coal.distance(a, tf_a, b, tf_b, request, res)), res


def placed_distance(a: Part, tf_a: Any, b: Part, tf_b: Any) -> Witness:
    """`signed_distance` with the poses as coal transforms (`coal_transform`: a caller that
    queries one part against many makes its transform once)."""
    d, res = coal_distance(a.geometry, tf_a, b.geometry, tf_b, signed_request())
    return d, np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2())


def pair_distances(
    parts_a: Sequence[Part],
    poses_a: np.ndarray,
    parts_b: Sequence[Part],
    poses_b: np.ndarray,
    pairs: np.ndarray,
) -> np.ndarray:
    """Signed distances of the index pairs ``pairs`` (``(k, 2)``: ``parts_a[i]`` and ``parts_b[j]``)."""
    return np.array(
        [signed_distance(parts_a[i], poses_a[i], parts_b[j], poses_b[j])[0] for i, j in pairs], dtype=float
    )
