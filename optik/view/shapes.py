"""Triangle meshes of the drawn links: capsule chains, plates, slides (numpy + trimesh).

A link is drawn as the *capsule chain* through the joint locations it carries: a sphere of
radius ``r`` at every point and a cylinder of radius ``r`` between consecutive points; a body
whose points enclose an area (a platform) also gets a flat plate, the triangle fan of its
outline. Vertices are in the body's own frame, so a link mesh is built once and then only
moved (``T_body(q)``).
"""

from __future__ import annotations

import itertools

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

__all__ = ["Mesh", "capsule_chain", "cylinder", "plate", "rotation", "wxyz"]

Mesh = tuple[np.ndarray, np.ndarray]
"""``(vertices (V, 3) float32, faces (F, 3) uint32)``."""

_SECTIONS = 16


def wxyz(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` of a 3x3 rotation matrix, or ``(n, 4)`` of ``(n, 3, 3)``."""
    xyzw = Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_quat()
    return np.roll(xyzw, 1, axis=-1)


def rotation(q_wxyz: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix of a quaternion ``(w, x, y, z)`` (normalized first)."""
    w, x, y, z = np.asarray(q_wxyz, dtype=float)
    return Rotation.from_quat([x, y, z, w]).as_matrix()


def _merge(parts: list[trimesh.Trimesh]) -> Mesh:
    m = trimesh.util.concatenate(parts)
    return np.asarray(m.vertices, dtype=np.float32), np.asarray(m.faces, dtype=np.uint32)


def cylinder(start: np.ndarray, end: np.ndarray, radius: float) -> Mesh:
    """A cylinder of ``radius`` from ``start`` to ``end`` (no caps needed: the chain puts spheres
    at the ends)."""
    return _merge([trimesh.creation.cylinder(radius=radius, segment=[start, end], sections=_SECTIONS)])


def capsule_chain(points: np.ndarray, radius: float, closed: bool = False) -> Mesh:
    """Spheres at ``points`` (``(k, 3)``, ``k >= 1``) and cylinders between consecutive points
    (and from the last back to the first when ``closed``)."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    parts = []
    for c in p:
        sphere = trimesh.creation.icosphere(subdivisions=2, radius=radius)
        sphere.apply_translation(c)
        parts.append(sphere)
    pairs = list(itertools.pairwise(p)) + ([(p[-1], p[0])] if closed and len(p) > 2 else [])
    for a, b in pairs:
        if np.linalg.norm(b - a) > 1e-9:
            parts.append(trimesh.creation.cylinder(radius=radius, segment=[a, b], sections=_SECTIONS))
    return _merge(parts)


def plate(outline: np.ndarray, thickness: float) -> Mesh:
    """A flat plate over an ordered planar outline (``(k, 3)``, ``k >= 3``): the triangle fan
    from the centroid, extruded by ``thickness`` along the outline's normal (both faces drawn)."""
    p = np.asarray(outline, dtype=float).reshape(-1, 3)
    c = p.mean(axis=0)
    normal = np.linalg.svd(p - c)[2][2]
    half = 0.5 * thickness * normal
    k = len(p)
    vertices = np.vstack([c + half, p + half, c - half, p - half])
    top = [(0, 1 + i, 1 + (i + 1) % k) for i in range(k)]
    bottom = [(k + 1, k + 2 + (i + 1) % k, k + 2 + i) for i in range(k)]
    rim = []
    for i in range(k):
        a, b = 1 + i, 1 + (i + 1) % k
        rim += [(a, a + k + 1, b), (b, a + k + 1, b + k + 1)]
    faces = np.array(top + bottom + rim, dtype=np.uint32)
    return vertices.astype(np.float32), faces
