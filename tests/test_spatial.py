"""Spatial math: rotations, transforms, RPY/ZYZ, so(3) exp/log, pose errors; numpy and CasADi alike."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optik import spatial

angle = st.floats(-np.pi, np.pi)
unit_vectors = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: np.linalg.norm(v) > 1e-3
)


def is_rotation(r, tol=1e-12):
    return np.allclose(r @ r.T, np.eye(3), atol=tol) and np.linalg.det(r) == pytest.approx(1.0, abs=tol)


@st.composite
def rotations(draw):
    """Rotations from random axis-angle, including half-turns and the identity."""
    axis = np.array(draw(unit_vectors))
    theta = draw(st.one_of(st.floats(0, np.pi), st.sampled_from([0.0, np.pi, np.pi - 1e-5, 1e-9])))
    return spatial.so3_exp(axis / np.linalg.norm(axis) * theta)


# ---------------------------------------------------------------------------- rotations and transforms
def test_elementary_rotations():
    a = 0.3
    c, s = np.cos(a), np.sin(a)
    np.testing.assert_allclose(spatial.rot_x(a), [[1, 0, 0], [0, c, -s], [0, s, c]])
    np.testing.assert_allclose(spatial.rot_y(a), [[c, 0, s], [0, 1, 0], [-s, 0, c]])
    np.testing.assert_allclose(spatial.rot_z(a), [[c, -s, 0], [s, c, 0], [0, 0, 1]])


@settings(max_examples=100, deadline=None)
@given(a=angle, b=angle)
def test_rotations_compose_and_are_orthonormal(a, b):
    for rot in (spatial.rot_x, spatial.rot_y, spatial.rot_z):
        assert is_rotation(rot(a))
        np.testing.assert_allclose(rot(a) @ rot(b), rot(a + b), atol=1e-12)
        np.testing.assert_allclose(rot(-a), rot(a).T, atol=1e-15)


def test_hat_vee_and_cross_product():
    w, v = np.array([0.3, -1.2, 0.5]), np.array([2.0, 0.1, -0.7])
    np.testing.assert_allclose(spatial.hat(w) @ v, np.cross(w, v))
    np.testing.assert_allclose(spatial.vee(spatial.hat(w)), w)


@settings(max_examples=100, deadline=None)
@given(r=rotations(), p=st.tuples(*[st.floats(-10, 10)] * 3))
def test_transform_inverse(r, p):
    t = spatial.transform(r, p)
    np.testing.assert_allclose(t @ spatial.inv_transform(t), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(spatial.rotation_of(t), r)
    np.testing.assert_allclose(spatial.translation_of(t), p)


def test_translation_and_planar_pose():
    np.testing.assert_allclose(spatial.translation(1, 2, 3)[:3, 3], [1, 2, 3])
    t = spatial.planar_pose(0.5, -0.2, 2.0)
    np.testing.assert_allclose(t[:3, :3], spatial.rot_z(2.0))
    np.testing.assert_allclose(spatial.planar_pose_of(t), [0.5, -0.2, 2.0])


@settings(max_examples=200, deadline=None)
@given(a=st.floats(-100, 100))
def test_wrap_angle(a):
    w = spatial.wrap_angle(a)
    assert -np.pi < w <= np.pi
    assert np.cos(w) == pytest.approx(np.cos(a), abs=1e-9) and np.sin(w) == pytest.approx(np.sin(a), abs=1e-9)


@settings(max_examples=300, deadline=None)
@given(
    a=st.floats(-1e12, 1e12)
    | st.sampled_from([np.pi, -np.pi, 3 * np.pi, -3 * np.pi, np.nextafter(-np.pi, 0.0)])
)
def test_wrap_angle_float_path_matches_the_array_path(a):
    """A Python float takes plain float arithmetic; the numbers are those of the numpy path."""
    w = spatial.wrap_angle(a)
    assert type(w) is float
    assert w == float(spatial.wrap_angle(np.array([a]))[0]) == spatial.wrap_angle(np.float64(a))


def test_wrap_angle_boundaries_and_arrays():
    assert spatial.wrap_angle(np.pi) == np.pi
    assert spatial.wrap_angle(-np.pi) == np.pi
    w = spatial.wrap_angle(np.array([-np.pi, 3 * np.pi, 0.0, -7.0]))
    assert np.all((w > -np.pi) & (w <= np.pi))


def _gap(x, lo, hi):
    return max(lo - x, x - hi, 0.0)


SHIFT_EPS = 1e-9
"""Rounding allowance (rad) of the wrap properties: a shift within this of a limit may land on
either side of it."""


@settings(max_examples=400, deadline=None)
@given(
    q=st.one_of(st.floats(-60, 60), st.sampled_from([np.pi, -np.pi, 0.0, 3.7525 + 6e-8, -3.9])),
    lo=st.one_of(st.floats(-20, 20), st.sampled_from([-np.pi, -3.9, -0.0175])),
    width=st.one_of(st.floats(0, 15), st.sampled_from([0.0, np.inf, 3.7700])),
    unbounded_below=st.booleans(),
)
def test_wrap_to_limits_properties(q, lo, width, unbounded_below):
    """The result is q + 2 pi k; a value within the limits stays within them (unchanged when it is
    in (-pi, pi]); the result is within the limits when some whole-turn shift of q is, else it is
    the shift nearest the limits; the value in (-pi, pi] is taken when it is within them."""
    lo, hi = (-np.inf if unbounded_below else lo), lo + width
    w = float(spatial.wrap_to_limits(np.array([q, q]), [lo, -np.inf], [hi, np.inf], [True, False])[0])
    assert spatial.wrap_to_limits(np.array([q, q]), [lo, -np.inf], [hi, np.inf], [True, False])[1] == q
    turns = (w - q) / (2 * np.pi)
    assert abs(turns - round(turns)) * 2 * np.pi <= SHIFT_EPS
    if lo <= q <= hi:
        assert lo <= w <= hi
        if -np.pi < q <= np.pi:
            assert w == q
    shifts = [q + 2 * np.pi * k for k in range(-30, 31)]
    if any(lo + SHIFT_EPS <= x <= hi - SHIFT_EPS for x in shifts):
        assert lo <= w <= hi
    assert _gap(w, lo, hi) <= min(_gap(x, lo, hi) for x in shifts) + SHIFT_EPS
    c = spatial.wrap_angle(q)
    if lo + SHIFT_EPS <= c <= hi - SHIFT_EPS and not lo <= q <= hi:
        assert w == pytest.approx(c, abs=SHIFT_EPS)


def test_wrap_to_limits_keeps_a_rounding_past_a_limit_beyond_pi_on_its_side():
    """The Panda's joint 6, limits [-0.0175, 3.7525]: 3.7525 + 6e-8 used to wrap to -2.53, past
    the other limit, where a clip moved it (another pose, 0.26 m away)."""
    lo, hi = np.array([-0.0175, -3.9]), np.array([3.7525, 0.8])
    q = np.array([[3.7525 + 6e-8, -3.9 - 1e-9], [3.7525 + 6e-8 + 2 * np.pi, 0.8 + 1e-9 - 2 * np.pi]])
    got = np.clip(spatial.wrap_to_limits(q, lo, hi, [True, True]), lo, hi)
    np.testing.assert_allclose(got, [[3.7525, -3.9], [3.7525, 0.8]], rtol=0, atol=1e-12)
    rows = np.random.default_rng(0).uniform(-20, 20, (50, 2))  # rows are wrapped one by one
    np.testing.assert_array_equal(
        spatial.wrap_to_limits(rows, lo, hi, [True, True]),
        [spatial.wrap_to_limits(r, lo, hi, [True, True]) for r in rows],
    )


entries = st.one_of(
    st.floats(-60, 60),
    st.sampled_from([np.pi, -np.pi, 0.0, -0.0, 3.7525 + 6e-8, -3.9, np.nan, np.inf, -np.inf]),
)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(
    shape=st.lists(st.integers(1, 5), min_size=0, max_size=3),
    data=st.data(),
    limits=st.lists(
        st.tuples(
            st.one_of(st.floats(-20, 20), st.sampled_from([-np.pi, -3.9, -0.0175])),
            st.one_of(st.floats(0, 15), st.sampled_from([0.0, np.inf, 3.7700])),
            st.booleans(),
            st.booleans(),
        ),
        min_size=1,
        max_size=4,
    ),
)
def test_wrap_to_limits_is_the_per_entry_rule_over_any_leading_shape(shape, data, limits):
    """Any ``(..., n)`` array (3+ dimensions too) gives, entry by entry, exactly what
    `spatial.wrap_into` gives for that angle (NaN for a non-finite one); other coordinates are
    untouched."""
    hi = np.array([a + w for a, w, _, _ in limits])
    lo = np.array([-np.inf if unbounded else a for a, _, unbounded, _ in limits])
    angular = np.array([m for *_, m in limits])
    n = len(limits)
    q = np.array(
        data.draw(st.lists(entries, min_size=n * int(np.prod(shape)), max_size=n * int(np.prod(shape))))
    )
    q = q.reshape((*shape, n))
    got = spatial.wrap_to_limits(q, lo, hi, angular)
    assert got.shape == q.shape
    want = q.copy()
    for idx in np.ndindex(q.shape):
        if angular[idx[-1]]:
            want[idx] = spatial.wrap_into(float(q[idx]), float(lo[idx[-1]]), float(hi[idx[-1]]))
    np.testing.assert_array_equal(got, want)


def test_wrap_to_limits_is_wrap_into_entry_by_entry():
    """The array arithmetic (every rule) gives exactly the numbers of the one-angle rule `wrap_into`:
    entries in and out of (-pi, pi], on +-pi, NaN and inf, limits beyond pi, one-sided and wide."""
    rng = np.random.default_rng(1)
    q = rng.uniform(-30.0, 30.0, (4000, 5))
    q[::7, 1], q[::5, 2], q[::3, 3], q[::11, 4] = np.nan, np.pi, -np.pi, np.inf
    q[::13, 0] = rng.uniform(-np.pi, np.pi, q[::13, 0].shape)
    lo = np.array([-2 * np.pi, -0.0175, -3.9, -1.0, -np.pi])
    hi = np.array([2 * np.pi, 3.7525, 0.8, np.inf, np.pi])
    got = spatial.wrap_to_limits(q, lo, hi, [True] * 5)
    want = [[spatial.wrap_into(float(v), lo[k], hi[k]) for k, v in enumerate(row)] for row in q]
    np.testing.assert_array_equal(got, want)


# ---------------------------------------------------------------------------- RPY and ZYZ
@settings(max_examples=150, deadline=None)
@given(r=rotations())
def test_rpy_round_trip_in_seed_ranges(r):
    roll, pitch, yaw = spatial.rot_to_rpy(r)
    assert -np.pi / 2 <= pitch <= np.pi / 2
    assert -np.pi <= roll <= np.pi and -np.pi <= yaw <= np.pi
    np.testing.assert_allclose(spatial.rpy_to_rot(roll, pitch, yaw), r, atol=1e-9)
    branches = spatial.rot_to_rpy_all(r)
    assert 1 <= len(branches) <= 2
    for b in branches:
        np.testing.assert_allclose(spatial.rpy_to_rot(*b), r, atol=1e-9)
    if len(branches) == 2:
        assert np.max(np.abs(spatial.wrap_angle(branches[0] - branches[1]))) > 1e-6


def test_rpy_is_z_y_x_and_seed_formulas():
    """Seed 001: ``phi_z = atan2(n_y, n_x)``, ``phi_y = atan2(-n_z, n_x c_z + n_y s_z)``."""
    roll, pitch, yaw = 0.4, -0.7, 2.1
    r = spatial.rpy_to_rot(roll, pitch, yaw)
    np.testing.assert_allclose(r, spatial.rot_z(yaw) @ spatial.rot_y(pitch) @ spatial.rot_x(roll))
    np.testing.assert_allclose(spatial.rot_to_rpy(r), [roll, pitch, yaw], atol=1e-12)
    assert len(spatial.rot_to_rpy_all(r)) == 2


@settings(max_examples=150, deadline=None)
@given(rpy=st.tuples(st.floats(-10, 10), st.floats(-10, 10), st.floats(-10, 10)))
def test_rpy_float_path_matches_the_matrix_products(rpy):
    """Three floats take the written-out product (URDF origins); arrays the three matrix
    products: the same rotation to rounding, for Python and numpy scalars alike."""
    products = spatial.rot_z(rpy[2]) @ spatial.rot_y(rpy[1]) @ spatial.rot_x(rpy[0])
    batched = spatial.rpy_to_rot(*(np.array([a]) for a in rpy))[0]
    for r in (spatial.rpy_to_rot(*rpy), spatial.rpy_to_rot(*np.array(rpy))):
        assert isinstance(r, np.ndarray) and r.shape == (3, 3) and is_rotation(r)
        np.testing.assert_allclose(r, products, rtol=0, atol=4e-16)
        np.testing.assert_allclose(r, batched, rtol=0, atol=4e-16)


@pytest.mark.parametrize("pitch", [np.pi / 2, -np.pi / 2])
def test_rpy_gimbal_lock(pitch):
    r = spatial.rpy_to_rot(0.3, pitch, 1.1)
    (only,) = spatial.rot_to_rpy_all(r)
    assert only[2] == 0.0 and only[1] == pytest.approx(pitch)
    np.testing.assert_allclose(spatial.rpy_to_rot(*only), r, atol=1e-12)


@settings(max_examples=150, deadline=None)
@given(r=rotations())
def test_zyz_round_trip_in_seed_ranges(r):
    phi, theta, psi = spatial.rot_to_zyz(r)
    assert -np.pi < phi <= np.pi and 0 <= theta <= np.pi and -np.pi <= psi < np.pi
    np.testing.assert_allclose(spatial.zyz_to_rot(phi, theta, psi), r, atol=1e-9)
    branches = spatial.rot_to_zyz_all(r)
    for b in branches:
        np.testing.assert_allclose(spatial.zyz_to_rot(*b), r, atol=1e-9)
    if len(branches) == 2:
        assert branches[1][1] < 0


@pytest.mark.parametrize("theta", [0.0, np.pi])
def test_zyz_gimbal_lock(theta):
    r = spatial.zyz_to_rot(0.7, theta, -0.4)
    (only,) = spatial.rot_to_zyz_all(r)
    assert only[0] == 0.0
    np.testing.assert_allclose(spatial.zyz_to_rot(*only), r, atol=1e-12)


def test_zyz_psi_half_open_range():
    """``psi = pi`` is reported as ``-pi`` (seed range ``-pi <= psi < pi``)."""
    psi = spatial.rot_to_zyz(spatial.zyz_to_rot(0.5, 1.0, np.pi))[2]
    assert psi == pytest.approx(-np.pi)


# ---------------------------------------------------------------------------- so(3)
@settings(max_examples=200, deadline=None)
@given(r=rotations())
def test_so3_log_exp_round_trip(r):
    w = spatial.so3_log(r)
    assert np.linalg.norm(w) <= np.pi + 1e-12
    np.testing.assert_allclose(spatial.so3_exp(w), r, atol=1e-9)
    assert np.linalg.norm(w) == pytest.approx(spatial.rotation_angle(r), abs=1e-9)


@pytest.mark.parametrize("theta", [0.0, 1e-12, 1e-7, 1.0, np.pi - 1e-2, np.pi - 1e-4, np.pi - 1e-7, np.pi])
def test_so3_log_near_zero_and_pi(theta):
    axis = np.array([0.48, -0.6, 0.64])
    w = axis * theta
    w_back = spatial.so3_log(spatial.so3_exp(w))
    if theta == np.pi:  # a half-turn about a is also one about -a
        assert np.allclose(w_back, w, atol=1e-9) or np.allclose(w_back, -w, atol=1e-9)
    else:
        np.testing.assert_allclose(w_back, w, atol=1e-9)


def test_rotation_angle_and_angle_between():
    assert spatial.rotation_angle(spatial.rot_x(0.3)) == pytest.approx(0.3)
    assert spatial.angle_between(spatial.rot_z(0.1), spatial.rot_z(-0.4)) == pytest.approx(0.5)


def test_pose_error():
    t_target = spatial.transform(spatial.rpy_to_rot(0.1, 0.2, 0.3), [1.0, 2.0, 3.0])
    np.testing.assert_allclose(spatial.pose_error(t_target, t_target), np.zeros(6), atol=1e-15)
    w = np.array([0.01, -0.02, 0.03])
    t = spatial.transform(spatial.so3_exp(w) @ t_target[:3, :3], t_target[:3, 3] + [0.1, 0.0, -0.2])
    np.testing.assert_allclose(spatial.pose_error(t, t_target), [0.1, 0.0, -0.2, *w], atol=1e-12)


# ---------------------------------------------------------------------------- numpy vs CasADi, batches
def _casadi(fn, *shapes):
    syms = [ca.SX.sym(f"x{i}", *s) for i, s in enumerate(shapes)]
    return ca.Function("f", syms, [fn(*syms)])


def test_numpy_and_casadi_agree():
    rng = np.random.default_rng(3)
    r = spatial.so3_exp(rng.normal(size=3))
    t = spatial.transform(r, rng.normal(size=3))
    t2 = spatial.transform(spatial.so3_exp(rng.normal(size=3)), rng.normal(size=3))
    r_pi = spatial.so3_exp(np.array([0.0, 0.6, 0.8]) * (np.pi - 1e-5))
    cases = [
        (spatial.rot_x, [(1, 1)], [0.7]),
        (spatial.rot_y, [(1, 1)], [0.7]),
        (spatial.rot_z, [(1, 1)], [0.7]),
        (spatial.rpy_to_rot, [(1, 1)] * 3, [0.1, -0.5, 2.0]),
        (spatial.zyz_to_rot, [(1, 1)] * 3, [0.1, 1.5, 2.0]),
        (spatial.rot_to_rpy, [(3, 3)], [r]),
        (spatial.rot_to_zyz, [(3, 3)], [r]),
        (spatial.so3_exp, [(3, 1)], [rng.normal(size=3)]),
        (spatial.so3_log, [(3, 3)], [r]),
        (spatial.so3_log, [(3, 3)], [r_pi]),
        (spatial.rotation_angle, [(3, 3)], [r]),
        (spatial.inv_transform, [(4, 4)], [t]),
        (spatial.pose_error, [(4, 4), (4, 4)], [t, t2]),
        (spatial.planar_pose, [(1, 1)] * 3, [0.3, -0.2, 1.0]),
        (spatial.planar_pose_of, [(4, 4)], [spatial.planar_pose(0.3, -0.2, 1.0)]),
        (spatial.wrap_angle, [(1, 1)], [7.0]),
    ]
    for fn, shapes, args in cases:
        numeric = np.asarray(fn(*args), dtype=float)
        symbolic = np.asarray(_casadi(fn, *shapes)(*args), dtype=float)
        np.testing.assert_allclose(symbolic.reshape(numeric.shape), numeric, atol=1e-9, err_msg=fn.__name__)


def test_batches_equal_single_evaluations():
    rng = np.random.default_rng(4)
    a = rng.uniform(-np.pi, np.pi, 7)
    for rot in (spatial.rot_x, spatial.rot_y, spatial.rot_z):
        np.testing.assert_allclose(rot(a), np.stack([rot(x) for x in a]))
    ws = rng.normal(size=(7, 3))
    rs = spatial.so3_exp(ws)
    np.testing.assert_allclose(rs, np.stack([spatial.so3_exp(w) for w in ws]))
    np.testing.assert_allclose(spatial.so3_log(rs), np.stack([spatial.so3_log(r) for r in rs]))
    np.testing.assert_allclose(spatial.rot_to_rpy(rs), np.stack([spatial.rot_to_rpy(r) for r in rs]))
    np.testing.assert_allclose(spatial.rot_to_zyz(rs), np.stack([spatial.rot_to_zyz(r) for r in rs]))
    ts = spatial.transform(rs, rng.normal(size=(7, 3)))
    np.testing.assert_allclose(spatial.inv_transform(ts), np.linalg.inv(ts), atol=1e-12)
    # a batch mixing ordinary rotations and near half-turns
    mixed = spatial.so3_exp(np.array([[0.1, 0.2, 0.3], [0.0, 0.0, np.pi - 1e-6]]))
    np.testing.assert_allclose(spatial.so3_exp(spatial.so3_log(mixed)), mixed, atol=1e-9)


def test_angle_distance_compares_modulo_two_pi_and_broadcasts():
    assert spatial.angle_distance([np.pi, 0.0], [-np.pi, 0.0]) == 0.0
    assert spatial.angle_distance([0.1, 2 * np.pi + 0.3], [0.0, 0.0]) == pytest.approx(0.3)
    got = spatial.angle_distance(np.array([[0.0, 0.0], [1.0, -1.0]]), np.array([0.5, 0.0]))
    np.testing.assert_allclose(got, [0.5, 1.0])
