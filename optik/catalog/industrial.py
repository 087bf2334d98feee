"""Industrial 6-axis arms from their published kinematic parameters.

* [`puma560`][optik.catalog.puma560]: Unimation PUMA 560, the standard-DH table and joint limits of
  Corke's Robotics Toolbox model (after Armstrong, Khatib and Burdick, 1986): a spherical wrist
  (axes 4, 5, 6 meet at the wrist centre), axes 1 and 2 meeting at the shoulder, axes 2 and 3
  parallel. Its analytic IK is derived from this structure (`optik.closed_form.derive`).
"""

from __future__ import annotations

import numpy as np

from optik.mechanism import Mechanism, dh_chain

_PI2 = np.pi / 2

PUMA560_DH = (
    # (d_i, a_i, alpha_i)
    (0.0, 0.0, _PI2),
    (0.0, 0.4318, 0.0),
    (0.15005, 0.0203, -_PI2),
    (0.4318, 0.0, _PI2),
    (0.0, 0.0, -_PI2),
    (0.0, 0.0, 0.0),
)
"""PUMA 560 standard-DH rows ``(d_i, a_i, alpha_i)`` (m, rad)."""
PUMA560_LIMIT_DEG = (
    (-160.0, 160.0),
    (-45.0, 225.0),
    (-225.0, 45.0),
    (-110.0, 170.0),
    (-100.0, 100.0),
    (-266.0, 266.0),
)
"""PUMA 560 joint limits (degrees)."""


def puma560() -> Mechanism:
    """Unimation PUMA 560: 6 revolute joints, end effector at the wrist centre's flange frame.

    Standard DH, ``A_i = Rot(z, q_i) Trans(z, d_i) Trans(x, a_i) Rot(x, alpha_i)`` with
    ``d = (0, 0, 0.15005, 0.4318, 0, 0)``, ``a = (0, 0.4318, 0.0203, 0, 0, 0)`` and
    ``alpha = (pi/2, 0, -pi/2, pi/2, -pi/2, 0)``; ``T(q) = A_1 ... A_6``. Limits (degrees)
    ``[-160, 160]``, ``[-45, 225]``, ``[-225, 45]``, ``[-110, 170]``, ``[-100, 100]``,
    ``[-266, 266]``.

    Returns:
        Mechanism with ``kind == "puma560"``, task ``"pose"``, coordinates ``q1..q6``.
    """
    lim = np.deg2rad(np.array(PUMA560_LIMIT_DEG))
    m = dh_chain(PUMA560_DH, "standard", lower=lim[:, 0], upper=lim[:, 1], name="puma560", task="pose")
    m.kind = "puma560"
    m.params = {}
    return m
