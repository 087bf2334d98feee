"""Floating bases in the solvers: a quadruped with a free base (``from_urdf(...,
floating_base=True)``) solved by lm, nlp, qp and dls for its base pose with its four feet on
given points, solve_ik_batch on base poses, and a base rotation across the half-turn where the
rotation vector's chart wraps. Every success is checked again from the returned ``q``."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import native, spatial


def _leg(name: str, x: float, y: float) -> str:
    side = 0.08 if y > 0 else -0.08
    return f"""
  <link name="{name}_hip"><inertial><mass value="0.5"/></inertial></link>
  <link name="{name}_thigh"><inertial><origin xyz="0 0 -0.1"/><mass value="0.6"/></inertial></link>
  <link name="{name}_calf"><inertial><origin xyz="0 0 -0.1"/><mass value="0.2"/></inertial></link>
  <link name="{name}_foot"/>
  <joint name="{name}_abd" type="revolute"><parent link="torso"/><child link="{name}_hip"/>
    <origin xyz="{x} {y} 0"/><axis xyz="1 0 0"/><limit lower="-0.8" upper="0.8"/></joint>
  <joint name="{name}_hip" type="revolute"><parent link="{name}_hip"/><child link="{name}_thigh"/>
    <origin xyz="0 {side} 0"/><axis xyz="0 1 0"/><limit lower="-1.5" upper="3.4"/></joint>
  <joint name="{name}_knee" type="revolute"><parent link="{name}_thigh"/><child link="{name}_calf"/>
    <origin xyz="0 0 -0.21"/><axis xyz="0 1 0"/><limit lower="-2.7" upper="-0.9"/></joint>
  <joint name="{name}_ankle" type="fixed"><parent link="{name}_calf"/><child link="{name}_foot"/>
    <origin xyz="0 0 -0.21"/></joint>"""


LEGS = (("FL", 0.19, 0.05), ("FR", 0.19, -0.05), ("RL", -0.19, 0.05), ("RR", -0.19, -0.05))
URDF = (
    '<robot name="quad"><link name="torso"><inertial><mass value="6"/></inertial></link>'
    + "".join(_leg(*leg) for leg in LEGS)
    + "</robot>"
)
FEET = tuple(f"{name}_foot" for name, _, _ in LEGS)


@pytest.fixture(scope="module")
def quad() -> optik.Mechanism:
    return optik.Mechanism.from_urdf(URDF, floating_base=True)


def _targets(m: optik.Mechanism, q: np.ndarray) -> dict:
    out: dict = {"torso": m.fk(q, "torso")}
    out.update({f: optik.Position(m.fk(q, f)[:3, 3]) for f in FEET})
    return out


def _check(m: optik.Mechanism, targets: dict, q: np.ndarray) -> None:
    """Recompute every error from ``q``: base pose, foot points, limits, |w| <= pi after wrap."""
    t = m.fk(q, "torso")
    want = targets["torso"]
    assert np.abs(t[:3, 3] - want[:3, 3]).max() < 1e-6
    assert spatial.angle_between(t[:3, :3], want[:3, :3]) < 1e-6
    for f in FEET:
        assert np.abs(m.fk(q, f)[:3, 3] - np.asarray(targets[f].xyz)).max() < 1e-6
    assert m.within_limits(q)
    assert np.linalg.norm(q[3:6]) <= np.pi + 1e-12


@pytest.mark.parametrize("method", ["lm", "nlp", "qp", "dls"])
def test_base_pose_with_feet_on_points(quad, method):
    m = quad
    for k in range(6):
        q = m.random_q(seed=k)
        q[:3] *= 0.3
        targets = _targets(m, q)
        r = optik.solve_ik(m, targets, method=method, time_limit=10.0)
        assert r.success, (method, k, r.message)
        _check(m, targets, r.q)


@pytest.mark.parametrize("method", ["lm", "nlp", "qp"])
def test_base_turns_across_the_half_turn(quad, method):
    """Seed at a rotation vector just inside |w| = pi, target just past it: the steps cross
    the chart's wrap (w and the opposite vector of angle 2 pi - |w| are one rotation)."""
    m = quad
    q0 = m.mid_q()
    q0[5] = np.pi - 0.05  # yaw 180 - 2.9 degrees
    goal = q0.copy()
    goal[5] = -(np.pi - 0.05)  # yaw -180 + 2.9 degrees: 0.1 rad further on
    targets = _targets(m, goal)
    r = optik.solve_ik(m, targets, q0=q0, method=method, time_limit=10.0)
    assert r.success, r.message
    _check(m, targets, r.q)
    t = m.fk(r.q, "torso")
    assert spatial.angle_between(t[:3, :3], spatial.rot_z(np.pi + 0.05)) < 1e-6


def test_batch_of_base_poses(quad):
    m = quad
    qs = m.random_q(8, seed=11)
    qs[:, :3] *= 0.3
    poses = m.fk(qs, "torso")
    res = optik.solve_ik_batch(m, poses, frame="torso", workers=1, time_limit=10.0)
    assert np.all(res.success)
    for q, pose in zip(res.q, poses, strict=True):
        t = m.fk(q, "torso")
        assert np.abs(t[:3, 3] - pose[:3, 3]).max() < 1e-6
        assert spatial.angle_between(t[:3, :3], pose[:3, :3]) < 1e-6
        assert m.within_limits(q) and np.linalg.norm(q[3:6]) <= np.pi + 1e-12


@pytest.mark.parametrize("method", ["lm", "nlp", "qp", "dls"])
def test_single_and_several_targets_give_one_canonical_base(quad, method):
    """A start already at the answer, its base rotation vector of norm > pi with every
    component < pi: the single-target result (lm's through its prepared call) and the
    several-target one are the same canonical ``q``, norm <= pi, same poses."""
    m = quad
    optik.solve_ik(m, m.fk(m.mid_q(), "torso"), frame="torso", method=method)  # lm: its prepared call
    native.wait()  # ... once its library is loaded
    for k, w in enumerate(([2.5, 2.5, 0.5], [-0.4, 3.0, -1.2])):
        q = m.mid_q()
        q[:3] = [0.1, -0.2, 0.3 + k]
        q[3:6] = w
        assert np.linalg.norm(w) > np.pi and np.abs(w).max() < np.pi
        t = m.fk(q, "torso")
        single = optik.solve_ik(m, t, frame="torso", q0=q, method=method)
        several = optik.solve_ik(m, _targets(m, q), q0=q, method=method)
        assert single.success and several.success, (method, k, single.message, several.message)
        np.testing.assert_allclose(single.q, several.q, atol=1e-9)
        for r in (single, several):
            assert np.linalg.norm(r.q[3:6]) <= np.pi
            _check(m, _targets(m, q), r.q)
            np.testing.assert_allclose(m.fk(r.q, "torso"), t, atol=1e-9)
