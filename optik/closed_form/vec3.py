"""3-vectors as tuples of components, for kernels written once and run on two backends.

A vector is a tuple ``(x, y, z)`` whose components are numpy arrays (one entry per target: the
vectorized kernels) or CasADi ``SX`` scalars (the symbolic kernel that is compiled to C for one
target at a time), or plain floats (constants of the model). Matrices are tuples of three rows.
The elementary functions differ between the backends; an [`Ops`][optik.closed_form.vec3.Ops]
holds them (``NUMPY``, ``CASADI``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

Vec = tuple[Any, Any, Any]
Mat = tuple[Vec, Vec, Vec]


@dataclass(frozen=True)
class Ops:
    """Elementary functions of a backend (``where(cond, a, b)`` selects elementwise)."""

    atan2: Callable[[Any, Any], Any]
    acos: Callable[[Any], Any]
    sqrt: Callable[[Any], Any]
    cos: Callable[[Any], Any]
    sin: Callable[[Any], Any]
    fmin: Callable[[Any, Any], Any]
    fmax: Callable[[Any, Any], Any]
    where: Callable[[Any, Any, Any], Any]
    known: Callable[[Any, Any, Any], Any] = lambda angle, c, s: angle
    """``known(angle, c, s)``: ``angle``, whose cosine and sine are ``c`` and ``s`` (a backend
    that remembers them, `remembering`, returns them from ``cos`` and ``sin``)."""
    remembers: bool = False
    """True for `remembering` backends (the kernels then form the cosines and sines of the
    angles they make, for `known`)."""


NUMPY = Ops(np.arctan2, np.arccos, np.sqrt, np.cos, np.sin, np.minimum, np.maximum, np.where)
CASADI = Ops(ca.atan2, ca.acos, ca.sqrt, ca.cos, ca.sin, ca.fmin, ca.fmax, ca.if_else)


def remembering(base: Ops) -> Ops:
    """``base`` that remembers the cosine and sine of the angles it makes, for a kernel that
    rotates by them next: ``atan2(y, x)`` records ``(x / r, y / r)``, ``r = sqrt(x^2 + y^2)``
    (``(1, 0)`` for ``r = 0``, as ``atan2(0, 0) = 0``), ``known`` records given ones, and ``cos``
    and ``sin`` of a recorded angle return them instead of evaluating the trigonometric functions
    (the compiled kernels spend most of their time in those). Angles are recorded by identity
    (each with a reference to itself, so no identity is reused while the record lives); use one
    per kernel construction."""
    memo: dict[int, tuple[Any, Any, Any]] = {}

    def known(angle: Any, c: Any, s: Any) -> Any:
        memo[id(angle)] = (angle, c, s)
        return angle

    def atan2(y: Any, x: Any) -> Any:
        r = base.sqrt(x * x + y * y)
        some = r > 0.0
        inv = 1.0 / base.where(some, r, 1.0)
        return known(base.atan2(y, x), base.where(some, x * inv, 1.0), y * inv)

    def cos(angle: Any) -> Any:
        hit = memo.get(id(angle))
        return hit[1] if hit is not None and hit[0] is angle else base.cos(angle)

    def sin(angle: Any) -> Any:
        hit = memo.get(id(angle))
        return hit[2] if hit is not None and hit[0] is angle else base.sin(angle)

    return Ops(atan2, base.acos, base.sqrt, cos, sin, base.fmin, base.fmax, base.where, known, True)


def neg(angle: Any, ops: Ops) -> Any:
    """``-angle``, its cosine and sine known to ``ops`` (``cos``, ``-sin`` of ``angle``)."""
    return ops.known(-angle, ops.cos(angle), -ops.sin(angle)) if ops.remembers else -angle


def half_turn(angle: Any, ops: Ops) -> Any:
    """``angle + pi``, its cosine and sine known to ``ops`` (``-cos``, ``-sin`` of ``angle``)."""
    return ops.known(angle + np.pi, -ops.cos(angle), -ops.sin(angle)) if ops.remembers else angle + np.pi


def vec(a: Any) -> Vec:
    """A constant 3-vector (numpy ``(3,)``) as a tuple of floats."""
    return (float(a[0]), float(a[1]), float(a[2]))


def add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(s: Any, a: Vec) -> Vec:
    return (s * a[0], s * a[1], s * a[2])


def dot(a: Vec, b: Vec) -> Any:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a: Vec, ops: Ops) -> Any:
    return ops.sqrt(dot(a, a))


def rot(k: Vec, c: Any, s: Any, p: Vec) -> Vec:
    """``rot(k, t) p`` for ``c = cos t``, ``s = sin t``:
    ``p c + (k x p) s + k (k . p)(1 - c)``."""
    kxp = cross(k, p)
    kp = dot(k, p) * (1.0 - c)
    return (
        p[0] * c + kxp[0] * s + k[0] * kp,
        p[1] * c + kxp[1] * s + k[1] * kp,
        p[2] * c + kxp[2] * s + k[2] * kp,
    )


def rot_mat(k: Vec, c: Any, s: Any) -> Mat:
    """The matrix of ``rot(k, t)`` (rows)."""
    v = 1.0 - c
    x, y, z = k
    return (
        (c + x * x * v, x * y * v - z * s, x * z * v + y * s),
        (x * y * v + z * s, c + y * y * v, y * z * v - x * s),
        (x * z * v - y * s, y * z * v + x * s, c + z * z * v),
    )


def mat_vec(m: Mat, a: Vec) -> Vec:
    return (dot(m[0], a), dot(m[1], a), dot(m[2], a))


def mat_t_vec(m: Mat, a: Vec) -> Vec:
    """``m^T a``."""
    return (
        m[0][0] * a[0] + m[1][0] * a[1] + m[2][0] * a[2],
        m[0][1] * a[0] + m[1][1] * a[1] + m[2][1] * a[2],
        m[0][2] * a[0] + m[1][2] * a[1] + m[2][2] * a[2],
    )


def mat_mul(a: Mat, b: Mat) -> Mat:
    cols = tuple(zip(*b, strict=True))
    return tuple(tuple(dot(row, col) for col in cols) for row in a)  # type: ignore[return-value]


def transpose(a: Mat) -> Mat:
    return tuple(zip(*a, strict=True))  # type: ignore[return-value]
