"""Collisions between a path's samples: each segment checked at interior configurations.

Between samples ``k`` and ``k + 1`` the joints move linearly, ``q(s) = q_k + s (q_{k+1} - q_k)``.
A segment is checked at ``c_k = ceil(max_j |q_{k+1,j} - q_{k,j}| / step) - 1`` interior points
``s = i / (c_k + 1)``, so that no joint moves more than ``step`` between two checked
configurations (its ends are the samples, checked as nodes of the graph). A segment between
two checked configurations can still graze an obstacle thinner than the motion of a link over
``step``: the check is as fine as the sampling, not a continuous one.
"""

from __future__ import annotations

import numpy as np

from optik.collision import World, check_many
from optik.mechanism import Mechanism

EDGE_STEP = 0.02
"""Default largest joint step (rad) between the configurations checked along a segment."""


def interior(q: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The interior configurations of the segments of ``q (N, n)`` ``(P, n)`` (module
    docstring) and the segment of each ``(P,)``."""
    d = np.diff(q, axis=0)
    count = np.maximum(np.ceil(np.abs(d).max(axis=1, initial=0.0) / step).astype(np.int64) - 1, 0)
    segment = np.repeat(np.arange(len(d)), count)
    i = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + 1
    s = i / (count[segment] + 1.0)
    return q[segment] + s[:, None] * d[segment], segment


def colliding_segments(m: Mechanism, q: np.ndarray, world: World, margin: float, step: float) -> np.ndarray:
    """The segments ``k`` (``q_k -> q_{k+1}``) with an interior configuration in collision with
    ``world`` or with the robot itself, ascending."""
    points, segment = interior(q, step)
    if not len(points):
        return np.zeros(0, dtype=np.int64)
    hit = check_many(m, points, world=world, margin=margin).in_collision
    return np.unique(segment[hit])
