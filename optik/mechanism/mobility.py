"""Mobility from the geometry: ``M = n_q - rank(dc/dq)`` at generic assembled configurations.

Gruebler-Kutzbach (`optik.mechanism.topology.gruebler_kutzbach`) counts ``lambda = 6``
constraints per loop of a spatial mechanism; a loop whose joints move in parallel planes
(a five-bar, a slider-crank or a 3-RPR built with revolute axes along x in 3-D) imposes only
3 independent ones, and the count comes out too low. The rank of the closure Jacobian counts
what the loops really impose: at an assembled configuration ``q`` (``c(q) = 0``) the first-order
motions are the null space of ``dc/dq``, of dimension ``n_q - rank``. Singular configurations
only lower the rank, so the largest rank over a few seeded assembled configurations is the
generic one.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["ASSEMBLY_TOL", "RANK_TOL", "generic_closure_rank"]

ASSEMBLY_TOL = 1e-10
"""A configuration is assembled when ``max |c(q)| <= ASSEMBLY_TOL``."""
RANK_TOL = 1e-8
"""Singular values of ``dc/dq`` at most ``RANK_TOL`` times the largest (or 1) do not count."""
_ITERATIONS = 60
_ASSEMBLIES = 3


def generic_closure_rank(
    closure: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], starts: np.ndarray
) -> int | None:
    """The largest rank of ``dc/dq`` over up to three configurations assembled from ``starts``.

    Each start is moved onto ``c(q) = 0`` by Gauss-Newton steps ``q <- q - pinv(J) c`` (the
    least-norm correction; no limits: mobility does not depend on them).

    Args:
        closure: ``q -> (c(q), dc/dq)``.
        starts: start configurations ``(k, n_q)``.

    Returns:
        The rank, or None when no start assembled within the iteration budget.
    """
    ranks = []
    for q in np.asarray(starts, dtype=float):
        for _ in range(_ITERATIONS):
            c, jac = (np.asarray(v, dtype=float) for v in closure(q))
            c = c.reshape(-1)
            if not np.all(np.isfinite(c)) or not np.all(np.isfinite(jac)):
                break
            if float(np.max(np.abs(c), initial=0.0)) <= ASSEMBLY_TOL:
                s = np.linalg.svd(jac, compute_uv=False)
                ranks.append(int(np.sum(s > RANK_TOL * max(1.0, float(s[0]) if s.size else 1.0))))
                break
            q = q - np.linalg.lstsq(jac, c, rcond=None)[0]
        if len(ranks) == _ASSEMBLIES:
            break
    return max(ranks) if ranks else None
