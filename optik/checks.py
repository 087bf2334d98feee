"""Validation of user input: shapes, finiteness, names. Raise [`optik.errors`][optik.errors] subclasses."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError


def real_array(value: Any, name: str) -> np.ndarray:
    """``value`` as a float array; strings, complex numbers and other non-real input raise an
    [`InvalidArgumentError`][optik.InvalidArgumentError] naming the argument (never numpy's own exception)."""
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nested sequences
        raise InvalidArgumentError(name, f"expected real numbers, got {value!r}") from exc
    if a.dtype.kind not in "biuf":
        raise InvalidArgumentError(name, f"expected real numbers, got {value!r}")
    return a.astype(float, copy=False)


def read_only(value: Any) -> np.ndarray:
    """A read-only float copy of ``value``: the arrays a model is built from, which cached
    solvers rely on (a write raises numpy's ``ValueError: assignment destination is read-only``)."""
    out = np.array(value, dtype=float)
    out.flags.writeable = False
    return out


def as_vector(value: Any, name: str, size: int | None = None) -> np.ndarray:
    """A finite float vector of the given size.

    Raises:
        ShapeError: not one-dimensional, or not of ``size`` entries.
        NonFiniteError: contains NaN or infinity.
    """
    if type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 1:
        # fast path (per IK call): no conversion; a finite sum implies finite entries (a sum of
        # plain floats overflows to inf silently, then the exact check below decides)
        if (size is None or value.shape[0] == size) and math.isfinite(sum(value.tolist())):
            return value
        a = value
    else:
        a = real_array(value, name)
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
    a = real_array(value, name)
    single = a.ndim <= 1
    a = np.atleast_2d(a)
    if a.ndim != 2 or a.shape[1] != size:
        raise ShapeError(name, f"expected shape ({size},) or (N, {size}), got {np.shape(value)}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(name, "contains NaN or infinity")
    return a, single


ORTHO_DIAG = 1e-6 + 1e-5
"""Tolerance of `as_transform` on each diagonal entry of ``R^T R - I`` (``np.allclose``:
atol 1e-6, rtol 1e-5)."""
ORTHO_OFF = 1e-6
"""Tolerance of `as_transform` on each off-diagonal entry of ``R^T R``."""


def as_transform(value: Any, name: str) -> np.ndarray:
    """A finite 4x4 homogeneous transform with an orthonormal rotation block.

    Raises:
        ShapeError: not 4x4.
        NonFiniteError: NaN or infinity.
        InvalidArgumentError: the last row is not ``[0, 0, 0, 1]`` or the rotation is not proper.
    """
    t = value if type(value) is np.ndarray and value.dtype == np.float64 else real_array(value, name)
    if t.shape != (4, 4):
        raise ShapeError(name, f"expected a 4x4 transform, got shape {t.shape}")
    rows = t.tolist()
    # a finite sum of plain floats implies finite entries (overflow: the exact check decides)
    total = sum(rows[0]) + sum(rows[1]) + sum(rows[2]) + sum(rows[3])
    if not math.isfinite(total) and not np.isfinite(t).all():
        raise NonFiniteError(name, "contains NaN or infinity")
    # np.allclose semantics (|a - b| <= atol + 1e-5 |b|) on plain floats: this runs per IK call
    (r00, r01, r02, _), (r10, r11, r12, _), (r20, r21, r22, _), (a, b, c, d) = rows
    if not (abs(a) <= 1e-9 and abs(b) <= 1e-9 and abs(c) <= 1e-9 and abs(d - 1.0) <= 1e-9 + 1e-5):
        raise InvalidArgumentError(name, f"last row must be [0, 0, 0, 1], got {t[3]}")
    # R^T R = I entry by entry (column dot products), then det R = c0 . (c1 x c2) >= 0
    if not (
        abs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0) <= ORTHO_DIAG
        and abs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0) <= ORTHO_DIAG
        and abs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0) <= ORTHO_DIAG
        and abs(r00 * r01 + r10 * r11 + r20 * r21) <= ORTHO_OFF
        and abs(r00 * r02 + r10 * r12 + r20 * r22) <= ORTHO_OFF
        and abs(r01 * r02 + r11 * r12 + r21 * r22) <= ORTHO_OFF
        and r00 * (r11 * r22 - r21 * r12) - r10 * (r01 * r22 - r21 * r02) + r20 * (r01 * r12 - r11 * r02)
        >= 0.0
    ):
        raise InvalidArgumentError(name, "rotation block is not a proper rotation (R^T R != I or det < 0)")
    return t


def check_seed(seed: Any) -> None:
    """Check a seed as `as_rng` takes it (an int >= 0, a numpy Generator or None) without making
    the generator (which costs about 20 us).

    Raises:
        InvalidArgumentError: anything else (named ``seed``).
    """
    if seed is None or isinstance(seed, np.random.Generator):
        return
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InvalidArgumentError("seed", f"expected an int >= 0 or a numpy Generator, got {seed!r}")


def as_rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    """A numpy Generator from a seed, an existing Generator, or None (seed 0: reproducible)."""
    if isinstance(seed, np.random.Generator):
        return seed
    check_seed(seed)
    return np.random.default_rng(0 if seed is None else int(seed))


def as_float(value: Any, name: str, minimum: float | None = None, strict: bool = False) -> float:
    """A finite real number, optionally bounded below (``>= minimum``, or ``> minimum`` when
    ``strict``).

    Raises:
        InvalidArgumentError: not a real number (None, a string, a sequence, complex ...).
        NonFiniteError: NaN or infinity.
        InvalidArgumentError: below the bound.
    """
    if type(value) is not float or not math.isfinite(value):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise InvalidArgumentError(name, f"expected a real number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise NonFiniteError(name, f"must be finite, got {value}")
    if minimum is not None and (value <= minimum if strict else value < minimum):
        raise InvalidArgumentError(name, f"must be {'>' if strict else '>='} {minimum:g}, got {value:g}")
    return value


def as_bool(value: Any, name: str) -> bool:
    """A boolean option: ``True`` or ``False`` (numpy's ``np.bool_`` too), nothing else.

    A string such as ``"no"`` or a number would be truthy or falsy by Python's rules and be
    taken silently for what it does not say.

    Raises:
        InvalidArgumentError: anything but a boolean.
    """
    if value is True or value is False:
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    raise InvalidArgumentError(name, f"expected True or False, got {value!r}")


def as_name(value: Any, name: str, choices: Any = None) -> str:
    """A string, optionally one of ``choices`` (anything supporting ``in``).

    Lists, None and other non-strings raise here instead of a ``TypeError`` from a dictionary
    lookup (an unhashable value) or a confusing "unknown name" later.

    Raises:
        InvalidArgumentError: not a string, or not one of ``choices`` (the message lists them).
    """
    if not isinstance(value, str):
        raise InvalidArgumentError(name, f"expected a string, got {value!r}")
    if choices is not None and value not in choices:
        raise InvalidArgumentError(name, f"unknown {name} {value!r}; use one of {sorted(choices)}")
    return value


MAX_COORDINATES = 10_000
"""Most coordinates a task sized by an ``n_q`` argument accepts (its arrays are ``n_q`` long)."""


def as_int(value: Any, name: str, minimum: int = 0, maximum: int | None = None) -> int:
    """An integer in ``[minimum, maximum]``; integral floats (``3.0``) are accepted, bools are not.

    Raises:
        InvalidArgumentError: not an integer (NaN, 2.5, a string ...) or out of the range.
    """
    v = as_float(value, name)
    if v != int(v) or v < minimum or (maximum is not None and v > maximum):
        bound = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
        raise InvalidArgumentError(name, f"expected an integer {bound}, got {value!r}")
    return int(v)


def as_limits(value: Any, name: str, size: int) -> np.ndarray:
    """``size`` joint limits: real numbers, where +-infinity means unbounded on that side.

    Raises:
        InvalidArgumentError: not real numbers.
        ShapeError: not ``size`` values.
        NonFiniteError: NaN.
    """
    a = real_array(value, name)
    if a.shape != (size,):
        raise ShapeError(name, f"expected {size} values, got shape {a.shape}")
    if np.isnan(a).any():
        raise NonFiniteError(name, f"contains NaN: {a}")
    return a
