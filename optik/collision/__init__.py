"""Collision geometry, worlds of obstacles and exact collision queries (coal).

* `World` (`optik.World`): named boxes, spheres, cylinders, capsules, convex meshes and point
  clouds (`optik.collision.world`).
* `check` / `check_many`: exact signed distances of a mechanism at ``q`` to itself and a world
  (`optik.collision.check`), from the URDF's ``<collision>`` geometry and the allowed-collision
  matrix of `optik.collision.robot`.

coal is the optional extra ``collision`` (``pip install 'optik[collision]'``).
"""

from optik.collision.check import CollisionBatch, CollisionPair, CollisionReport, check, check_many
from optik.collision.robot import RobotGeometry, robot_geometry
from optik.collision.shapes import Shape
from optik.collision.world import Obstacle, World

__all__ = [
    "CollisionBatch",
    "CollisionPair",
    "CollisionReport",
    "Obstacle",
    "RobotGeometry",
    "Shape",
    "World",
    "check",
    "check_many",
    "robot_geometry",
]
