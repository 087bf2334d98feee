"""URDF visuals as drawable meshes, each in the frame of the body that carries it.

A mechanism loaded from a URDF keeps its ``<visual>`` elements in ``m.params["visuals"]`` (see
`optik.mechanism.urdf_visuals`): a link (a named frame ``(body, offset)`` of the mechanism), the
geometry's pose ``origin`` in that link frame and the geometry. Its vertices in the body frame
are ``offset @ origin @ (scale * v)``. Meshes are read by trimesh (STL, OBJ, PLY, COLLADA with
pycollada, ...); boxes, cylinders, capsules and spheres are built (MJCF geoms too: see
`optik.mechanism.mjcf`). A visual that cannot be drawn (file not
found, unreadable, empty) is reported in the notes, and its body is drawn as a capsule chain.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import trimesh

from optik.mechanism import Mechanism

__all__ = ["body_visuals"]


def _geometry(visual: Any) -> trimesh.Trimesh:
    kind, size = visual.geometry, visual.size
    if kind == "box":
        mesh = trimesh.creation.box(extents=size)
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=size[0], height=size[1], sections=24)
    elif kind == "capsule":
        mesh = trimesh.creation.capsule(height=size[1], radius=size[0], count=[12, 12])
    elif kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=size[0])
    else:
        mesh = trimesh.load(visual.path, force="mesh")
    mesh.apply_scale(visual.scale)
    return mesh


def body_visuals(m: Mechanism) -> tuple[dict[str, trimesh.Trimesh], list[str]]:
    """The URDF visuals of ``m`` merged per body, in body coordinates, and one note per visual
    that is not drawn (with the reason). ``({}, [])`` for a mechanism without visuals."""
    parts: dict[str, list[trimesh.Trimesh]] = {}
    notes: list[str] = []
    for v in m.params.get("visuals", ()):
        where = f"link {v.link!r} {v.geometry}" + (f" {v.filename}" if v.filename else "")
        if v.link not in m.frames:
            notes.append(f"{where}: the link is not part of this chain")
            continue
        if v.geometry == "mesh" and v.path is None:
            notes.append(f"{where}: file not found")
            continue
        try:
            mesh = _geometry(v)
        except Exception as exc:  # trimesh raises many types for unreadable files
            notes.append(f"{where}: not readable ({type(exc).__name__}: {exc})")
            continue
        if len(mesh.faces) == 0:
            notes.append(f"{where}: empty mesh")
            continue
        body, offset = m.frames[v.link]
        mesh.apply_transform(np.asarray(offset, dtype=float) @ np.asarray(v.origin, dtype=float))
        parts.setdefault(body, []).append(mesh)
    return {b: trimesh.util.concatenate(p) if len(p) > 1 else p[0] for b, p in parts.items()}, notes
