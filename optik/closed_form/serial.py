"""Closed-form inverse kinematics of the serial catalog arms, vectorized over many targets.

Every function takes arrays of targets (anything that broadcasts; ``N`` targets after flattening)
and returns ``(q, ok)``: ``q`` of shape ``(N, B, n)`` with one row per branch and ``ok`` of shape
``(N, B)``, True where that branch reaches the target. Where ``ok`` is False the row is all
zeros (finite, never NaN). Angles are wrapped to ``[-pi, pi]``.

Mathematics (seed ``000``/``001`` notation):

* **Two links** ``l1, l2`` reaching ``(x, y)`` (planar 2R, the first two joints of the 3R arm,
  the shoulder-elbow pair of the 6R arm). Squaring and adding ``x = l1 c1 + l2 c12`` and
  ``y = l1 s1 + l2 s12`` gives ``P cos(theta1) + Q sin(theta1) + R = 0`` with ``P = -2 l1 x``,
  ``Q = -2 l1 y``, ``R = x^2 + y^2 + l1^2 - l2^2``, or equivalently the law of cosines
  ``c2 = (x^2 + y^2 - l1^2 - l2^2) / (2 l1 l2)``. With ``s2 = sigma sqrt(1 - c2^2)``:
  ``theta2 = atan2(s2, c2)`` and ``theta1 = atan2(y, x) - atan2(l2 s2, l1 + l2 c2)``.
  Branch 0 is ``sigma = +1`` (``theta2`` in ``[0, pi]``), branch 1 is ``sigma = -1``. For
  precision at both edges of the annulus, ``1 + c2 = (r^2 - (l1 - l2)^2) / (2 l1 l2)`` and
  ``1 - c2 = ((l1 + l2)^2 - r^2) / (2 l1 l2)`` are formed directly and
  ``s2 = sqrt((1 - c2)(1 + c2))``. The target is reachable when both are ``>= 0``; one that is
  negative by at most [`COS_TOL`][optik.closed_form.serial.COS_TOL] (rounding at the workspace boundary) is
  clipped to 0, anything beyond is unreachable.
* **Planar 3R** (seed 000): the wrist point ``x' = x - l3 cos(phi)``, ``y' = y - l3 sin(phi)``
  is a two-link problem, then ``theta3 = phi - theta1 - theta2`` (the seed prints
  ``phi - theta1 + theta2``, a typo that fails the FK round trip).
* **R-P** (seed 001, theta-r): ``(theta, r) = (atan2(y, x), sqrt(x^2 + y^2))`` and
  ``(theta + pi, -r)``; **P-P**: ``(q1, q2) = (x, y)``.
* **Seed 6R arm**: see [`ik_seed_6r`][optik.closed_form.serial.ik_seed_6r]. It is the cross-check of
  the arm's closed form derived from its joint axes
  ([`optik.closed_form.derived`][optik.closed_form.derived]: axes 2-4 parallel, 5 and 6
  intersecting), which answers for the arm when it is exact; this kernel answers (one target at a
  time) for the proportions where it is not (a link below the detection tolerance).

The kernels run over blocks of [`BLOCK`][optik.closed_form.serial.BLOCK] targets so that temporaries stay in
cache (``optik benchmark closed_form``: the 3R arm solves several million targets per second on one core).
[`optik.closed_form.ik`][optik.closed_form.ik] solves one target at a time; for the planar arms it calls
scalar twins of the kernels (``_*_one``, plain ``math`` on floats, the same operations in the same order),
since a numpy call on a one-element array costs about as much as the whole scalar solve.

Exactly degenerate targets have a defined representative: a two-link target at the origin with
``l1 = l2`` gives ``theta1 = 0``, ``theta2 = pi`` (``atan2(0, 0) = 0``); the R-P target at the
origin gives ``theta = 0`` (and ``pi``) with ``r = 0``; the 6R singularities are described in
[`ik_seed_6r`][optik.closed_form.serial.ik_seed_6r].
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np

from optik.catalog.serial import _positive
from optik.closed_form.registry import angle_mask, register
from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError
from optik.mechanism import Mechanism
from optik.spatial import wrap_angle

__all__ = [
    "COS_TOL",
    "SINGULAR_TOL",
    "ik_planar_2r",
    "ik_planar_3r",
    "ik_pp",
    "ik_rp",
    "ik_seed_6r",
]

COS_TOL = 1e-12
"""How far a law-of-cosines argument may leave ``[-1, 1]`` and still count as reachable."""

SINGULAR_TOL = 1e-12
"""Below this (relative to the arm's size for distances) a 6R singularity is treated as exact."""

_EPS = float(np.finfo(float).eps)
_TWO_PI = 2.0 * np.pi
_INV_TWO_PI = 1.0 / _TWO_PI
_SAME_BRANCH = 1e-4
"""The same-branch distance (the solvers layer, above this one, has it as ``BRANCH_TOL``)."""

BLOCK = 2048
"""Targets per block in the vectorized kernels."""


def _flat(**named: Any) -> list[np.ndarray]:
    """Finite float64 arrays, broadcast together and flattened to 1-D (a scalar gives N = 1)."""
    arrays = []
    for name, value in named.items():
        try:
            a = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InvalidArgumentError(name, f"expected numbers, got {value!r}") from exc
        if not np.all(np.isfinite(a)):
            raise NonFiniteError(name, "contains NaN or infinity")
        arrays.append(a)
    try:
        shape = np.broadcast_shapes(*(a.shape for a in arrays))
    except ValueError as exc:
        shapes = {k: np.shape(v) for k, v in named.items()}
        raise ShapeError("/".join(named), f"shapes do not broadcast: {shapes}") from exc
    return [np.broadcast_to(a, shape).reshape(-1) for a in arrays]


def _wrap(a: np.ndarray) -> None:
    """Wrap angles to ``[-pi, pi]`` in place: ``a -= 2 pi round(a / (2 pi))``."""
    k = a * _INV_TWO_PI
    np.round(k, out=k)
    k *= _TWO_PI
    a -= k


def _cos_slack(l1: float, l2: float, extent: Any) -> Any:
    """How far ``1 +- c2`` may fall below 0 for a reachable target: `COS_TOL` plus the
    rounding of ``(x, y)``. Coordinates formed from terms of magnitude ``extent`` (e.g.
    ``|x| + |y| + l3`` for the 3R wrist point) are off by ``delta = 4 eps extent``, which moves
    ``1 +- c2 = +-(r^2 - (l1 -+ l2)^2) / (2 l1 l2)`` by up to ``delta (l1 + l2 + delta) / (l1 l2)``:
    negligible for arms of similar links, decisive when ``l1 l2`` is tiny against ``extent^2``
    (then a point within rounding of the annulus is reached by the nearest boundary solution)."""
    delta = 4.0 * _EPS * extent
    return COS_TOL + delta * (l1 + l2 + delta) / (l1 * l2)


def _two_link(
    l1: float, l2: float, x: np.ndarray, y: np.ndarray, out: np.ndarray, extent: Any = None
) -> np.ndarray:
    """Both two-link solutions into ``out[..., b, 0]`` (theta1) and ``out[..., b, 1]`` (theta2).

    Args:
        l1, l2: link lengths.
        x, y: target of the second link's tip, any shape ``S``.
        out: array of shape ``S + (2, k)``, ``k >= 2``; branch ``b`` is ``sigma = 1 - 2 b``.
        extent: magnitude of the terms ``x`` and ``y`` were computed from (default
            ``|x| + |y|``), for the rounding slack of `_cos_slack`.

    Returns:
        Reachability mask of shape ``S`` (``1 + c2`` and ``1 - c2`` both ``>= -slack``).
    """
    r2 = x * x
    r2 += y * y
    # one bound for the block when it is within 2 COS_TOL (ordinary arms), else per target
    top = (math.sqrt(2.0 * float(r2.max())) if extent is None else float(np.max(extent))) if r2.size else 0.0
    tol = _cos_slack(l1, l2, top)
    if not tol <= 2.0 * COS_TOL:
        tol = _cos_slack(l1, l2, np.abs(x) + np.abs(y) if extent is None else extent)
    tol = -tol
    inv = 1.0 / (2.0 * l1 * l2)
    # 1 + c2 and 1 - c2 straight from the distances, so that s2 keeps full precision at both
    # boundaries of the annulus (also for l1 = l2 near the base, where c2 -> -1)
    one_plus = r2 - (l1 - l2) ** 2
    one_plus *= inv
    one_minus = np.subtract((l1 + l2) ** 2, r2)
    one_minus *= inv
    ok = (one_plus >= tol) & (one_minus >= tol) & (r2 < np.inf)  # r2 = inf: overflow, far away
    np.maximum(one_plus, 0.0, out=one_plus)
    np.maximum(one_minus, 0.0, out=one_minus)
    # (1 + c2) + (1 - c2) = 2 exactly, but not in rounding: rescale so that (c2, s2) is a unit
    # vector, or theta1 (from both) misses the target by l2 times the mismatch (l1 << l2); both
    # 0 (an annulus thinner than the rounding of r^2, l1 / l2 < 1e-16): the stretched arm c2 = 1
    scale = one_plus + one_minus
    flat = scale <= 0.0
    np.copyto(one_plus, 2.0, where=flat)
    np.copyto(scale, 2.0, where=flat)
    np.divide(2.0, scale, out=scale)
    one_plus *= scale
    one_minus *= scale
    s2 = one_minus * one_plus
    np.sqrt(s2, out=s2)
    c2 = np.subtract(one_plus, one_minus, out=one_minus)
    c2 *= 0.5
    np.arctan2(s2, c2, out=out[..., 0, 1])
    np.negative(out[..., 0, 1], out=out[..., 1, 1])
    beta = np.arctan2(y, x)
    # atan2(l2 s2, l1 + l2 c2) with l1 + l2 c2 = (l1 - l2) + l2 (1 + c2)
    s2 *= l2
    one_plus *= l2
    one_plus += l1 - l2
    delta = np.arctan2(s2, one_plus, out=s2)
    np.subtract(beta, delta, out=out[..., 0, 0])
    np.add(beta, delta, out=out[..., 1, 0])
    _wrap(out[..., 0])
    return ok


def _wrap_one(a: float) -> float:
    """`_wrap` of one float."""
    return a - round(a * _INV_TWO_PI) * _TWO_PI


def _two_link_one(
    l1: float, l2: float, x: float, y: float, extent: float | None = None
) -> tuple[bool, float, float, float]:
    """`_two_link` for one target: ``(ok, theta1 branch 0, theta1 branch 1, theta2 branch 0)``
    (branch 1 has ``-theta2``)."""
    r2 = x * x + y * y
    inv = 1.0 / (2.0 * l1 * l2)
    one_plus = (r2 - (l1 - l2) ** 2) * inv
    one_minus = ((l1 + l2) ** 2 - r2) * inv
    tol = -_cos_slack(l1, l2, abs(x) + abs(y) if extent is None else extent)
    if not (one_plus >= tol and one_minus >= tol and r2 < math.inf):
        return False, 0.0, 0.0, 0.0  # unreachable (also a target so far away that r2 overflows)
    one_plus = max(one_plus, 0.0)
    one_minus = max(one_minus, 0.0)
    total = one_plus + one_minus  # 2 up to rounding: rescale to a unit (c2, s2) (see _two_link)
    if total > 0.0:
        one_plus *= 2.0 / total
        one_minus *= 2.0 / total
    else:
        one_plus = 2.0
    s2 = math.sqrt(one_minus * one_plus)
    c2 = (one_plus - one_minus) * 0.5
    th2 = math.atan2(s2, c2)
    beta = math.atan2(y, x)
    delta = math.atan2(s2 * l2, one_plus * l2 + (l1 - l2))
    return True, _wrap_one(beta - delta), _wrap_one(beta + delta), th2


def _planar_2r_one(l1: float, l2: float, x: float, y: float) -> list[list[float]]:
    """The reachable branches of [`ik_planar_2r`][optik.closed_form.serial.ik_planar_2r] for one target, in
    branch order."""
    ok, t1a, t1b, t2 = _two_link_one(l1, l2, x, y)
    return [[t1a, t2], [t1b, -t2]] if ok else []


def _planar_3r_one(l1: float, l2: float, l3: float, x: float, y: float, phi: float) -> list[list[float]]:
    """The reachable branches of [`ik_planar_3r`][optik.closed_form.serial.ik_planar_3r] for one target, in
    branch order."""
    extent = abs(x) + abs(y) + l3
    ok, t1a, t1b, t2 = _two_link_one(l1, l2, math.cos(phi) * -l3 + x, math.sin(phi) * -l3 + y, extent)
    if not ok:
        return []
    return [[t1a, t2, _wrap_one(phi - t1a - t2)], [t1b, -t2, _wrap_one(phi - t1b + t2)]]


def _blocked(
    kernel: Callable[..., None], arrays: Sequence[np.ndarray], n_branches: int, n_q: int
) -> tuple[np.ndarray, np.ndarray]:
    """Run ``kernel(*blocks, q_block, ok_block)`` over blocks of [`BLOCK`][optik.closed_form.serial.BLOCK]
    targets.

    Working block by block keeps the kernels' temporaries in cache (several times faster than
    whole-array passes for a million targets) and bounds their memory. Rows of unreachable
    branches are zeroed at the end (``q`` is finite by construction).
    """
    n = arrays[0].shape[0]
    q = np.empty((n, n_branches, n_q))
    ok = np.empty((n, n_branches), dtype=bool)
    for start in range(0, n, BLOCK):
        sl = slice(start, start + BLOCK)
        kernel(*(a[sl] for a in arrays), q[sl], ok[sl])
    bad = ~ok
    if bad.any():
        q[bad] = 0.0
    return q, ok


def _planar_2r_block(
    l1: float, l2: float, x: np.ndarray, y: np.ndarray, q: np.ndarray, ok: np.ndarray
) -> None:
    ok[:] = _two_link(l1, l2, x, y, q)[:, None]


def _planar_3r_block(
    l1: float,
    l2: float,
    l3: float,
    x: np.ndarray,
    y: np.ndarray,
    phi: np.ndarray,
    q: np.ndarray,
    ok: np.ndarray,
) -> None:
    xw = np.cos(phi)
    xw *= -l3
    xw += x
    yw = np.sin(phi)
    yw *= -l3
    yw += y
    extent = np.abs(x) + np.abs(y)
    extent += l3
    ok[:] = _two_link(l1, l2, xw, yw, q, extent)[:, None]
    t3 = q[..., 2]
    np.subtract(phi[:, None], q[..., 0], out=t3)
    t3 -= q[..., 1]
    _wrap(t3)


def ik_planar_2r(lengths: Any, x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
    """All IK branches of the planar 2R arm ``x = l1 c1 + l2 c12``, ``y = l1 s1 + l2 s12``.

    Args:
        lengths: ``(l1, l2)``, both > 0.
        x, y: target coordinates (arrays broadcast; ``N`` targets after flattening).

    Returns:
        ``q`` of shape ``(N, 2, 2)``: branch 0 has ``theta2 >= 0`` (seed's ``sigma = +1``),
        branch 1 ``theta2 <= 0``; ``ok`` of shape ``(N, 2)``, False where
        ``sqrt(x^2 + y^2)`` is outside ``[|l1 - l2|, l1 + l2]``.

    Raises:
        InvalidArgumentError: a length is not > 0 (argument ``lengths``).
        NonFiniteError: NaN or infinity in ``x`` or ``y``.
        ShapeError: ``x`` and ``y`` do not broadcast.
    """
    l1, l2 = _positive(lengths, "lengths", 2)
    return _blocked(partial(_planar_2r_block, l1, l2), _flat(x=x, y=y), 2, 2)


def ik_planar_3r(lengths: Any, x: Any, y: Any, phi: Any) -> tuple[np.ndarray, np.ndarray]:
    """All IK branches of the planar 3R arm (seed 000, equations (9)-(11), typo corrected).

    ``x' = x - l3 cos(phi)``, ``y' = y - l3 sin(phi)`` is a two-link target for ``l1, l2``;
    ``theta3 = phi - theta1 - theta2``.

    Args:
        lengths: ``(l1, l2, l3)``, all > 0.
        x, y, phi: target pose (arrays broadcast; ``N`` targets after flattening).

    Returns:
        ``q`` of shape ``(N, 2, 3)`` (branch 0: ``theta2 >= 0``, branch 1: ``theta2 <= 0``) and
        ``ok`` of shape ``(N, 2)``.

    Raises:
        InvalidArgumentError: a length is not > 0 (argument ``lengths``).
        NonFiniteError: NaN or infinity in ``x``, ``y`` or ``phi``.
        ShapeError: the arrays do not broadcast.
    """
    l1, l2, l3 = _positive(lengths, "lengths", 3)
    return _blocked(partial(_planar_3r_block, l1, l2, l3), _flat(x=x, y=y, phi=phi), 2, 3)


def ik_rp(x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
    """Both IK branches of the R-P (theta-r) arm ``x = r cos(theta)``, ``y = r sin(theta)``.

    Returns:
        ``q`` of shape ``(N, 2, 2)``: ``(atan2(y, x), sqrt(x^2 + y^2))`` and
        ``(atan2(y, x) + pi, -sqrt(x^2 + y^2))`` (wrapped); ``ok`` all True (every point of the
        plane is reached; stroke limits are applied by [`optik.closed_form.ik`][optik.closed_form.ik]).

    Raises:
        NonFiniteError: NaN or infinity in ``x`` or ``y``.
        ShapeError: ``x`` and ``y`` do not broadcast.
    """
    xs, ys = _flat(x=x, y=y)
    q = np.empty((xs.shape[0], 2, 2))
    np.arctan2(ys, xs, out=q[:, 0, 0])
    np.hypot(xs, ys, out=q[:, 0, 1])
    np.add(q[:, 0, 0], np.pi, out=q[:, 1, 0])
    _wrap(q[:, 1, 0])
    np.negative(q[:, 0, 1], out=q[:, 1, 1])
    return q, np.ones((xs.shape[0], 2), dtype=bool)


def ik_pp(x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
    """The single IK branch of the Cartesian P-P arm: ``(q1, q2) = (x, y)``.

    Returns:
        ``q`` of shape ``(N, 1, 2)`` and ``ok`` of shape ``(N, 1)`` (all True).

    Raises:
        NonFiniteError: NaN or infinity in ``x`` or ``y``.
        ShapeError: ``x`` and ``y`` do not broadcast.
    """
    xs, ys = _flat(x=x, y=y)
    q = np.stack([xs, ys], axis=-1)[:, None, :]
    return q, np.ones((xs.shape[0], 1), dtype=bool)


def _transforms(value: Any, name: str) -> np.ndarray:
    t = np.asarray(value, dtype=np.float64)
    if t.ndim == 2:
        t = t[None]
    if t.ndim != 3 or t.shape[1:] != (4, 4):
        raise ShapeError(name, f"expected shape (4, 4) or (N, 4, 4), got {np.shape(value)}")
    if not np.all(np.isfinite(t)):
        raise NonFiniteError(name, "contains NaN or infinity")
    return t


def _safe_ratio(num: np.ndarray, den: np.ndarray, default: float) -> np.ndarray:
    """``num / den`` where ``den != 0``, else ``default``."""
    out = np.full(np.broadcast_shapes(num.shape, den.shape), default)
    return np.divide(num, den, out=out, where=den != 0)


def _triangle_angle(r: np.ndarray, d: float, c: float) -> np.ndarray:
    """The angle between the sides ``r`` and ``d`` of a triangle whose third side is ``c``,
    ``acos((r^2 + d^2 - c^2) / (2 r d))`` (argument clipped to ``[-1, 1]``; 0 when ``r d = 0``),
    by the half-angle form ``2 asin(sqrt(h))``, ``h = (c - |r - d|)(c + |r - d|) / (4 r d)``:
    ``acos`` near 1 turns one rounding unit into an angle of ``1.5e-8``, the half-angle form
    keeps full precision for thin triangles (an elbow far shorter than the wrist offset)."""
    gap = np.abs(r - d)
    h = _safe_ratio((c - gap) * (c + gap), 4.0 * r * d, 0.0)
    return 2.0 * np.arcsin(np.sqrt(np.clip(h, 0.0, 1.0)))


def _reachable_wrist(
    th234: np.ndarray, s5_abs: np.ndarray, beta: np.ndarray, r: np.ndarray, d: tuple[float, float, float]
) -> np.ndarray:
    """Move ``theta234`` into the range where the elbow reaches the wrist centre, when that costs
    at most [`SINGULAR_TOL`][optik.closed_form.serial.SINGULAR_TOL] of orientation.

    The wrist centre ``w = (rho', z) - d4 (c234, s234)`` has ``|w|^2 = r^2 + d4^2 - 2 r d4 cos(psi)``
    with ``psi = theta234 - beta``, ``beta = atan2(z, rho')``; the elbow reaches it when
    ``|d2 - d3| <= |w| <= d2 + d3``, an interval of ``|psi|``. Changing ``theta234`` by ``delta``
    changes the end-effector orientation by ``|s5 sin(delta)|`` (the approach vector tilts about
    the joint-5 axis), so near the wrist singularity, where rounding in ``R`` makes ``theta234``
    ill-conditioned (error ``~ eps / |s5|``), a target at the edge of the workspace is still
    reached with an FK error below the tolerance.
    """
    d2, d3, d4 = d
    lo = _triangle_angle(r, d4, abs(d2 - d3))
    hi = _triangle_angle(r, d4, d2 + d3)
    psi = th234 - beta
    _wrap(psi)
    inside = np.clip(np.abs(psi), lo, hi)
    moved = beta + np.where(psi >= 0.0, inside, -inside)
    cheap = (lo <= hi) & (s5_abs * np.abs(np.sin(moved - th234)) <= SINGULAR_TOL)
    return np.where(cheap, moved, th234)


def ik_seed_6r(d2: float, d3: float, d4: float, t: Any) -> tuple[np.ndarray, np.ndarray]:
    """All IK branches of the seed's 6-joint arm (seed 001), FK-verified derivation.

    ``A_n = Rot(z, theta_n) Trans(x, d_n) Rot(x, alpha_n)`` with ``d = (0, d2, d3, d4, 0, 0)``
    and ``alpha = (90, 0, 0, -90, 90, 0)`` degrees, so that ``p = (c1 rho, s1 rho, z)`` with
    ``rho = c234 d4 + c23 d3 + c2 d2``, ``z = s234 d4 + s23 d3 + s2 d2``, and the rotation is
    ``R = Rot(z, theta1) Rot(x, 90) Rot(z, theta234) Rot(x, -90) Rot(z, theta5) Rot(x, 90) Rot(z, theta6)``.
    With ``R = [n o a]``:

    1. shoulder: ``theta1 = atan2(p_y, p_x)`` or that plus ``pi`` (``rho`` changes sign);
    2. wrist: ``c234 s5 = a_x c1 + a_y s1 =: u`` and ``s234 s5 = a_z``, so
       ``theta234 = atan2(sigma a_z, sigma u)`` for ``sigma = +-1`` (the sign of ``s5``);
    3. elbow: the point ``(p_x c1 + p_y s1 - d4 c234, p_z - d4 s234)`` is a two-link target for
       ``d2, d3`` giving ``theta2, theta3`` (both elbow signs), ``theta4 = theta234 - theta2 - theta3``;
    4. ``M = R_04^T R = Rot(z, theta5) Rot(x, 90) Rot(z, theta6)`` gives
       ``theta5 = atan2(c234 u + s234 a_z, a_x s1 - a_y c1)`` and
       ``theta6 = atan2(c234 n_z - s234 (n_x c1 + n_y s1), c234 o_z - s234 (o_x c1 + o_y s1))``.

    Singular targets (infinitely many solutions) get a defined representative that still
    satisfies FK whenever the target is reachable at all:

    * wrist (``u = a_z = 0``, i.e. ``s5 = 0``): only ``theta234 +- theta6`` is fixed by ``R``;
      ``theta234 = atan2(z, rho') + sigma acos(k)`` is chosen so that the wrist centre lies at
      distance ``max(d2, d3)`` from the shoulder (the middle of the elbow's annulus), with
      ``k = (r^2 + d4^2 - max(d2, d3)^2) / (2 r d4)`` clipped to ``[-1, 1]``, ``r = |(rho', z)|``;
    * shoulder (``p_x = p_y = 0``): ``theta1`` is free; it is chosen as
      ``atan2(a_y, a_x) + acos(...)`` so that ``s234`` puts the wrist centre, as above, as close
      to distance ``max(d2, d3)`` as the orientation allows (and ``theta1 = atan2(a_y, a_x)``
      when ``p_z = 0``, where every ``theta1`` is equivalent).

    * wrist singular and the wrist centre near the waist axis: ``theta1`` is taken from the
      orientation, ``atan2(c5 a_x, -c5 a_y)``, when it agrees with the position to within the
      tolerance below (a short ``rho`` determines ``theta1`` poorly, the locked wrist exactly).

    A distance below [`SINGULAR_TOL`][optik.closed_form.serial.SINGULAR_TOL] (times ``d2 + d3 + d4``; unitless
    for ``s5``) counts as singular, so the representative's FK error is below that tolerance.

    Args:
        d2, d3, d4: link lengths along x (> 0).
        t: target transform(s) of the end effector, shape ``(4, 4)`` or ``(N, 4, 4)`` with
            proper rotation blocks.

    Returns:
        ``q`` of shape ``(N, 8, 6)``, branch index ``4 i_shoulder + 2 i_wrist + i_elbow``
        (index 0 = ``theta1 = atan2(p_y, p_x)``, ``s5 >= 0``, ``theta3 >= 0``), and ``ok`` of
        shape ``(N, 8)``.

    Raises:
        InvalidArgumentError: a length is not > 0 (argument ``d2/d3/d4``).
        ShapeError / NonFiniteError: bad ``t``.
    """
    d2, d3, d4 = _positive((d2, d3, d4), "d2/d3/d4", 3)
    return _blocked(partial(_seed_6r_block, d2, d3, d4), [_transforms(t, "t")], 8, 6)


def _seed_6r_block(
    d2: float, d3: float, d4: float, tt: np.ndarray, q_out: np.ndarray, ok_out: np.ndarray
) -> None:
    """One block of [`ik_seed_6r`][optik.closed_form.serial.ik_seed_6r] (steps 1-4 of its docstring)."""
    n_t = tt.shape[0]
    nx, ny, nz = tt[:, 0, 0], tt[:, 1, 0], tt[:, 2, 0]
    ox, oy, oz = tt[:, 0, 1], tt[:, 1, 1], tt[:, 2, 1]
    ax, ay, az = tt[:, 0, 2], tt[:, 1, 2], tt[:, 2, 2]
    px, py, pz = tt[:, 0, 3], tt[:, 1, 3], tt[:, 2, 3]
    mid = max(d2, d3)
    scale = SINGULAR_TOL * (d2 + d3 + d4)

    # 1. shoulder, with the representative of the shoulder singularity
    alpha = np.arctan2(ay, ax)
    h = np.hypot(ax, ay)
    s_star = np.clip(_safe_ratio(pz * pz + d4 * d4 - mid * mid, 2.0 * d4 * pz, 0.0), -1.0, 1.0)
    ratio = _safe_ratio(np.abs(az) * np.sqrt(1.0 - s_star * s_star), np.abs(s_star) * h, np.inf)
    th1_singular = alpha + np.arccos(np.minimum(ratio, 1.0))
    th1_base = np.where(np.hypot(px, py) <= scale, th1_singular, np.arctan2(py, px))
    # at a wrist singularity a = c5 (s1, -c1, 0) fixes theta1 better than a short rho does
    c5_sign = np.where(ax * np.sin(th1_base) - ay * np.cos(th1_base) >= 0.0, 1.0, -1.0)
    th1_orient = np.arctan2(c5_sign * ax, -c5_sign * ay)
    c1o, s1o = np.cos(th1_orient), np.sin(th1_orient)
    locked = (np.hypot(ax * c1o + ay * s1o, az) <= SINGULAR_TOL) & (np.abs(py * c1o - px * s1o) <= scale)
    th1_base = np.where(locked, th1_orient, th1_base)
    q = q_out.reshape(n_t, 2, 2, 2, 6)
    th1 = np.stack([th1_base, th1_base + np.pi], axis=1)
    _wrap(th1)
    q[..., 0] = th1[:, :, None, None]
    c1, s1 = np.cos(th1), np.sin(th1)

    # 2. wrist, with the representative of the wrist singularity
    u = ax[:, None] * c1 + ay[:, None] * s1
    az2 = np.broadcast_to(az[:, None], u.shape)
    rho = px[:, None] * c1 + py[:, None] * s1
    sigma = np.array([1.0, -1.0])
    th234 = np.arctan2(sigma * az2[..., None], sigma * u[..., None])
    r = np.hypot(rho, pz[:, None])
    beta = np.arctan2(pz[:, None], rho)[..., None]
    th234_singular = beta + sigma * _triangle_angle(r, d4, mid)[..., None]
    s5_abs = np.hypot(u, az2)[..., None]
    th234 = np.where(s5_abs <= SINGULAR_TOL, th234_singular, th234)
    th234 = _reachable_wrist(th234, s5_abs, beta, r[..., None], (d2, d3, d4))
    c234, s234 = np.cos(th234), np.sin(th234)

    # 3. elbow
    extent = (np.abs(px) + np.abs(py) + np.abs(pz) + d4)[:, None, None]
    ok = _two_link(d2, d3, rho[..., None] - d4 * c234, pz[:, None, None] - d4 * s234, q[..., 1:3], extent)
    np.subtract(th234[..., None], q[..., 1], out=q[..., 3])
    q[..., 3] -= q[..., 2]
    _wrap(q[..., 3])

    # 4. wrist angles from M = R_04^T R
    c1e, s1e = c1[..., None], s1[..., None]
    nr = nx[:, None, None] * c1e + ny[:, None, None] * s1e
    orr = ox[:, None, None] * c1e + oy[:, None, None] * s1e
    c5 = ax[:, None, None] * s1e - ay[:, None, None] * c1e
    q[..., 4] = np.arctan2(c234 * u[..., None] + s234 * az[:, None, None], c5)[..., None]
    s6 = c234 * nz[:, None, None] - s234 * nr
    q[..., 5] = np.arctan2(s6, c234 * oz[:, None, None] - s234 * orr)[..., None]
    ok_out.reshape(n_t, 2, 2, 2)[:] = ok[..., None]


# ---------------------------------------------------------------------------- registry adapters
def _distinct_rows(m: Mechanism, rows: list[list[float]]) -> list[list[float]]:
    """The reachable branches of one target (rows, in branch order) without repeats of an
    earlier kept one (same branch when every coordinate differs by < 1e-4, angles
    modulo 2 pi)."""
    if len(rows) <= 1:
        return rows
    mask = angle_mask(m)
    kept: list[list[float]] = []
    for cand in rows:
        if all(_far(cand, prev, mask) for prev in kept):
            kept.append(cand)
    return kept


def _far(a: list[float], b: list[float], mask: tuple[bool, ...]) -> bool:
    """Some coordinate differs by at least the same-branch distance (angles modulo 2 pi).

    Wrapping changes an angle difference below 3 rad by rounding only (< 1e-15), so only
    differences near the threshold or above 3 rad need the exact wrap."""
    for x, y, angle in zip(a, b, mask, strict=True):
        d = abs(x - y)
        if not angle:
            if d >= _SAME_BRANCH:
                return True
        elif d >= 0.999 * _SAME_BRANCH and (
            1.001 * _SAME_BRANCH < d <= 3.0 or abs(wrap_angle(x - y)) >= _SAME_BRANCH
        ):
            return True
    return False


def _planar_one(t: np.ndarray) -> tuple[float, float, float]:
    """``(x, y, phi)`` of a validated planar target
    ([`optik.spatial.planar_pose_of`][optik.spatial.planar_pose_of])."""
    return float(t[0, 3]), float(t[1, 3]), math.atan2(t[1, 0], t[0, 0])


def _rp_one(x: float, y: float) -> list[list[float]]:
    """The branches of [`ik_rp`][optik.closed_form.serial.ik_rp] for one target."""
    th = math.atan2(y, x)
    r = math.hypot(x, y)
    return [[th, r], [_wrap_one(th + np.pi), -r]]


def _adapter(solve: Callable[..., list[list[float]]], *names: str):
    """IK adapter ``(m, T) -> rows`` from a scalar solver ``solve(*params, x, y, phi)``
    (``names``: the ``m.params`` sequences, e.g. link lengths, passed first, unpacked)."""

    def adapter(m: Mechanism, t: np.ndarray) -> list[list[float]]:
        params = [v for name in names for v in m.params[name]]
        return _distinct_rows(m, solve(*params, *_planar_one(t)))

    return adapter


register("planar_2r", ik=_adapter(lambda l1, l2, x, y, phi: _planar_2r_one(l1, l2, x, y), "lengths"))
register("planar_3r", ik=_adapter(_planar_3r_one, "lengths"))
register("rp_arm", ik=_adapter(lambda x, y, phi: _rp_one(x, y)))
register("pp_arm", ik=_adapter(lambda x, y, phi: [[x, y]]))


def _seed_6r_rows(m: Mechanism, t: np.ndarray) -> list[list[float]]:
    """The branches of [`ik_seed_6r`][optik.closed_form.serial.ik_seed_6r] for one target: the
    seed arm's closed form where its derived one is not exact (links so short against the arm
    that the structure holds only within the detection tolerance)."""
    q, ok = ik_seed_6r(m.params["d2"], m.params["d3"], m.params["d4"], t)
    return _distinct_rows(m, q[0][ok[0]].tolist())


register("seed_6r_arm", ik=_seed_6r_rows, prefer_exact_derived=True)
