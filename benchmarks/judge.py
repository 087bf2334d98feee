"""The independent judge of the collision benchmarks: Pinocchio + coal re-check every claimed success.

`PinocchioJudge` is Pinocchio's own model of the whole URDF (joints outside the solved mechanism
held at their neutral value, zero for revolute and prismatic joints) and its collision geometry
(``buildGeomFromUrdf``, meshes as their convex hulls, as coal queries them). Its self pairs are
``addAllCollisionPairs`` minus the SRDF's (``removeCollisionPairs``) minus those no solved joint moves
apart: both geometries moved by the same set of solved joints (TALOS's torso and its right arm held
at zero, say) keep a constant distance whatever the solver answers. Every geometry is also paired
with every obstacle of the world, if any. An answer ``q`` succeeds when it lies within the limits,
puts every target frame within ``tol`` of its target (position ``|p - p*| <= tol`` in m, orientation
angle ``angle(R*^T R) <= tol`` in rad, by Pinocchio's FK) and every pair's coal distance is
``d >= margin - 1e-9``. It is used by ``optik benchmark collision`` (the Panda among obstacles) and
``optik benchmark collision_self`` (the dual Panda and TALOS near their own bodies).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

import optik
from optik import spatial
from optik.harness.peers.rules import settle

Targets = Mapping[str, np.ndarray]
"""A target pose (4x4) for each judged frame."""


class PinocchioJudge:
    """Pinocchio + coal on Pinocchio's own model of the whole URDF, its SRDF and a world.

    Args:
        m: the solved mechanism; its coordinates, by name, are the URDF joints an answer sets.
        urdf, srdf: the robot's files.
        frames: the frames whose poses are judged (a bare 4x4 target is the pose of the only one).
        package_dir: where the URDF's ``package://`` meshes are found (default
            `optik.mechanism.urdf_visuals.cmeel_share`, where example-robot-data installs).
        world: the obstacles (none by default; `PinocchioJudge.set_world` replaces them).
    """

    def __init__(
        self,
        m: optik.Mechanism,
        urdf: str | Path,
        srdf: str | Path,
        frames: Sequence[str],
        package_dir: str | Path | None = None,
        world: optik.World | None = None,
    ) -> None:
        import coal
        import pinocchio as pin

        from optik.mechanism.urdf_visuals import cmeel_share

        self.pin, self.coal, self.m = pin, coal, m
        self.model = model = pin.buildModelFromUrdf(str(urdf))
        package = cmeel_share() if package_dir is None else package_dir
        self.geom = pin.buildGeomFromUrdf(
            model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(package)]
        )
        self.geom.addAllCollisionPairs()
        pin.removeCollisionPairs(model, self.geom, str(srdf))
        self.index = [model.idx_qs[model.getJointId(name)] for name in m.coordinate_names]
        solved = {model.getJointId(name) for name in m.coordinate_names}
        moved_by = [frozenset(solved & set(model.supports[g.parentJoint])) for g in self.geom.geometryObjects]
        for k in reversed(range(len(self.geom.collisionPairs))):
            pair = self.geom.collisionPairs[k]
            if moved_by[pair.first] == moved_by[pair.second]:  # a constant distance: left out
                self.geom.removeCollisionPair(pair)
        self.data, self.gdata = model.createData(), self.geom.createData()
        self.shapes = []
        for go in self.geom.geometryObjects:
            g = go.geometry
            if isinstance(g, coal.BVHModelBase):
                g.buildConvexHull(True, "Qt")
                g = g.convex
            self.shapes.append(g)
        self.frame_ids = {f: model.getFrameId(f) for f in frames}
        self.set_world(optik.World() if world is None else world)

    def set_world(self, world: optik.World) -> None:
        """Judge against ``world`` (its coal objects, placed here at each object's pose)."""
        from optik.collision.shapes import coal_objects

        self.obstacles = []
        for o in world.snapshot():
            for geom, offset in coal_objects(o.shape):
                t = o.pose @ offset
                self.obstacles.append((geom, self.coal.Transform3s(t[:3, :3], t[:3, 3])))

    def accepts(self, q: np.ndarray | None, targets: Targets | np.ndarray, tol: float, margin: float) -> bool:
        """Whether an answer, wrapped and clipped into the limits first (`settle`, what `solve_ik` does
        to optik's own answers), passes `PinocchioJudge.ok`: the one judge path for every solver."""
        return self.ok(None if q is None else settle(self.m, q), targets, tol, margin)

    def ok(self, q: np.ndarray | None, targets: Targets | np.ndarray, tol: float, margin: float) -> bool:
        """Whether ``q`` exactly (no settling) lies within the limits, puts every frame within ``tol``
        of its target (m and rad, by Pinocchio's FK) and keeps every self pair and every
        geometry-obstacle pair at a coal distance ``>= margin - 1e-9``."""
        m = self.m
        if q is None or np.any(q < m.lower) or np.any(q > m.upper):
            return False
        if not isinstance(targets, Mapping):
            (frame,) = self.frame_ids
            targets = {frame: targets}
        pin, coal = self.pin, self.coal
        qp = pin.neutral(self.model)
        qp[self.index] = q
        pin.framesForwardKinematics(self.model, self.data, qp)
        for frame, target in targets.items():
            t = self.data.oMf[self.frame_ids[frame]]
            if np.linalg.norm(t.translation - target[:3, 3]) > tol:
                return False
            if spatial.angle_between(target[:3, :3], t.rotation) > tol:
                return False
        pin.updateGeometryPlacements(self.model, self.data, self.geom, self.gdata, qp)
        tf = [coal.Transform3s(p.rotation, p.translation) for p in self.gdata.oMg]
        pairs = [
            (self.shapes[p.first], tf[p.first], self.shapes[p.second], tf[p.second])
            for p in self.geom.collisionPairs
        ]
        pairs += [
            (shape, tf[k], obstacle, tb)
            for k, shape in enumerate(self.shapes)
            for obstacle, tb in self.obstacles
        ]
        for a, ta, b, tb in pairs:
            if coal.distance(a, ta, b, tb, coal.DistanceRequest(), coal.DistanceResult()) < margin - 1e-9:
                return False
        return True
