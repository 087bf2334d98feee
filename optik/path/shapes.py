"""Tool paths from a few numbers: a line, an arc, a polyline, waypoints (the ``[path]`` table of
a problem file).

Each returns ``n`` poses ``(n, 4, 4)`` evenly spaced by arc length:

* `line`: from the start pose to its position plus ``offset`` (base frame), orientation held;
* `arc`: the start position turned by ``angle`` about the axis through ``start + centre`` along
  ``axis`` (right hand), the tool turning with it (``turn_tool``) or held;
* `polyline`: through the start position and the corners ``start + offsets[i]``, orientation held;
* `waypoints`: through given poses, the position along the segments, the rotation along the
  geodesic of each segment (``R_i exp(s log(R_i^T R_{i+1}))``) in proportion.
"""

from __future__ import annotations

import numpy as np

from optik.checks import as_float, as_int, as_transform, as_vector, real_array
from optik.errors import InvalidArgumentError, ShapeError
from optik.spatial import so3_exp, so3_log

__all__ = ["arc", "line", "polyline", "waypoints"]


def _stations(lengths: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """For ``n`` stations evenly spaced along segments of ``lengths``: each one's segment and
    its fraction along it."""
    total = float(lengths.sum())
    if total <= 0.0:
        raise InvalidArgumentError("path", "has zero length")
    s = np.linspace(0.0, total, n)
    ends = np.cumsum(lengths)
    seg = np.minimum(np.searchsorted(ends, s, side="right"), len(lengths) - 1)
    start = ends[seg] - lengths[seg]
    frac = np.divide(s - start, lengths[seg], out=np.zeros(n), where=lengths[seg] > 0)
    return seg, np.clip(frac, 0.0, 1.0)


def waypoints(poses: object, n: int) -> np.ndarray:
    """``n`` poses through the waypoints ``poses (W, 4, 4)`` (module docstring)."""
    a = real_array(poses, "waypoints")
    if a.ndim != 3 or a.shape[1:] != (4, 4) or len(a) < 2:
        raise ShapeError("waypoints", f"expected W >= 2 poses of shape (W, 4, 4), got {a.shape}")
    ts = np.stack([as_transform(t, f"waypoints[{k}]") for k, t in enumerate(a)])
    count = as_int(n, "n", 2)
    seg, frac = _stations(np.linalg.norm(np.diff(ts[:, :3, 3], axis=0), axis=1), count)
    logs = [
        np.asarray(so3_log(ts[i, :3, :3].T @ ts[i + 1, :3, :3]), dtype=float).reshape(3)
        for i in range(len(ts) - 1)
    ]
    out = np.tile(np.eye(4), (count, 1, 1))
    for k, (i, f) in enumerate(zip(seg, frac, strict=True)):
        out[k, :3, 3] = (1.0 - f) * ts[i, :3, 3] + f * ts[i + 1, :3, 3]
        out[k, :3, :3] = ts[i, :3, :3] @ np.asarray(so3_exp(f * logs[i]), dtype=float)
    return out


def polyline(start: object, offsets: object, n: int) -> np.ndarray:
    """``n`` poses along the polyline from ``start`` through ``start + offsets[i]``."""
    t0 = as_transform(start, "start")
    pts = real_array(offsets, "points")
    if pts.ndim != 2 or pts.shape[1] != 3 or not len(pts):
        raise ShapeError("points", f"expected (K, 3) offsets, got {pts.shape}")
    ts = np.repeat(t0[None], len(pts) + 1, axis=0)
    ts[1:, :3, 3] += pts
    return waypoints(ts, n)


def line(start: object, offset: object, n: int) -> np.ndarray:
    """``n`` poses along the segment from ``start`` to its position plus ``offset``."""
    return polyline(start, as_vector(offset, "end", 3)[None], n)


def arc(
    start: object, centre: object, axis: object, angle: float, n: int, turn_tool: bool = True
) -> np.ndarray:
    """``n`` poses on the arc of ``angle`` (rad) about the axis through ``start + centre``."""
    t0 = as_transform(start, "start")
    c = t0[:3, 3] + as_vector(centre, "center", 3)
    ax = as_vector(axis, "axis", 3)
    if np.linalg.norm(ax) == 0.0:
        raise InvalidArgumentError("axis", "must not be zero")
    ax = ax / np.linalg.norm(ax)
    phi = np.linspace(0.0, as_float(angle, "angle"), as_int(n, "n", 2))
    out = np.repeat(t0[None], len(phi), axis=0)
    for k, a in enumerate(phi):
        r = np.asarray(so3_exp(a * ax), dtype=float)
        out[k, :3, 3] = c + r @ (t0[:3, 3] - c)
        if turn_tool:
            out[k, :3, :3] = r @ t0[:3, :3]
    return out
