"""Serial arms of the seeds: planar 2R, 3R, R-P (theta-r), P-P and the seed's 6-joint arm."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from optik.checks import as_vector
from optik.errors import InvalidArgumentError
from optik.mechanism import Joint, Mechanism, dh_chain, planar_chain


def _tag(m: Mechanism, kind: str, **params: object) -> Mechanism:
    m.kind = kind
    m.params = dict(params)
    return m


def _positive(lengths: Sequence[float], name: str, n: int) -> tuple[float, ...]:
    ls = as_vector(lengths, name, n)
    if np.any(ls <= 0):
        raise InvalidArgumentError(name, f"lengths must be > 0, got {tuple(ls)}")
    return tuple(float(v) for v in ls)


def planar_2r(
    lengths: Sequence[float] = (1.0, 0.8),
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
) -> Mechanism:
    """Planar 2R arm (seed 002): ``x = l1 c1 + l2 c12``, ``y = l1 s1 + l2 s12``.

    Task space ``position2d``; two IK branches (elbow up / down).
    """
    ls = _positive(lengths, "lengths", 2)
    m = planar_chain("RR", ls, lower, upper, name="planar_2r", task="position2d")
    return _tag(m, "planar_2r", lengths=ls)


def planar_3r(
    lengths: Sequence[float] = (1.0, 0.8, 0.5),
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
) -> Mechanism:
    """Planar 3R arm (seed 000, equation (1)); task ``pose2d`` with ``phi = theta1 + theta2 + theta3``."""
    ls = _positive(lengths, "lengths", 3)
    m = planar_chain("RRR", ls, lower, upper, name="planar_3r", task="pose2d")
    return _tag(m, "planar_3r", lengths=ls)


def rp_arm(
    lower: Sequence[float] = (-np.pi, 0.2),
    upper: Sequence[float] = (np.pi, 2.0),
) -> Mechanism:
    """The theta-r arm of seed 001: ``T = Rot(z, theta) Trans(x, r)``; task ``position2d``."""
    m = planar_chain("RP", (0.0, 0.0), lower, upper, name="rp_arm", task="position2d")
    return _tag(m, "rp_arm")


def pp_arm(
    lower: Sequence[float] = (-1.0, -1.0),
    upper: Sequence[float] = (1.0, 1.0),
) -> Mechanism:
    """Cartesian P-P arm: the first joint slides along x, the second along y; ``(x, y) = (q1, q2)``."""
    lo = as_vector(lower, "lower", 2)
    hi = as_vector(upper, "upper", 2)
    joints = [
        Joint("q1", "prismatic", "base", "link1", axis=[1, 0, 0], lower=lo[0], upper=hi[0]),
        Joint("q2", "prismatic", "link1", "link2", axis=[0, 1, 0], lower=lo[1], upper=hi[1]),
    ]
    m = Mechanism(joints, "base", {"ee": ("link2", np.eye(4))}, "ee", "pp_arm", "position2d")
    return _tag(m, "pp_arm")


SEED_6R_ALPHAS = (np.pi / 2, 0.0, 0.0, -np.pi / 2, np.pi / 2, 0.0)
"""Twist angles of the seed's 6-joint arm (seed 001)."""


def seed_6r_arm(
    d2: float = 1.0,
    d3: float = 0.8,
    d4: float = 0.3,
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
) -> Mechanism:
    """The 6-joint arm of seed 001: ``A_n = Rot(z, theta_n) Trans(x, d_n) Rot(x, alpha_n)``.

    ``d = (0, d2, d3, d4, 0, 0)``, ``alpha = (90, 0, 0, -90, 90, 0)`` degrees. Its FK, derived
    from the A-matrices (the seed prints ``n_y`` with a wrong sign), is:

    ```text
    n_y = s1 (c234 c5 c6 - s234 s6) + c1 s5 c6
    p   = (c1 rho, s1 rho, s234 d4 + s23 d3 + s2 d2),  rho = c234 d4 + c23 d3 + c2 d2
    ```
    """
    ds = _positive((d2, d3, d4), "d2/d3/d4", 3)
    rows = [
        (0.0, SEED_6R_ALPHAS[0]),
        (ds[0], 0.0),
        (ds[1], 0.0),
        (ds[2], SEED_6R_ALPHAS[3]),
        (0.0, SEED_6R_ALPHAS[4]),
        (0.0, 0.0),
    ]
    m = dh_chain(rows, "seed", lower=lower, upper=upper, name="seed_6r_arm", task="pose")
    return _tag(m, "seed_6r_arm", d2=ds[0], d3=ds[1], d4=ds[2])
