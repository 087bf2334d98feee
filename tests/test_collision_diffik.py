"""Velocity dampers in the QP differential IK (optik.diffik.collision): the row is the first-order
change of the exact distance, and a tracked path past an obstacle keeps the margin at every step
(which it does not without them)."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import spatial
from optik.collision import World, check, check_many, robot_geometry
from optik.collision.distance import signed_distance
from optik.diffik.collision import damper_rows
from optik.diffik.scenarios import ball_pass
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


@pytest.fixture(scope="module")
def ball():
    try:
        return ball_pass(steps=80, length=0.3)
    except optik.MissingExtraError:
        pytest.skip("example-robot-data (extra 'robots') is not installed")


def _exact_pairs(m, q, world, influence):
    """``(d, part a, part b or obstacle, world)`` of every pair within ``influence``, closest first,
    from coal on the geometry's own part poses (not the dampers' compiled kernel; ``world`` None:
    the robot's own pairs only)."""
    geo = robot_geometry(m)
    poses = geo.part_poses(q)
    moving = [m.frames[geo.links[k]][0] != m.base for k in geo.part_link]
    out = [
        (signed_distance(geo.parts[i], poses[i], geo.parts[j], poses[j])[0], i, j, False)
        for i, j in geo.self_pairs
    ]
    for i in np.flatnonzero(moving):
        for j, o in enumerate(world.parts() if world is not None else ()):
            out.append((signed_distance(geo.parts[i], poses[i], o, o.offset)[0], i, j, True))
    return sorted(p for p in out if p[0] < influence)


def _pair_distance(m, q, pair, world):
    geo = robot_geometry(m)
    poses = geo.part_poses(q)
    _, i, j, in_world = pair
    other, pose = (world.parts()[j], world.parts()[j].offset) if in_world else (geo.parts[j], poses[j])
    return signed_distance(geo.parts[i], poses[i], other, pose)[0]


def test_panda_damper_rows_are_the_distance_gradients(ball):
    """On the Panda beside the ball, with a wide influence (self pairs and the ball): one row per pair
    within it, ordered by distance, each ``-G`` row the central difference of that pair's exact
    distance (coal on the geometry's part poses), ``h = gamma (d - margin)``."""
    m, w = ball.m, ball.world
    out = optik.diffik.track(m, ball.q0, ball.path, ball.dt, world=w, margin=MARGIN)
    influence, eps = 0.15, 1e-5
    kinds = set()
    for q in (out.q[len(out.q) // 2], out.q[-1], *m.random_q(4, seed=3)):
        g, h, d_min = damper_rows(m, q, w, True, MARGIN, influence=influence, gain=0.3)
        pairs = _exact_pairs(m, q, w, influence)
        assert g.shape == (len(pairs), m.n_q)
        assert d_min == pytest.approx(pairs[0][0], abs=1e-9)
        for row, rhs, pair in zip(g, h, pairs, strict=True):
            kinds.add(pair[3])
            assert rhs == pytest.approx(0.3 * (pair[0] - MARGIN), abs=1e-9)
            for j in range(m.n_q):
                dq = np.zeros(m.n_q)
                dq[j] = eps
                slope = (_pair_distance(m, q + dq, pair, w) - _pair_distance(m, q - dq, pair, w)) / (2 * eps)
                assert -row[j] == pytest.approx(slope, abs=2e-4)
    assert kinds == {False, True}  # both self and world rows were checked


def test_panda_self_collision_dampers_without_a_world(ball):
    """``world=None, self_collision=True``: the robot's own pairs within the influence, nothing else."""
    m = ball.m
    for q in m.random_q(6, seed=5):
        g, h, _ = damper_rows(m, q, None, True, MARGIN, influence=0.15)
        pairs = _exact_pairs(m, q, None, 0.15)
        assert g.shape == (len(pairs), m.n_q)
        assert h == pytest.approx([0.5 * (p[0] - MARGIN) for p in pairs], abs=1e-9)
        assert damper_rows(m, q, None, False, MARGIN, influence=0.15)[0].shape == (0, m.n_q)


@pytest.mark.parametrize("dampers", [False, True])
def test_panda_ball_pass_keeps_the_margin(ball, dampers):
    """The benchmark's path (shortened): with dampers every configuration is clear of the ball and of
    the robot itself by the margin (exact check, no tolerance) and within the limits; without them
    the hand goes through the ball."""
    m, w = ball.m, ball.world
    kw = {"world": w, "margin": MARGIN} if dampers else {}
    out = optik.diffik.track(m, ball.q0, ball.path, ball.dt, **kw)
    dist = check_many(m, out.q, w).min_distance
    if dampers:
        assert dist.min() >= MARGIN
        assert out.within_limits and all(s == "ok" for s in out.status)
    else:
        assert dist.min() < 0


def test_panda_damper_rows_from_two_threads(ball):
    """Two threads computing rows at once get exactly the serial answers (per-thread buffers of the
    compiled screen and Jacobian calls, one coal result per query)."""
    from concurrent.futures import ThreadPoolExecutor

    m, w = ball.m, ball.world
    qs = m.random_q(40, seed=7)
    serial = [damper_rows(m, q, w, True, MARGIN, influence=0.15) for q in qs]
    with ThreadPoolExecutor(2) as pool:
        threaded = list(pool.map(lambda q: damper_rows(m, q, w, True, MARGIN, influence=0.15), qs))
    for (g1, h1, d1), (g2, h2, d2) in zip(serial, threaded, strict=True):
        assert np.array_equal(g1, g2) and np.array_equal(h1, h2) and d1 == d2


def _both_paths(m, q, w, influence):
    """``damper_rows`` (the compiled pair call once its library is loaded) and the same rows from
    coal's distances (`_coal_rows` on the same screen outputs), and the compiled call's count."""
    from optik.collision.world import state_of
    from optik.diffik import collision as dc

    fast = damper_rows(m, q, w, True, MARGIN, influence=influence)
    cq, state = dc._queries(m), state_of(w)
    capacity = 1 << max(len(state.parts) - 1, 0).bit_length()
    compiled = cq.compiled(capacity, state)
    assert compiled is not None
    fn, call = compiled
    fn.inputs[0][:] = q
    outputs = fn()
    call.bind(state, outputs)
    k = call(influence, dc.DAMPER_GAIN, MARGIN, True)
    outputs = outputs[:3]
    slow = dc._coal_rows(m, q, cq, state, outputs, True, influence, dc.DAMPER_GAIN, MARGIN)
    return fast, slow, k


def test_panda_compiled_pairs_are_coals(ball):
    """The compiled pair call (GJK on the hulls of boxes, spheres, capsules and meshes) gives
    coal's rows: the same pairs in the same order, the same distances (never above coal's, at most
    1e-6 m below: coal's GJK tolerance) and rows (to 1e-4 but for at most 5 %: witness points are
    not unique for parallel faces, and coal's are exact only to its tolerance; the rows' slopes are
    checked against the exact distance in test_panda_damper_rows_are_the_distance_gradients). It
    leaves every pair to coal when two hulls overlap (a random configuration inside an obstacle)
    or a cylinder is in the world."""
    from optik import native

    m = ball.m
    w = World()
    w.add_box("box", (0.2, 0.1, 0.3), spatial.translation(0.4, 0.2, 0.4))
    w.add_sphere("ball", 0.06, spatial.translation(0.3, -0.3, 0.5))
    w.add_capsule("rod", 0.03, 0.4, spatial.translation(0.5, 0.0, 0.3))
    damper_rows(m, m.random_q(1, seed=0)[0], w, True, MARGIN)
    native.wait()
    rows = left = off = 0
    for q in m.random_q(60, seed=11):
        (g1, h1, d1), (g2, h2, d2), k = _both_paths(m, q, w, 0.2)
        if k < 0:  # only when hulls overlap: then coal's own rows
            assert d2 < 0 and np.array_equal(g1, g2) and np.array_equal(h1, h2)
            left += 1
            continue
        assert g1.shape == g2.shape
        assert d1 == pytest.approx(d2, abs=1e-6) or d1 == d2 == np.inf
        # both GJK answers are upper bounds of the distance; coal stops at its tolerance (1e-6)
        assert np.all(h1 <= h2 + 1e-12) and np.all(h2 - h1 <= 1e-6)
        off += int((np.abs(g1 - g2).max(axis=1, initial=0.0) > 1e-4).sum())
        rows += len(h1)
    assert rows > 60 and left < 20 and off <= 0.05 * rows
    w.add_cylinder("post", 0.05, 0.5, spatial.translation(0.3, 0.3, 0.25))
    for q in m.random_q(10, seed=12):
        (g1, h1, d1), (g2, h2, d2), k = _both_paths(m, q, w, 0.3)
        assert k == -1 and np.array_equal(g1, g2) and np.array_equal(h1, h2) and d1 == d2
