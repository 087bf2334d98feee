"""Paths to track: sequences of 4x4 target poses sampled at the control period."""

from __future__ import annotations

from typing import Any

import numpy as np

from optik import spatial
from optik.checks import as_transform, as_vector
from optik.errors import InvalidArgumentError


def _count(n: Any, name: str = "n") -> int:
    if int(n) != n or n < 2:
        raise InvalidArgumentError(name, f"must be an integer >= 2, got {n!r}")
    return int(n)


def line_path(start: Any, end: Any, n: int) -> np.ndarray:
    """``n`` poses from ``start`` to ``end``: positions on the straight segment at constant speed,
    orientation interpolated along the geodesic ``R(s) = exp(s log(R_1 R_0^T)) R_0``.

    Args:
        start, end: 4x4 transforms.
        n: number of samples (``>= 2``), ends included.

    Returns:
        ``(n, 4, 4)`` array.
    """
    t0, t1 = as_transform(start, "start"), as_transform(end, "end")
    s = np.linspace(0.0, 1.0, _count(n))
    w = spatial.so3_log(t1[:3, :3] @ t0[:3, :3].T)
    rot = spatial.so3_exp(s[:, None] * w) @ t0[:3, :3]
    pos = t0[:3, 3] + s[:, None] * (t1[:3, 3] - t0[:3, 3])
    return spatial.transform(rot, pos)


def circle_path(
    center: Any,
    radius: float,
    n: int,
    rotation: Any = None,
    normal: Any = (0, 0, 1),
    start_angle: float = 0.0,
    turns: float = 1.0,
) -> np.ndarray:
    """``n`` poses on a circle at constant speed with a constant tool orientation.

    The circle lies in the plane through ``center`` normal to ``normal``; angle 0 is along the
    projection of ``+x`` on that plane (``+y`` when ``normal`` is nearly ``x``).

    Args:
        center: 3-vector.
        radius: ``> 0``.
        n: number of samples (``>= 2``), both ends included.
        rotation: constant 3x3 tool orientation (identity when None).
        normal: plane normal.
        start_angle: angle of the first sample (rad).
        turns: number of turns (1: a closed circle, first and last samples equal).
    """
    c = as_vector(center, "center", 3)
    r = float(as_vector(radius, "radius", 1)[0])
    if r <= 0:
        raise InvalidArgumentError("radius", f"must be > 0, got {r}")
    z = as_vector(normal, "normal", 3)
    if np.linalg.norm(z) == 0:
        raise InvalidArgumentError("normal", "must be non-zero")
    z = z / np.linalg.norm(z)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - (ref @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    a = start_angle + np.linspace(0.0, 2 * np.pi * turns, _count(n))
    pos = c + r * (np.cos(a)[:, None] * x + np.sin(a)[:, None] * y)
    rot = (
        np.eye(3)
        if rotation is None
        else as_transform(spatial.transform(np.asarray(rotation)), "rotation")[:3, :3]
    )
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
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 2 or not np.all(np.isfinite(pts)):
        raise InvalidArgumentError("points", f"expected (k >= 2, 3) finite points, got shape {pts.shape}")
    v = float(as_vector(speed, "speed", 1)[0])
    h = float(as_vector(dt, "dt", 1)[0])
    if v <= 0 or h <= 0:
        raise InvalidArgumentError("speed" if v <= 0 else "dt", "must be > 0")
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.append(np.arange(0.0, arc[-1], v * h), arc[-1])
    pos = np.stack([np.interp(s, arc, pts[:, k]) for k in range(3)], axis=-1)
    rot = (
        np.eye(3)
        if rotation is None
        else as_transform(spatial.transform(np.asarray(rotation)), "rotation")[:3, :3]
    )
    return spatial.transform(np.broadcast_to(rot, (len(s), 3, 3)), pos)
