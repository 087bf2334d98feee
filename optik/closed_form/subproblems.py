"""Paden-Kahan subproblems and their extensions (the IK-Geo numbering), vectorized.

Every function takes arrays whose last axis has length 3 (vectors) and that broadcast together
(``...`` below); axes ``k``, ``k1``, ``k2``, ``h`` are unit vectors. ``rot(k, theta)`` is the
rotation by ``theta`` about ``k``:

``rot(k, theta) p = p_par + cos(theta) p_perp + sin(theta) k x p``, ``p_par = k (k . p)``,
``p_perp = p - p_par``.

Each returns the angles and an ``exact`` mask: True where the equations hold exactly (up to
rounding), False where the answer is the least-squares one (or, for SP5 / SP6, where there is no
real solution, then the rows are NaN-free placeholders with ``ok`` False).

* **SP1** ``rot(k, theta) p1 = p2``: ``theta = atan2(k . (p1 x p2), p1_perp . p2_perp)``; least
  squares when ``|p1_perp| != |p2_perp|`` or ``k . p1 != k . p2``; any ``theta`` (0 returned)
  when ``p1_perp = 0``.
* **SP4** ``h . rot(k, theta) p = d``: ``a cos(theta) + b sin(theta) = c`` with
  ``a = h . p_perp``, ``b = h . (k x p)``, ``c = d - (h . k)(k . p)``; ``theta = atan2(b, a) +-
  acos(c / sqrt(a^2 + b^2))``; least squares ``atan2(b, a)`` (``c > 0``) or that ``+ pi`` when
  ``|c| > sqrt(a^2 + b^2)``; every ``theta`` (0 returned, ``exact`` where ``c = 0``) when
  ``a = b = 0`` (``h`` parallel to ``k`` or ``p`` along ``k``).
* **SP3** ``|rot(k, theta) p1 - p2| = d``: squaring gives the SP4
  ``p2 . rot(k, theta) p1 = (|p1|^2 + |p2|^2 - d^2) / 2``.
* **SP2** ``rot(k1, theta1) p1 = rot(k2, theta2) p2``: ``theta1`` solves the SP4
  ``k2 . rot(k1, theta1) p1 = k2 . p2``, then ``theta2`` the SP1
  ``rot(k2, theta2) p2 = rot(k1, theta1) p1`` (up to two pairs; needs ``k1`` not parallel to
  ``k2``).
* **SP5** ``p0 + rot(k1, theta1) p1 = rot(k2, theta2) (p2 + rot(k3, theta3) p3)``: up to four
  triples. See ``sp5``.
* **SP6** ``h1 . rot(k1, t1) p1 + h2 . rot(k2, t2) p2 = d1`` and
  ``h3 . rot(k1, t1) p3 + h4 . rot(k2, t2) p4 = d2``: up to four pairs. See ``sp6``.

SP5 and SP6 end in a trigonometric quartic
``a0 + a1 cos t + b1 sin t + a2 cos 2t + b2 sin 2t = 0`` (``trig_quartic``), whose roots are
the unit-circle eigenvalues ``z = e^{it}`` of the companion matrix of
``(a2 - i b2) z^4 + (a1 - i b1) z^3 + 2 a0 z^2 + (a1 + i b1) z + (a2 + i b2) = 0``, each refined
by two Newton steps on the real equation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optik.closed_form import vec3 as v3

__all__ = ["rot", "sp1", "sp2", "sp3", "sp4", "sp5", "sp6", "trig_quartic"]

EXACT_TOL = 1e-10
"""Relative residual below which a subproblem counts as solved exactly (not least squares)."""
ROOT_TOL = 1e-6
"""How far ``|z|`` of a quartic root may be from 1 and still count as a real angle (a double root
at a tangency splits by about the square root of the rounding error)."""


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b) if a.shape == b.shape else np.sum(a * b, axis=-1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` over the last axis, broadcasting (``np.cross`` without its axis moves: two to
    three times faster on the arrays of the search kernels)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack(np.broadcast_arrays(a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)


def rot(k: np.ndarray, theta: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``rot(k, theta) p`` (Rodrigues) for broadcasting ``k (..., 3)``, ``theta (...)``, ``p (..., 3)``."""
    c = np.cos(theta)[..., None]
    s = np.sin(theta)[..., None]
    kp = _dot(k, p)[..., None]
    return p * c + _cross(np.asarray(k), np.asarray(p)) * s + k * (kp * (1.0 - c))


def _split(a: np.ndarray) -> v3.Vec:
    a = np.asarray(a, dtype=float)
    return (a[..., 0], a[..., 1], a[..., 2])


# --------------------------------------------------- component form (numpy arrays or CasADi SX)
def sp1_c(k: v3.Vec, p1: v3.Vec, p2: v3.Vec, ops: v3.Ops) -> Any:
    """SP1 on component vectors: ``atan2(k . (p1 x p2), p1 . p2 - (k . p1)(k . p2))``."""
    return ops.atan2(v3.dot(v3.cross(k, p1), p2), v3.dot(p1, p2) - v3.dot(k, p1) * v3.dot(k, p2))


def sp4_terms_c(h: v3.Vec, k: v3.Vec, p: v3.Vec, d: Any) -> tuple[Any, Any, Any]:
    """``(a, b, c)`` of ``a cos(theta) + b sin(theta) = c`` (see the module docstring)."""
    kp = v3.dot(k, p)
    hk = v3.dot(h, k)
    return v3.dot(h, p) - hk * kp, v3.dot(h, v3.cross(k, p)), d - hk * kp


def sp4_roots_c(a: Any, b: Any, c: Any, ops: v3.Ops) -> tuple[Any, Any]:
    """The roots ``atan2(b, a) +- acos(c / sqrt(a^2 + b^2))`` of ``a cos + b sin = c`` (the
    argument clipped into ``[-1, 1]``: the least-squares root twice when there is none)."""
    phi = ops.atan2(b, a)
    r = ops.sqrt(a * a + b * b)
    cd = ops.fmax(-1.0, ops.fmin(1.0, c / ops.fmax(r, 1e-300)))
    delta = ops.acos(cd)
    if not ops.remembers:
        return phi + delta, phi - delta
    # cos and sin of the roots by the sum formulas, for the backends that remember them
    cp, sp_, sd = ops.cos(phi), ops.sin(phi), ops.sqrt((1.0 - cd) * (1.0 + cd))
    return (
        ops.known(phi + delta, cp * cd - sp_ * sd, sp_ * cd + cp * sd),
        ops.known(phi - delta, cp * cd + sp_ * sd, sp_ * cd - cp * sd),
    )


def sp4_c(h: v3.Vec, k: v3.Vec, p: v3.Vec, d: Any, ops: v3.Ops) -> tuple[Any, Any]:
    """SP4 on component vectors: the two roots (the least-squares one twice when there is none)."""
    return sp4_roots_c(*sp4_terms_c(h, k, p, d), ops)


def sp3_c(k: v3.Vec, p1: v3.Vec, p2: v3.Vec, d: Any, ops: v3.Ops) -> tuple[Any, Any]:
    """SP3 on component vectors (the SP4 of the module docstring)."""
    return sp4_c(p2, k, p1, 0.5 * (v3.dot(p1, p1) + v3.dot(p2, p2) - d * d), ops)


def sp2_c(k1: v3.Vec, p1: v3.Vec, k2: v3.Vec, p2: v3.Vec, ops: v3.Ops) -> list[tuple[Any, Any]]:
    """SP2 on component vectors: the two pairs ``(theta1, theta2)``."""
    pairs = []
    for t1 in sp4_c(k2, k1, p1, v3.dot(k2, p2), ops):
        pairs.append((t1, sp1_c(k2, p2, v3.rot(k1, ops.cos(t1), ops.sin(t1), p1), ops)))
    return pairs


# -------------------------------------------------------------- array form (with exactness flags)
def sp1(k: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Subproblem 1: ``theta`` with ``rot(k, theta) p1 = p2`` (least squares when impossible).

    Returns:
        ``(theta (...), exact (...))``.
    """
    theta = sp1_c(_split(k), _split(p1), _split(p2), v3.NUMPY)
    err = np.linalg.norm(rot(k, theta, p1) - p2, axis=-1)
    scale = np.maximum(np.linalg.norm(p1, axis=-1) + np.linalg.norm(p2, axis=-1), 1e-300)
    return theta, err <= EXACT_TOL * scale


def sp4(
    h: np.ndarray, k: np.ndarray, p: np.ndarray, d: np.ndarray, scale: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Subproblem 4: ``theta`` with ``h . rot(k, theta) p = d`` (both roots, or the least-squares one twice).

    Args:
        scale: the magnitude the exactness test is relative to (default ``|h| |p| + |d|``).

    Returns:
        ``(theta (..., 2), exact (...))``: the ``+ acos`` root first.
    """
    d = np.asarray(d, dtype=float)
    a, b, c = np.broadcast_arrays(*sp4_terms_c(_split(h), _split(k), _split(p), d))
    r = np.hypot(a, b)
    if scale is None:
        scale = np.linalg.norm(p, axis=-1) * np.linalg.norm(h, axis=-1) + np.abs(d)
    scale = np.broadcast_to(np.maximum(scale, 1e-300), r.shape)
    exact = (np.abs(c) <= r + EXACT_TOL * scale) & (
        (r > EXACT_TOL * scale) | (np.abs(c) <= EXACT_TOL * scale)
    )
    return np.stack(sp4_roots_c(a, b, c, v3.NUMPY), axis=-1), exact


def sp3(k: np.ndarray, p1: np.ndarray, p2: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Subproblem 3: ``theta`` with ``|rot(k, theta) p1 - p2| = d`` (both roots, or least squares).

    Returns:
        ``(theta (..., 2), exact (...))``.
    """
    rhs = 0.5 * (_dot(p1, p1) + _dot(p2, p2) - d * d)
    return sp4(p2, k, p1, rhs, _dot(p1, p1) + _dot(p2, p2) + d * d)


def sp2(
    k1: np.ndarray, p1: np.ndarray, k2: np.ndarray, p2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Subproblem 2: ``(theta1, theta2)`` with ``rot(k1, theta1) p1 = rot(k2, theta2) p2``.

    Returns:
        ``(theta1 (..., 2), theta2 (..., 2), exact (...))``: pair ``j`` is
        ``(theta1[..., j], theta2[..., j])``.
    """
    pairs = sp2_c(_split(k1), _split(p1), _split(k2), _split(p2), v3.NUMPY)
    t1 = np.stack(np.broadcast_arrays(*(a for a, _ in pairs)), axis=-1)
    t2 = np.stack(np.broadcast_arrays(*(b for _, b in pairs)), axis=-1)
    _, exact = sp4(k2, k1, p1, _dot(k2, p2))
    lhs = rot(np.asarray(k1)[..., None, :], t1, np.asarray(p1)[..., None, :])
    err = np.linalg.norm(lhs - rot(np.asarray(k2)[..., None, :], t2, np.asarray(p2)[..., None, :]), axis=-1)
    scale = np.maximum(np.linalg.norm(p1, axis=-1) + np.linalg.norm(p2, axis=-1), 1e-300)[..., None]
    return t1, t2, exact & np.all(err <= EXACT_TOL * scale, axis=-1)


def trig_quartic(coef: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real roots of ``a0 + a1 cos t + b1 sin t + a2 cos 2t + b2 sin 2t = 0``.

    Args:
        coef: ``(..., 5)`` coefficients ``(a0, a1, b1, a2, b2)``.

    Returns:
        ``(t (..., 4), ok (..., 4))``: the roots (any order), ``ok`` False for complex ones
        (their ``t`` is a finite placeholder).
    """
    a0, a1, b1, a2, b2 = np.moveaxis(coef, -1, 0)
    poly = np.stack([a2 - 1j * b2, a1 - 1j * b1, 2.0 * a0 + 0j, a1 + 1j * b1, a2 + 1j * b2], axis=-1)
    scale = np.max(np.abs(poly), axis=-1, keepdims=True)
    scale = np.where(scale > 0, scale, 1.0)
    poly = poly / scale
    lead = poly[..., 0]
    tiny = np.abs(lead) < 1e-13  # degree drop: a root near infinity, off the unit circle
    lead = np.where(tiny, 1e-13, lead)
    comp = np.zeros((*poly.shape[:-1], 4, 4), dtype=complex)
    comp[..., 0, :] = -poly[..., 1:] / lead[..., None]
    comp[..., 1, 0] = comp[..., 2, 1] = comp[..., 3, 2] = 1.0
    z = np.linalg.eigvals(comp)
    ok = np.abs(np.abs(z) - 1.0) <= ROOT_TOL
    t = np.angle(z)
    c = coef[..., None, :]
    for _ in range(2):  # Newton on the real equation
        f = (
            c[..., 0]
            + c[..., 1] * np.cos(t)
            + c[..., 2] * np.sin(t)
            + c[..., 3] * np.cos(2 * t)
            + c[..., 4] * np.sin(2 * t)
        )
        g = (
            -c[..., 1] * np.sin(t)
            + c[..., 2] * np.cos(t)
            - 2 * c[..., 3] * np.sin(2 * t)
            + 2 * c[..., 4] * np.cos(2 * t)
        )
        t = t - np.divide(f, g, out=np.zeros_like(f), where=np.abs(g) > 1e-12 * np.abs(c).sum(-1))
    return t, ok


def _sincos_linear(h: np.ndarray, k: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``h . rot(k, t) p = alpha + beta . (cos t, sin t)``: returns ``(alpha, beta (..., 2))``."""
    kp = _dot(k, p)
    hk = _dot(h, k)
    return hk * kp, np.stack([_dot(h, p) - hk * kp, _dot(h, _cross(np.asarray(k), np.asarray(p)))], axis=-1)


def sp6(
    h: np.ndarray, k1: np.ndarray, k2: np.ndarray, p: np.ndarray, d: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Subproblem 6: ``(t1, t2)`` with ``h[0] . rot(k1, t1) p[0] + h[1] . rot(k2, t2) p[1] = d[0]``
    and ``h[2] . rot(k1, t1) p[2] + h[3] . rot(k2, t2) p[3] = d[1]``.

    With ``x1 = (cos t1, sin t1)``, ``x2 = (cos t2, sin t2)`` the equations are linear,
    ``A x1 + B x2 = e``; the better conditioned of ``A``, ``B`` is inverted, e.g.
    ``x2 = u + V x1`` with ``|x2|^2 = 1``, a trigonometric quartic in ``t1``
    (``trig_quartic``), and ``t2 = atan2`` of ``x2``.

    Args:
        h, p: ``(4, ..., 3)`` the four ``h_i`` and ``p_i``.
        k1, k2: ``(..., 3)`` axes.
        d: ``(..., 2)``.

    Returns:
        ``(t1 (..., 4), t2 (..., 4), ok (..., 4))``.
    """
    al = [_sincos_linear(h[i], k1 if i in (0, 2) else k2, p[i]) for i in range(4)]
    e = np.stack([d[..., 0] - al[0][0] - al[1][0], d[..., 1] - al[2][0] - al[3][0]], axis=-1)
    a = np.stack([al[0][1], al[2][1]], axis=-2)  # (..., 2, 2): rows = equations
    b = np.stack([al[1][1], al[3][1]], axis=-2)
    det_a = np.abs(np.linalg.det(a))
    det_b = np.abs(np.linalg.det(b))
    swap = det_a > det_b  # invert the better conditioned matrix
    big = np.where(swap[..., None, None], a, b)
    small = np.where(swap[..., None, None], b, a)
    inv = np.linalg.inv(np.where(np.maximum(det_a, det_b)[..., None, None] > 0, big, np.eye(2)))
    u = np.einsum("...ij,...j->...i", inv, e)
    v = -inv @ small
    # |u + V x|^2 = 1 with x = (cos t, sin t)
    vu = np.einsum("...ji,...j->...i", v, u)
    vv = np.swapaxes(v, -1, -2) @ v
    coef = np.stack(
        [
            _dot(u, u) - 1.0 + 0.5 * (vv[..., 0, 0] + vv[..., 1, 1]),
            2.0 * vu[..., 0],
            2.0 * vu[..., 1],
            0.5 * (vv[..., 0, 0] - vv[..., 1, 1]),
            vv[..., 0, 1],
        ],
        axis=-1,
    )
    t, ok = trig_quartic(coef)
    x = np.stack([np.cos(t), np.sin(t)], axis=-1)
    y = u[..., None, :] + np.einsum("...ij,...kj->...ki", v, x)
    other = np.arctan2(y[..., 1], y[..., 0])
    ok &= (np.maximum(det_a, det_b) > 0)[..., None]
    t1 = np.where(swap[..., None], other, t)
    t2 = np.where(swap[..., None], t, other)
    return t1, t2, ok


def sp5(
    p0: np.ndarray,
    p1: np.ndarray,
    p2: np.ndarray,
    p3: np.ndarray,
    k1: np.ndarray,
    k2: np.ndarray,
    k3: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Subproblem 5: ``(t1, t2, t3)`` with ``p0 + rot(k1, t1) p1 = rot(k2, t2) (p2 + rot(k3, t3) p3)``.

    Taking the components along ``k2`` and the squared norms of both sides removes ``t2``:
    ``k2 . (p0 + rot(k1, t1) p1) = k2 . p2 + k2 . rot(k3, t3) p3`` and
    ``|p0 + rot(k1, t1) p1|^2 = |p2 + rot(k3, t3) p3|^2``, i.e.
    ``2 p0 . rot(k1, t1) p1 - 2 p2 . rot(k3, t3) p3 = |p2|^2 + |p3|^2 - |p0|^2 - |p1|^2``: an
    SP6 in ``(t1, t3)``; then ``t2`` is the SP1
    ``rot(k2, t2) (p2 + rot(k3, t3) p3) = p0 + rot(k1, t1) p1``.

    Returns:
        ``(t1 (..., 4), t2 (..., 4), t3 (..., 4), ok (..., 4))``.
    """
    h = np.stack(np.broadcast_arrays(k2, -k2, p0, -p2))
    p = np.stack(np.broadcast_arrays(p1, p3, p1, p3))
    d = np.stack(
        [
            _dot(k2, p2) - _dot(k2, p0),
            0.5 * (_dot(p2, p2) + _dot(p3, p3) - _dot(p0, p0) - _dot(p1, p1)),
        ],
        axis=-1,
    )
    t1, t3, ok = sp6(h, k1, k3, p, d)
    lhs = p0[..., None, :] + rot(k1[..., None, :], t1, p1[..., None, :])
    rhs = p2[..., None, :] + rot(k3[..., None, :], t3, p3[..., None, :])
    t2, exact = sp1(k2[..., None, :], rhs, lhs)
    return t1, t2, t3, ok & exact
