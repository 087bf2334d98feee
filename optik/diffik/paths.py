"""Paths to track: sequences of 4x4 target poses sampled at the control period."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from optik import spatial
from optik.checks import as_batch, as_float, as_transform, as_vector, real_array
from optik.errors import InvalidArgumentError, ShapeError

MAX_SAMPLES = 1_000_000
"""Most poses one path function returns (128 MB of 4x4 transforms): a longer path is an
[InvalidArgumentError][optik.InvalidArgumentError] naming the argument that sets the count,
never a huge allocation (split a longer motion into several paths)."""


def _arc_samples(length: float, speed: Any, dt: Any) -> np.ndarray:
    """Arc lengths ``0, step, 2 step, ..., length`` with ``step = speed * dt`` (the last one
    ``length``, never a near-duplicate of the one before it).

    Raises:
        InvalidArgumentError: bad ``speed`` or ``dt``, or more than `MAX_SAMPLES` samples
            (argument ``speed/dt``).
    """
    step = as_float(speed, "speed", 0.0, strict=True) * as_float(dt, "dt", 0.0, strict=True)
    # the sample count is known before anything is allocated: arc length / step, plus the end
    if not length / step < MAX_SAMPLES - 1:
        raise InvalidArgumentError(
            "speed/dt",
            f"the path would have about {length / step:.3g} samples (arc length {length:.3g} m, "
            f"{step:.3g} m per sample); at most {MAX_SAMPLES} are allowed",
        )
    s = np.arange(math.floor(length / step * (1 + 1e-12)) + 1) * step
    s = s[s < length - 1e-9 * step]
    return np.append(s, length)


def _rotation(rotation: Any) -> np.ndarray:
    """The 3x3 tool orientation (identity when None), validated as a proper rotation."""
    if rotation is None:
        return np.eye(3)
    r = real_array(rotation, "rotation")
    if r.shape != (3, 3):
        raise ShapeError("rotation", f"expected a 3x3 rotation, got shape {r.shape}")
    return as_transform(spatial.transform(r), "rotation")[:3, :3]


def line_path(start: Any, end: Any, speed: float, dt: float, rotation: Any = None) -> np.ndarray:
    """A straight segment from ``start`` to ``end`` at constant tool speed, sampled every
    ``speed * dt`` of its length, ``end`` included (as `polyline_path` and `circle_path`).

    The orientation is ``rotation`` throughout when given; otherwise, between two transforms,
    it turns along the geodesic ``R(s) = exp(s log(R_1 R_0^T)) R_0`` in proportion to the
    distance travelled (``s`` from 0 to 1), and it is the identity between two points.

    Args:
        start, end: 4x4 transforms or 3-vectors (positions).
        speed: tool speed (m/s, ``> 0``).
        dt: sample period (s, ``> 0``).
        rotation: constant 3x3 tool orientation (default: interpolated, see above).

    Returns:
        ``(n, 4, 4)`` array (two poses, ``start`` and ``end``, when the positions coincide).

    Raises:
        InvalidArgumentError: bad ends, speed or dt, or more than `MAX_SAMPLES` samples
            (argument ``speed/dt``).
    """
    t0, t1 = _pose(start, "start"), _pose(end, "end")
    length = float(np.linalg.norm(t1[:3, 3] - t0[:3, 3]))
    s = _arc_samples(length, speed, dt) / length if length > 0 else np.array([0.0, 1.0])
    pos = t0[:3, 3] + s[:, None] * (t1[:3, 3] - t0[:3, 3])
    if rotation is not None:
        return spatial.transform(np.broadcast_to(_rotation(rotation), (len(s), 3, 3)), pos)
    w = spatial.so3_log(t1[:3, :3] @ t0[:3, :3].T)
    rot = spatial.so3_exp(s[:, None] * w) @ t0[:3, :3]
    return spatial.transform(rot, pos)


def _pose(value: Any, name: str) -> np.ndarray:
    """A 4x4 transform, or a 3-vector as a translation."""
    v = real_array(value, name)
    if v.shape == (3,):
        return spatial.transform(np.eye(3), as_vector(v, name, 3))
    return as_transform(v, name)


def circle_path(
    center: Any,
    radius: float,
    speed: float,
    dt: float,
    rotation: Any = None,
    normal: Any = (0, 0, 1),
    start_angle: float = 0.0,
    turns: float = 1.0,
) -> np.ndarray:
    """A circle at constant tool speed and constant tool orientation, sampled every
    ``speed * dt`` of its arc, the last point included (as `line_path` and `polyline_path`).

    The circle lies in the plane through ``center`` normal to ``normal``; angle 0 is along the
    projection of ``+x`` on that plane (``+y`` when ``normal`` is nearly ``x``).

    Args:
        center: 3-vector.
        radius: ``> 0``.
        speed: tool speed (m/s, ``> 0``).
        dt: sample period (s, ``> 0``).
        rotation: constant 3x3 tool orientation (identity when None).
        normal: plane normal.
        start_angle: angle of the first sample (rad).
        turns: number of turns (1: a closed circle, first and last samples equal; negative:
            clockwise about ``normal``).

    Raises:
        InvalidArgumentError: a bad argument, or more than `MAX_SAMPLES` samples (argument
            ``speed/dt``).
    """
    c = as_vector(center, "center", 3)
    r = as_float(radius, "radius", 0.0, strict=True)
    a0, turns = as_float(start_angle, "start_angle"), as_float(turns, "turns")
    z = as_vector(normal, "normal", 3)
    if np.linalg.norm(z) == 0:
        raise InvalidArgumentError("normal", "must be non-zero")
    if turns == 0:
        raise InvalidArgumentError("turns", "must be non-zero")
    z = z / np.linalg.norm(z)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - (ref @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    a = a0 + np.sign(turns) * _arc_samples(2 * np.pi * r * abs(turns), speed, dt) / r
    pos = c + r * (np.cos(a)[:, None] * x + np.sin(a)[:, None] * y)
    rot = _rotation(rotation)
    return spatial.transform(np.broadcast_to(rot, (len(a), 3, 3)), pos)


def polyline_path(points: Any, speed: float, dt: float, rotation: Any = None) -> np.ndarray:
    """A seam through ``points`` at constant tool speed and constant tool orientation (the seeds'
    welding example: the torch keeps its angle and moves uniformly along the seam).

    Samples are ``speed * dt`` apart along the polyline (arc length), the last point included.

    Args:
        points: ``(k, 3)`` corner points, ``k >= 2``.
        speed: tool speed (m/s, ``> 0``).
        dt: sample period (s, ``> 0``).
        rotation: constant 3x3 tool orientation (identity when None).

    Returns:
        ``(n, 4, 4)`` array.

    Raises:
        InvalidArgumentError: bad points, speed or dt, or more than `MAX_SAMPLES`
            samples (argument ``speed/dt``).
    """
    pts, _ = as_batch(points, "points", 3)
    if pts.shape[0] < 2:
        raise InvalidArgumentError("points", f"expected at least 2 points, got {pts.shape[0]}")
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    s = _arc_samples(float(arc[-1]), speed, dt)
    pos = np.stack([np.interp(s, arc, pts[:, k]) for k in range(3)], axis=-1)
    rot = _rotation(rotation)
    return spatial.transform(np.broadcast_to(rot, (len(s), 3, 3)), pos)
