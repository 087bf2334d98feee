"""Redundant 7-DOF arms from their published kinematic parameters, and the shipped URDF files.

* [`panda`][optik.catalog.arms.panda]: Franka Emika Panda, the modified-DH table of Franka's documentation,
  flange ``panda_link8`` 0.107 m beyond axis 7.
* [`iiwa14`][optik.catalog.arms.iiwa14]: KUKA LBR iiwa 14 R820, a standard-DH chain whose axes meet the
  vertical line of the stretched arm at 0.36 m, 0.78 m and 1.18 m, flange at 1.306 m.

Both describe the same robots as the URDF files shipped in ``optik/data/urdf`` (found with
[`urdf_path`][optik.catalog.arms.urdf_path]; base and tip links in
[`URDF_CHAINS`][optik.catalog.arms.URDF_CHAINS]): for every ``q``, ``panda().fk(q) ==
Mechanism.from_urdf(urdf_path("panda"), "panda_link0", "panda_link8").fk(q)`` and likewise for the iiwa
(tested to 1e-12).

* [`dual_panda`][optik.catalog.arms.dual_panda]: two of those Pandas on a turning torso, a URDF tree
  (``dual_panda.urdf``, in [`URDF_TREES`][optik.catalog.arms.URDF_TREES]) with two tool frames.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

from optik import spatial
from optik.checks import as_name
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism, dh_chain

URDF_CHAINS: dict[str, tuple[str, str]] = {
    "panda": ("panda_link0", "panda_link8"),
    "iiwa14": ("iiwa_link_0", "iiwa_link_ee"),
}
"""``{robot: (base_link, tip_link)}`` of the URDF files shipped with optik."""

URDF_TREES: dict[str, str] = {"dual_panda": "world"}
"""``{robot: root link}`` of the shipped URDF trees (several end effectors): load the whole tree
with ``optik.Mechanism.from_urdf(urdf_path(name))``."""

_PI2 = np.pi / 2

PANDA_MDH = (
    # (a_{i-1}, alpha_{i-1}, d_i)
    (0.0, 0.0, 0.333),
    (0.0, -_PI2, 0.0),
    (0.0, _PI2, 0.316),
    (0.0825, _PI2, 0.0),
    (-0.0825, -_PI2, 0.384),
    (0.0, _PI2, 0.0),
    (0.088, _PI2, 0.0),
)
"""Panda modified-DH rows ``(a_{i-1}, alpha_{i-1}, d_i)`` (Franka documentation)."""
PANDA_FLANGE_D = 0.107
"""Distance from the axis-7 frame to the flange along its z axis (m)."""
PANDA_LOWER = (-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973)
PANDA_UPPER = (2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973)
PANDA_VELOCITY = (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)
"""Panda joint velocity limits (rad/s, datasheet)."""

IIWA14_DH = (
    # (d_i, a_i, alpha_i)
    (0.36, 0.0, -_PI2),
    (0.0, 0.0, _PI2),
    (0.42, 0.0, _PI2),
    (0.0, 0.0, -_PI2),
    (0.4, 0.0, -_PI2),
    (0.0, 0.0, _PI2),
    (0.126, 0.0, 0.0),
)
"""iiwa 14 R820 standard-DH rows ``(d_i, a_i, alpha_i)``: axes at q = 0 along
+z, +y, +z, -y, +z, +y, +z of the base frame."""
IIWA14_LIMIT_DEG = (170.0, 120.0, 170.0, 120.0, 170.0, 120.0, 175.0)
"""iiwa 14 R820 symmetric position limits (degrees, datasheet)."""
IIWA14_VELOCITY_DEG = (85.0, 85.0, 100.0, 75.0, 130.0, 135.0, 135.0)
"""iiwa 14 R820 joint velocity limits (deg/s, datasheet)."""


def _arm(m: Mechanism, kind: str, velocity_limits: np.ndarray) -> Mechanism:
    m.kind = kind
    m.params = {"velocity_limits": velocity_limits}
    return m


def panda() -> Mechanism:
    """Franka Emika Panda arm without hand: 7 revolute joints, end effector at the flange.

    Modified DH (Craig), ``A_i = Rot(x, alpha_{i-1}) Trans(x, a_{i-1}) Rot(z, q_i) Trans(z, d_i)``
    with ``a = (0, 0, 0, 0.0825, -0.0825, 0, 0.088)``, ``d = (0.333, 0, 0.316, 0, 0.384, 0, 0)``,
    ``alpha = (0, -pi/2, pi/2, pi/2, -pi/2, pi/2, pi/2)`` and the flange ``Trans(z, 0.107)``:
    ``T(q) = A_1 ... A_7 Trans(z, 0.107)``, so ``T(0)`` has position ``(0.088, 0, 0.926)`` and
    the flange's z axis pointing down. Limits and ``params["velocity_limits"]`` (rad/s) are
    Franka's datasheet values; joint 4 never reaches 0 (``[-3.0718, -0.0698]``).

    Returns:
        Mechanism with ``kind == "panda"``, task ``"pose"``, coordinates ``q1..q7``.
    """
    m = dh_chain(
        PANDA_MDH,
        "modified",
        lower=PANDA_LOWER,
        upper=PANDA_UPPER,
        flange=spatial.translation(0.0, 0.0, PANDA_FLANGE_D),
        name="panda",
        task="pose",
    )
    return _arm(m, "panda", np.array(PANDA_VELOCITY))


def iiwa14() -> Mechanism:
    """KUKA LBR iiwa 14 R820: 7 revolute joints, end effector at the flange.

    Standard DH, ``A_i = Rot(z, q_i) Trans(z, d_i) Trans(x, a_i) Rot(x, alpha_i)`` with
    ``d = (0.36, 0, 0.42, 0, 0.4, 0, 0.126)``, ``a = 0`` and
    ``alpha = (-pi/2, pi/2, pi/2, -pi/2, -pi/2, pi/2, 0)``: ``T(q) = A_1 ... A_7``, so ``T(0)``
    is the stretched arm, identity rotation at height 1.306 m. Shoulder (axes 1-3) and wrist
    (axes 5-7) are spherical. Limits +-170, +-120, +-170, +-120, +-170, +-120, +-175 degrees and
    ``params["velocity_limits"]`` 85, 85, 100, 75, 130, 135, 135 deg/s (stored in rad/s).

    Returns:
        Mechanism with ``kind == "iiwa14"``, task ``"pose"``, coordinates ``q1..q7``.
    """
    limit = np.deg2rad(IIWA14_LIMIT_DEG)
    m = dh_chain(IIWA14_DH, "standard", lower=-limit, upper=limit, name="iiwa14", task="pose")
    return _arm(m, "iiwa14", np.deg2rad(IIWA14_VELOCITY_DEG))


def urdf_path(name: str) -> Path:
    """Path of a URDF file shipped with optik (``"panda"``, ``"iiwa14"`` or ``"dual_panda"``).

    The base and tip links of each arm's file are ``URDF_CHAINS[name]``; load the chain with
    ``optik.Mechanism.from_urdf(urdf_path(name), *URDF_CHAINS[name])``. The trees of
    `URDF_TREES` load whole: ``optik.Mechanism.from_urdf(urdf_path("dual_panda"))``.

    Raises:
        InvalidArgumentError: ``name`` is not a string or names no shipped URDF.
    """
    as_name(name, "name")
    if name not in URDF_CHAINS and name not in URDF_TREES:
        known = sorted([*URDF_CHAINS, *URDF_TREES])
        raise InvalidArgumentError("name", f"no shipped URDF {name!r}; available: {known}")
    resource = resources.files("optik") / "data" / "urdf" / f"{name}.urdf"
    return Path(str(resource))


def dual_panda() -> Mechanism:
    """Two Panda arms on a turning torso, from the shipped ``dual_panda.urdf``: a tree of 15
    revolute joints (``torso_joint``, then ``left_panda_joint1..7`` and ``right_panda_joint1..7``).

    The torso turns about z at 0.2 m; each arm is the Panda of `panda` (same joints and limits),
    based 0.3 m left / right of the torso axis and 0.6 m up, tilted 0.5 rad outwards about x.
    The frames ``left_tool`` and ``right_tool`` sit 0.1034 m beyond each flange, turned
    ``-pi/4`` about z (the Panda hand's TCP); every link is a frame and ``ee`` is ``left_tool``.
    Made for several targets at once: ``optik.solve_ik(m, {"left_tool": T1, "right_tool": T2})``.

    Its collision geometry is the Panda's of example-robot-data (extra ``robots``): each link's
    mesh, the hand and its closed fingers as fixed links below each flange, and the shipped
    ``dual_panda.srdf`` (that Panda's skipped link pairs, per arm), so collision-aware IK of both
    hands works: ``optik.solve_ik(m, {...}, self_collision=True, margin=0.01)``.
    """
    path = urdf_path("dual_panda")
    m = Mechanism.from_urdf(path, srdf=path.with_suffix(".srdf"))
    m.kind = "dual_panda"
    return m
