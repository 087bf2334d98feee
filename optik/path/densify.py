"""Densification: the tool between two samples stays near the straight segment between them.

Between samples ``k`` and ``k + 1`` the joints move along the straight joint-space segment
``q(s) = q_k + s (q_{k+1} - q_k)``; the tool point ``p(s)`` of that motion leaves the straight
Cartesian segment ``[p_k, p_{k+1}]`` in between. `deviation` measures the largest distance of
``p(s)`` from that segment at ``s = 1/4, 1/2, 3/4``; where it exceeds the tolerance, `midpoints`
inserts the pose halfway (position halfway, rotation halfway along the geodesic
``R_k exp(log(R_k^T R_{k+1}) / 2)``), and the path is planned again, until every segment is
within the tolerance or the rounds run out.
"""

from __future__ import annotations

import numpy as np

from optik.batch import fk_batch
from optik.mechanism import Mechanism
from optik.spatial import so3_exp, so3_log

FRACTIONS = np.array([0.25, 0.5, 0.75])
"""Where each segment's tool deviation is measured."""


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of points ``p (..., 3)`` from the segments ``[a, b]`` (broadcast)."""
    ab = b - a
    den = np.einsum("...i,...i->...", ab, ab)
    s = np.clip(np.einsum("...i,...i->...", p - a, ab) / np.where(den > 0.0, den, 1.0), 0.0, 1.0)
    return np.linalg.norm(p - (a + s[..., None] * ab), axis=-1)


def tool_deviation(m: Mechanism, q: np.ndarray, frame: str | None) -> tuple[np.ndarray, np.ndarray]:
    """The tool poses of the samples ``(N, 4, 4)`` and the largest tool deviation ``(N - 1,)``
    of each joint segment from the straight segment between the tool points of its ends
    (module docstring), from one FK batch over the samples and the inner points."""
    inner = q[:-1, None] + FRACTIONS[None, :, None] * np.diff(q, axis=0)[:, None]  # (N-1, F, n)
    fk = fk_batch(m, np.concatenate([q, inner.reshape(-1, m.n_q)]), frame)
    tips = fk[: len(q), :3, 3]
    mid = fk[len(q) :, :3, 3].reshape(len(q) - 1, len(FRACTIONS), 3)
    return fk[: len(q)], segment_distance(mid, tips[:-1, None], tips[1:, None]).max(axis=1, initial=0.0)


def halfway(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The pose halfway between ``a`` and ``b`` (4x4; position and geodesic rotation)."""
    out = np.eye(4)
    out[:3, 3] = 0.5 * (a[:3, 3] + b[:3, 3])
    out[:3, :3] = a[:3, :3] @ np.asarray(so3_exp(0.5 * np.asarray(so3_log(a[:3, :3].T @ b[:3, :3]))))
    return out


def midpoints(
    poses: np.ndarray, values: list[np.ndarray | None], segments: np.ndarray
) -> tuple[np.ndarray, list[np.ndarray | None]]:
    """``poses (N, 4, 4)`` and the per-pose ``values`` (times, tolerances: ``(N,)`` arrays or
    None) with a sample inserted halfway along each of ``segments`` (indices ``k`` of the
    segments ``k -> k + 1``)."""
    at = segments + 1
    new = np.stack([halfway(poses[k], poses[k + 1]) for k in segments])
    out = [None if v is None else np.insert(v, at, 0.5 * (v[segments] + v[at])) for v in values]
    return np.insert(poses, at, new, axis=0), out
