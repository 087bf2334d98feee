"""Closed-form IK of the serial arms: every branch FK-verified, the original q recovered."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optik import catalog, closed_form, spatial
from optik.closed_form import ik_planar_2r, ik_planar_3r, ik_pp, ik_rp, ik_seed_6r
from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError, SolverUnavailableError
from optik.mechanism import planar_chain

FK_TOL = 1e-9
SAME_Q = 1e-6

GEOMETRIES_2 = [(1.0, 0.8), (0.5, 1.3), (1.0, 1.0), (0.3, 2.0)]
GEOMETRIES_3 = [(1.0, 0.8, 0.5), (0.4, 1.1, 0.9), (1.0, 1.0, 0.2), (2.0, 0.3, 1.2)]


@functools.cache
def arm(kind, dims):
    """Catalog arms cached by geometry, so that hypothesis examples reuse the compiled FK."""
    make = getattr(catalog, kind)
    return make(*dims) if kind in ("seed_6r_arm", "rp_arm", "pp_arm") else make(dims)


def q_in_limits(m):
    return st.tuples(*(st.floats(float(lo), float(hi)) for lo, hi in zip(m.lower, m.upper, strict=True)))


def joint_distance(m, a, b):
    """Max coordinate difference, angles modulo 2 pi."""
    d = np.asarray(a, float) - np.asarray(b, float)
    ang = m.revolute_mask
    d[..., ang] = (d[..., ang] + np.pi) % (2 * np.pi) - np.pi
    return np.max(np.abs(d), axis=-1)


def fk_error(m, q, t):
    """FK error of q against target t in the mechanism's task space (planar: x, y (and phi))."""
    tq = m.fk(q)
    if m.task == "position2d":
        return float(np.max(np.abs(tq[:2, 3] - t[:2, 3])))
    return float(np.max(np.abs(tq - t)))


RAW = {
    "planar_2r": lambda m, t: ik_planar_2r(m.params["lengths"], t[0, 3], t[1, 3]),
    "planar_3r": lambda m, t: ik_planar_3r(m.params["lengths"], *spatial.planar_pose_of(t)),
    "rp_arm": lambda m, t: ik_rp(t[0, 3], t[1, 3]),
    "pp_arm": lambda m, t: ik_pp(t[0, 3], t[1, 3]),
    "seed_6r_arm": lambda m, t: ik_seed_6r(m.params["d2"], m.params["d3"], m.params["d4"], t),
}
"""The vectorized solver of each kind, called on one target (every branch, no merging)."""


def check_round_trip(m, q, recover=True, strict=True):
    """FK -> closed form -> every branch reaches the target and q itself is among the branches.

    The vectorized solver must return q to 1e-6 (``strict``); ``closed_form.ik`` merges branches
    closer than the same-branch distance 1e-4, so there q is found to 1e-4.
    """
    t = m.fk(q)
    branches = closed_form.ik(m, t, respect_limits=False)
    assert branches, f"no branch for a reachable target (q={q})"
    for b in branches:
        assert np.all(np.isfinite(b))
        assert fk_error(m, b, t) < FK_TOL
    for i in range(len(branches)):
        for j in range(i):
            assert joint_distance(m, branches[i], branches[j]) >= 1e-4
    if recover:
        raw, ok = RAW[m.kind](m, t)
        assert np.min(np.where(ok[0], joint_distance(m, raw[0], q), np.inf)) < (SAME_Q if strict else 1e-4)
        assert min(joint_distance(m, b, q) for b in branches) < 1e-4
    return branches


# ---------------------------------------------------------------------------- property tests
@settings(max_examples=200, deadline=None)
@given(dims=st.sampled_from(GEOMETRIES_2), data=st.data())
def test_planar_2r_round_trip(dims, data):
    m = arm("planar_2r", dims)
    q = np.array(data.draw(q_in_limits(m)))
    r = np.hypot(*m.fk(q)[:2, 3])
    check_round_trip(m, q, recover=r > 1e-6)


@settings(max_examples=200, deadline=None)
@given(dims=st.sampled_from(GEOMETRIES_3), data=st.data())
def test_planar_3r_round_trip(dims, data):
    m = arm("planar_3r", dims)
    l1, l2, _ = dims
    q = np.array(data.draw(q_in_limits(m)))
    wrist = l1 * np.exp(1j * q[0]) + l2 * np.exp(1j * (q[0] + q[1]))
    check_round_trip(m, q, recover=abs(wrist) > 1e-6)


@settings(max_examples=120, deadline=None)
@given(data=st.data())
def test_rp_round_trip(data):
    m = arm("rp_arm", ())
    q = np.array(data.draw(q_in_limits(m)))
    branches = check_round_trip(m, q)
    assert len(branches) == 2
    assert {np.sign(b[1]) for b in branches} == {1.0, -1.0}


@settings(max_examples=100, deadline=None)
@given(data=st.data())
def test_pp_round_trip(data):
    m = arm("pp_arm", ())
    q = np.array(data.draw(q_in_limits(m)))
    assert len(check_round_trip(m, q)) == 1


@settings(max_examples=200, deadline=None)
@given(dims=st.sampled_from(GEOMETRIES_3), data=st.data())
def test_seed_6r_round_trip(dims, data):
    m = arm("seed_6r_arm", dims)
    q = np.array(data.draw(q_in_limits(m)))
    p = m.fk(q)[:3, 3]
    # at the wrist (s5 = 0) and shoulder (p_x = p_y = 0) singularities, and when the folded elbow
    # puts the wrist centre on the shoulder (d2 = d3, theta3 = pi), q is one of infinitely many
    elbow_reach = abs(dims[0] + dims[1] * np.exp(1j * q[2]))
    regular = abs(np.sin(q[4])) > 1e-6 and np.hypot(p[0], p[1]) > 1e-6 and elbow_reach > 1e-6
    # a stretched or folded elbow angle is the square root of a rounding-level cosine, which the
    # wrist's conditioning (1 / |s5|) amplifies: there q is recovered to the same-branch 1e-4
    check_round_trip(m, q, recover=regular, strict=abs(np.sin(q[2])) > 1e-3)


# ---------------------------------------------------------------------------- thousands of targets
BATCH = 4000


def _batch_check(m, q_true, q, ok, b_expected, generic):
    """Vectorized output: shapes, finiteness, FK of every reachable branch, recovery, distinctness."""
    n = len(q_true)
    assert q.shape == (n, b_expected, m.n_q) and ok.shape == (n, b_expected)
    assert np.all(np.isfinite(q))
    assert np.all(q[~ok] == 0.0)
    t = m.fk(q_true)
    flat_q, flat_ok = q.reshape(-1, m.n_q), ok.reshape(-1)
    tb = m.fk(flat_q[flat_ok])
    tt = np.repeat(t, b_expected, axis=0)[flat_ok]
    if m.task == "position2d":
        tb, tt = tb[:, :2, 3], tt[:, :2, 3]
    assert np.max(np.abs(tb - tt)) < FK_TOL
    found = (joint_distance(m, q, q_true[:, None, :]) < SAME_Q) & ok
    assert np.all(found.any(axis=1)[generic])
    if b_expected > 1:
        both = ok.all(axis=1) & generic
        d = joint_distance(m, q[:, :, None, :], q[:, None, :, :])
        off_diag = ~np.eye(b_expected, dtype=bool)
        assert np.all(d[both][:, off_diag] > 1e-4)


def test_planar_2r_batch():
    m = catalog.planar_2r((1.0, 0.7))
    qt = m.random_q(BATCH, seed=1)
    t = m.fk(qt)
    q, ok = ik_planar_2r((1.0, 0.7), t[:, 0, 3], t[:, 1, 3])
    assert ok.all()
    _batch_check(m, qt, q, ok, 2, np.abs(np.sin(qt[:, 1])) > 1e-3)
    assert np.all(q[:, 0, 1] >= 0) and np.all(q[:, 1, 1] <= 0)


def test_planar_3r_batch():
    ls = (1.0, 0.8, 0.5)
    m = catalog.planar_3r(ls)
    qt = m.random_q(BATCH, seed=2)
    t = m.fk(qt)
    x, y, phi = spatial.planar_pose_of(t).T
    q, ok = ik_planar_3r(ls, x, y, phi)
    assert ok.all()
    _batch_check(m, qt, q, ok, 2, np.abs(np.sin(qt[:, 1])) > 1e-3)
    assert np.all(np.abs(q) <= np.pi)


def test_rp_and_pp_batch():
    for m, solve in ((catalog.rp_arm(), ik_rp), (catalog.pp_arm(), ik_pp)):
        qt = m.random_q(BATCH, seed=3)
        t = m.fk(qt)
        q, ok = solve(t[:, 0, 3], t[:, 1, 3])
        _batch_check(m, qt, q, ok, 2 if m.kind == "rp_arm" else 1, np.ones(BATCH, bool))


def test_seed_6r_batch():
    d = (1.0, 0.8, 0.3)
    m = catalog.seed_6r_arm(*d)
    qt = m.random_q(BATCH, seed=4)
    q, ok = ik_seed_6r(*d, m.fk(qt))
    generic = np.abs(np.sin(qt[:, 4])) > 1e-3
    _batch_check(m, qt, q, ok, 8, generic)
    # generically the arm has 8 branches only when the elbow reaches in both shoulder postures
    assert ok.sum(axis=1).max() == 8 and ok.sum(axis=1).min() >= 2


# ---------------------------------------------------------------------------- seed formulas
def test_3r_matches_seed_p_q_r_form_and_seed_theta3_typo_fails():
    """theta1 from the seed's P cos + Q sin + R = 0 solution (9); theta3 = phi - theta1 - theta2."""
    l1, l2, l3 = 1.0, 0.8, 0.5
    m = catalog.planar_3r((l1, l2, l3))
    rng = np.random.default_rng(5)
    for q in m.random_q(50, seed=rng):
        x, y, phi = spatial.planar_pose_of(m.fk(q))
        xp, yp = x - l3 * np.cos(phi), y - l3 * np.sin(phi)
        rr = np.hypot(xp, yp)
        gamma = np.arctan2(-yp / rr, -xp / rr)
        branches, _ = ik_planar_3r((l1, l2, l3), x, y, phi)
        for sigma, b in zip((1, -1), branches[0], strict=True):
            th1 = gamma + sigma * np.arccos(-(xp**2 + yp**2 + l1**2 - l2**2) / (2 * l1 * rr))
            th2 = np.arctan2(yp - l1 * np.sin(th1), xp - l1 * np.cos(th1)) - th1
            assert abs(spatial.wrap_angle(b[0] - th1)) < 1e-9
            assert abs(spatial.wrap_angle(b[1] - th2)) < 1e-9
            typo = np.array([th1, th2, phi - th1 + th2])
            assert fk_error(m, typo, m.fk(q)) > 1e-3 or abs(np.sin(th2)) < 1e-3


# ---------------------------------------------------------------------------- unreachable, limits
def test_unreachable_is_empty_and_finite():
    q, ok = ik_planar_2r((1.0, 0.5), [2.0, 0.1, 0.0], [0.0, 0.2, 0.0])
    assert not ok.any() and np.all(q == 0.0)
    m = catalog.planar_2r((1.0, 0.5))
    assert closed_form.ik(m, spatial.translation(2.0, 0.0, 0.0)) == []
    m3 = catalog.planar_3r((1.0, 0.8, 0.5))
    assert closed_form.ik(m3, spatial.planar_pose(3.0, 0.0, 0.0)) == []
    m6 = catalog.seed_6r_arm()
    t = spatial.translation(0.0, 0.0, 5.0)
    q6, ok6 = ik_seed_6r(1.0, 0.8, 0.3, t)
    assert not ok6.any() and np.all(np.isfinite(q6))
    assert closed_form.ik(m6, t) == []


def test_boundary_target_is_reached_once():
    """At full stretch the two elbow branches coincide and are reported once."""
    m = catalog.planar_2r((1.0, 0.5))
    branches = closed_form.ik(m, spatial.translation(1.5, 0.0, 0.0))
    assert len(branches) == 1
    assert fk_error(m, branches[0], spatial.translation(1.5, 0.0, 0.0)) < FK_TOL


def test_degenerate_targets_have_documented_representative():
    q, ok = ik_planar_2r((1.0, 1.0), 0.0, 0.0)
    assert ok.all()
    np.testing.assert_allclose(np.abs(q[0]), [[0.0, np.pi], [0.0, np.pi]])
    q, ok = ik_rp(0.0, 0.0)
    np.testing.assert_allclose(np.abs(q[0]), [[0.0, 0.0], [np.pi, 0.0]])
    m = catalog.seed_6r_arm()
    for q0 in ([0.3, 0.4, -0.5, 0.2, 0.0, 0.7], [0.3, 0.4, -0.5, 0.2, np.pi, 0.7]):
        check_round_trip(m, np.array(q0), recover=False)
    t = m.fk(np.array([0.3, np.pi / 2, 0.0, 0.0, 0.5, 0.7]))
    t[:2, 3] = 0.0  # exactly on the shoulder axis
    branches = closed_form.ik(m, t, respect_limits=False)
    assert branches and all(fk_error(m, b, t) < FK_TOL for b in branches)


def test_limit_filtering():
    m = catalog.planar_2r((1.0, 0.7))
    q = np.array([0.4, -1.1])
    t = m.fk(q)
    assert len(closed_form.ik(m, t)) == 2
    narrowed = m.with_limits(lower=[-np.pi, 0.0], upper=[np.pi, np.pi])
    (only,) = closed_form.ik(narrowed, t)
    assert only[1] > 0 and fk_error(m, only, t) < FK_TOL
    assert closed_form.ik(m.with_limits(lower=[-np.pi, -0.5], upper=[np.pi, 0.5]), t) == []
    # the R-P arm's default stroke (r >= 0.2) removes the r < 0 branch
    rp = catalog.rp_arm()
    branches = closed_form.ik(rp, rp.fk(np.array([2.5, 1.0])))
    assert len(branches) == 1 and branches[0][1] == pytest.approx(1.0)
    # seed 6R: theta1 near the original leaves the shoulder's other posture out
    m6 = catalog.seed_6r_arm()
    q6 = np.array([0.3, 0.4, -0.5, 0.2, 0.9, 0.7])
    t6 = m6.fk(q6)
    lo, hi = m6.lower.copy(), m6.upper.copy()
    lo[0], hi[0] = 0.0, 1.0
    kept = closed_form.ik(m6.with_limits(lo, hi), t6)
    assert kept and all(0.0 <= b[0] <= 1.0 for b in kept)
    assert len(kept) < len(closed_form.ik(m6, t6))


def test_angles_shifted_into_limits():
    """A branch at theta1 = -3 is reported as theta1 = 2 pi - 3 when the limits are [0, 2 pi]."""
    m = catalog.planar_2r((1.0, 0.7), lower=[0.0, -np.pi], upper=[2 * np.pi, np.pi])
    q = np.array([2 * np.pi - 3.0, 1.0])
    branches = closed_form.ik(m, m.fk(q))
    assert min(np.max(np.abs(b - q)) for b in branches) < SAME_Q


# ---------------------------------------------------------------------------- API and errors
def test_dispatch_errors_for_mechanisms_without_closed_form():
    hand_built = planar_chain("RRRR", (1.0, 1.0, 1.0, 1.0))
    assert not closed_form.has_ik(hand_built)
    with pytest.raises(SolverUnavailableError, match="no closed-form IK"):
        closed_form.ik(hand_built, np.eye(4))
    renamed = catalog.planar_3r()
    renamed.kind = "not_a_catalog_kind"
    with pytest.raises(SolverUnavailableError):
        closed_form.ik(renamed, np.eye(4))
    for make in (catalog.planar_2r, catalog.planar_3r, catalog.rp_arm, catalog.pp_arm, catalog.seed_6r_arm):
        assert closed_form.has_ik(make())


def test_bad_input_names_the_argument():
    with pytest.raises(InvalidArgumentError, match="lengths"):
        ik_planar_2r((1.0, -0.5), 0.0, 0.0)
    with pytest.raises(InvalidArgumentError, match="lengths"):
        ik_planar_3r((1.0, 0.5), 0.0, 0.0, 0.0)
    with pytest.raises(NonFiniteError, match=r"^x:"):
        ik_planar_2r((1.0, 0.5), [0.0, np.nan], 0.0)
    with pytest.raises(NonFiniteError, match="phi"):
        ik_planar_3r((1.0, 0.5, 0.2), 0.0, 0.0, np.inf)
    with pytest.raises(ShapeError, match="x/y"):
        ik_rp(np.zeros(3), np.zeros(4))
    with pytest.raises(InvalidArgumentError, match=r"^y:"):
        ik_pp(0.0, "a")
    with pytest.raises(ShapeError, match=r"^t:"):
        ik_seed_6r(1.0, 0.8, 0.3, np.eye(3))
    with pytest.raises(NonFiniteError, match=r"^t:"):
        ik_seed_6r(1.0, 0.8, 0.3, np.full((4, 4), np.nan))
    with pytest.raises(InvalidArgumentError, match="d2/d3/d4"):
        ik_seed_6r(1.0, 0.0, 0.3, np.eye(4))
    with pytest.raises(InvalidArgumentError, match="target"):
        closed_form.ik(catalog.planar_2r(), np.full((4, 4), np.nan))


def test_shapes_scalars_and_broadcasting():
    q, ok = ik_planar_3r((1.0, 0.8, 0.5), 1.0, 0.5, 0.3)
    assert q.shape == (1, 2, 3) and ok.shape == (1, 2)
    q, ok = ik_planar_3r((1.0, 0.8, 0.5), np.ones((4, 5)), 0.5, np.zeros(5))
    assert q.shape == (20, 2, 3) and ok.shape == (20, 2)
    q, ok = ik_seed_6r(1.0, 0.8, 0.3, np.stack([np.eye(4)] * 3))
    assert q.shape == (3, 8, 6)


def test_rpy_and_zyz_are_reexports():
    assert closed_form.rpy_all is spatial.rot_to_rpy_all
    assert closed_form.zyz_all is spatial.rot_to_zyz_all
