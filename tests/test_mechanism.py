"""Mechanism model: mobility, FK against the seed formulas, Jacobians, statics, DH builders, errors."""

from __future__ import annotations

import functools
import inspect
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optik import catalog, spatial
from optik.errors import (
    InvalidArgumentError,
    LimitsError,
    ModelError,
    NonFiniteError,
    OptikError,
    ShapeError,
    UnknownFrameError,
)
from optik.mechanism import Joint, Mechanism, dh_chain, planar_chain
from optik.mechanism.topology import gruebler_kutzbach
from optik.solvers import solve_ik


def _catalog_names() -> list[str]:
    """Every catalog constructor that builds a mechanism from its defaults."""
    names = []
    for name in catalog.__all__:
        obj = getattr(catalog, name)
        if not inspect.isfunction(obj):
            continue
        params = inspect.signature(obj).parameters.values()
        if all(p.default is not inspect.Parameter.empty for p in params) and isinstance(obj(), Mechanism):
            names.append(name)
    return names


CATALOG = _catalog_names()


@functools.cache
def built(name: str) -> Mechanism:
    return getattr(catalog, name)()


def test_catalog_discovery_sees_the_seed_mechanisms():
    seeds = {"planar_2r", "planar_3r", "rp_arm", "pp_arm", "seed_6r_arm", "slider_crank", "five_bar"}
    assert seeds | {"planar_3rpr", "stewart_gough", "doggy"} <= set(CATALOG)


# ---------------------------------------------------------------------------- mobility
KNOWN_MOBILITY = {
    "planar_2r": 2,
    "planar_3r": 3,
    "rp_arm": 2,
    "pp_arm": 2,
    "seed_6r_arm": 6,
    "puma560": 6,
    "panda": 7,
    "iiwa14": 7,
    "dual_panda": 15,  # two arms of 7 on a torso joint
    "slider_crank": 1,
    "five_bar": 2,
    "doggy": 3,
    "planar_3rpr": 3,
    "stewart_gough": 6,
}
"""The known mobility of every catalog mechanism (the textbook count of each linkage)."""


def test_every_catalog_mechanism_has_a_known_mobility():
    assert set(CATALOG) <= set(KNOWN_MOBILITY)


@pytest.mark.parametrize("name", sorted(KNOWN_MOBILITY))
def test_mobility(name):
    assert built(name).mobility() == KNOWN_MOBILITY[name]


TURN = spatial.transform(spatial.rot_y(np.pi / 2) @ spatial.rot_x(0.3), np.zeros(3))
"""A turn that takes the x-y plane out of itself (revolute axes from z to x)."""


def _stood_up(m: Mechanism) -> Mechanism:
    """``m`` turned by `TURN`: the same linkage, no longer recognised as planar, so that its
    closures are spatial (5 rows per revolute cut joint)."""
    joints = [replace(j, origin=TURN @ j.origin) if j.parent == m.base else j for j in m.joints]
    stood = m._rebuild(joints)
    assert not stood.planar
    return stood


@pytest.mark.parametrize("name", ["slider_crank", "five_bar", "doggy", "planar_3rpr"])
def test_mobility_of_planar_loops_built_in_3d(name):
    """Gruebler-Kutzbach counts 6 constraints per loop in 3-D (five-bar: 6 (4 - 5) + 5 = -1);
    the loops impose 3, which the closure Jacobian's rank sees."""
    m = built(name)
    stood = _stood_up(m)
    q = m.mid_q()
    np.testing.assert_allclose(stood.fk(q), TURN @ m.fk(q), atol=1e-12)  # the same linkage, turned
    assert stood.n_closure > m.n_closure
    assert gruebler_kutzbach(len(stood.topology.bodies) - 1, stood.joints, False) < KNOWN_MOBILITY[name]
    assert stood.mobility() == KNOWN_MOBILITY[name]


def test_mobility_falls_back_to_gruebler_when_nothing_assembles(caplog):
    """A five-bar whose links cannot meet (base pivots 10 m apart, links of 1 m): no start
    assembles, the topology's count is returned and the fallback is logged."""
    m = catalog.five_bar(base=((0.0, 0.0), (10.0, 0.0)), lengths=(1.0, 1.0, 1.0, 1.0))
    with caplog.at_level("WARNING", logger="optik.mechanism.mechanism"):
        assert m.mobility() == 2
    assert "Gruebler" in caplog.text


def test_closed_chains_have_closures_and_serial_arms_none():
    for name in ("planar_2r", "planar_3r", "rp_arm", "pp_arm", "seed_6r_arm"):
        m = built(name)
        assert not m.is_closed and m.closure(m.mid_q()).shape == (0,)
    for name in ("slider_crank", "five_bar", "doggy", "planar_3rpr", "stewart_gough"):
        assert built(name).is_closed and built(name).n_closure > 0


# ---------------------------------------------------------------------------- FK vs seed formulas
angles = st.floats(-np.pi, np.pi)


@settings(max_examples=100, deadline=None)
@given(q=st.tuples(angles, angles, angles))
def test_planar_3r_fk_is_seed_equation_1(q):
    l1, l2, l3 = 1.0, 0.8, 0.5
    t = built("planar_3r").fk(np.array(q))
    t1, t12, t123 = q[0], q[0] + q[1], q[0] + q[1] + q[2]
    x = l1 * np.cos(t1) + l2 * np.cos(t12) + l3 * np.cos(t123)
    y = l1 * np.sin(t1) + l2 * np.sin(t12) + l3 * np.sin(t123)
    np.testing.assert_allclose(t, spatial.planar_pose(x, y, t123), atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(theta=angles, r=st.floats(0.2, 2.0))
def test_rp_fk_is_seed_theta_r(theta, r):
    """Seed 001: ``T = Rot(z, theta) Trans(x, r)``."""
    c, s = np.cos(theta), np.sin(theta)
    expected = np.array([[c, -s, 0, r * c], [s, c, 0, r * s], [0, 0, 1, 0], [0, 0, 0, 1]])
    np.testing.assert_allclose(built("rp_arm").fk(np.array([theta, r])), expected, atol=1e-12)


def test_pp_fk():
    np.testing.assert_allclose(
        built("pp_arm").fk(np.array([0.3, -0.7])), spatial.translation(0.3, -0.7), atol=0
    )


def seed_6r_formulas(q, d2, d3, d4, printed_ny=False):
    """The complete 6-joint transform as printed in seed 001 (n_y optionally with its sign typo)."""
    c = np.cos(q)
    s = np.sin(q)
    c1, c2, c5, c6 = c[0], c[1], c[4], c[5]
    s1, s2, s5, s6 = s[0], s[1], s[4], s[5]
    c23, s23 = np.cos(q[1] + q[2]), np.sin(q[1] + q[2])
    c234, s234 = np.cos(q[1] + q[2] + q[3]), np.sin(q[1] + q[2] + q[3])
    nx = c1 * (c234 * c5 * c6 - s234 * s6) - s1 * s5 * c6
    ny = s1 * (c234 * c5 * c6 - s234 * s6) + (-1 if printed_ny else 1) * c1 * s5 * c6
    nz = s234 * c5 * c6 + c234 * s6
    ox = -c1 * (c234 * c5 * s6 + s234 * c6) + s1 * s5 * s6
    oy = -s1 * (c234 * c5 * s6 + s234 * c6) - c1 * s5 * s6
    oz = -s234 * c5 * s6 + c234 * c6
    ax = c1 * c234 * s5 + s1 * c5
    ay = s1 * c234 * s5 - c1 * c5
    az = s234 * s5
    rho = c234 * d4 + c23 * d3 + c2 * d2
    pz = s234 * d4 + s23 * d3 + s2 * d2
    return np.array([[nx, ox, ax, c1 * rho], [ny, oy, ay, s1 * rho], [nz, oz, az, pz], [0.0, 0.0, 0.0, 1.0]])


@settings(max_examples=100, deadline=None)
@given(q=st.tuples(*[angles] * 6))
def test_seed_6r_fk_is_seed_transform_with_corrected_ny(q):
    qq = np.array(q)
    np.testing.assert_allclose(built("seed_6r_arm").fk(qq), seed_6r_formulas(qq, 1.0, 0.8, 0.3), atol=1e-12)


def test_seed_6r_printed_ny_has_a_sign_error():
    q = np.array([0.3, -0.4, 0.5, 0.2, 0.9, -0.6])
    t = built("seed_6r_arm").fk(q)
    assert abs(seed_6r_formulas(q, 1.0, 0.8, 0.3, printed_ny=True)[1, 0] - t[1, 0]) > 0.1
    # the printed column would not even be a unit vector orthogonal to o and a
    r_printed = seed_6r_formulas(q, 1.0, 0.8, 0.3, printed_ny=True)[:3, :3]
    assert not np.allclose(r_printed.T @ r_printed, np.eye(3), atol=1e-3)


def test_seed_6r_fk_is_product_of_a_matrices():
    """``A_n = Rot(z, theta_n) Trans(x, d_n) Rot(x, alpha_n)`` multiplied by hand."""
    d = (0.0, 1.0, 0.8, 0.3, 0.0, 0.0)
    alpha = np.radians([90, 0, 0, -90, 90, 0])
    q = np.array([0.1, 0.7, -1.2, 0.4, -0.8, 2.0])
    t = np.eye(4)
    for k in range(6):
        t = (
            t
            @ spatial.transform(spatial.rot_z(q[k]))
            @ spatial.translation(d[k])
            @ spatial.transform(spatial.rot_x(alpha[k]))
        )
    np.testing.assert_allclose(built("seed_6r_arm").fk(q), t, atol=1e-12)


# ---------------------------------------------------------------------------- Jacobian vs finite differences
def finite_difference_jacobian(m: Mechanism, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences: linear part from positions, angular part from
    ``(log(R(q + h e_k) R(q)^T) - log(R(q - h e_k) R(q)^T)) / (2 h)``."""
    n = m.n_q
    steps = np.concatenate([q + h * np.eye(n), q - h * np.eye(n), q[None]])
    t = m.fk(steps)
    r0 = t[-1, :3, :3]
    tp, tm = t[:n], t[n : 2 * n]
    lin = (tp[:, :3, 3] - tm[:, :3, 3]) / (2 * h)
    ang = (spatial.so3_log(tp[:, :3, :3] @ r0.T) - spatial.so3_log(tm[:, :3, :3] @ r0.T)) / (2 * h)
    return np.concatenate([lin, ang], axis=1).T


@pytest.mark.parametrize("name", CATALOG)
def test_jacobian_matches_finite_differences(name):
    m = built(name)
    rng = np.random.default_rng(11)
    for q in m.random_q(5, seed=rng):
        j = m.jacobian(q)
        assert j.shape == (6, m.n_q)
        np.testing.assert_allclose(j, finite_difference_jacobian(m, q), atol=1e-7, rtol=1e-6)


@pytest.mark.parametrize("name", ["planar_2r", "planar_3r"])
def test_planar_jacobian_determinant_is_l1_l2_sin_theta2(name):
    m = built(name)
    l1, l2 = m.params["lengths"][:2]
    for q in m.random_q(50, seed=12):
        assert m.jacobian_determinant(q) == pytest.approx(l1 * l2 * np.sin(q[1]), abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(["planar_2r", "planar_3r"]), data=st.data())
def test_planar_jacobian_singular_exactly_at_sin_theta2_zero(name, data):
    m = built(name)
    q = np.array(data.draw(st.tuples(*[angles] * m.n_q)))
    l1, l2 = m.params["lengths"][:2]
    j = m.task_jacobian(q)
    smallest = np.linalg.svd(j, compute_uv=False)[-1]
    if abs(l1 * l2 * np.sin(q[1])) < 1e-12:
        assert smallest < 1e-12
    else:
        # |det| = prod(sigma) <= smallest * largest^(n - 1): the smallest singular value is bounded
        # below (the SVD gives it to an absolute ~ eps * largest, hence the 1e-14 slack)
        largest = np.linalg.svd(j, compute_uv=False)[0]
        assert smallest >= abs(l1 * l2 * np.sin(q[1])) / largest ** (m.n_q - 1) - 1e-14
    q_sing = q.copy()
    q_sing[1] = data.draw(st.sampled_from([0.0, np.pi, -np.pi]))
    assert abs(m.jacobian_determinant(q_sing)) < 1e-12
    assert np.linalg.matrix_rank(m.task_jacobian(q_sing), tol=1e-10) == m.n_q - 1


@pytest.mark.parametrize("name", CATALOG)
def test_statics_duality(name):
    """Virtual work: ``tau . qdot = F . xdot`` with ``tau = J^T F`` and ``xdot = J qdot``."""
    m = built(name)
    rng = np.random.default_rng(13)
    q = m.random_q(seed=rng)
    j = m.task_jacobian(q)
    f = rng.normal(size=j.shape[0])
    qdot = rng.normal(size=m.n_q)
    tau = m.joint_torques(q, f)
    assert tau @ qdot == pytest.approx(f @ (j @ qdot), rel=1e-12, abs=1e-12)


# ---------------------------------------------------------------------------- DH builders
def _rz(a):
    return spatial.transform(spatial.rot_z(a))


def _rx(a):
    return spatial.transform(spatial.rot_x(a))


def _hand_dh(convention, rows, types, q):
    t = np.eye(4)
    for row, kind, qi in zip(rows, types, q, strict=True):
        theta, slide = (qi, 0.0) if kind == "R" else (0.0, qi)
        if convention == "seed":
            d, alpha = row
            t = t @ _rz(theta) @ spatial.translation(slide) @ spatial.translation(d) @ _rx(alpha)
        elif convention == "standard":
            d, a, alpha = row
            t = t @ _rz(theta) @ spatial.translation(0, 0, d + slide) @ spatial.translation(a) @ _rx(alpha)
        else:
            a_prev, alpha_prev, d = row
            t = (
                t
                @ _rx(alpha_prev)
                @ spatial.translation(a_prev)
                @ _rz(theta)
                @ spatial.translation(0, 0, d + slide)
            )
    return t


@pytest.mark.parametrize("convention", ["seed", "standard", "modified"])
@pytest.mark.parametrize("types", ["RRR", "RPR", "PRR"])
def test_dh_builders_match_hand_multiplied_a_matrices(convention, types):
    rng = np.random.default_rng(14)
    width = 2 if convention == "seed" else 3
    rows = rng.uniform(-1.0, 1.0, size=(3, width))
    m = dh_chain(rows, convention, types=types)
    for q in rng.uniform(-1.0, 1.0, size=(5, 3)):
        np.testing.assert_allclose(m.fk(q), _hand_dh(convention, rows, types, q), atol=1e-12)


def test_dh_intermediate_frames():
    rows = [(0.5, np.pi / 2), (0.7, 0.0)]
    m = dh_chain(rows, "seed")
    q = np.array([0.3, -0.4])
    np.testing.assert_allclose(m.fk(q, frame="frame1"), _hand_dh("seed", rows[:1], "R", q[:1]), atol=1e-12)


def test_planar_chain_rp_and_pr():
    m = planar_chain("PR", (0.0, 0.5))
    np.testing.assert_allclose(m.fk(np.array([0.3, np.pi / 2]))[:2, 3], [0.3, 0.5], atol=1e-12)


# ---------------------------------------------------------------------------- topology and input errors
def test_duplicate_joint_names():
    joints = [Joint("a", "revolute", "base", "l1"), Joint("a", "revolute", "l1", "l2")]
    with pytest.raises(ModelError, match="duplicate"):
        Mechanism(joints)


def test_disconnected_bodies():
    joints = [Joint("a", "revolute", "base", "l1"), Joint("b", "revolute", "x1", "x2")]
    with pytest.raises(ModelError, match="not connected"):
        Mechanism(joints)


def test_joint_to_itself_and_prismatic_only_loop():
    with pytest.raises(ModelError, match="itself"):
        Mechanism([Joint("a", "revolute", "l1", "l1")])
    loop = [
        Joint("p1", "prismatic", "base", "l1", axis=[1, 0, 0]),
        Joint("p2", "prismatic", "l1", "l2", axis=[0, 1, 0]),
        Joint("p3", "prismatic", "l2", "base", axis=[1, 1, 0]),
    ]
    with pytest.raises(ModelError, match="close a loop"):
        Mechanism(loop)


def test_bad_input_raises_named_optik_errors():
    m = built("planar_3r")
    cases = [
        (lambda: m.fk([0.0, np.nan, 0.0]), NonFiniteError, "q"),
        (lambda: m.fk([0.0, 0.0]), ShapeError, "q"),
        (lambda: m.jacobian(np.zeros((2, 2))), ShapeError, "q"),
        (lambda: m.fk(np.zeros(3), frame="nope"), UnknownFrameError, "frame"),
        (lambda: m.with_limits(lower=[0, 0, 1], upper=[1, 1, 0]), LimitsError, "lower/upper"),
        (lambda: m.with_limits(lower=[0, 0, np.nan]), NonFiniteError, "lower"),
        (lambda: m.joint_torques(np.zeros(3), [1.0, 2.0]), ShapeError, "wrench"),
        (lambda: m.task_jacobian(np.zeros(3), task="bogus"), InvalidArgumentError, "task"),
        (lambda: catalog.planar_3r(lengths=(1.0, -1.0, 1.0)), InvalidArgumentError, "lengths"),
        (lambda: planar_chain("RX", (1.0, 1.0)), InvalidArgumentError, "types"),
        (lambda: dh_chain([(1.0, 0.0)], "craig"), InvalidArgumentError, "convention"),
        (lambda: Joint("j", "hinge", "a", "b"), InvalidArgumentError, "type"),
        (lambda: Joint("j", "revolute", "a", "b", lower=1.0, upper=0.0), LimitsError, "lower/upper"),
        (lambda: Mechanism([Joint("j", "revolute", "base", "b")], ee="tip"), UnknownFrameError, "ee"),
    ]
    for call, error, argument in cases:
        with pytest.raises(error) as info:
            call()
        assert isinstance(info.value, OptikError)
        assert argument in str(info.value)
        if isinstance(info.value, InvalidArgumentError):
            assert info.value.argument == argument


def test_unknown_frame_message_lists_known_frames():
    m = built("planar_2r")
    with pytest.raises(UnknownFrameError, match="known"):
        m.jacobian(np.zeros(2), frame="tool")


def test_limits_wrap_and_within_limits():
    m = built("planar_2r").with_limits(lower=[0.0, -1.0], upper=[2 * np.pi, 1.0])
    w = m.wrap(np.array([-0.5, 0.2]))
    assert w[0] == pytest.approx(2 * np.pi - 0.5) and m.within_limits(w)
    assert not m.within_limits(np.array([0.1, 1.5]))
    assert m.kind == "planar_2r" and m.params == built("planar_2r").params


def test_wrap_keeps_an_angle_on_a_limit_beyond_pi():
    """-3.9 (PR2's upper-arm roll lower limit) wraps to 2.383 and back to -3.9 - 4e-16, just
    outside the limit: it used to be left at 2.383 and clipped to the upper limit (another pose)."""
    m = built("planar_2r").with_limits(lower=[-3.9, -1.0], upper=[0.8, 1.0])
    w = m.wrap(np.array([-3.9, 0.2]))
    assert w[0] == -3.9 and w[1] == pytest.approx(0.2, abs=1e-15)
    rows = np.array([[-3.9, 0.2], [0.8, -1.0], [5.0, 0.3], [-6.0, 0.9]])
    np.testing.assert_array_equal(m.wrap(rows), np.array([m.wrap(r) for r in rows]))  # rows at once
    target = m.fk(np.array([-3.9, 0.2]))
    res = solve_ik(m, target, q0=[-3.85, 0.1], method="lm", compile=False)
    assert res.success and np.allclose(m.fk(res.q), target, atol=1e-6)


def test_fk_of_an_empty_batch_and_unhashable_frame_names():
    """An empty batch gives no poses (it used to raise IndexError); a frame that is no string
    is an unknown frame (a list used to raise TypeError from the cache lookup)."""
    m = catalog.planar_2r()
    assert m.fk(np.zeros((0, 2))).shape == (0, 4, 4)
    for call in (m.fk, m.jacobian):
        with pytest.raises(UnknownFrameError, match=r"^frame:"):
            call(np.zeros(2), frame=["ee"])


@settings(max_examples=200, deadline=None)
@given(
    v=st.tuples(*(st.sampled_from([0.0, 1.0, 1e-8, 1e-5, 2e-5, -1e-8, 1.0 + 1e-5, 1.0 - 2e-5]),) * 3)
    | st.tuples(*(st.floats(-2, 2),) * 3)
)
def test_planar_axis_check_is_numpys_allclose(v):
    """The planarity test's ``[0, 0, 1]`` comparison on floats answers as ``np.allclose`` does,
    at the tolerance's edges too."""
    from optik.mechanism.mechanism import _is_unit_z

    assert _is_unit_z(np.array(v)) == np.allclose(v, [0, 0, 1])
