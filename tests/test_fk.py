"""Numerical forward kinematics of closed chains (optik.solve_fk, optik.solve_fk_all)."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import closed_form as cf
from optik.solvers import fk as fk_mod
from optik.solvers.fk import same_mode


def _stewart_target(rng: np.random.Generator) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = optik.spatial.rpy_to_rot(*rng.uniform(-0.3, 0.3, 3))
    t[:3, 3] = np.array([0.0, 0.0, 1.0]) + rng.uniform(-0.15, 0.15, 3)
    return t


def _targets(name: str, rng: np.random.Generator, n: int) -> list:
    """Random reachable targets of each catalog closed chain."""
    makers = {
        "five_bar": lambda: optik.Position(rng.uniform(-0.2, 1.2), rng.uniform(0.9, 1.7)),
        "doggy": lambda: optik.Pose2D(rng.uniform(-0.3, 0.3), rng.uniform(0.55, 1.0), rng.uniform(-0.5, 0.5)),
        "slider_crank": lambda: optik.Position(rng.uniform(-1.2, -0.8), 0.0),
        "planar_3rpr": lambda: optik.Pose2D(
            rng.uniform(0.6, 1.4), rng.uniform(0.4, 1.1), rng.uniform(-np.pi, np.pi)
        ),
        "stewart_gough": lambda: _stewart_target(rng),
    }
    return [makers[name]() for _ in range(n)]


CHAINS = ["five_bar", "doggy", "slider_crank", "planar_3rpr", "stewart_gough"]


@pytest.mark.parametrize("name", CHAINS)
def test_round_trip_pose_ik_fk_all_contains_the_configuration(name):
    m = getattr(optik.catalog, name)()
    rng = np.random.default_rng(4)
    n = 1 if name == "stewart_gough" else 8
    checked = 0
    for target in _targets(name, rng, n):
        for q in cf.ik(m, target):
            a = q[m.actuated_indices]
            modes = optik.solve_fk_all(m, a)
            assert any(same_mode(m, r.q, q) for r in modes)
            assert all(r.success and r.residual <= 1e-9 for r in modes)
            one = optik.solve_fk(m, a, q0=q)
            assert one.success and same_mode(m, one.q, q)
            assert np.allclose(one.pose, m.fk(q), atol=1e-9)
            checked += 1
            if name == "stewart_gough":
                break
    assert checked >= n


@pytest.mark.parametrize("name", ["five_bar", "slider_crank", "planar_3rpr"])
def test_numeric_multistart_matches_closed_form(name):
    m = getattr(optik.catalog, name)()
    rng = np.random.default_rng(9)
    for target in _targets(name, rng, 4):
        q = cf.ik(m, target)[0]
        a = q[m.actuated_indices]
        exact = optik.solve_fk_all(m, a, method="closed_form")
        numeric = optik.solve_fk_all(m, a, method="numeric", seed=1)
        assert len(numeric) == len(exact) >= 1
        for r in exact:
            best = min(np.max(np.abs(optik.spatial.wrap_angle(r.q - s.q))) for s in numeric)
            assert best < 1e-9


def test_five_bar_two_assembly_modes_and_four_working_modes_numerically():
    m = optik.catalog.five_bar()
    branches = cf.ik(m, optik.Position(0.5, 1.4))
    assert len(branches) == 4
    for q in branches:
        modes = optik.solve_fk_all(m, q[:2], method="numeric", seed=3)
        assert len(modes) == 2
        assert any(np.max(np.abs(optik.spatial.wrap_angle(r.q - q))) < 1e-9 for r in modes)


def test_tracking_follows_the_assembly_mode_of_q0():
    """Step the actuators of each five-bar mode: the answer is the same mode moved a little."""
    m = optik.catalog.five_bar()
    q_start = cf.ik(m, optik.Position(0.5, 1.4))
    for q0 in q_start:
        a1 = q0[:2] + np.array([0.15, -0.1])
        res = optik.solve_fk(m, a1, q0=q0)
        modes = cf.fk(m, a1)
        nearest = min(modes, key=lambda q: np.linalg.norm(optik.spatial.wrap_angle(q - q0)))
        assert res.success and same_mode(m, res.q, nearest)


def test_doggy_fk_from_four_leg_angles_is_least_squares_with_residual_check():
    m = optik.catalog.doggy()
    pose = optik.Pose2D(0.1, 0.8, 0.2)
    for q in cf.ik(m, pose):
        a = q[m.actuated_indices]
        res = optik.solve_fk(m, a)
        assert res.success
        assert np.allclose(res.pose, pose.as_transform(), atol=1e-9)
        bad = optik.solve_fk(m, a + np.array([0.05, 0.0, 0.0, 0.0]), time_limit=0.2)
        assert not bad.success
        assert bad.residual > 1e-3
        assert "cannot assemble" in bad.message


def test_non_assemblable_inputs_fail_with_residual_and_message():
    m = optik.catalog.planar_3rpr()
    res = optik.solve_fk(m, [0.3, 0.3, 2.5], time_limit=0.2)
    assert not res.success and res.residual > 1e-3 and "cannot assemble" in res.message
    assert optik.solve_fk_all(m, [0.3, 0.3, 2.5]) == []
    assert optik.solve_fk_all(m, [0.3, 0.3, 2.5], method="numeric", time_limit=0.3) == []


def test_time_limit_is_honoured(cpu_clock):
    m = optik.catalog.stewart_gough()
    with cpu_clock() as cpu:  # the work done, which a busy machine does not lengthen (conftest)
        res = optik.solve_fk(m, [0.5, 0.5, 0.5, 0.5, 0.5, 2.5], time_limit=0.1)
    assert cpu.seconds < 0.5
    assert not res.success


def test_near_singular_assembly_is_flagged():
    """Distal links almost stretched: the two assembly modes nearly merge."""
    m = optik.catalog.five_bar(base=((0.0, 0.0), (0.4, 0.0)), lengths=(1.0, 1.0, 1.2, 1.2))
    res = optik.solve_fk(m, [np.pi, 2e-5])  # |B1 B2| = l3 + l4 - 1e-10
    assert res.success
    assert res.condition_number > fk_mod.SINGULAR_CONDITION
    assert res.extra["singular"] and "singularity" in res.message
    regular = optik.solve_fk(m, [2.0, 1.0])
    assert regular.success and not regular.extra["singular"] and regular.condition_number < 100


def test_stewart_numeric_tracking_from_a_nearby_posture():
    m = optik.catalog.stewart_gough()
    rng = np.random.default_rng(8)
    target = _stewart_target(rng)
    q0 = cf.ik(m, target)[0]
    moved = target.copy()
    moved[:3, 3] += [0.05, -0.03, 0.04]
    q1 = cf.ik(m, moved)[0]
    res = optik.solve_fk(m, q1[m.actuated_indices], q0=q0)
    assert res.success and np.allclose(res.pose, moved, atol=1e-8)


def test_invalid_inputs_raise_named_errors():
    m = optik.catalog.five_bar()
    with pytest.raises(optik.ShapeError, match="actuated"):
        optik.solve_fk(m, [0.1, 0.2, 0.3])
    with pytest.raises(optik.NonFiniteError, match="actuated"):
        optik.solve_fk(m, [np.nan, 0.2])
    with pytest.raises(optik.InvalidArgumentError, match="time_limit"):
        optik.solve_fk(m, [0.1, 0.2], time_limit=0.0)
    with pytest.raises(optik.InvalidArgumentError, match="method"):
        optik.solve_fk_all(m, [0.1, 0.2], method="magic")
    with pytest.raises(optik.ShapeError, match="q0"):
        optik.solve_fk(m, [0.1, 0.2], q0=[0.0])
    with pytest.raises(optik.InvalidArgumentError, match=r"^m:"):
        optik.solve_fk(optik.catalog.planar_2r(), [0.1, 0.2])
    with pytest.raises(optik.SolverUnavailableError):
        optik.solve_fk_all(optik.Mechanism(m.joints, name="hand_built"), [0.1, 0.2], method="closed_form")


@pytest.mark.parametrize(
    ("function", "name", "value"),
    [
        (optik.solve_fk, "max_iter", 0),
        (optik.solve_fk, "max_iter", np.nan),
        (optik.solve_fk, "max_jump", np.nan),
        (optik.solve_fk, "max_jump", -1.0),
        (optik.solve_fk, "max_restarts", -1),
        (optik.solve_fk, "max_restarts", 1.5),
        (optik.solve_fk, "singular_condition", np.nan),
        (optik.solve_fk_all, "patience", -1),
        (optik.solve_fk_all, "max_iter", 2.5),
        (optik.solve_fk_all, "singular_condition", np.inf),
    ],
)
def test_invalid_numeric_options_raise_named_errors(function, name, value):
    with pytest.raises(optik.InvalidArgumentError, match=rf"^{name}:"):
        function(optik.catalog.five_bar(), [0.1, 0.2], **{name: value})


def test_compiled_functions_are_cached_per_mechanism():
    m = optik.catalog.slider_crank()
    assert fk_mod._compiled(m) is fk_mod._compiled(m)
    assert fk_mod._compiled(m) is not fk_mod._compiled(optik.catalog.slider_crank())


def test_hand_built_mechanism_uses_the_numeric_multistart():
    """No catalog kind, a name that is no identifier: the multi-start finds both modes."""
    m0 = optik.catalog.five_bar()
    m = optik.Mechanism(m0.joints, frames={"tool": ("distal1", np.eye(4))}, ee="tool", name="my five-bar")
    modes = optik.solve_fk_all(m, [1.2, 0.6], seed=0)
    exact = cf.fk(m0, [1.2, 0.6])
    assert len(modes) == len(exact) == 2
    assert all(any(same_mode(m, r.q, q) for r in modes) for q in exact)
    assert all(r.extra["method"] == "numeric" for r in modes)


def test_stewart_fk_all_honours_its_time_limit(cpu_clock):
    """The homotopy behind the Stewart-Gough closed form gets solve_fk_all's budget: a short one
    ends in time and says that completeness was not certified (it ran 0.7-3.7 s at 0.02 s).
    Its CPU seconds are bounded, not its wall-clock time, which a busy machine lengthens."""
    sg = optik.catalog.stewart_gough()
    legs = [1.2, 1.1, 1.15, 1.25, 1.2, 1.1]
    optik.solve_fk_all(sg, legs)  # builds the compiled tracker
    with cpu_clock() as cpu, pytest.warns(RuntimeWarning, match="completeness not certified"):
        optik.solve_fk_all(sg, legs, time_limit=0.005)
    assert cpu.seconds < 3 * 0.005 + 0.5


@pytest.mark.parametrize("name", ["five_bar", "planar_3rpr", "doggy", "slider_crank"])
def test_closed_form_modes_are_measured_as_the_general_path_measures(name):
    """The closed-form modes' pose, residual and condition number (one buffered evaluation of
    closure, Jacobian and pose per mode, one stacked SVD) equal what ``m.fk``, the closure and
    `_measures` give at the returned ``q``, and actuated values outside their limits are
    reported on every mode."""
    m = getattr(optik.catalog, name)()
    cm = fk_mod._compiled(m)
    rng = np.random.default_rng(5)
    checked = 0
    for target in _targets(name, rng, 6):
        for q in cf.ik(m, target):
            modes = optik.solve_fk_all(m, q[m.actuated_indices], within_limits=False)
            for r in modes:
                np.testing.assert_allclose(r.pose, m.fk(r.q), atol=1e-14)
                residual, cond = fk_mod._residual_and_condition(cm, r.q)
                assert r.residual == pytest.approx(residual, abs=1e-15)
                assert r.condition_number == pytest.approx(cond, rel=1e-9)
                checked += 1
    assert checked >= 6
    if name == "planar_3rpr":  # legs a little past their upper limit: still assembling
        rpr = optik.catalog.planar_3rpr(leg_limits=(0.1, 1.0))
        legs = rpr.upper[rpr.actuated_indices] * 1.02
        modes = optik.solve_fk_all(rpr, legs, within_limits=False)
        assert len(modes)
        assert all("the actuated values are outside their limits: rho" in r.message for r in modes)
