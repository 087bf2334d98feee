"""Study's coordinates of SE(3) and the Stewart-Gough leg equations as quadrics in them.

A pose ``(R, t)`` is the point ``z = (e, g)`` of ``P^7`` with ``R = R(e)`` (``e`` the rotation
quaternion) and ``g = t e / 2``; every real pose has ``e != 0`` and lies on the Study quadric
``e . g = 0``. The functions accept complex geometry (complexified start instances of a
parameter homotopy): every formula is a polynomial identity.
"""

from __future__ import annotations

import numpy as np


def quat_left(a: np.ndarray) -> np.ndarray:
    """``L(a)`` with ``a * b = L(a) b`` (Hamilton product, scalar first)."""
    a0, a1, a2, a3 = a
    return np.array([[a0, -a1, -a2, -a3], [a1, a0, -a3, a2], [a2, a3, a0, -a1], [a3, -a2, a1, a0]])


def quat_right(b: np.ndarray) -> np.ndarray:
    """``R(b)`` with ``a * b = R(b) a`` (Hamilton product, scalar first)."""
    b0, b1, b2, b3 = b
    return np.array([[b0, -b1, -b2, -b3], [b1, b0, b3, -b2], [b2, -b3, b0, b1], [b3, b2, -b1, b0]])


def quat_to_rot(e: np.ndarray) -> np.ndarray:
    """Rotation matrix of a (not necessarily unit) quaternion ``e = (e0, e1, e2, e3)``; for
    ``e`` of shape ``(..., 4)`` the matrices ``(..., 3, 3)``."""
    e = np.asarray(e, dtype=float)
    w, x, y, z = np.moveaxis(e / np.linalg.norm(e, axis=-1, keepdims=True), -1, 0)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


_UNIT = np.eye(4)[1:]
_L_BASIS = np.array([quat_left(u) for u in _UNIT])  # L(v) = sum_k v_k _L_BASIS[k] for pure v
_R_BASIS = np.array([quat_right(u) for u in _UNIT])


def study_matrices(b: np.ndarray, p: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The Stewart-Gough FK as 7 symmetric ``8 x 8`` quadric matrices in ``z = (e, g)``
    (real or complex ``b``, ``p``: ``(6, 3)``; ``c``: ``(6,)``).

    Row 0 is the Study quadric ``e . g = 0``; row ``i + 1`` the leg ``i``,
    ``|R p_i + t - b_i|^2 = rho_i^2`` times ``|e|^2`` with ``c_i = |p_i|^2 + |b_i|^2 - rho_i^2``:

    ``c_i |e|^2 - 2 <b e, e p> + 4 <e p - b e, g> + 4 |g|^2 = 0``

    (``b``, ``p`` as pure quaternions, ``<.,.>`` the bilinear product of R^4 / C^4), i.e. the
    blocks ``[[c I - (A + A^T), 2 D^T], [2 D, 4 I]]`` with ``A = L(b)^T R(p)``, ``D = R(p) - L(b)``.
    """
    lb = np.einsum("ik,kab->iab", b, _L_BASIS)
    rp = np.einsum("ik,kab->iab", p, _R_BASIS)
    a = np.swapaxes(lb, 1, 2) @ rp
    d = 2 * (rp - lb)
    dtype = np.result_type(b, p, c, float)
    mats = np.zeros((7, 8, 8), dtype=dtype)
    mats[0, :4, 4:] = mats[0, 4:, :4] = 0.5 * np.eye(4)
    mats[1:, :4, :4] = np.asarray(c)[:, None, None] * np.eye(4) - (a + np.swapaxes(a, 1, 2))
    mats[1:, 4:, :4] = d
    mats[1:, :4, 4:] = np.swapaxes(d, 1, 2)
    mats[1:, 4:, 4:] = 4 * np.eye(4)
    return mats


def leg_constants(b: np.ndarray, p: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """``c_i = |p_i|^2 + |b_i|^2 - rho_i^2`` (bilinear squares for complex geometry)."""
    return np.sum(p * p, axis=1) + np.sum(b * b, axis=1) - np.asarray(rho) ** 2


def stewart_quadrics(b: np.ndarray, p: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """`study_matrices` for leg lengths ``rho``, each leg quadric scaled to unit Frobenius norm."""
    mats = study_matrices(b, p, leg_constants(b, p, rho))
    mats[1:] /= np.linalg.norm(mats[1:], axis=(1, 2))[:, None, None]
    return mats
