"""The record a model-file reader returns: what `optik.mechanism.urdf.parse_urdf` and
`optik.mechanism.mjcf.parse_mjcf` read, as the arguments of a `Mechanism` and its ``params``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optik.mechanism.joint import Joint, LinearClosure

__all__ = ["ParsedModel"]


@dataclass(frozen=True)
class ParsedModel:
    """What a model-file reader read: the arguments of a `Mechanism` and its ``params``.

    Attributes:
        name: the model's name (URDF ``<robot name>``, MJCF ``<mujoco model>``; ``"urdf"`` /
            ``"mjcf"`` when absent).
        base: the fixed body: the URDF base link (or the floating-base world frame), MJCF
            ``"world"``.
        joints: one `Joint` per coordinate-carrying joint in coordinate order (URDF: the moving
            joints, mimic joints included; MJCF: MuJoCo's joint order, then one cut joint per
            modelled ``connect`` equality).
        frames: fixed bodies (links reached through fixed joints, MJCF sites),
            ``{name: (body, 4x4 offset)}``.
        ee: the end-effector frame (URDF: ``tip_link``, or the deepest leaf of a tree; MJCF: the
            body with the most joints above it; the first on a tie).
        params: what the reader keeps besides: the source label (``"urdf"`` / ``"mjcf"``) and
            the format's own entries, listed in `optik.mechanism.urdf.parse_urdf` and
            `optik.mechanism.mjcf.parse_mjcf`.
        inertials: ``{body: (mass, centre of mass in the body frame)}`` of the bodies with a
            mass.
        linear_closures: linear equations of joint values (MJCF: fixed-tendon equalities of
            three or more joints).
    """

    name: str
    base: str
    joints: tuple[Joint, ...]
    frames: dict[str, tuple[str, np.ndarray]]
    ee: str
    params: dict[str, object] = field(default_factory=dict)
    inertials: dict[str, tuple[float, np.ndarray]] = field(default_factory=dict)
    linear_closures: tuple[LinearClosure, ...] = ()
