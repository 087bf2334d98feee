"""Unbounded joints (``lower=-inf, upper=inf``, URDF continuous): accepted, sampled over one
turn, never clipped, and solved across +-pi by lm, nlp, dls and qp (no wall: the angle wraps)."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import Joint, Mechanism, Pose2D, diffik, spatial
from optik.errors import LimitsError, NonFiniteError

INF = np.inf


def _arm(lower: float = -INF, upper: float = INF) -> Mechanism:
    return optik.planar_chain("RR", [1.0, 0.7], lower=[lower, lower], upper=[upper, upper])


def test_unbounded_joints_are_accepted_and_sampled_over_one_turn():
    j = Joint("j", "revolute", "a", "b", lower=-INF, upper=INF)
    assert j.lower == (-INF,) and j.upper == (INF,)
    with pytest.raises(LimitsError):
        Joint("j", "revolute", "a", "b", lower=np.nan)
    m = Mechanism(
        [
            Joint("r", "revolute", "base", "l1", lower=-INF, upper=INF),
            Joint("s", "revolute", "l1", "l2", lower=0.5, upper=INF),
            Joint("t", "revolute", "l2", "l3", lower=-INF, upper=-4.0),
            Joint("p", "prismatic", "l3", "l4", axis=[1, 0, 0], lower=-INF, upper=INF),
        ]
    )
    lo, hi = m.sampling_bounds
    np.testing.assert_allclose(lo, [-np.pi, 0.5, -4.0 - 2 * np.pi, -1.0])
    np.testing.assert_allclose(hi, [np.pi, 0.5 + 2 * np.pi, -4.0, 1.0])
    assert m.unbounded.all()
    np.testing.assert_allclose(m.mid_q(), 0.5 * (lo + hi))
    qs = m.random_q(500, seed=1)
    assert np.isfinite(qs).all() and (qs >= lo).all() and (qs <= hi).all()
    assert m.within_limits([10.0, 100.0, -50.0, 1e6])
    np.testing.assert_allclose(m.clip([10.0, 0.0, 0.0, 5.0]), [10.0, 0.5, -4.0, 5.0])
    assert m.with_limits(upper=[INF, INF, INF, 2.0]).upper[3] == 2.0
    with pytest.raises(NonFiniteError, match=r"^lower"):
        m.with_limits(lower=[np.nan, 0, 0, 0])


@pytest.mark.parametrize("method", ["lm", "nlp", "dls", "qp"])
def test_a_target_just_across_pi_is_reached_without_going_around(method):
    q_true = np.array([np.pi - 0.05, 0.4])
    q0 = np.array([-np.pi + 0.05, 0.4])  # 0.1 rad away through +-pi, 6.18 rad the other way
    t = _arm().fk(q_true)
    target = Pose2D(t[0, 3], t[1, 3], np.arctan2(t[1, 0], t[0, 0]))
    opts = {"max_restarts": 0} if method in ("lm", "nlp") else {}
    res = optik.solve_ik(_arm(), target, q0=q0, method=method, time_limit=1.0, **opts)
    assert res.success, res.message
    assert -np.pi < res.q[0] <= np.pi  # reported wrapped
    np.testing.assert_allclose(_arm().fk(res.q), t, atol=1e-6)  # checked independently
    assert res.iterations <= 20  # a short step across pi, not a trip around the circle
    if method in ("lm", "nlp"):  # the same start with a wall at +-pi fails without restarts
        walled = optik.solve_ik(_arm(-np.pi, np.pi), target, q0=q0, method=method, **opts)
        assert not walled.success


@pytest.mark.parametrize("method", ["lm", "nlp", "dls", "qp"])
def test_unbounded_ik_with_restarts_and_unreachable_targets(method):
    m = _arm()
    t = m.fk([2.5, -1.0])
    reachable = optik.solve_ik(m, Pose2D(t[0, 3], t[1, 3], 1.5), method=method, seed=3, time_limit=1.0)
    assert reachable.success and np.isfinite(reachable.q).all()
    np.testing.assert_allclose(m.fk(reachable.q), t, atol=1e-6)
    far = optik.solve_ik(m, Pose2D(5.0, 0.0, 0.0), method=method, time_limit=0.05)  # restarts drawn
    assert not far.success and np.isfinite(far.q).all() and far.message


def test_diffik_frame_task_turns_an_unbounded_joint_past_pi():
    m = _arm()
    q = np.array([np.pi - 0.3, 0.0])
    goal = m.fk(np.array([np.pi + 0.3, 0.0]))
    task = diffik.FrameTask(target=goal)
    for _ in range(60):
        q = diffik.step(m, q, [task], 0.05, "qp").q
    assert q[0] > np.pi  # went on through pi instead of stopping at a wall
    np.testing.assert_allclose(m.fk(q)[:2, 3], goal[:2, 3], atol=1e-4)
    assert spatial.wrap_angle(q[0]) == pytest.approx(-np.pi + 0.3, abs=1e-3)


def test_urdf_continuous_joint_is_unbounded():
    text = (
        '<robot name="w"><link name="a"/><link name="b"/><joint name="wheel" type="continuous">'
        '<parent link="a"/><child link="b"/><axis xyz="0 1 0"/></joint></robot>'
    )
    m = optik.Mechanism.from_urdf(text)
    assert m.lower.tolist() == [-INF] and m.upper.tolist() == [INF] and m.mid_q().tolist() == [0.0]
