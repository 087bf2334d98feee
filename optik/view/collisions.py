"""The viewer's collision layer: the robot's collision geometry, the world's objects, the colliding links.

`CollisionLayer` draws, in one viser scene:

* every collision part of the robot (`optik.collision.robot_geometry`: URDF ``<collision>``
  primitives, meshes as the convex hulls the checks use), one scene node per link moved by the
  link's pose ``T_link(q)``, the parts its children at their constant offsets; hidden until
  `CollisionLayer.set_shown` (the panel's "collision geometry" box);
* every object of the `optik.World` under a transform gizmo of its own: dragging it calls
  ``on_move(name, pose)`` (the viewer moves the object and solves IK again);
* the colliding links and objects in red: `CollisionLayer.update` runs the exact check
  (`optik.collision.check` at the viewer's margin) at every shown ``q``, and every part of a link
  in a pair closer than the margin is drawn red, and shown even while the geometry is hidden.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import trimesh

from optik import spatial
from optik.collision import World, check, robot_geometry
from optik.collision.check import CollisionReport
from optik.collision.shapes import Shape, shape_vertices
from optik.mechanism import Mechanism
from optik.view.shapes import rotation, wxyz

__all__ = ["CLEAR", "HIT", "OBJECT", "CollisionLayer", "shape_mesh"]

CLEAR = (150, 160, 175)
"""Colour of a collision part clear by the margin."""
HIT = (230, 40, 40)
"""Colour of a part of a link or object in a pair closer than the margin."""
OBJECT = (205, 175, 100)
"""Colour of a world object clear by the margin."""


def shape_mesh(shape: Shape) -> trimesh.Trimesh:
    """A triangle mesh of a collision shape in its own frame: the primitives as built by trimesh,
    a mesh as its convex hull (what the checks use), a point cloud as one ball per point."""
    s = shape.size
    if shape.kind == "box":
        return trimesh.creation.box(extents=s)
    if shape.kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=2, radius=s[0])
    if shape.kind == "cylinder":
        return trimesh.creation.cylinder(radius=s[0], height=s[1], sections=24)
    if shape.kind == "capsule":
        return trimesh.creation.capsule(height=s[1], radius=s[0], count=[12, 12])
    points, radius = shape_vertices(shape)
    if shape.kind == "mesh":
        return trimesh.convex.convex_hull(points)
    balls = []
    for p in points:
        ball = trimesh.creation.icosphere(subdivisions=1, radius=radius)
        ball.apply_translation(p)
        balls.append(ball)
    return trimesh.util.concatenate(balls)


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


class CollisionLayer:
    """Collision geometry, world objects and colliding links of one robot in a viser scene.

    Args:
        scene: the `viser.SceneApi`.
        m: the mechanism (with collision geometry).
        q: the first configuration.
        world: the obstacles (None: none).
        margin: the clearance (m) below which a pair counts as colliding (the robot against
            itself, its allowed-collision matrix aside, and against the world).
        on_move: ``on_move(name, pose)`` when the page drags object ``name`` to ``pose`` (4x4).
        gizmo_scale: size of the objects' gizmos (m).

    Raises:
        InvalidArgumentError: ``m`` has no collision geometry.
    """

    def __init__(
        self,
        scene: Any,
        m: Mechanism,
        q: np.ndarray,
        world: World | None,
        margin: float,
        on_move: Callable[[str, np.ndarray], Any],
        gizmo_scale: float,
    ) -> None:
        self.scene, self.m, self.world = scene, m, world
        self.margin = margin
        self.geo = robot_geometry(m)
        self.shown = False
        self._links = [
            scene.add_frame(f"/collision/{_safe(link)}", show_axes=False) for link in self.geo.links
        ]
        self.parts: list[tuple[str, Any]] = []
        """``(link, mesh handle)`` of every robot part, in the order of the geometry's parts."""
        for k, part in enumerate(self.geo.parts):
            link = self.geo.links[self.geo.part_link[k]]
            mesh = shape_mesh(part.shape)
            mesh.apply_transform(part.offset)
            self.parts.append((link, self._mesh(f"/collision/{_safe(link)}/part_{k}", mesh, CLEAR, False)))
        self.gizmos: dict[str, Any] = {}
        """The gizmo of every world object, by name (its mesh is its child)."""
        self.objects: dict[str, Any] = {}
        """The mesh handle of every world object, by name."""
        for o in world.snapshot() if world is not None else ():
            node = f"/world/{_safe(o.name)}"
            gizmo = scene.add_transform_controls(
                node, scale=gizmo_scale, position=o.pose[:3, 3], wxyz=wxyz(o.pose[:3, :3]), depth_test=False
            )
            self.gizmos[o.name] = gizmo
            self.objects[o.name] = self._mesh(f"{node}/shape", shape_mesh(o.shape), OBJECT, True)
            gizmo.on_update(self._dragged(o.name, gizmo, on_move))
        self.report: CollisionReport | None = None
        """The exact check of the shown configuration."""
        self.colliding: frozenset[str] = frozenset()
        """Links and objects in a pair closer than the margin at the shown configuration."""
        self.update(q)

    def _mesh(self, node: str, mesh: trimesh.Trimesh, color: tuple[int, int, int], visible: bool) -> Any:
        return self.scene.add_mesh_simple(
            node,
            np.asarray(mesh.vertices, dtype=np.float32),
            np.asarray(mesh.faces, dtype=np.uint32),
            color=color,
            opacity=0.6,
            side="double",
            visible=visible,
            cast_shadow=False,
            receive_shadow=False,
        )

    @staticmethod
    def _dragged(name: str, gizmo: Any, on_move: Callable[[str, np.ndarray], Any]) -> Callable[[Any], None]:
        """The gizmo callback: the page's drags only (assignments from Python run it with no client)."""

        def moved(event: Any) -> None:
            if event.client is not None:
                on_move(
                    name, spatial.transform(rotation(gizmo.wxyz), np.asarray(gizmo.position, dtype=float))
                )

        return moved

    def place(self, name: str, pose: np.ndarray) -> None:
        """Put object ``name``'s gizmo (and so its mesh) at ``pose``."""
        gizmo = self.gizmos[name]
        gizmo.position, gizmo.wxyz = pose[:3, 3], wxyz(pose[:3, :3])

    def update(self, q: np.ndarray) -> CollisionReport:
        """Move the parts to ``q``, run the exact check and colour what collides; returns the report."""
        poses = self.geo.link_poses(q)
        for handle, t in zip(self._links, poses, strict=True):
            handle.position, handle.wxyz = t[:3, 3], wxyz(t[:3, :3])
        report = check(self.m, q, self.world, self.margin)
        hit = frozenset(name for p in report.close_pairs for name in (p.a, p.b))
        self.report, self.colliding = report, hit
        self._paint()
        return report

    def set_shown(self, on: bool) -> None:
        """Show every collision part (True) or only those of colliding links (False)."""
        self.shown = bool(on)
        self._paint()

    def _paint(self) -> None:
        for link, handle in self.parts:
            red = link in self.colliding
            handle.color = HIT if red else CLEAR
            handle.visible = self.shown or red
        for name, handle in self.objects.items():
            handle.color = HIT if name in self.colliding else OBJECT
