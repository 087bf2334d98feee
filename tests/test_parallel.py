"""Closed forms of the closed-chain catalog (optik.closed_form.parallel), checked against the model.

Every branch returned by a closed form is FK-verified: its loop closure must vanish (``m.closure``)
and its end-effector pose (``m.fk``) must be the target. Round trips go pose -> IK -> FK (all
modes) and back.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import optik
from optik import closed_form as cf
from optik.closed_form import parallel as par
from optik.closed_form.parallel.common import rot2
from optik.solvers.fk import same_mode

CLOSE = 1e-11


def _contains(m: optik.Mechanism, qs: list[np.ndarray], q: np.ndarray) -> bool:
    return any(same_mode(m, x, q, 1e-8) for x in qs)


def _closes(m: optik.Mechanism, q: np.ndarray) -> bool:
    return float(np.max(np.abs(m.closure(q)))) < CLOSE


angles = st.floats(-np.pi, np.pi, allow_nan=False)


# ----------------------------------------------------------------------------- five-bar
@pytest.mark.parametrize(
    "m",
    [
        optik.catalog.five_bar(),
        optik.catalog.five_bar(base=((0, 0), (0, 0)), lengths=(1, 1, 1.2, 1.2), tool=1.6),
    ],
    ids=["five_bar", "seed_coaxial_tool"],
)
@settings(max_examples=40, deadline=None)
@given(th1=angles, th2=angles)
def test_five_bar_fk_modes_close_and_ik_recovers_them(m, th1, th2):
    modes = cf.fk(m, [th1, th2], respect_limits=False)
    assert len(modes) in (0, 1, 2)
    for q in modes:
        assert _closes(m, q)
        # a folded or stretched link pair is a workspace boundary of its 2R chain, where the
        # IK loses half the digits (sqrt sensitivity); keep to well-conditioned configurations
        assume(min(abs(np.sin(q[2])), abs(np.sin(q[3]))) > 1e-3)
        target = m.fk(q)
        branches = cf.ik(m, target, respect_limits=False)
        assert _contains(m, branches, q)
        for b in branches:
            assert _closes(m, b)
            assert np.allclose(m.fk(b)[:2, 3], target[:2, 3], atol=1e-12)


def test_five_bar_has_four_working_modes_and_two_assembly_modes():
    m = optik.catalog.five_bar()
    branches = cf.ik(m, optik.Position(0.5, 1.4))
    assert len(branches) == 4
    assert all(_closes(m, q) for q in branches)
    pairs = {tuple(np.round(q[:2], 9)) for q in branches}
    assert len(pairs) == 4  # four distinct actuator pairs
    modes = cf.fk(m, branches[0][:2])
    assert len(modes) == 2
    assert _contains(m, modes, branches[0])


def test_five_bar_out_of_reach_and_apart_circles():
    m = optik.catalog.five_bar()
    assert cf.ik(m, optik.Position(5.0, 5.0)) == []
    far = optik.catalog.five_bar(lengths=(1.0, 1.0, 0.2, 0.2))
    assert cf.fk(far, [np.pi, 0.0]) == []  # B1 and B2 are 3 apart, distal links reach 0.4


# ----------------------------------------------------------------------------- doggy
@settings(max_examples=25, deadline=None)
@given(x=st.floats(-0.3, 0.3), y=st.floats(0.55, 0.9), phi=st.floats(-0.3, 0.3))
def test_doggy_ik_four_combinations_and_fk_recovers_pose(x, y, phi):
    m = optik.catalog.doggy()
    pose = optik.Pose2D(x, y, phi)
    branches = cf.ik(m, pose, respect_limits=False)
    assert len(branches) == 4
    for q in branches:
        assert _closes(m, q)
        assert np.allclose(m.fk(q), pose.as_transform(), atol=1e-12)
        (back,) = cf.fk(m, q[m.actuated_indices], respect_limits=False)
        assert same_mode(m, back, q, 1e-9)
        assert np.allclose(m.fk(back), pose.as_transform(), atol=1e-12)


def test_doggy_inconsistent_leg_angles_do_not_assemble():
    m = optik.catalog.doggy()
    q = cf.ik(m, optik.Pose2D(0.0, 0.8, 0.1), respect_limits=False)[0]
    a = q[m.actuated_indices]
    a[0] += 0.05
    assert cf.fk(m, a, respect_limits=False) == []


# ----------------------------------------------------------------------------- slider-crank
@settings(max_examples=30, deadline=None)
@given(theta=angles, offset=st.floats(-0.2, 0.2))
def test_slider_crank_two_modes_round_trip(theta, offset):
    m = optik.catalog.slider_crank(crank=0.3, rod=1.0, offset=offset)
    modes = cf.fk(m, [theta], respect_limits=False)
    assert len(modes) == 2
    for q in modes:
        assert _closes(m, q)
        assume(abs(np.sin(q[1])) > 1e-3)  # dead centres: the IK loses half the digits there
        assert _contains(m, cf.ik(m, m.fk(q), respect_limits=False), q)


def test_slider_crank_rod_too_short_and_target_off_the_line():
    m = optik.catalog.slider_crank(crank=0.5, rod=0.3, offset=0.0)
    assert cf.fk(m, [np.pi / 2]) == []
    assert cf.ik(optik.catalog.slider_crank(), optik.Position(0.8, 0.1)) == []


# ----------------------------------------------------------------------------- 3-RPR
def _rpr_sample(rng: np.random.Generator):
    b, p = rng.normal(size=(3, 2)), 0.7 * rng.normal(size=(3, 2))
    t, phi = rng.normal(size=2), rng.uniform(-np.pi, np.pi)
    rho = np.linalg.norm(t + p @ rot2(phi).T - b, axis=1)
    return b, p, rho, np.array([*t, phi])


def test_3rpr_fk_finds_every_real_root_of_a_dense_scan():
    """Random geometries: the pose is found, every mode meets the legs to 1e-9, and no sign
    change of the polynomial on a dense grid of headings is left without a mode."""
    rng = np.random.default_rng(7)
    counts = []
    for _ in range(200):
        b, p, rho, x = _rpr_sample(rng)
        poses = par.planar_3rpr_poses(b, p, rho)
        counts.append(len(poses))
        assert len(poses) <= 6
        assert any(np.allclose(y, x, atol=1e-8) for y in poses)
        for y in poses:
            legs = np.linalg.norm(y[:2] + p @ rot2(y[2]).T - b, axis=1)
            assert np.allclose(legs, rho, atol=1e-9)
        c = par.rpr_polynomial(b, p, rho)
        grid = np.linspace(-np.pi, np.pi, 4001)
        f = np.real(sum(c[k + 3] * np.exp(1j * k * grid) for k in range(-3, 4)))
        assert np.sum(np.sign(f[1:]) != np.sign(f[:-1])) <= len(poses)
    assert {2, 4, 6} <= set(counts)


def test_3rpr_polynomial_is_degree_six():
    """The e^{+-4 i phi} terms of |N|^2 - rho_1^2 D^2 cancel: 7 coefficients hold it exactly."""
    rng = np.random.default_rng(3)
    b, p, rho, _ = _rpr_sample(rng)
    c = par.rpr_polynomial(b, p, rho)
    for phi in rng.uniform(-np.pi, np.pi, 5):
        d, e = p[1:] - p[0], b[1:] - b[0]
        w = d @ rot2(phi).T - e
        k = rho[1:] ** 2 - rho[0] ** 2 - np.sum(w * w, axis=1)
        det = np.linalg.det(w)
        n = np.array([[w[1, 1], -w[0, 1]], [-w[1, 0], w[0, 0]]]) @ k
        direct = n @ n - rho[0] ** 2 * (2 * det) ** 2
        assert np.real(sum(c[j + 3] * np.exp(1j * j * phi) for j in range(-3, 4))) == pytest.approx(
            direct, rel=1e-9, abs=1e-9
        )


def test_3rpr_six_modes_and_half_turn_heading():
    """A case with 6 real modes, and a pose with phi = pi (where tan(phi/2) substitutions fail)."""
    rng = np.random.default_rng(11)
    while True:
        b, p, rho, _ = _rpr_sample(rng)
        if len(par.planar_3rpr_poses(b, p, rho)) == 6:
            break
    m = optik.catalog.planar_3rpr(base=b, platform=p, leg_limits=(0.0, 100.0))
    qs = cf.fk(m, rho)
    assert len(qs) == 6
    assert all(_closes(m, q) for q in qs)
    m = optik.catalog.planar_3rpr()
    q = cf.ik(m, optik.Pose2D(1.0, 0.7, np.pi))[0]
    assert _contains(m, cf.fk(m, q[m.actuated_indices]), q)


def test_3rpr_round_trip_in_the_catalog():
    m = optik.catalog.planar_3rpr()
    rng = np.random.default_rng(1)
    for _ in range(30):
        pose = optik.Pose2D(rng.uniform(0.6, 1.4), rng.uniform(0.4, 1.1), rng.uniform(-np.pi, np.pi))
        (q,) = cf.ik(m, pose, respect_limits=False)
        assert _closes(m, q)
        assert np.allclose(m.fk(q), pose.as_transform(), atol=1e-12)
        assert _contains(m, cf.fk(m, q[m.actuated_indices], respect_limits=False), q)


# ----------------------------------------------------------------------------- Stewart-Gough
def _random_pose(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return par.quat_to_rot(rng.normal(size=4)), np.array([0.0, 0.0, 1.1]) + 0.25 * rng.normal(size=3)


def test_stewart_quadrics_vanish_at_a_posture():
    rng = np.random.default_rng(0)
    b, p = rng.normal(size=(6, 3)), rng.normal(size=(6, 3))
    r, t = _random_pose(rng)
    rho = np.linalg.norm(p @ r.T + t - b, axis=1)
    w = optik.spatial.so3_log(r)
    ang = np.linalg.norm(w)
    e = np.r_[np.cos(ang / 2), np.sin(ang / 2) * w / ang]
    assert np.allclose(par.quat_to_rot(e), r)
    g = 0.5 * par.quat_left(np.r_[0.0, t]) @ e
    z = np.r_[e, g]
    mats = par.stewart_quadrics(b, p, rho)
    assert np.allclose([z @ mt @ z for mt in mats], 0.0, atol=1e-12)


def test_stewart_general_geometry_all_forty_and_pose_found():
    rng = np.random.default_rng(5)
    b, p = rng.normal(size=(6, 3)), 0.6 * rng.normal(size=(6, 3))
    r, t = _random_pose(rng)
    rho = np.linalg.norm(p @ r.T + t - b, axis=1)
    fk = par.stewart_poses(b, p, rho, seed=1)
    assert fk.complete and fk.complex_solutions == 40
    assert any(np.allclose(r2, r, atol=1e-9) and np.allclose(t2, t, atol=1e-9) for r2, t2 in fk.poses)
    for r2, t2 in fk.poses:
        assert np.allclose(np.linalg.norm(p @ r2.T + t2 - b, axis=1), rho, atol=1e-9)


def test_stewart_polish_of_many_postures_is_the_polish_of_each():
    """`polish_stewart_many` (all real candidates at once, each with its own stopping rule)
    gives each posture exactly what `polish_stewart` gives it alone: perturbed postures of a
    random platform, one exact already (no step) and one far off."""
    from optik.closed_form.parallel.stewart_gough import polish_stewart_many

    rng = np.random.default_rng(8)
    b, p = rng.normal(size=(6, 3)), 0.6 * rng.normal(size=(6, 3))
    r, t = _random_pose(rng)
    rho = np.linalg.norm(p @ r.T + t - b, axis=1)
    rs = np.stack(
        [optik.spatial.so3_exp(rng.normal(scale=s, size=3)) @ r for s in (0.0, 1e-6, 1e-3, 0.05, 0.5)]
    )
    ts = t + rng.normal(size=(5, 3)) * np.array([0.0, 1e-6, 1e-3, 0.05, 0.5])[:, None]
    r_all, t_all, err_all = polish_stewart_many(b, p, rho, rs, ts)
    for k in range(5):
        r1, t1, err1 = par.polish_stewart(b, p, rho, rs[k], ts[k])
        np.testing.assert_array_equal(r_all[k], r1)
        np.testing.assert_array_equal(t_all[k], t1)
        assert err_all[k] == err1
    assert np.all(err_all[:4] < 1e-12)  # the near ones converge


def test_stewart_catalog_round_trip_with_half_turn():
    """Pose -> IK -> FK (all) -> contains the pose; one pose is a half-turn about z, which a
    Cayley chart cannot reach."""
    m = optik.catalog.stewart_gough()
    half_turn = np.eye(4)
    half_turn[:3, :3] = optik.spatial.rot_z(np.pi)
    half_turn[:3, 3] = [0.05, -0.02, 1.2]
    rng = np.random.default_rng(2)
    tilted = np.eye(4)
    tilted[:3, :3] = optik.spatial.rpy_to_rot(*rng.uniform(-0.3, 0.3, 3))
    tilted[:3, 3] = [0.1, 0.05, 1.0]
    for target in (half_turn, tilted):
        (q,) = cf.ik(m, target)
        assert _closes(m, q)
        assert np.allclose(m.fk(q), target, atol=1e-12)
        modes = cf.fk(m, q[m.actuated_indices])
        assert all(_closes(m, x) for x in modes)
        assert any(np.allclose(m.fk(x), target, atol=1e-9) for x in modes)


def test_stewart_unreachable_leg_lengths_give_no_posture():
    """Platform points within 0.5 of base points of radius 1 and a platform of diameter 1.2
    keep leg 6 shorter than 3.7: a 5 m leg cannot assemble."""
    m = optik.catalog.stewart_gough()
    assert cf.fk(m, [0.5, 0.5, 0.5, 0.5, 0.5, 5.0]) == []


@pytest.mark.parametrize(
    ("name", "target"),
    [
        ("five_bar", optik.Position(0.5, 1.4)),
        ("doggy", optik.Pose2D(0.1, 0.8, 0.2)),
        ("slider_crank", optik.Position(1.0, 0.0)),
    ],
)
def test_numeric_ik_finds_every_closed_form_branch(name, target):
    """Numerical multi-start IK (closure as constraints, closed form switched off) finds the
    4 / 4 / 2 closed-form branches to 1e-9."""
    m = getattr(optik.catalog, name)()
    exact = cf.ik(m, target)
    numeric = optik.solve_ik_all(m, target, closed_form=False, tol=1e-12, time_limit=3.0, seed=0)
    assert len(numeric) == len(exact) == {"five_bar": 4, "doggy": 4, "slider_crank": 2}[name]
    for q in exact:
        assert min(np.max(np.abs(optik.spatial.wrap_angle(r.q - q))) for r in numeric) < 1e-9


def test_3rpr_congruent_platform_continuum_gives_representatives():
    """Platform congruent to the base with equal legs: at phi = 0 every translation on a circle
    assembles (a quadruple root of F whose cluster centre is found); the isolated modes at
    phi = +-pi/2 are returned as well, and every returned pose meets the legs."""
    b = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    rho = np.ones(3)
    poses = par.planar_3rpr_poses(b, b.copy(), rho)
    headings = np.array([x[2] for x in poses])
    assert np.sum(np.abs(headings) < 1e-9) == par.CONTINUUM_SAMPLES
    assert np.sum(np.abs(np.abs(headings) - np.pi / 2) < 1e-9) == 2
    for x in poses:
        legs = np.linalg.norm(x[:2] + b @ rot2(x[2]).T - b, axis=1)
        assert np.allclose(legs, rho, atol=1e-9)


def test_homotopy_tracks_every_solution_of_two_circles():
    """x^2 + y^2 = w^2 and (x - w)^2 + y^2 = w^2 in P^2: Bezout 4 = the two real intersections
    (1/2, +-sqrt(3)/2) plus the two circular points (1, +-i, 0) at infinity, all nonsingular."""
    from optik.closed_form import homotopy

    f1 = np.diag([-1.0, 1.0, 1.0])
    f2 = np.array([[0.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    res = homotopy.track(np.array([f1, f2]), np.random.default_rng(0))
    assert res.converged.all() and np.all(res.residual < 1e-12)
    z = homotopy.refine(np.array([f1, f2]), res.z)
    finite = z[np.abs(z[:, 0]) > 1e-6 * np.linalg.norm(z, axis=1)]
    points = sorted((finite[:, 1:] / finite[:, :1]).real.tolist(), key=lambda v: v[1])
    assert np.allclose(points, [[0.5, -np.sqrt(3) / 2], [0.5, np.sqrt(3) / 2]], atol=1e-12)
    at_infinity = z[np.abs(z[:, 0]) <= 1e-6 * np.linalg.norm(z, axis=1)]
    assert len(at_infinity) == 2
    assert np.allclose(np.abs(at_infinity[:, 2] / at_infinity[:, 1]), 1.0)


def test_stewart_incomplete_search_is_flagged_and_warned():
    m = optik.catalog.stewart_gough()
    target = optik.spatial.transform(np.eye(3), np.array([0.0, 0.0, 1.0]))
    legs = cf.ik(m, target)[0][m.actuated_indices]
    hurried = par.stewart_poses(m.params["base"], m.params["platform"], legs, time_limit=0.02)
    assert not hurried.complete
    with pytest.warns(RuntimeWarning, match="not certified"):
        par.stewart_gough_fk(m, legs, time_limit=0.02)
