"""`World`: the obstacles around a robot, each a named `Shape` at a pose in the robot's base frame.

```python
W = optik.World()
W.add_box("table", (1.0, 1.2, 0.04), optik.spatial.translation(0.5, 0.0, -0.02))
W.add_sphere("ball", 0.05, optik.spatial.translation(0.4, 0.2, 0.3))
W.move("ball", optik.spatial.translation(0.4, -0.2, 0.3))
W.remove("ball")
```

Poses are 4x4 homogeneous transforms of the shape's frame (see `optik.collision.shapes`) in the
base frame of the mechanism it is checked against (default: the identity). A world is safe to
share between threads: every change takes a lock and makes a new immutable `snapshot`, which
is what the checks and the solvers read (a check runs against the world as it was when it
started). `World.state` is that version with what the checks and solvers derive from it (coal
parts, their transforms, the slot values of `optik.collision.slots`), made once per change, so a
solve that reads it once sees one version throughout. `World.from_table` builds one from the
``[world]`` table of a problem file.
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from optik import spatial
from optik.checks import as_float, as_name, as_transform, as_vector, real_array
from optik.collision.distance import coal_transform
from optik.collision.parts import Part, parts_of
from optik.collision.shapes import Shape
from optik.collision.slots import capacity_for, slot_values
from optik.errors import InvalidArgumentError, UnknownFrameError

__all__ = ["Obstacle", "World", "WorldState", "state_of"]


@dataclass(frozen=True)
class Obstacle:
    """One object of a world.

    Attributes:
        name: its name in the world.
        shape: its geometry.
        pose: 4x4 pose of the shape's frame in the base frame.
    """

    name: str
    shape: Shape
    pose: np.ndarray


@dataclass(frozen=True, eq=False)
class WorldState:
    """One version of a world and what the checks and solvers derive from it.

    Attributes:
        version: the `World.version` it was made at.
        parts: the coal parts of the objects (a point cloud gives one per point).
        transforms: coal's transform of each part's pose.
        capacity: its slot capacity (`optik.collision.slots.capacity_for` of the number of parts).
        slots: the parts' slot values (`optik.collision.slots.slot_values`, read-only).
    """

    version: int
    parts: tuple[Part, ...]
    transforms: tuple[Any, ...] = field(repr=False)
    capacity: int
    slots: np.ndarray = field(repr=False)

    @classmethod
    def of(cls, version: int, parts: tuple[Part, ...]) -> WorldState:
        """The state of ``parts`` (their transforms and slot values computed here)."""
        capacity = capacity_for(len(parts))
        slots = slot_values(parts, capacity)
        slots.flags.writeable = False
        return cls(version, parts, tuple(coal_transform(p.offset) for p in parts), capacity, slots)


@functools.cache
def _empty() -> WorldState:
    return WorldState.of(0, ())


def state_of(world: World | None) -> WorldState:
    """``world.state()``, or the state of an empty world for None.

    Raises:
        InvalidArgumentError: ``world`` is neither a `World` nor None.
    """
    if world is None:
        return _empty()
    if not isinstance(world, World):
        raise InvalidArgumentError("world", f"expected an optik.World or None, got {type(world).__name__}")
    return world.state()


class World:
    """Named obstacles (boxes, spheres, cylinders, capsules, convex meshes, point clouds).

    ``len(W)`` is the number of objects, ``W.names`` their names in insertion order, ``name in W``
    tests one. Adding a name that exists raises (use `move` to change a pose).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._objects: dict[str, Obstacle] = {}
        self._snapshot: tuple[Obstacle, ...] = ()
        self._version = 0
        self._state: WorldState | None = None

    # ------------------------------------------------------------------ building
    def _add(self, name: Any, shape: Shape, pose: Any) -> None:
        key = as_name(name, "name")
        t = np.eye(4) if pose is None else as_transform(pose, "pose").copy()
        t.flags.writeable = False
        with self._lock:
            if key in self._objects:
                raise InvalidArgumentError(
                    "name", f"the world has an object {key!r} already (move or remove it)"
                )
            self._objects[key] = Obstacle(key, shape, t)
            self._changed()

    def _changed(self) -> None:
        self._snapshot = tuple(self._objects.values())
        self._version += 1

    def add_box(self, name: str, size: Any, pose: Any = None) -> None:
        """A box of edge lengths ``size = (x, y, z)`` centred at ``pose``."""
        self._add(name, Shape("box", tuple(as_vector(size, "size", 3))), pose)

    def add_sphere(self, name: str, radius: float, pose: Any = None) -> None:
        """A sphere of ``radius`` centred at ``pose``."""
        self._add(name, Shape("sphere", (as_float(radius, "radius"),)), pose)

    def add_cylinder(self, name: str, radius: float, length: float, pose: Any = None) -> None:
        """A cylinder of ``radius`` and ``length`` along the z axis of ``pose``, centred there."""
        self._add(name, Shape("cylinder", (as_float(radius, "radius"), as_float(length, "length"))), pose)

    def add_capsule(self, name: str, radius: float, length: float, pose: Any = None) -> None:
        """The points within ``radius`` of the z segment of ``length`` centred at ``pose``."""
        self._add(name, Shape("capsule", (as_float(radius, "radius"), as_float(length, "length"))), pose)

    def add_mesh(self, name: str, path: str | os.PathLike[str], pose: Any = None, scale: Any = 1.0) -> None:
        """The convex hull of a mesh file (STL, OBJ, DAE, ... as coal's loader reads them), scaled
        by ``scale`` (one factor or one per axis)."""
        s = np.broadcast_to(as_vector(np.atleast_1d(np.asarray(scale, dtype=float)), "scale"), (3,))
        if not isinstance(path, (str, os.PathLike)) or not Path(path).is_file():
            raise InvalidArgumentError("path", f"no mesh file {path!r}")
        self._add(name, Shape("mesh", tuple(s), path=Path(path)), pose)

    def add_points(self, name: str, xyz: Any, radius: float) -> None:
        """A point cloud: a sphere of ``radius`` around each row of ``xyz`` (``(N, 3)``, base frame)."""
        pts = real_array(xyz, "xyz")
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise InvalidArgumentError("xyz", f"expected (N, 3) points, N >= 1, got shape {pts.shape}")
        self._add(name, Shape("points", (as_float(radius, "radius"),), points=pts), None)

    def move(self, name: str, pose: Any) -> None:
        """Place object ``name`` at ``pose``.

        Raises:
            UnknownFrameError: no such object.
        """
        t = as_transform(pose, "pose").copy()
        t.flags.writeable = False
        with self._lock:
            obj = self._get(name)
            self._objects[obj.name] = Obstacle(obj.name, obj.shape, t)
            self._changed()

    def remove(self, name: str) -> None:
        """Remove object ``name``.

        Raises:
            UnknownFrameError: no such object.
        """
        with self._lock:
            del self._objects[self._get(name).name]
            self._changed()

    def _get(self, name: Any) -> Obstacle:
        key = as_name(name, "name")
        if key not in self._objects:
            raise UnknownFrameError("name", f"no object {key!r} in the world; objects: {list(self._objects)}")
        return self._objects[key]

    # ------------------------------------------------------------------ reading
    @property
    def names(self) -> tuple[str, ...]:
        """The objects' names, in insertion order."""
        return tuple(o.name for o in self._snapshot)

    def __len__(self) -> int:
        return len(self._snapshot)

    def __contains__(self, name: object) -> bool:
        return any(o.name == name for o in self._snapshot)

    def __getitem__(self, name: str) -> Obstacle:
        with self._lock:
            return self._get(name)

    def snapshot(self) -> tuple[Obstacle, ...]:
        """The objects as they are now (immutable: later changes make a new tuple)."""
        return self._snapshot

    def parts(self) -> tuple[Part, ...]:
        """The coal parts of the objects as they are now (built once per change)."""
        return self.state().parts

    def state(self) -> WorldState:
        """The world as it is now with its derived data (`WorldState`, built once per change)."""
        with self._lock:
            version, snapshot, state = self._version, self._snapshot, self._state
        if state is not None and state.version == version:
            return state
        parts = tuple(p for o in snapshot for p in parts_of(o.name, o.shape, np.asarray(o.pose)))
        state = WorldState.of(version, parts)
        with self._lock:
            if self._version == version:
                self._state = state
        return state

    @property
    def version(self) -> int:
        """A counter that every change increments (caches of derived data compare it)."""
        return self._version

    def __repr__(self) -> str:
        return f"World({', '.join(f'{o.name}: {o.shape.kind}' for o in self._snapshot)})"

    # ------------------------------------------------------------------ problem files
    @classmethod
    def from_table(cls, table: Mapping[str, Any], folder: str | os.PathLike[str] | None = None) -> World:
        """A world from the ``[world]`` table of a problem file: one sub-table per object.

        ```toml
        [world.table]
        box = [1.0, 1.2, 0.04]          # or sphere = r, cylinder = [r, length],
        xyz = [0.5, 0.0, -0.02]         # capsule = [r, length], mesh = "file.stl",
        rpy = [0.0, 0.0, 0.0]           # points = [[x, y, z], ...] with radius = r
        ```

        ``xyz`` (metres) and ``rpy`` (radians, URDF's roll-pitch-yaw) place it (default 0);
        ``scale`` scales a mesh, whose path is relative to ``folder`` (the problem file's).

        Raises:
            InvalidArgumentError: an object with no shape key or two, an unknown key or a bad
                value (named ``world.<object>.<key>``).
        """
        world = cls()
        kinds = ("box", "sphere", "cylinder", "capsule", "mesh", "points")
        for name, spec in table.items():
            where = f"world.{name}"
            if not isinstance(spec, Mapping):
                raise InvalidArgumentError(where, f"expected a table [{where}], got {spec!r}")
            unknown = set(spec) - {*kinds, "xyz", "rpy", "scale", "radius"}
            if unknown:
                raise InvalidArgumentError(where, f"unknown keys {sorted(unknown)}")
            given = [k for k in kinds if k in spec]
            if len(given) != 1:
                raise InvalidArgumentError(where, f"give exactly one shape key of {kinds}, got {given}")
            kind = given[0]
            xyz = as_vector(spec.get("xyz", (0.0, 0.0, 0.0)), f"{where}.xyz", 3)
            rpy = as_vector(spec.get("rpy", (0.0, 0.0, 0.0)), f"{where}.rpy", 3)
            pose = spatial.transform(spatial.rpy_to_rot(*rpy), xyz)
            value = spec[kind]
            if kind == "box":
                world.add_box(name, value, pose)
            elif kind == "sphere":
                world.add_sphere(name, value, pose)
            elif kind in ("cylinder", "capsule"):
                r, length = as_vector(value, f"{where}.{kind}", 2)
                getattr(world, f"add_{kind}")(name, r, length, pose)
            elif kind == "mesh":
                path = Path(str(value))
                if not path.is_absolute() and folder is not None:
                    path = Path(folder) / path
                world.add_mesh(name, path, pose, spec.get("scale", 1.0))
            else:
                if "radius" not in spec:
                    raise InvalidArgumentError(where, "points need a radius")
                pts = real_array(value, f"{where}.points")
                if pts.ndim != 2 or pts.shape[1:] != (3,):
                    raise InvalidArgumentError(f"{where}.points", f"expected (N, 3) points, got {pts.shape}")
                world.add_points(name, pts @ pose[:3, :3].T + pose[:3, 3], spec["radius"])
        return world
