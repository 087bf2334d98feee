"""The arms and the EAIK peer shared by the all-solutions and the path benchmarks.

`ur_arm` loads a UR arm from example-robot-data, `eaik_robot` builds EAIK's model of an arm (by
EAIK's own parser where it has one) with the tool transform between the two, and
`valid_solutions` keeps the solutions of a peer that pass one independent FK and limit check
(the check every claimed solution of every solver gets). `axis_offsets` and `ik_geo_target` are
the model and target conventions of the product-of-exponentials peers (ik-geo, EAIK), shared by
the all-solutions, general 6R and 1-D search benchmarks. ``eaik_dh`` and ``eaik_urdf`` are EAIK's
modules, None where it is not installed.
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib import metadata
from pathlib import Path

import numpy as np

from optik.catalog.industrial import PUMA560_DH
from optik.closed_form.derived import chain_axes
from optik.mechanism import Mechanism

try:  # an optional peer
    import eaik.IK_DH as eaik_dh
    import eaik.IK_URDF as eaik_urdf
except ImportError:  # pragma: no cover - depends on the environment
    eaik_dh = eaik_urdf = None

__all__ = [
    "FK_TOL",
    "axis_offsets",
    "eaik_dh",
    "eaik_robot",
    "eaik_urdf",
    "ik_geo_target",
    "ur_arm",
    "urdf_path",
    "valid_solutions",
]

FK_TOL = 1e-6
"""FK check of a solution: position (m) and orientation (rad) errors at most this."""
UR_DIR = "cmeel.prefix/share/example-robot-data/robots/ur_description/urdf"


def urdf_path(name: str) -> Path | None:
    """The joint-limited URDF of a UR arm in example-robot-data, or None."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return None
    path = Path(str(dist.locate_file(f"{UR_DIR}/{name}_joint_limited_robot.urdf")))
    return path if path.exists() else None


def ur_arm(name: str) -> tuple[Mechanism | None, str]:
    """A UR arm of example-robot-data (base ``base_link``, tip ``tool0``), or a note."""
    path = urdf_path(name)
    if path is None:
        return None, f'{name}: skipped, example-robot-data is not installed (pip install "optik[robots]")'
    m = Mechanism.from_urdf(path, "base_link", "tool0")
    m.name = name
    return m, ""


def axis_offsets(r: np.ndarray, home: np.ndarray) -> np.ndarray:
    """The offsets ``p_0 .. p_n`` of ik-geo's and EAIK's product-of-exponentials model of an n-joint
    chain, from a point ``r_i`` of each joint axis at ``q = 0`` (rows of ``r``) and the tool pose
    ``home`` (4x4) there: ``p_0 = r_0`` (the base to axis 1), ``p_i = r_i - r_(i-1)`` (axis ``i`` to
    axis ``i + 1``) and ``p_n = t_home - r_(n-1)`` (the last axis to the tool); shape ``(n + 1, 3)``."""
    return np.vstack([r[0], np.diff(r, axis=0), home[:3, 3] - r[-1]])


def ik_geo_target(target: np.ndarray, home: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ik-geo's ``(R, p)`` arguments for optik's 4x4 tool target, ``home`` the tool rotation at
    ``q = 0``: ``R = R_T R_home^T`` (ik-geo's end rotation is the identity at ``q = 0``), passed
    transposed because the binding reads a 3x3 array column by column (its ``forward_kinematics``
    returns the transpose the same way)."""
    return np.ascontiguousarray((target[:3, :3] @ home.T).T), target[:3, 3].copy()


def eaik_robot(m: Mechanism) -> tuple[object, np.ndarray, str]:
    """EAIK's robot for the arm, built by EAIK's own parser where it has one (its URDF reader
    for the UR arms, its DH constructor for the PUMA 560), else from optik's joint axes at
    ``q = 0`` (the seed arm); with ``X`` such that EAIK's FK is ``m.fk(q) X`` (EAIK's tool
    frame differs), checked on 16 random configurations."""
    path = urdf_path(m.name) if m.name in ("ur5", "ur10") else None
    if path is not None:
        robot, source = eaik_urdf.UrdfRobot(str(path)), "EAIK's URDF parser"
    elif m.kind == "puma560":
        d, a, alpha = (np.array(c) for c in zip(*PUMA560_DH, strict=True))
        robot, source = eaik_dh.DhRobot(alpha, a, d), "EAIK's DH constructor"
    else:
        ax = chain_axes(m)
        offsets = axis_offsets(ax.r, ax.home)
        robot, source = eaik_dh.EAIK.Robot(ax.h.T, offsets.T, ax.home[:3, :3], [], True), "optik's axes"
    raw = getattr(robot, "_robot", robot)  # the compiled robot: timed without EAIK's Python wrapper
    x = np.linalg.inv(m.fk(np.zeros(6))) @ np.asarray(raw.fwdkin(np.zeros(6)))
    for q in m.random_q(16, seed=99):
        gap = np.abs(m.fk(q) @ x - np.asarray(raw.fwdkin(q))).max()
        if gap > 1e-9:
            raise RuntimeError(f"{m.name}: EAIK's model ({source}) differs from optik's by {gap:.1e}")
    return raw, x, source


def valid_solutions(m: Mechanism, qs: Sequence[np.ndarray], target: np.ndarray) -> list[np.ndarray]:
    """The ``qs`` (shifted into the limits by ``m.wrap``) passing the FK and limit check."""
    out = []
    for q in qs:
        w = m.wrap(np.asarray(q, dtype=float))
        t = m.fk(w)
        rel = t[:3, :3].T @ target[:3, :3]
        angle = np.arccos(np.clip(0.5 * (np.trace(rel) - 1.0), -1.0, 1.0))
        if np.linalg.norm(t[:3, 3] - target[:3, 3]) <= FK_TOL and angle <= FK_TOL and m.within_limits(w):
            out.append(w)
    return out
