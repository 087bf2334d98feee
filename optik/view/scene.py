"""The drawn mechanism: link meshes, prismatic slides, joint frames and the end effector.

Every pose comes from the mechanism's CasADi model, one compiled function per mechanism:

``q -> (T_b(q) for every body b, A_j(q) = T_parent(q) origin_j for every joint j,
p(B_j(q)) = p(T_child(q) child_offset_j), T_ee(q))``.

A link is the capsule chain through the joint locations its body carries (the same points the
matplotlib figures use, `optik.plot.body_points`), built once in the body frame,
``p_local = T_b(q0)^-1 p``, and moved by ``T_b(q)``; a body whose points enclose an area is a
plate. A prismatic joint's slide ``A_j -> B_j`` changes length with ``q`` and is rebuilt on
every update. Joint frames are drawn at ``A_j`` (orange: actuated, grey: passive).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.plot import Geometry, body_points, ordered_outline
from optik.view.shapes import Mesh, capsule_chain, cylinder, plate, wxyz

__all__ = ["Poses", "RobotDrawing", "Style", "poses"]

_FUNCTIONS: PerMechanism[ca.Function] = PerMechanism()


@dataclass(frozen=True)
class Poses:
    """Poses of one configuration.

    Attributes:
        bodies: ``{body: 4x4 T_b}``.
        joint_frames: ``(J, 4, 4)`` parent-side joint frames ``A_j``.
        child_side: ``(J, 3)`` origins of the child-side joint frames ``B_j``.
        ee: 4x4 pose of the end-effector frame.
    """

    bodies: dict[str, np.ndarray]
    joint_frames: np.ndarray
    child_side: np.ndarray
    ee: np.ndarray

    def geometry(self) -> Geometry:
        """The joint locations as an `optik.plot.Geometry`."""
        return Geometry(self.joint_frames[:, :3, 3], self.child_side, self.ee)


def _function(m: Mechanism) -> ca.Function:
    f = _FUNCTIONS.get(m)
    if f is None:
        t = m.body_transforms
        bodies = [t[b] for b in m.topology.bodies]
        frames = [ca.mtimes(t[j.parent], ca.DM(j.origin)) for j in m.joints]
        child = [ca.mtimes(t[j.child], ca.DM(j.child_offset))[:3, 3] for j in m.joints]
        outputs = [ca.horzcat(*bodies), ca.horzcat(*frames), ca.horzcat(*child), m.frame_expr()]
        f = ca.Function("view_poses", [m.q_sym], outputs)
        _FUNCTIONS[m] = f
    return f


def _stack(block: Any, n: int) -> np.ndarray:
    """``4 x 4n`` horizontal blocks -> ``(n, 4, 4)``."""
    return np.asarray(block).reshape(4, n, 4).transpose(1, 0, 2)


def poses(m: Mechanism, q: Any) -> Poses:
    """Body poses, joint frames and end effector of ``m`` at ``q``.

    Raises:
        ShapeError, NonFiniteError: ``q`` is not a finite vector of ``m.n_q`` values.
    """
    t_b, t_a, p_b, t_ee = _function(m)(m.check_q(q))
    names = m.topology.bodies
    bodies = dict(zip(names, _stack(t_b, len(names)), strict=True))
    return Poses(bodies, _stack(t_a, len(m.joints)), np.asarray(p_b).T, np.asarray(t_ee))


def extent(m: Mechanism, q: Any) -> float:
    """Size of the mechanism at ``q``: the largest span of its joint locations (>= 1 mm)."""
    pts = poses(m, q).geometry().points()
    return float(max(np.max(np.ptp(pts, axis=0)), 1e-3))


@dataclass(frozen=True)
class Style:
    """Colours (RGB 0-255), opacity and sizes of a drawing.

    Attributes:
        link: colour of the moving links.
        ground: colour of the base body.
        slide: colour of the prismatic slides.
        opacity: 1 for the displayed configuration, below 1 for ghosts.
        frames: draw joint frames and the end-effector frame.
        radius: link radius (m).
    """

    link: tuple[int, int, int] = (90, 150, 210)
    ground: tuple[int, int, int] = (120, 120, 120)
    slide: tuple[int, int, int] = (200, 90, 60)
    opacity: float = 1.0
    frames: bool = True
    radius: float = 0.02


def _safe(name: str) -> str:
    """A body or joint name as one scene-node path segment."""
    return name.replace("/", "_")


_ACTUATED = (235, 130, 20)
_PASSIVE = (170, 170, 170)


class RobotDrawing:
    """One configuration of a mechanism in a viser scene, under the node ``name``.

    Args:
        scene: the `viser.SceneApi` to draw into.
        m: the mechanism.
        q: first configuration.
        name: scene-node prefix (e.g. ``"/robot"``, ``"/ghosts/3"``).
        style: colours, opacity, sizes.
        visuals: ``{body: mesh in body coordinates}`` drawn instead of the capsule chain of those
            bodies (`optik.view.visuals.body_visuals`: URDF visuals).
    """

    def __init__(
        self, scene: Any, m: Mechanism, q: Any, name: str, style: Style, visuals: dict[str, Any] | None = None
    ) -> None:
        self.scene, self.m, self.name, self.style = scene, m, name, style
        p = poses(m, q)
        g = p.geometry()
        r = style.radius
        # one scene node per body, moved by T_b(q); its link mesh and the joint frames it carries
        # are children with constant poses, so an update sends one pose per moving body
        self._bodies = {b: scene.add_frame(self._node(b), show_axes=False) for b in m.topology.bodies}
        self.visual_bodies = tuple(b for b in m.topology.bodies if visuals and b in visuals)
        """Bodies drawn with their URDF visuals (the others are capsule chains)."""
        for body in m.topology.bodies:
            if body in self.visual_bodies:
                scene.add_mesh_trimesh(
                    f"{self._node(body)}/visual", visuals[body], cast_shadow=False, receive_shadow=False
                )
                continue
            pts = body_points(m, g, body)
            if body == m.base and len(pts) == 1:
                pts = [np.zeros(3), *pts]  # a pedestal from the base origin to the first joint
            if not pts or (len(pts) == 1 and body != m.base):
                continue
            inv = np.linalg.inv(p.bodies[body])
            local = (inv[:3, :3] @ np.array(pts).T).T + inv[:3, 3]
            mesh = self._link_mesh(local, r, body == m.base)
            color = style.ground if body == m.base else style.link
            self._mesh(f"{self._node(body)}/link", mesh, color)
        self._slides = [k for k, j in enumerate(m.joints) if j.type == "prismatic" and not j.cut]
        self._slide_handles: dict[int, Any] = {}
        self._visible = True
        if style.frames:
            size = 2.5 * r
            for j in m.joints:
                color = _ACTUATED if j.actuated and not j.cut else _PASSIVE
                scene.add_frame(
                    f"{self._node(j.parent)}/joint_{_safe(j.name)}",
                    axes_length=size,
                    axes_radius=0.12 * size,
                    origin_radius=1.6 * r,
                    origin_color=color,
                    position=j.origin[:3, 3],
                    wxyz=wxyz(j.origin[:3, :3]),
                )
            body, offset = m.frames[m.ee]
            scene.add_frame(
                f"{self._node(body)}/ee",
                axes_length=8 * r,
                axes_radius=0.6 * r,
                position=offset[:3, 3],
                wxyz=wxyz(offset[:3, :3]),
            )
        self._moving = [b for b in m.topology.bodies if b != m.base]
        self.update(q)

    def _node(self, body: str) -> str:
        return f"{self.name}/{_safe(body)}"

    @staticmethod
    def _link_mesh(local: np.ndarray, r: float, ground: bool) -> Mesh:
        ordered, area = ordered_outline(list(local))
        chain = capsule_chain(ordered, (0.6 if ground else 1.0) * r, closed=area)
        if not area:
            return chain
        slab = plate(ordered, 0.8 * r)
        return np.vstack([chain[0], slab[0]]), np.vstack([chain[1], slab[1] + len(chain[0])])

    def _mesh(self, node: str, mesh: Mesh, color: tuple[int, int, int], visible: bool = True) -> Any:
        opacity = None if self.style.opacity >= 1 else self.style.opacity
        return self.scene.add_mesh_simple(
            node,
            mesh[0],
            mesh[1],
            color=color,
            opacity=opacity,
            side="double",
            visible=visible,
            cast_shadow=False,
            receive_shadow=False,
        )

    def update(self, q: Any) -> Poses:
        """Move the drawing to configuration ``q``; returns its poses."""
        p = poses(self.m, q)
        t = np.array([p.bodies[b] for b in self._moving]).reshape(-1, 4, 4)
        for body, position, quaternion in zip(self._moving, t[:, :3, 3], wxyz(t[:, :3, :3]), strict=True):
            handle = self._bodies[body]
            handle.position, handle.wxyz = position, quaternion
        for k in self._slides:
            mesh = cylinder(p.joint_frames[k, :3, 3], p.child_side[k], 0.7 * self.style.radius)
            node = f"{self.name}/slides/{_safe(self.m.joints[k].name)}"
            self._slide_handles[k] = self._mesh(node, mesh, self.style.slide, self._visible)
        return p

    def set_visible(self, visible: bool) -> None:
        """Show or hide the whole drawing."""
        self._visible = visible
        for handle in self._handles():
            handle.visible = visible

    @property
    def visible(self) -> bool:
        """Whether the drawing is shown."""
        return self._visible

    def _handles(self) -> list[Any]:
        return [*self._bodies.values(), *self._slide_handles.values()]

    def remove(self) -> None:
        """Remove the drawing from the scene."""
        for handle in self._handles():
            handle.remove()
