"""The layered graph of a path and its path of least weighted joint motion.

Layer ``k`` holds the nodes of sample ``k`` (configurations ``(K_k, n)``); every node of layer
``k`` is joined to every node of layer ``k + 1`` by an edge of cost

```
c(a, b) = |W (q_b - q_a)|_2 ,   W = diag(weights)
```

(a joint with a period ``P_j > 0`` measures its difference modulo ``P_j``, in
``[-P_j / 2, P_j / 2]``: the relaxed graph of `optik.path.plan`) unless the edge breaks a
per-joint step bound ``|q_b - q_a|_j <= s_kj`` (the velocity limits
times the segment's duration), in which case it is removed. The path of least total cost from
layer 0 to the last layer is found by dynamic programming (Bellman's recursion, one layer at a
time, each layer one vectorized numpy step over its ``K_k x K_{k+1}`` edges):

```
C_0(a) = 0,   C_{k+1}(b) = min_a C_k(a) + c(a, b),   p_{k+1}(b) = argmin_a ...
```

then traced back from ``argmin_b C_{N-1}(b)``. The answer is the exact optimum over the graph:
every path through the layers is one sequence of edges and the recursion keeps, for every node,
the cheapest way to it.

The recursion runs in C (``dp.c``, compiled once per machine by `optik.native.source_library`;
the call releases the GIL) with an exact branch and bound: the predecessors of a node are
visited outwards from it in the coordinate that tells the nodes apart most, stopping once that
coordinate's distance alone, added to the least predecessor cost, reaches the best found, and
an edge's squared length is summed joint by joint, stopping when it can no longer improve.
Each layer is sorted once in that coordinate, warm-started from the previous layer's order
(consecutive poses list their solutions alike), and its nodes are visited in that order.
Without a C compiler the same recursion runs in numpy (`least_motion_numpy`), one vectorized
step per layer. Equal totals (ties, e.g. two copies of one node) may resolve differently on the
two paths; the cost is the same.
"""

from __future__ import annotations

import ctypes
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optik import native

SOURCE = Path(__file__).with_name("dp.c")
"""The C kernel of `least_motion`."""
_LIB: list[ctypes.CDLL | None] = []
_LOCK = threading.Lock()


class Layered(Sequence[np.ndarray]):
    """Rows in consecutive layers, stored contiguously: layer ``k`` is
    ``data[offset[k] : offset[k + 1]]`` (a view). The graph's nodes ``(M, n)`` and their
    groups ``(M,)`` take this form, so that the dynamic program and the checks read one array
    and no per-layer objects are built; it is a sequence of its layers (``len``, index, iterate).
    """

    def __init__(self, data: np.ndarray, offset: np.ndarray) -> None:
        self.data, self.offset = data, np.asarray(offset, dtype=np.int64)

    @classmethod
    def of(cls, layers: Sequence[np.ndarray]) -> Layered:
        """``layers`` as a `Layered` (itself when it already is one)."""
        if isinstance(layers, Layered):
            return layers
        sizes = np.array([len(x) for x in layers], dtype=np.int64)
        return cls(np.concatenate(layers), np.concatenate([[0], np.cumsum(sizes)]))

    @classmethod
    def by_owner(cls, data: np.ndarray, owner: np.ndarray, count: int) -> Layered:
        """Rows ``data`` whose layers ``owner`` (ascending) are given, over ``count`` layers."""
        return cls(data, np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=count))]))

    @property
    def sizes(self) -> np.ndarray:
        """Rows per layer ``(N,)``."""
        return np.diff(self.offset)

    def owner(self) -> np.ndarray:
        """The layer of each row ``(M,)``."""
        return np.repeat(np.arange(len(self)), self.sizes)

    def rows(self, index: np.ndarray) -> np.ndarray:
        """Row ``index[k]`` of each layer ``k`` (``(N, ...)``)."""
        return self.data[self.offset[:-1] + index]

    def keep(self, mask: np.ndarray) -> Layered:
        """The rows where ``mask (M,)`` holds, in their layers."""
        return Layered.by_owner(self.data[mask], self.owner()[mask], len(self))

    def __len__(self) -> int:
        return len(self.offset) - 1

    def __getitem__(self, k):  # type: ignore[override]  # a layer (int), not slices
        k = range(len(self))[k]
        return self.data[self.offset[k] : self.offset[k + 1]]


@dataclass(frozen=True)
class GraphPath:
    """The optimum through a layered graph.

    Attributes:
        index: per layer, the chosen node (``-1`` everywhere when there is no path).
        cost: its total cost (``inf`` when there is no path).
        blocked: the first layer that no node of the previous one reaches within the step
            bounds (-1 when a path exists).
    """

    index: np.ndarray
    cost: float
    blocked: int


def differences(a: np.ndarray, b: np.ndarray, periods: np.ndarray) -> np.ndarray:
    """``b - a`` (broadcast), modulo the period of each joint that has one."""
    d = b - a
    p = np.where(periods > 0.0, periods, 1.0)
    return np.where(periods > 0.0, d - p * np.round(d / p), d)


def edge_costs(
    a: np.ndarray, b: np.ndarray, weights: np.ndarray, periods: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Costs ``(K_a, K_b)`` of every edge between nodes ``a (K_a, n)`` and ``b (K_b, n)``, and
    the joint differences ``(K_a, K_b, n)`` the step bounds are checked on."""
    d = differences(a[:, None, :], b[None, :, :], periods)
    dw = d * weights
    return np.sqrt(np.einsum("ijk,ijk->ij", dw, dw)), d


def compiled() -> ctypes.CDLL | None:
    """The compiled kernel (built on first use, cached on disk), or None without a C compiler."""
    with _LOCK:
        if not _LIB:
            text = native.driver_source(SOURCE)
            lib = None if text is None else native.source_library(text, "optik_path_dp", "auto")
            if lib is not None:
                fn = lib.optik_path_dp
                ptr, i32 = ctypes.c_void_p, ctypes.c_int
                fn.argtypes = [i32, ptr, ptr, i32, i32, *[ptr] * 13]
                fn.restype = i32
            _LIB.append(lib)
        return _LIB[0]


def _ptr(a: np.ndarray | None) -> int | None:
    return None if a is None else a.ctypes.data


def _key_joint(layers: Sequence[np.ndarray], weights: np.ndarray) -> int:
    """The joint the C kernel orders the predecessors by: the (weighted) one with the most
    distinct values among a layer's nodes (over up to 8 layers; ties by spread), so that the
    window of predecessors it scans is the narrowest."""
    picked = [layers[k] for k in range(0, len(layers), max(1, len(layers) // 8))]
    distinct = np.zeros(len(weights))
    spread = np.zeros(len(weights))
    for layer in picked:
        distinct += 1 + np.count_nonzero(np.diff(np.sort(layer, axis=0), axis=0) > 1e-9, axis=0)
        spread += np.abs(layer - layer.mean(axis=0)).sum(axis=0)
    score = np.where(weights > 0, distinct + spread * weights / (1.0 + (spread * weights).max()), -1.0)
    return int(np.argmax(score))


def least_motion(
    layers: Sequence[np.ndarray],
    weights: np.ndarray,
    step_bounds: np.ndarray | None = None,
    periods: np.ndarray | None = None,
    removed: np.ndarray | None = None,
) -> GraphPath:
    """The path of least weighted joint motion through ``layers`` (module docstring).

    Args:
        layers: per sample, its nodes ``(K_k, n)`` (each ``K_k >= 1``).
        weights: per-joint weights ``(n,)``.
        step_bounds: ``(N - 1, n)`` largest allowed ``|q_{k+1} - q_k|`` per joint and segment,
            or None (no bound).
        periods: per joint, the period of its differences (0: none; default none).
        removed: edges taken out of the graph ``(F, 3)``, each ``(k, a, b)``: from node ``a`` of
            layer ``k - 1`` to node ``b`` of layer ``k`` (None: none).

    Returns:
        The optimal `GraphPath`.
    """
    per = np.zeros(layers[0].shape[1]) if periods is None else np.ascontiguousarray(periods, dtype=float)
    lib = compiled()
    if lib is None:
        return least_motion_numpy(layers, weights, step_bounds, per, removed)
    graph = Layered.of(layers)
    sizes = graph.sizes
    offset = graph.offset.astype(np.int32)
    w = np.ascontiguousarray(weights, dtype=float)
    first = _key_joint(graph, w)
    nodes = np.ascontiguousarray(graph.data, dtype=float)
    bounds = None if step_bounds is None else np.ascontiguousarray(step_bounds, dtype=float)
    total = len(nodes)
    cost, back = np.empty(total), np.empty(total, dtype=np.int32)
    order, tmp, here = (np.empty(int(sizes.max()), dtype=np.int32) for _ in range(3))
    index, best, key = np.empty(len(layers), dtype=np.int32), np.zeros(1), np.empty(total)
    fstart = fpred = None
    if removed is not None and len(removed):
        e = np.asarray(removed, dtype=np.int64).reshape(-1, 3)
        target = graph.offset[e[:, 0]] + e[:, 2]
        by = np.argsort(target, kind="stable")
        fpred = np.ascontiguousarray(graph.offset[e[by, 0] - 1] + e[by, 1], dtype=np.int32)
        counts = np.bincount(target, minlength=total)
        fstart = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    blocked = lib.optik_path_dp(
        len(layers), _ptr(offset), _ptr(nodes), nodes.shape[1], first, _ptr(w), _ptr(per), _ptr(bounds),
        _ptr(cost), _ptr(back), _ptr(order), _ptr(tmp), _ptr(index), _ptr(best), _ptr(key), _ptr(here),
        _ptr(fstart), _ptr(fpred),
    )  # fmt: skip
    if blocked >= 0:
        return GraphPath(np.full(len(layers), -1), float("inf"), int(blocked))
    return GraphPath(index.astype(int), float(best[0]), -1)


def least_motion_numpy(
    layers: Sequence[np.ndarray],
    weights: np.ndarray,
    step_bounds: np.ndarray | None,
    periods: np.ndarray,
    removed: np.ndarray | None = None,
) -> GraphPath:
    """`least_motion` in numpy, one vectorized step per layer (without compiled code)."""
    n_layers = len(layers)
    cost = np.zeros(len(layers[0]))
    back: list[np.ndarray] = []
    e = (
        np.zeros((0, 3), dtype=np.int64)
        if removed is None
        else np.asarray(removed, dtype=np.int64).reshape(-1, 3)
    )
    for k in range(1, n_layers):
        c, d = edge_costs(layers[k - 1], layers[k], weights, periods)
        if step_bounds is not None:
            c[(np.abs(d) > step_bounds[k - 1]).any(axis=-1)] = np.inf
        here = e[e[:, 0] == k]
        c[here[:, 1], here[:, 2]] = np.inf
        total = cost[:, None] + c
        arg = total.argmin(axis=0)
        cost = total[arg, np.arange(total.shape[1])]
        if not np.isfinite(cost).any():
            return GraphPath(np.full(n_layers, -1), float("inf"), k)
        back.append(arg)
    index = np.empty(n_layers, dtype=int)
    index[-1] = int(cost.argmin())
    for k in range(n_layers - 1, 0, -1):
        index[k - 1] = back[k - 1][index[k]]
    return GraphPath(index, float(cost[index[-1]]), -1)


def branch_changes(
    layers: Sequence[np.ndarray],
    index: np.ndarray,
    weights: np.ndarray,
    groups: Sequence[np.ndarray],
    periods: np.ndarray,
) -> np.ndarray:
    """Per sample, how many branch changes the path ``index`` made before it.

    A step ``k -> k + 1`` changes branch when the chosen node of layer ``k + 1`` is not the node
    nearest (in weighted joint distance) to the chosen node of layer ``k`` among the nodes of its
    own group (the nodes of one tool pose: one free-axis sample, one self-motion sample). On a
    densely sampled path the nearest solution of the next pose is the continuation of the same
    branch, so a step to any other is a jump to another branch. Differences are taken modulo
    ``periods`` as in `least_motion`. Only the nodes of the chosen groups are measured.
    """
    if len(index) < 2:
        return np.zeros(len(index), dtype=int)
    nodes, tags = Layered.of(layers), Layered.of(groups)
    picked = nodes.offset[:-1] + index
    chosen = nodes.data[picked]
    # the nodes of layers 1.. in the chosen node's group (each layer's chosen node among them)
    start = nodes.offset[1]
    same = start + np.flatnonzero(tags.data[start:] == np.repeat(tags.data[picked[1:]], nodes.sizes[1:]))
    layer = np.searchsorted(nodes.offset, same, side="right") - 1
    dist = np.linalg.norm(differences(chosen[layer - 1], nodes.data[same], periods) * weights, axis=1)
    nearest = np.minimum.reduceat(dist, np.searchsorted(layer, np.arange(1, len(index))))
    flips = dist[np.searchsorted(same, picked[1:])] > nearest
    return np.concatenate([[0], np.cumsum(flips)])
