"""Legged robots of example-robot-data with a floating base (the optional extra ``robots``).

`legged` loads a quadruped or a humanoid whole, with a free base
(`optik.Mechanism.from_urdf(..., floating_base=True)`: six coordinates ``root_joint[0..5]``,
position and rotation vector), and puts in ``m.params`` what whole-body IK with balance needs:

* ``"feet"``: the contact frames (the feet of a quadruped, the soles' links of a humanoid);
* ``"hands"``: the hand frames of a humanoid (empty for a quadruped);
* ``"standing"``: a standing configuration: every joint at the table's posture (0 where not
  given, clipped into the limits), the base lifted so that the lowest foot frame is on z = 0;
* ``"sole"``: for flat feet, the sole's corners ``(x, y)`` around each foot frame (m), from
  which `support_polygon` makes the support polygon; None for point feet.

`LEGGED` is the table. The masses are the URDF inertials: `Mechanism.com` is checked against
Pinocchio for all of them (tests/test_com.py).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from optik.checks import as_name
from optik.errors import InvalidArgumentError, MissingExtraError
from optik.mechanism import Mechanism

__all__ = ["LEGGED", "LeggedRobot", "legged", "legged_names", "support_polygon"]


@dataclass(frozen=True)
class LeggedRobot:
    """One row of `LEGGED`: the URDF (relative to example-robot-data's ``robots`` folder), the
    foot and hand frames, the standing posture ``{joint: angle}`` and the sole's corners (None
    for point feet)."""

    urdf: str
    feet: tuple[str, ...]
    hands: tuple[str, ...] = ()
    posture: tuple[tuple[str, float], ...] = ()
    sole: tuple[tuple[float, float], ...] | None = None


_GO2_LEGS = tuple(
    (f"{leg}_{j}_joint", a) for leg in ("FL", "FR", "RL", "RR") for j, a in (("thigh", 0.8), ("calf", -1.5))
)

LEGGED: dict[str, LeggedRobot] = {
    "go2": LeggedRobot(
        "go2_description/urdf/go2.urdf", ("FL_foot", "FR_foot", "RL_foot", "RR_foot"), posture=_GO2_LEGS
    ),
    "g1": LeggedRobot(
        "g1_description/urdf/g1_29dof_rev_1_0.urdf",
        ("left_ankle_roll_link", "right_ankle_roll_link"),
        ("left_rubber_hand", "right_rubber_hand"),
        sole=((-0.05, -0.03), (0.12, -0.03), (0.12, 0.03), (-0.05, 0.03)),
    ),
}
"""The legged robots of `legged`: the Unitree Go2 quadruped (point feet, knees bent) and the
Unitree G1 humanoid (29 joints, flat feet)."""


def legged_names() -> tuple[str, ...]:
    """The names `legged` takes."""
    return tuple(LEGGED)


def legged(name: str) -> Mechanism:
    """The legged robot ``name`` of `LEGGED` with a floating base (see the module docstring).

    Raises:
        InvalidArgumentError: unknown name.
        MissingExtraError: example-robot-data is not installed, or lacks the file.
    """
    from optik.catalog.robots import DISTRIBUTION, robots_dir

    key = as_name(name, "name")
    if key not in LEGGED:
        raise InvalidArgumentError("name", f"unknown legged robot {key!r}; known: {', '.join(LEGGED)}")
    row = LEGGED[key]
    path = robots_dir() / row.urdf
    if not path.is_file():
        raise MissingExtraError(f"{DISTRIBUTION} has no {row.urdf} (robot {key!r}); its version is too old")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # example-robot-data's URDFs name meshes of other packages
        m = Mechanism.from_urdf(path, floating_base=True)
    q = np.zeros(m.n_q)
    for joint, angle in row.posture:
        q[m.coordinate_names.index(joint)] = angle
    q = np.clip(q, m.lower, m.upper)
    q[2] = -min(m.fk(q, f)[2, 3] for f in row.feet)
    q.flags.writeable = False
    m.kind, m.name = f"legged:{key}", key
    m.params.update({"feet": row.feet, "hands": row.hands, "standing": q, "sole": row.sole})
    return m


def support_polygon(m: Mechanism, q: np.ndarray, feet: tuple[str, ...] | None = None) -> np.ndarray:
    """The counter-clockwise support polygon ``(k, 2)`` of the feet at ``q``: the convex hull of
    the soles' corners (flat feet, ``m.params["sole"]``) or of the foot points.

    Raises:
        InvalidArgumentError: ``m`` is not from `legged`, or fewer than three support points.
    """
    from scipy.spatial import ConvexHull

    if "feet" not in m.params:
        raise InvalidArgumentError("m", "expected a mechanism from optik.catalog.legged")
    feet = m.params["feet"] if feet is None else feet
    corners = m.params["sole"] or ((0.0, 0.0),)
    points = []
    for f in feet:
        t = m.fk(q, f)
        points += [t[:2, 3] + t[:2, :2] @ np.asarray(c) for c in corners]
    pts = np.array(points)
    if len(pts) < 3:
        raise InvalidArgumentError("feet", "a support polygon needs at least three points")
    return pts[ConvexHull(pts).vertices]
