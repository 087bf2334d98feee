"""Tracking scenarios shared by the tests, the benchmarks and the docs' figures
(``docs/figures/diffik.py``), so that a figure or a benchmark shows exactly what a test checks.

Each returns the mechanism, the start configuration, the sampled path of target poses and the
step ``dt``; a scenario with a secondary task returns it too, one with obstacles its world.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optik import catalog, spatial
from optik.catalog.robots import robots_dir
from optik.collision import World
from optik.diffik.base import Task
from optik.diffik.paths import line_path
from optik.diffik.tasks import PostureTask
from optik.errors import ModelError
from optik.mechanism import Mechanism
from optik.solvers import solve_ik


@dataclass(frozen=True)
class Scenario:
    """One tracking run: ``track(m, q0, path, dt, method, tasks=tasks)`` (``dt`` 0.01 s).

    Attributes:
        m: the mechanism.
        q0: start configuration (for `elbow_singularity` the seed of the IK that finds it).
        path: target poses, shape ``(N, 4, 4)``.
        dt: time step (s).
        tasks: secondary tasks.
        world: obstacles (None: none).
    """

    m: Mechanism
    q0: np.ndarray
    path: np.ndarray
    dt: float
    tasks: tuple[Task, ...] = ()
    world: World | None = None


def elbow_singularity() -> Scenario:
    """The planar 2R arm driven along x from 1 m to 5 cm beyond its reach and back (99 steps of
    0.01 s each way): the elbow straightens through the singularity ``sin q2 = 0``.

    ``q0`` is the elbow-down seed of the IK of the start point ``(1, 0)``, not the start itself.
    """
    m = catalog.planar_2r()
    reach = sum(m.params["lengths"])
    start, end = spatial.translation(1.0, 0.0, 0.0), spatial.translation(reach + 0.05, 0.0, 0.0)
    speed = (reach + 0.05 - 1.0) / 0.99
    path = np.concatenate([line_path(start, end, speed, 0.01), line_path(end, start, speed, 0.01)])
    return Scenario(m, np.array([0.5, -1.5]), path, 0.01)


def self_motion() -> Scenario:
    """The Panda's flange held fixed for 150 steps of 0.01 s while a priority-1 posture task
    turns joint 3 by 1 rad (cost on that joint only, 5 % of the remaining way per step): pure
    self-motion in the null space of the flange task."""
    m = catalog.panda()
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    turn = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    elbow = PostureTask(q0 + turn, cost=turn, gain=0.05, priority=1)
    return Scenario(m, q0, np.repeat(m.fk(q0)[None], 150, axis=0), 0.01, (elbow,))


BALL_Q = np.array([0.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785])
"""The Panda configuration whose tool point is the middle of the `ball_pass` line."""


def ball_pass(steps: int = 200, length: float = 0.5, radius: float = 0.05, offset: float = 0.0) -> Scenario:
    """The Panda of example-robot-data (``panda_link0`` to ``panda_hand_tcp``, its SRDF) moves its
    tool point ``length`` m along y at a fixed orientation in ``steps`` samples of 0.01 s, the line
    centred on the tool point at `BALL_Q`; a ball of radius ``radius`` sits at the middle, its
    surface ``offset`` m beside the line (along x), so that the hand meets it unless it avoids it.
    ``q0`` is the IK solution (from `BALL_Q`, within 10 s) of the first sample.

    Raises:
        MissingExtraError: example-robot-data is not installed.
        ModelError: the first sample cannot be reached (only for other arguments).
    """
    d = robots_dir() / "panda_description"
    m = Mechanism.from_urdf(
        d / "urdf" / "panda.urdf", "panda_link0", "panda_hand_tcp", srdf=d / "srdf" / "panda.srdf"
    )
    start = m.fk(BALL_Q)
    start[1, 3] -= length / 2
    res = solve_ik(m, start, q0=BALL_Q, time_limit=10.0)  # the first call may build code: no tight clock
    if not res.success:
        raise ModelError(f"the start of the ball path is not reachable: {res.message}")
    path = np.repeat(start[None], steps, axis=0)
    path[:, 1, 3] += np.linspace(0.0, length, steps)
    world = World()
    centre = path[steps // 2, :3, 3] + (offset + radius, 0.0, 0.0)
    world.add_sphere("ball", radius, spatial.translation(*centre))
    return Scenario(m, res.q, path, 0.01, world=world)
