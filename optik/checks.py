"""Validation of user input: shapes, finiteness, names. Raise :mod:`optik.errors` subclasses."""

from __future__ import annotations

from typing import Any

import numpy as np

from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError


def as_vector(value: Any, name: str, size: int | None = None) -> np.ndarray:
    """A finite float vector of the given size.

    Raises:
        ShapeError: not one-dimensional, or not of ``size`` entries.
        NonFiniteError: contains NaN or infinity.
    """
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidArgumentError(name, f"expected numbers, got {value!r}") from exc
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1:
        raise ShapeError(name, f"expected a vector, got an array of shape {a.shape}")
    if size is not None and a.shape[0] != size:
        raise ShapeError(name, f"expected {size} values, got {a.shape[0]}")
    if not np.isfinite(a).all():
        raise NonFiniteError(name, f"contains NaN or infinity: {a}")
    return a


def as_batch(value: Any, name: str, size: int) -> tuple[np.ndarray, bool]:
    """A finite ``(N, size)`` array, and whether the input was a single vector.

    Raises:
        ShapeError: last axis is not ``size`` or more than two axes.
        NonFiniteError: contains NaN or infinity.
    """
    a = np.asarray(value, dtype=float)
    single = a.ndim <= 1
    a = np.atleast_2d(a)
    if a.ndim != 2 or a.shape[1] != size:
        raise ShapeError(name, f"expected shape ({size},) or (N, {size}), got {np.shape(value)}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(name, "contains NaN or infinity")
    return a, single


_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_EYE3 = np.eye(3)


def as_transform(value: Any, name: str) -> np.ndarray:
    """A finite 4x4 homogeneous transform with an orthonormal rotation block.

    Raises:
        ShapeError: not 4x4.
        NonFiniteError: NaN or infinity.
        InvalidArgumentError: the last row is not ``[0, 0, 0, 1]`` or the rotation is not proper.
    """
    t = np.asarray(value, dtype=float)
    if t.shape != (4, 4):
        raise ShapeError(name, f"expected a 4x4 transform, got shape {t.shape}")
    if not np.isfinite(t).all():
        raise NonFiniteError(name, "contains NaN or infinity")
    # np.allclose semantics (|a - b| <= atol + 1e-5 |b|) without its overhead: this runs per IK call
    if not (np.abs(t[3] - _LAST_ROW) <= 1e-9 + 1e-5 * _LAST_ROW).all():
        raise InvalidArgumentError(name, f"last row must be [0, 0, 0, 1], got {t[3]}")
    r = t[:3, :3]
    if not (np.abs(r.T @ r - _EYE3) <= 1e-6 + 1e-5 * _EYE3).all() or np.linalg.det(r) < 0:
        raise InvalidArgumentError(name, "rotation block is not a proper rotation (R^T R != I or det < 0)")
    return t


def as_rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    """A numpy Generator from a seed, an existing Generator, or None (seed 0: reproducible)."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        seed = 0
    if not isinstance(seed, (int, np.integer)):
        raise InvalidArgumentError("seed", f"expected an int or numpy Generator, got {seed!r}")
    return np.random.default_rng(int(seed))
