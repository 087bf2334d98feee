"""Joints: the motion one body may have relative to another.

A joint connects a ``parent`` body to a ``child`` body. Its pose is

``T_child = T_parent @ origin @ motion(q) @ inv(child_offset)``

where ``origin`` places the joint frame in the parent body (as in URDF), ``motion(q)`` is the
joint's own motion and ``child_offset`` places the same joint frame in the child body (identity
for joints of a serial chain, where the child body frame *is* the joint frame).

Joint types and their coordinates (``dof`` = connectivity ``f`` in Gruebler-Kutzbach):

| type | dof | motion(q) |
|---|---|---|
| revolute | 1 | ``Rot(axis, q)`` (Rodrigues) |
| prismatic | 1 | ``Trans(q * axis)`` |
| fixed | 0 | identity |
| universal | 2 | ``Rot(axis, q0) Rot(axis2, q1)`` |
| spherical | 3 | ``exp([q]x)``: q is a rotation vector (one chart covering SO(3)) |
| free | 6 | ``Trans(q[0:3]) exp([q[3:6]]x)``: a floating base (parent-frame position, rotation vector) |

A free joint's six coordinates are unbounded by default; they are those of a spherical joint
placed after three prismatic joints along the parent's axes, in one joint (MJCF ``<freejoint>``).

When a joint closes a loop (a *cut* joint) it has no coordinates; instead it contributes
loop-closure equations (see `optik.mechanism.closure`).

A *mimic* joint (URDF ``<mimic>``) is a revolute or prismatic joint without a coordinate of its
own: its value is ``q_mimic = multiplier * q_source + offset`` of another joint's coordinate
(`Mimic`), so it counts ``dof = 0`` (it moves, but adds no freedom) and the Jacobians of the
frames after it depend on ``q_source`` through the coupling.

Limits may be infinite: ``Joint("j", "revolute", ..., lower=-inf, upper=inf)`` is an unbounded
(URDF ``continuous``) joint, whose angle wraps instead of meeting a wall at +-pi.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from optik import spatial
from optik.checks import as_float, as_name, read_only, real_array
from optik.errors import InvalidArgumentError, LimitsError

JOINT_DOF = {"revolute": 1, "prismatic": 1, "fixed": 0, "universal": 2, "spherical": 3, "free": 6}
"""Connectivity of each joint type."""

_DEFAULT_LIMIT = {"revolute": np.pi, "prismatic": 1.0, "universal": np.pi, "spherical": np.pi, "free": np.inf}


def _unit(v: Any, name: str) -> np.ndarray:
    a = real_array(v, name).reshape(-1)
    norm = math.sqrt(float(a @ a)) if a.shape == (3,) else 0.0  # inf or nan when an entry is
    if not math.isfinite(norm) or norm < 1e-12:
        raise InvalidArgumentError(name, f"expected a finite non-zero 3-vector, got {v!r}")
    return a / norm


@dataclass(frozen=True)
class Mimic:
    """The coupling of a mimic joint: ``q_mimic = multiplier * q[joint] + offset``.

    Args:
        joint: name of the source joint (a revolute or prismatic joint with its own coordinate).
        multiplier: the factor (URDF default 1).
        offset: the offset, rad or m (URDF default 0).
    """

    joint: str
    multiplier: float = 1.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        as_name(self.joint, "mimic.joint")
        for key in ("multiplier", "offset"):
            object.__setattr__(self, key, as_float(getattr(self, key), f"mimic.{key}"))

    def value(self, q_source: Any) -> Any:
        """``multiplier * q_source + offset`` (numbers, arrays or CasADi symbols)."""
        return self.multiplier * q_source + self.offset


@dataclass(frozen=True)
class LinearClosure:
    """A linear equation of joint values that a mechanism must satisfy besides its cut joints:
    ``sum_k c_k q_k = value`` over revolute or prismatic joints (tree or mimic joints), e.g. a
    MuJoCo fixed tendon of three or more joints held at constant length. It is one row
    ``sum_k c_k q_k - value`` of `Mechanism.closure`.

    Args:
        name: a label (for messages).
        coefficients: ``((joint name, c_k), ...)``, at least one.
        value: the right-hand side (rad or m, as the joints).
    """

    name: str
    coefficients: tuple[tuple[str, float], ...]
    value: float

    def __post_init__(self) -> None:
        as_name(self.name, "linear_closure.name")
        try:
            pairs = [(j, c) for j, c in self.coefficients]
        except (TypeError, ValueError) as exc:
            raise InvalidArgumentError(
                _TERMS, f"expected (joint name, coefficient) pairs, got {self.coefficients!r}"
            ) from exc
        terms = tuple((as_name(j, _TERMS), as_float(c, _TERMS)) for j, c in pairs)
        if not terms:
            raise InvalidArgumentError(_TERMS, f"closure {self.name!r} has no term")
        object.__setattr__(self, "coefficients", terms)
        object.__setattr__(self, "value", as_float(self.value, "linear_closure.value"))


_TERMS = "linear_closure.coefficients"


def _limits(value: Any, name: str, joint: str, default: float, n: int) -> tuple[float, ...]:
    """One limit per coordinate (``default`` when None); NaN and non-numbers raise here."""
    if value is None:
        return (default,) * n
    a = real_array(value, f"{name} (joint {joint!r})").reshape(-1)
    if np.isnan(a).any():
        raise LimitsError(name, f"joint {joint!r}: contains NaN: {value!r}")
    return tuple(a.tolist())


def axis_rotation(axis: np.ndarray, angle: Any) -> Any:
    """Rotation by ``angle`` about the unit ``axis``: ``exp([axis]x angle)``.

    Uses the closed form ``I + sin(a) K + (1 - cos(a)) K^2`` with ``K = [axis]x``; the
    elementary rotations are used for coordinate axes so that symbolic expressions stay small.
    """
    for i, fn in enumerate((spatial.rot_x, spatial.rot_y, spatial.rot_z)):
        e = np.zeros(3)
        e[i] = 1.0
        if np.allclose(axis, e):
            return fn(angle)
        if np.allclose(axis, -e):
            return fn(-angle)
    k = spatial.hat(axis)
    if spatial.is_symbolic(angle):
        return ca.DM.eye(3) + ca.sin(angle) * ca.DM(k) + (1 - ca.cos(angle)) * ca.DM(k @ k)
    a = np.asarray(angle, dtype=float)[..., None, None]
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * (k @ k)


@dataclass(frozen=True)
class Joint:
    """One joint between two named bodies.

    Args:
        name: unique joint name; coordinates are named after it.
        type: ``"revolute"``, ``"prismatic"``, ``"fixed"``, ``"universal"``, ``"spherical"`` or
            ``"free"``.
        parent: parent body name.
        child: child body name.
        origin: 4x4 pose of the joint frame in the parent body frame.
        axis: joint axis in the joint frame (revolute, prismatic; first axis of a universal).
        axis2: second axis of a universal joint (in the frame after the first rotation).
        lower: lower limit(s), one per coordinate (default -pi for angles and rotation vectors,
            -1 m for slides, -inf for the six coordinates of a free joint).
        upper: upper limit(s), one per coordinate.
        actuated: whether the joint's coordinates are driven (inputs of FK).
        child_offset: 4x4 pose of the joint frame in the child body frame.
        cut: force this joint to close a loop (no coordinates, closure equations instead).
        mimic: make this revolute or prismatic joint follow another joint's coordinate
            (`Mimic`); it then has no coordinate and no limits of its own.
    """

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray = field(default_factory=lambda: np.eye(4))
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    axis2: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    lower: tuple[float, ...] | None = None
    upper: tuple[float, ...] | None = None
    actuated: bool = True
    child_offset: np.ndarray = field(default_factory=lambda: np.eye(4))
    cut: bool = False
    mimic: Mimic | None = None

    def __post_init__(self) -> None:
        as_name(self.type, "type", JOINT_DOF)
        for key in ("name", "parent", "child"):
            if not isinstance(getattr(self, key), str) or not getattr(self, key):
                raise InvalidArgumentError(key, f"expected a non-empty string, got {getattr(self, key)!r}")
        for key in ("actuated", "cut"):
            flag = getattr(self, key)
            if not isinstance(flag, bool | np.bool_ | int | np.integer) or flag not in (0, 1):
                raise InvalidArgumentError(key, f"joint {self.name!r}: expected a bool, got {flag!r}")
            object.__setattr__(self, key, bool(flag))
        for key in ("origin", "child_offset"):
            t = real_array(getattr(self, key), key)
            if t.shape != (4, 4) or not np.all(np.isfinite(t)):
                raise InvalidArgumentError(key, f"joint {self.name!r}: expected a finite 4x4 transform")
            object.__setattr__(self, key, read_only(t))
        object.__setattr__(self, "axis", read_only(_unit(self.axis, f"axis (joint {self.name!r})")))
        object.__setattr__(self, "axis2", read_only(_unit(self.axis2, f"axis2 (joint {self.name!r})")))
        if self.mimic is not None:
            if not isinstance(self.mimic, Mimic):
                got = f"expected a Mimic, got {self.mimic!r}"
                raise InvalidArgumentError("mimic", f"joint {self.name!r}: {got}")
            if self.type not in ("revolute", "prismatic") or self.cut:
                raise InvalidArgumentError(
                    "mimic", f"joint {self.name!r}: only revolute and prismatic tree joints can mimic"
                )
            if self.mimic.joint == self.name:
                raise InvalidArgumentError("mimic", f"joint {self.name!r} cannot mimic itself")
        n = self.dof
        default = _DEFAULT_LIMIT.get(self.type, 0.0)
        lo = _limits(self.lower, "lower", self.name, -default, n)
        hi = _limits(self.upper, "upper", self.name, default, n)
        if len(lo) != n or len(hi) != n:
            raise LimitsError(
                "lower/upper", f"joint {self.name!r} has {n} coordinate(s), got {len(lo)}/{len(hi)} limits"
            )
        for a, b in zip(lo, hi, strict=True):
            if a > b:
                raise LimitsError("lower/upper", f"joint {self.name!r}: need lower <= upper, got {a} > {b}")
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)

    @property
    def dof(self) -> int:
        """Connectivity (number of coordinates when the joint is in the spanning tree); 0 for
        a mimic joint, whose motion is a function of another joint's coordinate."""
        return 0 if self.mimic is not None else JOINT_DOF[self.type]

    def coordinate_names(self) -> tuple[str, ...]:
        """Names of the joint's coordinates: the joint name, or ``name[i]`` for several."""
        if self.dof == 1:
            return (self.name,)
        return tuple(f"{self.name}[{i}]" for i in range(self.dof))

    def motion(self, q: Any) -> Any:
        """The joint's relative motion ``motion(q)`` as a 4x4 transform (numpy or CasADi)."""
        if self.type == "fixed":
            return np.eye(4)
        if self.type == "revolute":
            return spatial.transform(axis_rotation(self.axis, q[0]))
        if self.type == "prismatic":
            symbolic = spatial.is_symbolic(q[0])
            return spatial.transform(position=ca.DM(self.axis) * q[0] if symbolic else q[0] * self.axis)
        if self.type == "universal":
            r, r2 = axis_rotation(self.axis, q[0]), axis_rotation(self.axis2, q[1])
            return spatial.transform(spatial.matmul(r, r2))
        if self.type == "spherical":
            return spatial.transform(spatial.so3_exp(q))
        return spatial.transform(spatial.so3_exp(q[3:6]), q[0:3])
