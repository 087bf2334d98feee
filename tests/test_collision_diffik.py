"""Velocity dampers in the QP differential IK (optik.diffik.collision): the row is the first-order
change of the exact distance, and a tracked path past an obstacle keeps the margin at every step
(which it does not without them)."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import spatial
from optik.collision import World, check
from optik.diffik.collision import damper_rows
from optik.errors import InvalidArgumentError

pytest.importorskip("coal", reason="collision checks need coal (extra 'collision')")

MARGIN = 0.01


@pytest.fixture(scope="module")
def arm(toy_arm_urdf) -> optik.Mechanism:
    return optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip")


def _ball_world(arm):
    w = World()
    w.add_sphere("ball", 0.05, spatial.translation(0.75, 0.25, 0.1))
    return w


def test_damper_row_is_the_distance_gradient(arm):
    """``-G`` times a small ``dq`` is the exact distance change (central differences of coal; row 0
    is the closest pair's), in penetration and apart; pairs beyond the influence get no row."""
    w = _ball_world(arm)
    eps = 1e-6
    for q in (np.array([0.1, 0.6]), np.array([-0.5, 0.3])):
        g, h, d = damper_rows(arm, q, w, False, MARGIN, influence=0.5)
        assert g.shape[0] >= 1 and h[0] == pytest.approx(0.5 * (d - MARGIN))
        for j in range(2):
            dq = np.zeros(2)
            dq[j] = eps
            ahead = check(arm, q + dq, w, self_collision=False).min_distance
            behind = check(arm, q - dq, w, self_collision=False).min_distance
            assert -g[0, j] == pytest.approx((ahead - behind) / (2 * eps), rel=1e-4, abs=1e-7)
    assert d > MARGIN
    far = damper_rows(arm, q, w, False, MARGIN, influence=(d + MARGIN) / 2)
    assert far[0].shape == (0, 2)


@pytest.mark.parametrize("dampers", [False, True])
def test_tracking_past_a_ball_keeps_the_margin(arm, dampers):
    """The tip sweeps an arc whose arm passes through the ball: with dampers every configuration
    is clear by the margin (exact check), without them some collide."""
    w = _ball_world(arm)
    angles = np.linspace(-0.2, 0.9, 60)
    path = np.array([arm.fk(np.array([a, 0.3]))[:3, 3] for a in angles])
    kw = {"world": w, "margin": MARGIN} if dampers else {}
    out = optik.diffik.track(arm, np.array([-0.2, 0.3]), path, 0.01, **kw)
    dist = np.array([check(arm, q, w).min_distance for q in out.q])
    if dampers:
        assert dist.min() >= MARGIN - 1e-3
    else:
        assert dist.min() < 0


def test_bad_damper_arguments(arm):
    w = _ball_world(arm)
    task = optik.diffik.FrameTask(None, arm.fk(np.zeros(2)), position_cost=1.0, orientation_cost=0.0)
    with pytest.raises(InvalidArgumentError, match="influence"):
        optik.diffik.step(arm, np.zeros(2), [task], 0.01, world=w, margin=0.1, influence=0.05)
    with pytest.raises(InvalidArgumentError, match="collision_gain"):
        optik.diffik.step(arm, np.zeros(2), [task], 0.01, world=w, collision_gain=1.5)
    with pytest.raises(InvalidArgumentError, match="world"):
        optik.diffik.step(arm, np.zeros(2), [task], 0.01, method="dls", world=w)
