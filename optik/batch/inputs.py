"""Validation of batch inputs: many targets and starts at once, vectorized."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from optik.checks import as_batch
from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError
from optik.mechanism import Mechanism
from optik.solvers.base import default_task
from optik.solvers.lm import request_seed
from optik.solvers.lm_kernel import target_seeds
from optik.targets import Pose2D, Position, target_transform

_ORTHO = 1e-5
"""Tolerance of ``R^T R = I`` per entry (as `optik.checks.as_transform`)."""


def as_targets(m: Mechanism, targets: Any) -> tuple[np.ndarray, str]:
    """``(N, 4, 4)`` transforms of a batch of targets and the task they imply.

    Accepted: an ``(N, 4, 4)`` array of homogeneous transforms (task: the mechanism's own), an
    ``(N, 3)`` array of positions (``"position"``, ``"position2d"`` for planar mechanisms), or a
    sequence of `optik.Pose2D` (``"pose2d"``), `optik.Position` or 4x4 transforms.

    Raises:
        ShapeError, NonFiniteError, InvalidArgumentError: naming ``targets`` (and the index of
            the first bad one).
    """
    if isinstance(targets, Sequence) and not isinstance(targets, np.ndarray) and len(targets):
        first = targets[0]
        if isinstance(first, (Pose2D, Position)):
            kinds = {type(t) for t in targets}
            if len(kinds) != 1:
                raise InvalidArgumentError(
                    "targets", f"mixed target types {sorted(k.__name__ for k in kinds)}"
                )
            t = np.stack([target_transform(x, f"targets[{i}]") for i, x in enumerate(targets)])
            return t, default_task(m, first)
    try:
        a = np.asarray(targets, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidArgumentError(
            "targets", f"expected an array of transforms or positions: {exc}"
        ) from None
    if a.ndim == 2 and a.shape[1] == 3:
        positions, _ = as_batch(a, "targets", 3)
        t = np.tile(np.eye(4), (len(positions), 1, 1))
        t[:, :3, 3] = positions
        return t, default_task(m, Position(0.0, 0.0, 0.0))
    if a.ndim == 1 and a.shape[0] == 0:
        return np.zeros((0, 4, 4)), m.task
    if a.ndim != 3 or a.shape[1:] != (4, 4):
        raise ShapeError("targets", f"expected (N, 4, 4) transforms or (N, 3) positions, got shape {a.shape}")
    _check_transforms(a)
    return a, m.task


def _check_transforms(t: np.ndarray) -> None:
    bad = ~np.isfinite(t).all(axis=(1, 2))
    if bad.any():
        raise NonFiniteError("targets", f"targets[{int(np.argmax(bad))}] contains NaN or infinity")
    last = np.abs(t[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) > 1e-9
    r = t[:, :3, :3]
    gram = np.abs(np.einsum("nki,nkj->nij", r, r) - np.eye(3)).max(axis=(1, 2))
    bad = last | (gram > _ORTHO) | (np.linalg.det(r) < 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise InvalidArgumentError(
            "targets", f"targets[{i}] is not a homogeneous transform with a proper rotation"
        )


def as_starts(m: Mechanism, q0: Any, n: int) -> np.ndarray:
    """``(n, n_q)`` starts: mid-limit for None, one vector repeated, or one row per target.

    Raises:
        ShapeError, NonFiniteError: naming ``q0``.
    """
    if q0 is None:
        return np.tile(m.mid_q(), (n, 1))
    q, single = as_batch(q0, "q0", m.n_q)
    if single:
        return np.tile(q[0], (n, 1))
    if len(q) != n:
        raise ShapeError("q0", f"expected one start or {n} (one per target), got {len(q)}")
    return np.ascontiguousarray(q)


def target_seed_array(seed: Any, n: int) -> tuple[np.ndarray, int | None]:
    """The seeds of ``n`` targets (uint64) and the batch seed they derive from.

    ``seed`` is the batch seed (None is 0, as for `optik.solve_ik`; a Generator gives one draw):
    target ``i`` gets ``target_seeds(seed, 0, n)[i]``. Or ``seed`` is a sequence of ``n`` ints,
    one per target (e.g. ``result.seed[rows]`` of an earlier batch); the batch seed is then None.

    Raises:
        InvalidArgumentError, ShapeError: naming ``seed``.
    """
    if isinstance(seed, np.random.Generator) or seed is None:
        base = request_seed(seed)
        return target_seeds(base, 0, n), base
    if np.ndim(seed) == 0:
        return target_seeds(_seed_int(seed), 0, n), _seed_int(seed)
    values = [_seed_int(s) for s in np.asarray(seed, dtype=object).reshape(-1)]
    if np.ndim(seed) != 1 or len(values) != n:
        raise ShapeError("seed", f"expected one int or {n} ints (one per target), got shape {np.shape(seed)}")
    return np.array(values, dtype=np.uint64), None


def _seed_int(value: Any) -> int:
    integer = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    if not integer or not 0 <= value < 2**64:
        raise InvalidArgumentError("seed", f"expected ints in [0, 2^64) or a numpy Generator, got {value!r}")
    return int(value)
