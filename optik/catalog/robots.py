"""Real robot arms from ``example-robot-data`` (the optional extra ``robots``).

``pip install "optik[robots]"`` installs the URDF files of
[example-robot-data](https://github.com/Gepetto/example-robot-data) (about 70 real robots, kept
by the Gepetto team for pinocchio); `robot` loads one arm chain of one of them as an
`optik.Mechanism`: ``optik.catalog.robot("ur5")`` is the chain ``base_link -> tool0`` of
``ur5_robot.urdf`` (6 revolute joints), ``optik.catalog.robot("talos_left_arm")`` the left arm
of TALOS.

`ARMS` is the one table of every arm chain: the URDF file (relative to the package's
``robots`` folder), the base link (the link the first arm joint hangs from, so that torso,
lift and base joints are not part of the arm) and the tip link (the tool frame or flange). Same
arm on another base (``ur5_gripper``, ``b1-z1``, ``anymal-kinova``) and chains that are not arms
(legs, hands, fingers, pendulums) are left out. The package holds no KUKA iiwa and no UR
e-series; the iiwa 14 ships with optik (`optik.catalog.iiwa14`).

The files are found through the installed distribution's file list (`importlib.metadata`: the
cmeel packaging puts them under ``site-packages/cmeel.prefix/share/example-robot-data/robots``),
or in ``$EXAMPLE_ROBOT_DATA_MODEL_DIR`` when that is set (a source checkout's ``robots`` folder).
"""

from __future__ import annotations

import importlib.metadata
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from optik.checks import as_name
from optik.errors import InvalidArgumentError, MissingExtraError
from optik.mechanism import Mechanism

__all__ = ["ARMS", "RobotArm", "robot", "robot_names", "robot_urdf", "robots_dir"]

DISTRIBUTION = "example-robot-data"
"""The package that ships the URDF files (pip extra ``robots``)."""
_SHARE = "share/example-robot-data/robots"


@dataclass(frozen=True)
class RobotArm:
    """One arm chain of an example-robot-data URDF.

    Attributes:
        urdf: the file, relative to the ``robots`` folder of the package.
        base_link: the link the arm hangs from.
        tip_link: the end effector (tool frame or flange).
        description: the robot and the chain, in words.
    """

    urdf: str
    base_link: str
    tip_link: str
    description: str


def _pair(robot_key: str, urdf: str, base: str, tips: tuple[str, str], what: str) -> dict[str, RobotArm]:
    """The left and right arms of a two-armed robot (``tips`` = left, right)."""
    return {
        f"{robot_key}_{side}_arm": RobotArm(urdf, base, tip, f"{what}, {side} arm")
        for side, tip in zip(("left", "right"), tips, strict=True)
    }


_UR = "ur_description/urdf"
ARMS: dict[str, RobotArm] = {
    **{
        f"ur{size}{suffix}": RobotArm(
            f"{_UR}/ur{size}_{file}robot.urdf",
            "base_link",
            "tool0",
            f"Universal Robots UR{size}, 6R, {limits}",
        )
        for size in (3, 5, 10)
        for suffix, file, limits in (
            ("", "", "joints +-2 pi"),
            ("_limited", "joint_limited_", "joints +-pi"),
        )
    },
    "panda": RobotArm(
        "panda_description/urdf/panda.urdf",
        "panda_link0",
        "panda_hand_tcp",
        "Franka Emika Panda, 7R, hand TCP",
    ),
    "kinova": RobotArm(
        "kinova_description/robots/kinova.urdf",
        "base",
        "j2s6s200_end_effector",
        "Kinova Jaco 2 (j2s6s200), 6R, continuous joints",
    ),
    "xarm7": RobotArm("xarm_description/urdf/xarm7.urdf", "link_base", "link_eef", "UFactory xArm 7, 7R"),
    "z1": RobotArm("z1_description/urdf/z1.urdf", "link00", "gripperStator", "Unitree Z1, 6R, gripper base"),
    "so100": RobotArm("so_arm_description/urdf/so100.urdf", "base", "gripper", "SO-ARM100, 5R, wrist"),
    "so101": RobotArm(
        "so_arm_description/urdf/so101.urdf",
        "base_link",
        "gripper_frame_link",
        "SO-ARM101, 5R, gripper frame",
    ),
    **_pair(
        "talos",
        "talos_data/robots/talos_reduced.urdf",
        "torso_2_link",
        ("gripper_left_base_link", "gripper_right_base_link"),
        "PAL TALOS humanoid, 7R",
    ),
    **_pair(
        "baxter",
        "baxter_description/urdf/baxter.urdf",
        "torso",
        ("left_gripper", "right_gripper"),
        "Baxter, 7R",
    ),
    "tiago_arm": RobotArm(
        "tiago_description/robots/tiago.urdf",
        "torso_lift_link",
        "arm_tool_link",
        "PAL TIAGo, 7R, above the lift",
    ),
    **_pair(
        "tiago_dual",
        "tiago_description/robots/tiago_dual.urdf",
        "torso_lift_link",
        ("arm_left_tool_link", "arm_right_tool_link"),
        "PAL TIAGo dual, 7R",
    ),
    **_pair(
        "tiago_pro",
        "tiago_pro_description/robots/tiago_pro.urdf",
        "torso_lift_link",
        ("arm_left_tool_link", "arm_right_tool_link"),
        "PAL TIAGo Pro, 7R",
    ),
    **_pair(
        "pr2",
        "pr2_description/urdf/pr2.urdf",
        "torso_lift_link",
        ("l_gripper_tool_frame", "r_gripper_tool_frame"),
        "Willow Garage PR2, 7R, forearm and wrist roll continuous",
    ),
    **_pair(
        "romeo",
        "romeo_description/urdf/romeo.urdf",
        "torso",
        ("l_gripper", "r_gripper"),
        "Aldebaran Romeo, 7R",
    ),
    **_pair("icub", "icub_description/robots/icub.urdf", "chest", ("l_gripper", "r_gripper"), "iCub, 7R"),
    **_pair(
        "g1",
        "g1_description/urdf/g1_29dof_rev_1_0.urdf",
        "torso_link",
        ("left_rubber_hand", "right_rubber_hand"),
        "Unitree G1 humanoid (29 DOF), 7R",
    ),
    **_pair(
        "centauro",
        "centauro_description/urdf/centauro.urdf",
        "torso_2",
        ("arm1_8", "arm2_8"),
        "IIT Centauro, 6R",
    ),
    **_pair(
        "alex",
        "alex_description/urdf/alex_nub_hands.urdf",
        "Torso",
        ("LeftWristRollLink", "RightWristRollLink"),
        "Boardwalk Robotics Alex, 6R",
    ),
    "hextilt_arm": RobotArm(
        "hextilt_description/urdf/hextilt_flying_arm_5.urdf",
        "hextilt__base_link",
        "flying_arm_5__gripper",
        "flying arm of the Hextilt aerial robot, 5R",
    ),
}
"""Every arm chain `robot` knows, by name."""


def robot_names() -> tuple[str, ...]:
    """The names `robot` accepts, sorted."""
    return tuple(sorted(ARMS))


@lru_cache(maxsize=1)
def _installed_dir() -> Path | None:
    try:
        dist = importlib.metadata.distribution(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        return None
    for file in dist.files or ():
        parts = file.as_posix()
        if _SHARE in parts and parts.endswith(".urdf"):
            folder = Path(str(dist.locate_file(parts[: parts.index(_SHARE) + len(_SHARE)])))
            if folder.is_dir():
                return folder
    return None


def robots_dir() -> Path:
    """The ``robots`` folder of example-robot-data.

    Raises:
        MissingExtraError: the package is not installed (or ``$EXAMPLE_ROBOT_DATA_MODEL_DIR``
            names no folder).
    """
    env = os.environ.get("EXAMPLE_ROBOT_DATA_MODEL_DIR")
    if env:
        if not Path(env).is_dir():
            raise MissingExtraError(f"$EXAMPLE_ROBOT_DATA_MODEL_DIR={env!r} is not a folder")
        return Path(env)
    folder = _installed_dir()
    if folder is None:
        raise MissingExtraError(
            f'the robot descriptions need the {DISTRIBUTION!r} package: pip install "optik[robots]"'
        )
    return folder


def _arm(name: object) -> RobotArm:
    key = as_name(name, "name")
    if key not in ARMS:
        raise InvalidArgumentError("name", f"unknown robot {key!r}; known: {', '.join(robot_names())}")
    return ARMS[key]


def robot_urdf(name: str) -> Path:
    """The URDF file of the arm ``name`` (see `ARMS`).

    Raises:
        InvalidArgumentError: unknown name (the message lists the known ones).
        MissingExtraError: example-robot-data is not installed, or lacks that file.
    """
    arm = _arm(name)
    path = robots_dir() / arm.urdf
    if not path.is_file():
        raise MissingExtraError(f"{DISTRIBUTION} has no {arm.urdf} (robot {name!r}); its version is too old")
    return path


def robot(name: str) -> Mechanism:
    """The arm chain ``name`` of example-robot-data (see `ARMS`) as a mechanism.

    The chain ``base_link -> tip_link`` of its URDF (`optik.Mechanism.from_urdf`): coordinates
    named after the URDF joints, the URDF limits (continuous joints unbounded), task ``"pose"``;
    ``m.kind`` is ``"robot:<name>"`` and ``m.params`` has the URDF path, links and velocity
    limits.

    Raises:
        InvalidArgumentError: unknown name (the message lists the known ones).
        MissingExtraError: example-robot-data is not installed: ``pip install "optik[robots]"``.
    """
    arm = _arm(name)
    m = Mechanism.from_urdf(robot_urdf(name), arm.base_link, arm.tip_link)
    m.kind = f"robot:{name}"
    m.name = name
    return m
