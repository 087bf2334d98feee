"""Honest FK reports: every mode with its limit status, dropped modes counted and explained,
actuated values outside their limits answered as such; closed-form branches that pass their
closure check (issue 9 items of the parallel closed forms)."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import closed_form as cf
from optik.solvers.fk import same_mode


def _rpr_beyond_limits():
    """A 3-RPR posture whose legs are longer than the catalog's upper leg limit 2.5."""
    m = optik.catalog.planar_3rpr()
    q = cf.ik(m, optik.Pose2D(3.2, 0.4, 0.3), respect_limits=False)[0]
    legs = q[m.actuated_indices]
    assert np.max(legs) > m.params["leg_limits"][1]
    return m, q, legs


def test_3rpr_legs_beyond_their_limits_are_answered_as_such():
    m, q, legs = _rpr_beyond_limits()
    modes = optik.solve_fk_all(m, legs)
    assert modes == [] and len(modes.dropped) >= 1
    assert "outside their limits" in modes.message and "rho" in modes.message
    assert "within_limits=False" in modes.message
    every = optik.solve_fk_all(m, legs, within_limits=False)
    assert len(every) == len(modes.dropped) and every.dropped == []
    assert any(same_mode(m, r.q, q, 1e-8) for r in every)
    for r in every:
        assert not r.limits_ok and not r.success
        assert r.residual <= 1e-9 and float(np.max(np.abs(m.closure(r.q)))) <= 1e-9
        out = {m.coordinate_names[i] for i in m.actuated_indices if not m.lower[i] <= r.q[i] <= m.upper[i]}
        assert out and out <= set(r.limits_violated)
        assert "actuated values are outside their limits" in r.message
    single = optik.solve_fk(m, legs, q0=q)
    assert not single.success and not single.limits_ok and "outside their limits" in single.message


def test_modes_within_limits_report_limits_ok_and_nothing_dropped():
    m = optik.catalog.planar_3rpr()
    q = cf.ik(m, optik.Pose2D(1.0, 0.7, 0.2))[0]
    modes = optik.solve_fk_all(m, q[m.actuated_indices], within_limits=False)
    for r in modes:
        assert r.limits_ok == m.within_limits(r.q)
        assert r.limits_ok == (r.limits_violated == ())
    inside = optik.solve_fk_all(m, q[m.actuated_indices])
    assert len(inside) + len(inside.dropped) == len(modes)
    assert all(r.limits_ok and r.success for r in inside)
    assert (inside.message == "") == (inside.dropped == [])


def test_passive_limit_violations_are_counted_not_silent():
    m = optik.catalog.five_bar()
    narrow = m.with_limits(lower=[-np.pi, -np.pi, 0.0, -np.pi], upper=[np.pi, np.pi, np.pi, np.pi])
    i_psi1 = narrow.coordinate_names.index("psi1")
    a = [2.2, 0.9]
    every = optik.solve_fk_all(narrow, a, within_limits=False)
    assert len(every) == 2
    modes = optik.solve_fk_all(narrow, a)
    out = [r for r in every if not r.limits_ok]
    assert len(modes.dropped) == len(out) >= 1
    # psi1 past its limits [0, pi] by the least whole-turn shift (4.47 rather than -1.81)
    assert all("psi1" in r.limits_violated and r.q[i_psi1] > np.pi for r in modes.dropped)
    assert "psi1" in modes.message


def test_stewart_leg_pointing_down_is_a_valid_posture():
    m = optik.catalog.stewart_gough()
    pose = optik.spatial.transform(optik.spatial.rot_z(0.2), np.array([0.1, -0.05, -1.0]))
    (q,) = cf.ik(m, pose)
    assert m.within_limits(q)
    modes = optik.solve_fk_all(m, q[m.actuated_indices])
    assert any(np.allclose(r.pose, pose, atol=1e-9) for r in modes)
    assert all(r.limits_ok for r in modes)


def test_stewart_zero_length_leg_is_answered_not_raised():
    m = optik.catalog.stewart_gough()
    b, p = m.params["base"], m.params["platform"]
    pose = optik.spatial.transform(np.eye(3), b[0] - p[0])  # platform point 0 on base point 0
    (q,) = cf.ik(m, pose, respect_limits=False)
    assert q[m.actuated_indices][0] == 0.0 and float(np.max(np.abs(m.closure(q)))) <= 1e-12
    assert np.allclose(m.fk(q), pose, atol=1e-12)
    assert cf.ik(m, pose) == []  # the leg is shorter than its limit
    res = optik.solve_ik(m, pose)
    assert not res.success and res.message
    every = optik.solve_ik_all(m, pose)
    assert every == [] and len(every.outside_limits) == 1 and "outside the joint limits" in every.message


@pytest.mark.parametrize("lengths", [(1e9, 1e9, 1e9, 1e9), (1.0, 1.0, 1.2, 1.2)])
def test_five_bar_branches_all_pass_their_closure_check(lengths):
    m = optik.catalog.five_bar(lengths=lengths)
    size = max(lengths)
    rng = np.random.default_rng(3)
    targets = [np.zeros(2), np.array(m.params["base"][1], dtype=float)]
    for a in rng.uniform(-np.pi, np.pi, (60, 2)):
        for q in cf.fk(m, a, respect_limits=False):
            assert float(np.max(np.abs(m.closure(q)))) <= 1e-12 * size
            targets.append(m.fk(q)[:2, 3])
    for xy in targets:
        t = optik.spatial.translation(xy[0], xy[1], 0.0)
        for q in cf.ik(m, t, respect_limits=False):
            assert float(np.max(np.abs(m.closure(q)))) <= 1e-12 * size
            assert np.linalg.norm(m.fk(q)[:2, 3] - xy) <= 1e-12 * size


def test_within_limits_must_be_a_bool():
    with pytest.raises(optik.OptikError, match="within_limits"):
        optik.solve_fk_all(optik.catalog.five_bar(), [0.1, 0.2], within_limits="no")


def test_stewart_general_platform_every_real_posture_within_the_catalog_limits():
    """A general 6-6 with 10 real postures, some with legs pointing down: all come back."""
    rng = np.random.default_rng(0)
    b, p = rng.normal(size=(6, 3)), 0.6 * rng.normal(size=(6, 3))
    r = optik.closed_form.parallel.quat_to_rot(rng.normal(size=4))
    t = np.r_[0.0, 0.0, 1.0] + 0.2 * rng.normal(size=3)
    rho = np.linalg.norm(p @ r.T + t - b, axis=1)
    poses = optik.closed_form.parallel.stewart_poses(b, p, rho).poses
    assert len(poses) == 10
    assert any(np.any((p @ r2.T + t2 - b)[:, 2] < 0) for r2, t2 in poses)  # a leg points down
    m = optik.catalog.stewart_gough(b, p, leg_limits=(0.0, 100.0))
    modes = optik.solve_fk_all(m, rho)
    assert len(modes) == 10 and modes.dropped == [] and modes.message == ""
    assert all(r.limits_ok and r.success and r.residual <= 1e-9 for r in modes)
    assert any(
        np.allclose(x.pose[:3, :3], r, atol=1e-9) and np.allclose(x.pose[:3, 3], t, atol=1e-9) for x in modes
    )
