"""Target types for IK: planar poses and positions (a 4x4 transform is the full pose)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from optik.checks import as_transform, as_vector

_PLAIN = (float, int)


@dataclass(frozen=True)
class Pose2D:
    """A pose in the x-y plane: position ``(x, y)`` and heading ``phi`` (radians, about z).

    Its transform is ``Trans(x, y, 0) Rot(z, phi)``.
    """

    x: float
    y: float
    phi: float

    def __post_init__(self) -> None:
        x, y, phi = self.x, self.y, self.phi
        if type(x) in _PLAIN and type(y) in _PLAIN and type(phi) in _PLAIN:
            # plain numbers: float() converts them as numpy would (no array round trip)
            x, y, phi = float(x), float(y), float(phi)
            if math.isfinite(x + y + phi) or (math.isfinite(x) and math.isfinite(y) and math.isfinite(phi)):
                object.__setattr__(self, "x", x)
                object.__setattr__(self, "y", y)
                object.__setattr__(self, "phi", phi)
                return
        v = as_vector([self.x, self.y, self.phi], "Pose2D", 3)
        object.__setattr__(self, "x", float(v[0]))
        object.__setattr__(self, "y", float(v[1]))
        object.__setattr__(self, "phi", float(v[2]))

    def as_array(self) -> np.ndarray:
        """``[x, y, phi]``."""
        return np.array([self.x, self.y, self.phi])

    def as_transform(self) -> np.ndarray:
        """The 4x4 transform ``Trans(x, y, 0) Rot(z, phi)``."""
        # spatial.planar_pose's entries (same np.cos / np.sin, zeros as 0 * c) without its
        # generic numpy / CasADi dispatch: this runs per IK call
        c, s = np.cos(self.phi), np.sin(self.phi)
        z = 0 * c
        return np.array(
            [[c, -s, z, self.x], [s, c, z, self.y], [z, z, 1 + z, 0.0], [0.0, 0.0, 0.0, 1.0]], dtype=float
        )


@dataclass(frozen=True)
class Position:
    """A position-only target (3-vector; for planar mechanisms z is 0)."""

    xyz: tuple[float, float, float]

    def __init__(self, xyz: Any, y: float | None = None, z: float | None = None) -> None:
        if y is not None:
            xyz = [xyz, y, 0.0 if z is None else z]
        v = as_vector(xyz, "Position", None)
        if v.shape[0] == 2:
            v = np.append(v, 0.0)
        if v.shape[0] != 3:
            v = as_vector(v, "Position", 3)
        object.__setattr__(self, "xyz", (float(v[0]), float(v[1]), float(v[2])))

    def as_array(self) -> np.ndarray:
        """``[x, y, z]``."""
        return np.array(self.xyz)

    def as_transform(self) -> np.ndarray:
        """A transform with this translation and identity rotation."""
        x, y, z = self.xyz
        return np.array([[1.0, 0.0, 0.0, x], [0.0, 1.0, 0.0, y], [0.0, 0.0, 1.0, z], [0.0, 0.0, 0.0, 1.0]])


Target = np.ndarray | Pose2D | Position
"""Anything [`optik.solve_ik`][optik.solve_ik] accepts as a target."""


def target_transform(target: Any, name: str = "target") -> np.ndarray:
    """The 4x4 transform of a target (validated)."""
    if isinstance(target, (Pose2D, Position)):
        return target.as_transform()
    return as_transform(target, name)
