"""Tracking scenarios shared by the tests and the docs' figures (``docs/figures/diffik.py``), so
that a figure shows exactly what a test checks.

Each returns the mechanism, the start configuration, the sampled path of target poses and the
step ``dt``; a scenario with a secondary task returns it too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optik import catalog, spatial
from optik.diffik.base import Task
from optik.diffik.paths import line_path
from optik.diffik.tasks import PostureTask
from optik.mechanism import Mechanism


@dataclass(frozen=True)
class Scenario:
    """One tracking run: ``track(m, q0, path, dt, method, tasks=tasks)`` (``dt`` 0.01 s).

    Attributes:
        m: the mechanism.
        q0: start configuration (for `elbow_singularity` the seed of the IK that finds it).
        path: target poses, shape ``(N, 4, 4)``.
        dt: time step (s).
        tasks: secondary tasks.
    """

    m: Mechanism
    q0: np.ndarray
    path: np.ndarray
    dt: float
    tasks: tuple[Task, ...] = ()


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
