"""The ``<visual>`` and ``<collision>`` elements of URDF links (never used by the kinematics).

Visuals are kept for drawing, collision elements for `optik.collision` (same fields, read by
the same `read_visuals` with ``tag="collision"``).

Each visual is a `Visual`: the link it belongs to (a named frame of the mechanism), its pose in
that link's frame (``<origin>``), and its geometry: a ``mesh`` (``filename`` as written, e.g.
``package://pkg/meshes/a.stl`` or ``meshes/a.stl``, with ``scale``), a ``box`` (``size``), a
``cylinder`` (``radius``, ``length``) or a ``sphere`` (``radius``). Drawing a visual at ``q``
means placing its geometry at ``m.fk(q, frame=visual.link) @ visual.origin``.

Mesh files are located, when possible, by `resolve_mesh`: a relative name against the URDF's
folder, ``package://PKG/rest`` against ``$ROS_PACKAGE_PATH`` entries, the folders above the
URDF file and the ``share`` folder of ROS packages installed by pip (`cmeel_share`, e.g.
example-robot-data's) (a folder named ``PKG``, or holding a ``PKG`` folder), ``file://`` as a
path. The
answer is ``Visual.path`` (None when the file was not found; the name is kept either way).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["GEOMETRIES", "Visual", "read_visuals", "resolve_mesh"]

GEOMETRIES = ("mesh", "box", "cylinder", "sphere")
"""URDF geometry elements."""


@dataclass(frozen=True)
class Visual:
    """One ``<visual>`` of a link.

    Attributes:
        link: the link (a frame of the mechanism).
        origin: 4x4 pose of the geometry in the link frame.
        geometry: ``"mesh"``, ``"box"``, ``"cylinder"`` or ``"sphere"``; ``"capsule"`` too for
            MJCF geoms (`optik.mechanism.mjcf`).
        filename: the mesh file name as written in the URDF (None for other geometries).
        path: the mesh file found on disk (None if not found or not a mesh).
        scale: scale factors along x, y, z (of a mesh; of a unit sphere for an MJCF ellipsoid).
        size: box edge lengths ``(x, y, z)``, ``(radius, length)`` of a cylinder or of a
            capsule's cylindrical part (along z),
            ``(radius,)`` of a sphere, ``()`` for a mesh.
    """

    link: str
    origin: np.ndarray
    geometry: str
    filename: str | None = None
    path: Path | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    size: tuple[float, ...] = ()


def cmeel_share() -> Path | None:
    """The first ``cmeel.prefix/share`` folder of a ``sys.path`` entry (``site-packages``):
    where pip installs ROS packages built with cmeel (example-robot-data, the Pinocchio stack),
    or None when there is none."""
    shares = (Path(entry) / "cmeel.prefix" / "share" for entry in sys.path if entry)
    return next((s for s in shares if s.is_dir()), None)


def resolve_mesh(filename: str, folder: Path | None) -> Path | None:
    """The mesh file a URDF ``filename`` refers to, or None when it cannot be found.

    Args:
        filename: ``package://PKG/rest``, ``file:///abs/path`` or a path (relative to the URDF).
        folder: the URDF file's folder (None for URDF text: only absolute names resolve).
    """
    if filename.startswith("file://"):
        candidates = [Path(filename[len("file://") :])]
    elif filename.startswith("package://"):
        # "package:///pkg/..." (an extra slash, e.g. TALOS in example-robot-data) names pkg too
        package, _, rest = filename[len("package://") :].lstrip("/").partition("/")
        roots = [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
        if folder is not None:
            roots += [folder, *folder.parents]
        share = cmeel_share()
        roots += [share] if share is not None else []
        candidates = [root / rest for root in roots if root.name == package]
        candidates += [root / package / rest for root in roots]
    else:
        path = Path(filename)
        candidates = [path] if path.is_absolute() else ([folder / path] if folder is not None else [])
    return next((c for c in candidates if c.is_file()), None)


def read_visuals(
    links: Iterable[Any],
    pose: Callable[[Any, str], np.ndarray],
    numbers: Callable[[str, str | None, int, tuple[float, ...]], np.ndarray],
    folder: Path | None,
    tag: str = "visual",
) -> tuple[Visual, ...]:
    """The ``<visual>`` (or ``<collision>``) elements of the given ``<link>`` elements, in
    document order.

    Args:
        links: the ``<link>`` elements to read.
        pose: ``pose(element, where)``: the 4x4 of an element's ``<origin>`` child.
        numbers: ``numbers(where, text, n, default)``: ``n`` finite floats of an attribute
            (raising the URDF reader's `ModelError` that names the file).
        folder: the URDF file's folder, for `resolve_mesh`.
        tag: ``"visual"`` or ``"collision"``.

    Unknown geometries and visuals without a geometry are skipped (they draw nothing).
    """
    out: list[Visual] = []
    for link in links:
        name = link.get("name")
        for i, vis in enumerate(link.findall(tag)):
            where = f"link {name!r} <{tag}> {i}"
            geom = vis.find("geometry")
            shape = next((g for g in ([] if geom is None else list(geom)) if g.tag in GEOMETRIES), None)
            if shape is None:
                continue
            origin = pose(vis, where)
            kind = shape.tag
            if kind == "mesh":
                filename = shape.get("filename") or ""
                scale = numbers(f"{where} <mesh scale>", shape.get("scale"), 3, (1.0, 1.0, 1.0))
                out.append(
                    Visual(
                        name,
                        origin,
                        kind,
                        filename,
                        resolve_mesh(filename, folder) if filename else None,
                        (float(scale[0]), float(scale[1]), float(scale[2])),
                    )
                )
                continue
            if kind == "box":
                size = numbers(f"{where} <box size>", shape.get("size"), 3, (0.0, 0.0, 0.0))
            elif kind == "cylinder":
                r = numbers(f"{where} <cylinder radius>", shape.get("radius"), 1, (0.0,))
                length = numbers(f"{where} <cylinder length>", shape.get("length"), 1, (0.0,))
                size = np.concatenate([r, length])
            else:
                size = numbers(f"{where} <sphere radius>", shape.get("radius"), 1, (0.0,))
            out.append(Visual(name, origin, kind, size=tuple(float(v) for v in size)))
    return tuple(out)
