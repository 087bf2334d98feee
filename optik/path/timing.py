"""Times of a joint path, and its velocities and accelerations.

Given times: the graph removes the edges that break the velocity limits (`step_bounds`).
Without times: each segment ``k`` lasts

```
dt_k = max( d_k / speed,  max_j |q_{k+1,j} - q_{k,j}| / v_j,  min_dt )
```

``d_k`` the tool's travel on it (the nominal time at the tool speed ``speed``, when given), the
second term the shortest time the velocity limits ``v`` allow. A segment is *stretched* when the
second term exceeds the first. Velocities and accelerations are second-order finite differences
on the (non-uniform) times (``numpy.gradient``): at an inner sample the velocity is a convex
combination of the two adjacent segment velocities ``(q_{k+1} - q_k) / dt_k``, so it meets any
bound that the segments meet.
"""

from __future__ import annotations

import numpy as np

MIN_DT = 1e-3
"""Shortest segment duration (s) without times: a segment over which nothing moves."""


def step_bounds(times: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Largest joint step per segment ``(N - 1, n)``: ``v_j dt_k``."""
    return np.diff(times)[:, None] * velocity[None, :]


def segment_times(
    q: np.ndarray, travel: np.ndarray, velocity: np.ndarray | None, speed: float | None
) -> tuple[np.ndarray, int]:
    """Times ``(N,)`` from 0 (module docstring) and the number of stretched segments."""
    nominal = travel / speed if speed is not None else np.zeros(len(travel))
    if velocity is None:
        dt = np.maximum(nominal, MIN_DT) if speed is not None else np.ones(len(travel))
        return np.concatenate([[0.0], np.cumsum(dt)]), 0
    fastest = (np.abs(np.diff(q, axis=0)) / velocity).max(axis=1) if len(q) > 1 else np.zeros(0)
    dt = np.maximum(np.maximum(nominal, fastest), MIN_DT)
    stretched = int(np.count_nonzero(fastest > nominal)) if speed is not None else 0
    return np.concatenate([[0.0], np.cumsum(dt)]), stretched


def derivatives(q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocities and accelerations ``(N, n)`` of the samples (zeros for a single sample)."""
    if len(q) < 2:
        return np.zeros_like(q), np.zeros_like(q)
    qd = np.gradient(q, t, axis=0)
    return qd, np.gradient(qd, t, axis=0)
