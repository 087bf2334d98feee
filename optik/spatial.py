"""Spatial math on numpy arrays and CasADi symbols alike.

Every function here accepts either numpy values (scalars or arrays; arrays broadcast, so a batch
of ``N`` angles gives ``N`` matrices of shape ``(N, 3, 3)``) or CasADi ``SX``/``MX``/``DM``
expressions (scalars; the result is a CasADi matrix). One implementation serves both so that the
symbolic models and the numerical references cannot drift apart.

Conventions:

* ``rot_x``, ``rot_y``, ``rot_z`` are the elementary rotations
  ``Rot(z, a) = [[c, -s, 0], [s, c, 0], [0, 0, 1]]`` (and their cyclic analogues).
* Homogeneous transforms are 4x4 ``[[R, p], [0, 0, 0, 1]]``.
* RPY is the seed's ``Rot(z, yaw) Rot(y, pitch) Rot(x, roll)`` (the seed names the angles
  ``phi_z, phi_y, phi_x``); it is also URDF's ``rpy``.
* ZYZ Euler angles are ``Rot(z, phi) Rot(y, theta) Rot(z, psi)`` with the seed's ranges
  ``-pi < phi <= pi``, ``0 <= theta <= pi``, ``-pi <= psi < pi``.
* Rotation vectors (``so3_log``/``so3_exp``) are axis times angle, angle in ``[0, pi]``.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

__all__ = [
    "angle_between",
    "hat",
    "inv_transform",
    "is_symbolic",
    "matmul",
    "planar_pose",
    "planar_pose_of",
    "pose_error",
    "rot_to_rpy",
    "rot_to_rpy_all",
    "rot_to_zyz",
    "rot_to_zyz_all",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotation_angle",
    "rotation_of",
    "rpy_to_rot",
    "so3_exp",
    "so3_log",
    "transform",
    "translation",
    "translation_of",
    "vee",
    "wrap_angle",
    "wrap_into",
    "wrap_rotation_vector",
    "wrap_to_limits",
    "zyz_to_rot",
]

_SYMBOLIC = (ca.SX, ca.MX)
_TWO_PI = 2.0 * math.pi


def is_symbolic(*values: Any) -> bool:
    """True if any value is a CasADi ``SX`` or ``MX`` expression."""
    return any(isinstance(v, _SYMBOLIC) for v in values)


class _Num:
    """numpy flavour of the few primitives the formulas need."""

    sin = staticmethod(np.sin)
    cos = staticmethod(np.cos)
    sqrt = staticmethod(np.sqrt)
    atan2 = staticmethod(np.arctan2)
    fabs = staticmethod(np.abs)

    @staticmethod
    def mat(rows: list[list[Any]]) -> np.ndarray:
        entries = [np.asarray(e, dtype=float) for r in rows for e in r]
        if all(e.ndim == 0 for e in entries):  # one matrix: no broadcasting and stacking (tens of us)
            return np.array(rows, dtype=float)
        flat = np.broadcast_arrays(*entries)
        n_cols = len(rows[0])
        stacked = [np.stack(flat[i * n_cols : (i + 1) * n_cols], axis=-1) for i in range(len(rows))]
        return np.stack(stacked, axis=-2)

    @staticmethod
    def where(cond: Any, a: Any, b: Any) -> Any:
        return np.where(cond, a, b)


class _Sym:
    """CasADi flavour of the same primitives."""

    sin = staticmethod(ca.sin)
    cos = staticmethod(ca.cos)
    sqrt = staticmethod(ca.sqrt)
    atan2 = staticmethod(ca.atan2)
    fabs = staticmethod(ca.fabs)

    @staticmethod
    def mat(rows: list[list[Any]]) -> Any:
        return ca.vertcat(*[ca.horzcat(*r) for r in rows])

    @staticmethod
    def where(cond: Any, a: Any, b: Any) -> Any:
        return ca.if_else(cond, a, b)


def _ops(*values: Any) -> type[_Num] | type[_Sym]:
    return _Sym if is_symbolic(*values) or any(isinstance(v, ca.DM) for v in values) else _Num


def _el(m: Any, i: int, j: int) -> Any:
    """Element (i, j) of a matrix or of every matrix in a batch."""
    return m[i, j] if not isinstance(m, np.ndarray) else m[..., i, j]


def matmul(a: Any, b: Any) -> Any:
    """Matrix product of numpy arrays (batched) or CasADi matrices."""
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
        return a @ b
    return ca.mtimes(a, b)


def _transpose(m: Any) -> Any:
    return np.swapaxes(m, -1, -2) if isinstance(m, np.ndarray) else m.T


def wrap_angle(a: Any) -> Any:
    """Wrap angles to ``(-pi, pi]``.

    Args:
        a: angle(s) in radians (numpy or CasADi).

    Returns:
        ``a - 2 pi k`` in ``(-pi, pi]`` (a float for a Python float, computed with plain float
        arithmetic: the same numbers as the array path, without its cost on hot scalar loops).
    """
    if type(a) is float:
        w = (a + math.pi) % _TWO_PI - math.pi
        return w + _TWO_PI if w <= -math.pi else w
    if is_symbolic(a):
        return ca.atan2(ca.sin(a), ca.cos(a))
    w = np.mod(np.asarray(a, dtype=float) + np.pi, 2.0 * np.pi) - np.pi
    return (
        np.where(w <= -np.pi, w + 2.0 * np.pi, w)
        if np.ndim(w)
        else (float(w + 2.0 * np.pi) if w <= -np.pi else float(w))
    )


def angle_distance(a: Any, b: Any) -> Any:
    """Max-norm distance of angle vectors compared modulo ``2 pi``: ``max_i |wrap(a_i - b_i)|``
    over the last axis (broadcast over the others; a float for two vectors).

    Args:
        a, b: angles (rad), numpy arrays of broadcastable shapes ``(..., n)``.
    """
    return np.max(np.abs(wrap_angle(np.subtract(a, b))), axis=-1)


def wrap_rotation_vector(w: np.ndarray) -> np.ndarray:
    """The rotation vector of the same rotation with angle in ``[0, pi]``.

    ``w = theta u`` with ``theta = |w| > pi`` is replaced by ``wrap_angle(theta) u``: the angle
    reduced modulo 2 pi in one step (a negative reduced angle is the rotation about ``-u``), so
    the cost does not grow with ``|w|``. A vector with ``|w| <= pi`` is returned unchanged.

    Args:
        w: finite rotation vector(s) (numpy, shape ``(..., 3)``).
    """
    w = np.asarray(w, dtype=float)
    # nested hypot: no overflow for huge finite entries (unlike the dot product)
    norm = np.hypot(np.hypot(w[..., 0], w[..., 1]), w[..., 2])
    over = norm > np.pi
    if not over.any():
        return w
    scale = np.where(over, wrap_angle(norm) / np.where(over, norm, 1.0), 1.0)
    return w * scale[..., None]


def wrap_to_limits(q: Any, lower: Any, upper: Any, angular: Any) -> np.ndarray:
    """The angles of ``q`` shifted by whole turns to their canonical value within the limits.

    For each angle coordinate ``i`` (``angular[i]``) the result is ``q_i + 2 pi k`` with the
    integer ``k`` chosen by these rules, in order:

    1. ``c = q_i`` when ``-pi < q_i <= pi``, else ``c = wrap_angle(q_i)``, the value in
       ``(-pi, pi]``; ``c`` when ``lower_i <= c <= upper_i``;
    2. else ``q_i`` itself when it lies within the limits (a value on a limit beyond pi, such as
       -3.9, is not shifted out and back: that could round it just outside);
    3. else, of ``c + 2 pi k``, the one nearest the interval ``[lower_i, upper_i]``, i.e. minimizing
       ``max(lower_i - x, x - upper_i, 0)``: one inside when any is (the smallest ``|k|`` of
       those), otherwise the nearest outside, which a clip then moves onto the near limit (a
       value a rounding past a limit beyond pi, 3.7525 + 6e-8 on the Panda's joint 6, stays
       there instead of wrapping to -2.53, past the other limit).

    Other coordinates are returned unchanged; a value within the limits never leaves them, and
    one in ``(-pi, pi]`` within them is returned exactly. NaN stays NaN.

    Args:
        q: coordinates, shape ``(..., n)`` (numpy, float).
        lower, upper: limits, shape ``(n,)`` (``-inf`` / ``inf`` allowed).
        angular: boolean mask ``(n,)`` of the angle coordinates.

    Returns:
        A new float array of the shape of ``q``.
    """
    out = np.array(q, dtype=float)
    mask = np.asarray(angular, dtype=bool)
    if not mask.any():
        return out
    a = out[..., mask]
    lo, hi = np.asarray(lower, dtype=float)[mask], np.asarray(upper, dtype=float)[mask]
    with np.errstate(invalid="ignore"):
        in_pi = (a > -np.pi) & (a <= np.pi)
        todo = ~(in_pi & (lo <= a) & (a <= hi))  # rule 1 with c = q_i: these stay as they are
        n_todo = int(np.count_nonzero(todo))
        if n_todo == 0:  # the common case: nothing to do
            return out
        lo, hi = np.broadcast_to(lo, a.shape)[todo], np.broadcast_to(hi, a.shape)[todo]
        v = a[todo]
        if n_todo <= _FEW_WRAPS:
            a[todo] = [
                wrap_into(x, lo_i, hi_i)
                for x, lo_i, hi_i in zip(v.tolist(), lo.tolist(), hi.tolist(), strict=True)
            ]
            out[..., mask] = a
            return out
        c = np.where(in_pi[todo], v, wrap_angle(v))
        # rule 3: whole turns from c to the near limit, and that count's neighbours (rounding);
        # of the four candidates the least gap wins, of gap 0 the least |k| (argmin: the first)
        k = np.floor((np.where(c < lo, lo, hi) - c) / _TWO_PI) + _NEIGHBOUR_TURNS
        x = c + _TWO_PI * k
        key = np.where(x < lo, lo - x, np.where(x > hi, x - hi, -1.0 / (1.0 + np.abs(k))))
        nearest = x[key.argmin(axis=0), np.arange(n_todo)]
        w = np.where((lo <= c) & (c <= hi), c, np.where((lo <= v) & (v <= hi), v, nearest))
    a[todo] = np.where(np.isfinite(v), w, np.nan)
    out[..., mask] = a
    return out


_FEW_WRAPS = 16
"""Up to this many angles to shift, `wrap_to_limits` runs `wrap_into` on each (about 2 us an
angle); beyond, its array arithmetic (about 30 us a call, then 0.1 us an angle) costs less."""

_NEIGHBOUR_TURNS = np.arange(-1.0, 3.0)[:, None]
"""The turns ``base - 1 .. base + 2`` that `wrap_to_limits` compares (column of offsets)."""


def wrap_into(a: float, lower: float, upper: float) -> float:
    """One angle by the rules of `wrap_to_limits` (plain floats: the same arithmetic as
    `wrap_angle` and as the compiled closed-form driver); NaN for a non-finite ``a``."""
    if not math.isfinite(a):
        return math.nan
    c = a if -math.pi < a <= math.pi else wrap_angle(a)
    if lower <= c <= upper:
        return c
    if lower <= a <= upper:
        return a
    # whole turns from c to the nearest point of the interval (c is outside it), and that
    # count's neighbours (rounding): the candidate of least gap wins, of gap 0 the least |k|
    base = math.floor(((lower if c < lower else upper) - c) / _TWO_PI)
    best, best_key = c, math.inf
    for k in (base - 1, base, base + 1, base + 2):
        x = c + _TWO_PI * k
        key = lower - x if x < lower else (x - upper if x > upper else -1.0 / (1.0 + abs(k)))
        if key < best_key:
            best, best_key = x, key
    return best


def rot_x(a: Any) -> Any:
    """``Rot(x, a) = [[1, 0, 0], [0, c, -s], [0, s, c]]``."""
    o = _ops(a)
    c, s = o.cos(a), o.sin(a)
    return o.mat([[1 + 0 * c, 0 * c, 0 * c], [0 * c, c, -s], [0 * c, s, c]])


def rot_y(a: Any) -> Any:
    """``Rot(y, a) = [[c, 0, s], [0, 1, 0], [-s, 0, c]]``."""
    o = _ops(a)
    c, s = o.cos(a), o.sin(a)
    return o.mat([[c, 0 * c, s], [0 * c, 1 + 0 * c, 0 * c], [-s, 0 * c, c]])


def rot_z(a: Any) -> Any:
    """``Rot(z, a) = [[c, -s, 0], [s, c, 0], [0, 0, 1]]``."""
    o = _ops(a)
    c, s = o.cos(a), o.sin(a)
    return o.mat([[c, -s, 0 * c], [s, c, 0 * c], [0 * c, 0 * c, 1 + 0 * c]])


def hat(w: Any) -> Any:
    """Skew-symmetric matrix ``[w]x`` with ``[w]x v = w x v``.

    Args:
        w: 3-vector (numpy, shape ``(..., 3)``, or CasADi 3x1).
    """
    if isinstance(w, (ca.SX, ca.MX, ca.DM)):
        return ca.vertcat(ca.horzcat(0, -w[2], w[1]), ca.horzcat(w[2], 0, -w[0]), ca.horzcat(-w[1], w[0], 0))
    w = np.asarray(w, dtype=float)
    z = np.zeros_like(w[..., 0])
    return _Num.mat([[z, -w[..., 2], w[..., 1]], [w[..., 2], z, -w[..., 0]], [-w[..., 1], w[..., 0], z]])


def vee(m: Any) -> Any:
    """Inverse of [`hat`][optik.spatial.hat] applied to the skew part: ``vee(M) = [M32, M13, M21]``.

    For a general matrix this returns the vee of ``M`` read off its lower/upper entries; callers
    pass skew matrices (or ``(M - M^T) / 2``).
    """
    if isinstance(m, np.ndarray):
        return np.stack([m[..., 2, 1], m[..., 0, 2], m[..., 1, 0]], axis=-1)
    return ca.vertcat(m[2, 1], m[0, 2], m[1, 0])


def translation(x: Any = 0.0, y: Any = 0.0, z: Any = 0.0) -> Any:
    """Homogeneous transform of a pure translation ``Trans(x, y, z)``."""
    o = _ops(x, y, z)
    if o is _Sym:
        return o.mat([[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]])
    x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
    zero, one = np.zeros_like(x), np.ones_like(x)
    return o.mat([[one, zero, zero, x], [zero, one, zero, y], [zero, zero, one, z], [zero, zero, zero, one]])


def transform(rotation: Any = None, position: Any = None) -> Any:
    """Homogeneous transform ``[[R, p], [0, 1]]``.

    Args:
        rotation: 3x3 rotation (identity when None). numpy batches ``(..., 3, 3)`` allowed.
        position: 3-vector (zero when None). numpy batches ``(..., 3)`` allowed.
    """
    symbolic = isinstance(rotation, (ca.SX, ca.MX, ca.DM)) or isinstance(position, (ca.SX, ca.MX, ca.DM))
    if symbolic:
        r = ca.DM.eye(3) if rotation is None else rotation
        p = ca.DM.zeros(3, 1) if position is None else ca.reshape(position, 3, 1)
        return ca.vertcat(ca.horzcat(r, p), ca.DM([[0, 0, 0, 1]]))
    r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    p = np.zeros(3) if position is None else np.asarray(position, dtype=float)
    batch = np.broadcast_shapes(r.shape[:-2], p.shape[:-1])
    t = np.zeros((*batch, 4, 4))
    t[..., :3, :3] = r
    t[..., :3, 3] = p
    t[..., 3, 3] = 1.0
    return t


def rotation_of(t: Any) -> Any:
    """Rotation block of a homogeneous transform."""
    return t[..., :3, :3] if isinstance(t, np.ndarray) else t[:3, :3]


def translation_of(t: Any) -> Any:
    """Translation column of a homogeneous transform."""
    return t[..., :3, 3] if isinstance(t, np.ndarray) else t[:3, 3]


def inv_transform(t: Any) -> Any:
    """Inverse of a homogeneous transform: ``[[R^T, -R^T p], [0, 1]]``."""
    r, p = rotation_of(t), translation_of(t)
    rt = _transpose(r)
    if isinstance(t, np.ndarray):
        return transform(rt, -np.einsum("...ij,...j->...i", rt, p))
    return transform(rt, -ca.mtimes(rt, p))


def rpy_to_rot(roll: Any, pitch: Any, yaw: Any) -> Any:
    """``Rot(z, yaw) Rot(y, pitch) Rot(x, roll)`` (seed 001: ``phi_x, phi_y, phi_z``).

    With ``c_a, s_a`` the cosine and sine of each angle, the product written out is

    ```text
    [[c_y c_p, c_y s_p s_r - s_y c_r, c_y s_p c_r + s_y s_r],
     [s_y c_p, s_y s_p s_r + c_y c_r, s_y s_p c_r - c_y s_r],
     [-s_p,    c_p s_r,               c_p c_r]]
    ```

    which three floats (Python or numpy scalars: a URDF origin) get directly, in plain float
    arithmetic (the array path's numbers to rounding, without its three matrix products).
    """
    if isinstance(roll, float) and isinstance(pitch, float) and isinstance(yaw, float):
        cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
        return np.array(
            [
                [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                [-sp, cp * sr, cp * cr],
            ]
        )
    return matmul(matmul(rot_z(yaw), rot_y(pitch)), rot_x(roll))


def rot_to_rpy(r: Any) -> Any:
    """RPY angles ``(roll, pitch, yaw)`` of a rotation, by the seed's atan2 formulas.

    With ``R = [n o a]``:

    * ``yaw = atan2(n_y, n_x)``,
    * ``pitch = atan2(-n_z, n_x cos(yaw) + n_y sin(yaw))`` in ``[-pi/2, pi/2]``,
    * ``roll = atan2(a_x sin(yaw) - a_y cos(yaw), o_y cos(yaw) - o_x sin(yaw))``.

    At gimbal lock (``n_x = n_y = 0``, pitch = +-pi/2) only ``roll -+ yaw`` is defined; the
    answer then takes ``yaw = 0`` (``atan2(0, 0) = 0``) and puts the whole rotation about the
    vertical into ``roll``.

    Returns:
        numpy: array ``(..., 3)``; CasADi: 3x1 expression.
    """
    o = _ops(r)
    nx, ny, nz = _el(r, 0, 0), _el(r, 1, 0), _el(r, 2, 0)
    ox, oy = _el(r, 0, 1), _el(r, 1, 1)
    ax, ay = _el(r, 0, 2), _el(r, 1, 2)
    if o is _Num:
        # exact zero at gimbal lock so that atan2(0, 0) = 0 picks the documented branch
        tiny = np.hypot(nx, ny) < 1e-12
        nx, ny = np.where(tiny, 0.0, nx), np.where(tiny, 0.0, ny)
    yaw = o.atan2(ny, nx)
    cz, sz = o.cos(yaw), o.sin(yaw)
    pitch = o.atan2(-nz, nx * cz + ny * sz)
    roll = o.atan2(ax * sz - ay * cz, oy * cz - ox * sz)
    if o is _Num:
        return np.stack(np.broadcast_arrays(roll, pitch, yaw), axis=-1)
    return ca.vertcat(roll, pitch, yaw)


def rot_to_rpy_all(r: np.ndarray) -> list[np.ndarray]:
    """Both RPY triples of a rotation (numpy, one matrix).

    Besides ``(roll, pitch, yaw)`` from [`rot_to_rpy`][optik.spatial.rot_to_rpy], the triple
    ``(roll + pi, pi - pitch, yaw + pi)`` (wrapped) gives the same matrix. At gimbal lock the
    two coincide up to the undetermined ``roll -+ yaw`` split and only one is returned.
    """
    first = np.asarray(rot_to_rpy(np.asarray(r, dtype=float)))
    roll, pitch, yaw = first
    if abs(abs(pitch) - np.pi / 2) < 1e-9:
        return [first]
    second = np.array([wrap_angle(roll + np.pi), wrap_angle(np.pi - pitch), wrap_angle(yaw + np.pi)])
    return [first, second]


def zyz_to_rot(phi: Any, theta: Any, psi: Any) -> Any:
    """``Rot(z, phi) Rot(y, theta) Rot(z, psi)``."""
    return matmul(matmul(rot_z(phi), rot_y(theta)), rot_z(psi))


def rot_to_zyz(r: Any) -> Any:
    """ZYZ Euler angles ``(phi, theta, psi)`` in the seed's ranges.

    ``theta = atan2(sqrt(r13^2 + r23^2), r33)`` in ``[0, pi]``, ``phi = atan2(r23, r13)``,
    ``psi = atan2(r32, -r31)``. At gimbal lock (``theta`` = 0 or pi) only ``phi +- psi`` is
    defined; the answer takes ``phi = 0`` and ``psi = atan2(r21, r11)`` (theta = 0) or
    ``psi = atan2(r21, -r11)`` (theta = pi), with ``psi`` in the seed's half-open range
    ``-pi <= psi < pi``.

    Returns:
        numpy: array ``(..., 3)``; CasADi: 3x1 expression.
    """
    o = _ops(r)
    r11, r21, r31 = _el(r, 0, 0), _el(r, 1, 0), _el(r, 2, 0)
    r13, r23, r33 = _el(r, 0, 2), _el(r, 1, 2), _el(r, 2, 2)
    r32 = _el(r, 2, 1)
    st = o.sqrt(r13 * r13 + r23 * r23)
    theta = o.atan2(st, r33)
    lock = st < 1e-12
    phi = o.where(lock, 0.0 * st, o.atan2(r23, r13))
    # at theta = 0: R = Rz(phi + psi); at theta = pi: R = Rz(phi) Ry(pi) Rz(psi) -> r21 = sin(psi - phi)
    psi_lock = o.atan2(r21, o.where(r33 > 0, r11, -r11))
    psi = o.where(lock, psi_lock, o.atan2(r32, -r31))
    if o is _Num:
        psi = np.where(psi >= np.pi, psi - 2.0 * np.pi, psi)
        phi = np.where(phi <= -np.pi, phi + 2.0 * np.pi, phi)
        return np.stack(np.broadcast_arrays(phi, theta, psi), axis=-1)
    psi = ca.if_else(psi >= np.pi, psi - 2.0 * np.pi, psi)
    phi = ca.if_else(phi <= -np.pi, phi + 2.0 * np.pi, phi)
    return ca.vertcat(phi, theta, psi)


def rot_to_zyz_all(r: np.ndarray) -> list[np.ndarray]:
    """Both ZYZ triples of a rotation (numpy, one matrix).

    The first lies in the seed's ranges; the second is ``(phi + pi, -theta, psi + pi)`` (angles
    wrapped), which has ``theta < 0``. At gimbal lock only the first is returned.
    """
    first = np.asarray(rot_to_zyz(np.asarray(r, dtype=float)))
    phi, theta, psi = first
    if theta < 1e-9 or theta > np.pi - 1e-9:
        return [first]
    return [first, np.array([wrap_angle(phi + np.pi), -theta, wrap_angle(psi + np.pi)])]


def so3_exp(w: Any) -> Any:
    """Rodrigues' formula ``exp([w]x) = I + sin(t)/t [w]x + (1 - cos(t))/t^2 [w]x^2``, ``t = |w|``.

    Near ``t = 0`` the Taylor expansions of the two coefficients are used.
    """
    if isinstance(w, (ca.SX, ca.MX, ca.DM)):
        t2 = ca.dot(w, w)
        t = ca.sqrt(t2 + 1e-300)
        small = t2 < 1e-8
        a = ca.if_else(small, 1 - t2 / 6, ca.sin(t) / t)
        b = ca.if_else(small, 0.5 - t2 / 24, (1 - ca.cos(t)) / (t2 + 1e-300))
        k = hat(w)
        return ca.DM.eye(3) + a * k + b * ca.mtimes(k, k)
    w = np.asarray(w, dtype=float)
    t2 = np.sum(w * w, axis=-1)
    t = np.sqrt(t2)
    small = t2 < 1e-8
    safe_t = np.where(small, 1.0, t)
    a = np.where(small, 1 - t2 / 6, np.sin(safe_t) / safe_t)
    b = np.where(small, 0.5 - t2 / 24, (1 - np.cos(safe_t)) / (safe_t * safe_t))
    k = hat(w)
    return np.eye(3) + a[..., None, None] * k + b[..., None, None] * (k @ k)


def rotation_angle(r: Any) -> Any:
    """Geodesic angle of a rotation in ``[0, pi]``: ``atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2)``.

    The atan2 form is accurate at both ends (unlike ``acos`` of the trace).
    """
    o = _ops(r)
    tr = _el(r, 0, 0) + _el(r, 1, 1) + _el(r, 2, 2)
    sx = _el(r, 2, 1) - _el(r, 1, 2)
    sy = _el(r, 0, 2) - _el(r, 2, 0)
    sz = _el(r, 1, 0) - _el(r, 0, 1)
    return o.atan2(0.5 * o.sqrt(sx * sx + sy * sy + sz * sz), 0.5 * (tr - 1.0))


def angle_between(r_a: Any, r_b: Any) -> Any:
    """Geodesic distance ``angle(R_a^T R_b)`` between two rotations, in ``[0, pi]``."""
    return rotation_angle(matmul(_transpose(r_a), r_b))


def so3_log(r: Any) -> Any:
    """Rotation vector ``w`` (axis times angle, angle in ``[0, pi]``) with ``exp([w]x) = R``.

    Uses the angle from [`rotation_angle`][optik.spatial.rotation_angle] and the axis from the skew part when
    the angle is below ``pi - 1e-3``; closer to a half-turn the axis is read from the symmetric part ``(R +
    R^T) / 2 - cos(t) I = (1 - cos(t)) a a^T`` (largest diagonal column), whose sign is fixed by the skew
    part.
    """
    theta = rotation_angle(r)
    if isinstance(r, np.ndarray):
        r = np.asarray(r, dtype=float)
        s = vee(r - np.swapaxes(r, -1, -2)) / 2.0
        sin_t = np.sin(theta)
        small = theta < 1e-6
        coef = np.where(small, 0.5 * (1 + theta**2 / 6), theta / (2 * np.where(small, 1, sin_t)))
        w = 2 * coef[..., None] * s
        near_pi = theta > np.pi - 1e-3
        if np.any(near_pi):
            # symmetric part: (R + R^T) / 2 - cos(t) I = (1 - cos(t)) a a^T (no skew leak-through)
            b = (r + np.swapaxes(r, -1, -2)) / 2.0 - np.cos(theta)[..., None, None] * np.eye(3)
            diag = np.stack([b[..., 0, 0], b[..., 1, 1], b[..., 2, 2]], axis=-1)
            k = np.argmax(diag, axis=-1)
            idx = np.broadcast_to(k[..., None, None], (*b.shape[:-1], 1))
            col = np.take_along_axis(b, idx, axis=-1)[..., 0]
            axis = col / np.linalg.norm(col, axis=-1, keepdims=True)
            sign = np.where(np.sum(axis * s, axis=-1) < 0, -1.0, 1.0)
            w = np.where(near_pi[..., None], (sign * theta)[..., None] * axis, w)
        return w
    s = vee(r - r.T) / 2
    sin_t = ca.sin(theta)
    coef = ca.if_else(theta < 1e-6, 0.5 * (1 + theta**2 / 6), theta / (2 * sin_t + 1e-300))
    w_regular = 2 * coef * s
    b = ((r + r.T) / 2 - ca.cos(theta) * ca.DM.eye(3)) / (1 - ca.cos(theta) + 1e-300)  # = a a^T
    cols = [b[:, i] / ca.sqrt(b[i, i] + 1e-300) for i in range(3)]
    col = ca.if_else(
        b[0, 0] >= ca.fmax(b[1, 1], b[2, 2]), cols[0], ca.if_else(b[1, 1] >= b[2, 2], cols[1], cols[2])
    )
    sign = ca.if_else(ca.dot(col, s) < 0, -1, 1)
    w_pi = sign * theta * col
    return ca.if_else(theta > np.pi - 1e-3, w_pi, w_regular)


def pose_error(t: Any, t_target: Any) -> Any:
    """Pose error ``[p - p*; log(R R*^T)]`` of ``t`` against ``t_target``, in the base frame.

    The rotational part is the rotation vector that takes the target orientation to the current
    one, expressed in the base frame; its norm is the geodesic angle. This is the error whose
    time derivative is the base-frame geometric twist ``J(q) qdot``.

    Returns:
        numpy ``(..., 6)`` or a CasADi 6x1 expression.
    """
    r, rt = rotation_of(t), rotation_of(t_target)
    dp = translation_of(t) - translation_of(t_target)
    w = so3_log(matmul(r, _transpose(rt)))
    if isinstance(dp, np.ndarray) and isinstance(w, np.ndarray):
        return np.concatenate([dp, w], axis=-1)
    return ca.vertcat(ca.reshape(dp, 3, 1), w)


def planar_pose(x: Any, y: Any, phi: Any) -> Any:
    """Homogeneous transform of a planar pose: ``Trans(x, y, 0) Rot(z, phi)``."""
    o = _ops(x, y, phi)
    if o is _Sym:
        return transform(rot_z(phi), ca.vertcat(x, y, 0))
    return transform(
        rot_z(phi), np.stack(np.broadcast_arrays(x, y, np.zeros_like(np.asarray(phi, float))), -1)
    )


def planar_pose_of(t: Any) -> Any:
    """``(x, y, phi)`` of a transform of the x-y plane; ``phi = atan2(R21, R11)``."""
    o = _ops(t)
    phi = o.atan2(_el(t, 1, 0), _el(t, 0, 0))
    if o is _Num:
        return np.stack(np.broadcast_arrays(_el(t, 0, 3), _el(t, 1, 3), phi), axis=-1)
    return ca.vertcat(t[0, 3], t[1, 3], phi)
