"""Iterated differential IK as position IK: ``solve_ik(..., method="dls" | "qp")``."""

from __future__ import annotations

import numpy as np
import pytest

import optik


@pytest.mark.parametrize("method", ["dls", "qp"])
@pytest.mark.parametrize(
    ("name", "make_target"),
    [
        ("seed_6r_arm", lambda m, q: m.fk(q)),
        ("panda", lambda m, q: m.fk(q)),
        ("planar_3r", lambda m, q: optik.Pose2D(*optik.spatial.planar_pose_of(m.fk(q)))),
        ("planar_2r", lambda m, q: optik.Position(m.fk(q)[:3, 3])),
    ],
)
def test_round_trip_from_fk(method: str, name: str, make_target) -> None:
    m = getattr(optik.catalog, name)()
    rng = np.random.default_rng(7)  # the targets do not depend on the restarts the solver draws
    for k in range(3):
        q_true = m.random_q(seed=rng)
        res = optik.solve_ik(m, make_target(m, q_true), method=method, time_limit=2.0, seed=k)
        assert res.success, res.message
        assert res.method == method and res.limits_ok
        assert res.position_error <= 1e-6 and res.orientation_error <= 1e-6


@pytest.mark.parametrize("method", ["dls", "qp"])
def test_closed_chain_round_trip(method: str) -> None:
    m = optik.catalog.five_bar()
    res = optik.solve_ik(m, optik.Position(0.5, 1.3), method=method, time_limit=2.0)
    assert res.success, res.message
    assert res.closure_error <= 1e-9
    np.testing.assert_allclose(m.fk(res.q)[:2, 3], [0.5, 1.3], atol=1e-6)


@pytest.mark.parametrize("method", ["dls", "qp"])
def test_start_outside_the_limits_is_fine(method: str) -> None:
    m = optik.catalog.panda()
    q_true = np.array([0.3, -0.4, 0.2, -1.8, 0.1, 1.6, 0.4])
    q0 = m.mid_q()
    q0[3] = m.upper[3] + 0.1
    res = optik.solve_ik(m, m.fk(q_true), q0=q0, method=method, time_limit=2.0)
    assert res.success and res.limits_ok


@pytest.mark.parametrize("method", ["dls", "qp"])
def test_unreachable_target_is_a_normal_failure_within_the_time_limit(method: str, cpu_clock) -> None:
    m = optik.catalog.planar_2r()
    with cpu_clock() as cpu:  # the work done, which a busy machine does not lengthen (conftest)
        res = optik.solve_ik(m, optik.Position(3.0, 0.0), method=method, time_limit=0.2)
    assert not res.success and res.status == "time_limit"
    assert "position error" in res.message
    assert res.position_error == pytest.approx(3.0 - 1.8, abs=1e-3)  # closest: stretched towards it
    assert cpu.seconds < 0.2 + 0.3


@pytest.mark.parametrize(
    ("method", "option"), [("dls", "bogus"), ("dls", "lm_damping"), ("qp", "damping"), ("qp", "threshold")]
)
def test_unknown_option_names_the_argument(method, option) -> None:
    """An option the method does not read is an error, not silently ignored."""
    m = optik.catalog.planar_2r()
    with pytest.raises(optik.InvalidArgumentError, match=rf"^options:.*{option}"):
        optik.solve_ik(m, optik.Position(1.0, 0.5), method=method, **{option: 0.1})


@pytest.mark.parametrize(
    ("method", "name", "value"),
    [
        ("dls", "max_iterations", float("nan")),
        ("qp", "max_iterations", "a"),
        ("qp", "stall_iterations", None),
        ("qp", "lm_damping", "x"),
        ("qp", "lm_damping", -1.0),
        ("dls", "damping", -1.0),
        ("dls", "threshold", "x"),
    ],
)
def test_bad_option_values_raise_named_errors(method, name, value):
    """They used to leak ValueError / TypeError from int(), float() or a comparison."""
    m = optik.catalog.planar_2r()
    with pytest.raises(optik.InvalidArgumentError, match=rf"^{name}:"):
        optik.solve_ik(m, optik.Position(0.5, 0.5, 0.0), method=method, **{name: value})
