"""IK methods ``closed_form``, ``lm``, ``nlp`` and ``solve_ik_all`` on serial arms and closed chains."""

from __future__ import annotations

import time

import numpy as np
import pytest

import optik
from optik import closed_form
from optik.solvers.base import joint_distance

NUMERIC = ("lm", "nlp")
SERIAL = ("planar_2r", "planar_3r", "seed_6r_arm")


def _arm(name: str) -> optik.Mechanism:
    return getattr(optik.catalog, name)()


def _targets(m: optik.Mechanism, n: int, seed: int) -> list[np.ndarray]:
    return list(m.fk(m.random_q(n, seed=seed)))


def _nearest_branch(m: optik.Mechanism, q: np.ndarray, target: np.ndarray) -> float:
    return min(joint_distance(m, q, b) for b in closed_form.ik(m, target))


@pytest.mark.parametrize("name", SERIAL)
@pytest.mark.parametrize("method", ("closed_form", *NUMERIC))
def test_methods_solve_serial_arms_on_a_closed_form_branch(name: str, method: str) -> None:
    m = _arm(name)
    for target in _targets(m, 4, seed=11):
        res = optik.solve_ik(m, target, method=method, time_limit=2.0, tol=1e-9, seed=3)
        assert res.success, res.message
        assert res.method == method
        assert res.limits_ok and m.within_limits(res.q)
        assert res.position_error <= 1e-9 and res.orientation_error <= 1e-9
        assert _nearest_branch(m, res.q, target) < 1e-6


def test_default_method_prefers_closed_form_then_lm() -> None:
    assert optik.solvers.pick_method(_arm("planar_3r"), "pose2d") == "closed_form"
    assert optik.solvers.pick_method(optik.catalog.panda(), "pose") == "lm"
    assert optik.solvers.pick_method(_arm("planar_3r"), "position2d") == "lm"


def _assembled(m: optik.Mechanism, actuated: list[float]) -> np.ndarray:
    modes = closed_form.fk(m, actuated)
    assert modes, "test configuration must assemble"
    return modes[0]


@pytest.mark.parametrize(("name", "actuated"), [("five_bar", [1.5, 1.2]), ("planar_3rpr", [1.0, 1.2, 1.1])])
@pytest.mark.parametrize("method", ("closed_form", *NUMERIC))
def test_methods_solve_closed_chains(name: str, method: str, actuated: list[float]) -> None:
    m = _arm(name)
    q_true = _assembled(m, actuated)
    target = m.fk(q_true)
    res = optik.solve_ik(m, target, method=method, time_limit=3.0, seed=1)
    assert res.success, res.message
    assert res.closure_error <= 1e-9
    assert np.max(np.abs(m.closure(res.q))) <= 1e-9
    assert m.within_limits(res.q)
    np.testing.assert_allclose(m.fk(res.q)[:2, 3], target[:2, 3], atol=1e-6)


@pytest.mark.parametrize("name", SERIAL)
def test_solve_ik_all_finds_every_closed_form_branch(name: str) -> None:
    m = _arm(name)
    for seed in (0, 2):
        target = m.fk(m.random_q(seed=seed))
        branches = closed_form.ik(m, target)
        for use_closed_form in (True, False):
            sols = optik.solve_ik_all(
                m, target, time_limit=5.0, tol=1e-10, seed=seed, patience=400, closed_form=use_closed_form
            )
            assert all(s.success for s in sols)
            for b in branches:
                assert min(joint_distance(m, b, s.q) for s in sols) < 1e-6
            for s in sols:  # distinct, each on a branch
                assert _nearest_branch(m, s.q, target) < 1e-6
            pairs = [(a, b) for i, a in enumerate(sols) for b in sols[i + 1 :]]
            assert all(joint_distance(m, a.q, b.q) >= 1e-4 for a, b in pairs)


def test_solve_ik_all_unreachable_is_empty() -> None:
    m = _arm("planar_2r")
    assert optik.solve_ik_all(m, optik.Position(3.0, 0.0), time_limit=0.2, patience=5) == []


@pytest.mark.parametrize("method", ("closed_form", *NUMERIC))
def test_limits_are_never_violated(method: str) -> None:
    m = _arm("planar_3r").with_limits(lower=[-1.0, 0.1, -1.5], upper=[1.0, 2.0, 1.5])
    rng = np.random.default_rng(5)
    for _ in range(5):
        target = m.fk(rng.uniform(m.lower, m.upper))
        res = optik.solve_ik(m, target, method=method, time_limit=1.0, seed=rng)
        assert res.success, res.message
        assert np.all(res.q >= m.lower) and np.all(res.q <= m.upper)
    # a target reachable only outside the limits: the answer still respects them
    res = optik.solve_ik(m, m.fk([2.5, -1.0, 0.0]), method=method, time_limit=0.2)
    assert not res.success and res.limits_ok
    assert np.all(res.q >= m.lower) and np.all(res.q <= m.upper)


@pytest.mark.parametrize("method", ("closed_form", *NUMERIC))
def test_unreachable_target_gives_closest_pose_and_message(method: str) -> None:
    m = _arm("planar_2r")  # reach 1.8
    res = optik.solve_ik(m, optik.Position(3.0, 0.0), method=method, time_limit=0.1)
    assert not res.success
    assert res.message
    if method != "closed_form":  # numerical methods return the closest configuration found
        assert res.position_error == pytest.approx(1.2, abs=1e-4)
        assert res.status == "time_limit"
    else:
        assert res.status == "unreachable"


@pytest.mark.parametrize("method", NUMERIC)
def test_time_limit_is_honoured(method: str) -> None:
    m = _arm("seed_6r_arm")
    far = optik.spatial.translation(5.0, 0.0, 0.0)
    optik.solve_ik(m, far, method=method, time_limit=0.01)  # builds and caches the problem
    for limit in (1e-4, 0.05):
        # the CPU time of this thread, not the wall clock: a busy machine stretches the wall time of
        # any call, but a solver that ignored its limit would spend more than the limit computing
        t0 = time.thread_time()
        res = optik.solve_ik(m, far, method=method, time_limit=limit)
        spent = time.thread_time() - t0
        assert not res.success and res.status == "time_limit"
        assert spent < limit + 0.03  # one iteration / block and the result evaluation past the limit


def test_seeded_restarts_are_reproducible() -> None:
    m = _arm("seed_6r_arm")
    target = m.fk(m.random_q(seed=8))
    a = optik.solve_ik(m, target, method="lm", seed=42, time_limit=1.0)
    b = optik.solve_ik(m, target, method="lm", seed=42, time_limit=1.0)
    np.testing.assert_array_equal(a.q, b.q)
    assert a.restarts == b.restarts


def test_lm_without_compiler_matches_compiled() -> None:
    m = _arm("planar_3r")
    target = m.fk(m.random_q(seed=4))
    a = optik.solve_ik(m, target, method="lm", compile=True, seed=1)
    b = optik.solve_ik(m, target, method="lm", compile=False, seed=1)
    assert a.success and b.success
    np.testing.assert_allclose(a.q, b.q, atol=1e-9)


def test_nlp_sqpmethod_is_selectable() -> None:
    m = _arm("planar_2r")
    target = m.fk([0.4, 1.1])
    res = optik.solve_ik(m, target, method="nlp", solver="sqpmethod", time_limit=2.0)
    assert res.success, res.message


def test_nlp_monitor_stops_at_tolerance_through_the_buffer_callback() -> None:
    from optik.solvers.nlp import _Monitor

    mon = _Monitor(2, 0, 1)
    mon.errors = lambda x: (abs(float(x[0])), 0.0, 0.0)
    mon.goal = (1e-3, 1.0, 1.0)
    args = [np.array([0.5, 0.0]), 0.0, np.zeros(0), np.zeros(2), np.zeros(0), np.zeros(1)]
    assert float(mon(*args)) == 0.0
    args[0] = np.array([1e-4, 0.0])
    assert float(mon(*args)) == 1.0
    assert mon.reached and mon.best_score == pytest.approx(0.1)


def test_nlp_default_stall_rules() -> None:
    from optik.solvers.nlp import _default_stall

    assert _default_stall("sqpmethod", False, True) == (0.7, 0.7)
    assert _default_stall("ipopt", False, True) == (0.8, 0.8)
    assert _default_stall("ipopt", True, True) == (1.0, 0.8)  # closed chains: near the target only
    assert _default_stall("ipopt", False, False) == (1.0, 1.0)  # IPOPT's optimum asked for


def test_nlp_ipopt_redundant_arm_reaches_tight_tolerance() -> None:
    m = optik.catalog.panda()
    rng = np.random.default_rng(3)
    for q in m.random_q(5, seed=rng):
        res = optik.solve_ik(m, m.fk(q), method="nlp", tol=1e-6, time_limit=5.0, seed=1)  # answers, not speed
        assert res.success, res.message


def test_posture_resolves_redundancy() -> None:
    m = _arm("planar_3r")  # redundant for the position2d task
    target = optik.Position(1.2, 0.6)
    q_ref = np.array([0.3, 0.9, -0.4])
    free = optik.solve_ik(m, target, method="lm", q_ref=q_ref, q0=[-1.0, 2.0, 1.5])
    pulled = optik.solve_ik(m, target, method="lm", q_ref=q_ref, posture_gain=1.0, q0=[-1.0, 2.0, 1.5])
    assert free.success and pulled.success
    assert np.linalg.norm(pulled.q - q_ref) < np.linalg.norm(free.q - q_ref) - 0.1
    nlp = optik.solve_ik(
        m, target, method="nlp", q_ref=q_ref, posture=1e-4, stop_at_tolerance=False, tol=1e-5, time_limit=2.0
    )
    assert nlp.success
    assert np.linalg.norm(nlp.q - q_ref) < np.linalg.norm(free.q - q_ref)


def test_nlp_secondary_objectives_run() -> None:
    m = _arm("planar_3r")
    target = optik.Position(1.0, 0.5)
    for opts in ({"manipulability": 1e-6}, {"limits": 1e-6}):
        res = optik.solve_ik(m, target, method="nlp", time_limit=2.0, tol=1e-5, **opts)
        assert res.success, (opts, res.message)


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"target": np.full((4, 4), np.nan)}, optik.NonFiniteError),
        ({"target": np.eye(3)}, optik.ShapeError),
        ({"q0": [0.0, 0.0]}, optik.ShapeError),
        ({"q0": [np.inf, 0.0, 0.0]}, optik.NonFiniteError),
        ({"frame": "nowhere"}, optik.UnknownFrameError),
        ({"time_limit": -1.0}, optik.InvalidArgumentError),
        ({"method": "magic"}, optik.SolverUnavailableError),
        ({"method": "lm", "bogus_option": 1}, optik.InvalidArgumentError),
        ({"method": "nlp", "solver": "snopt"}, optik.InvalidArgumentError),
        ({"method": "lm", "block": 0}, optik.InvalidArgumentError),
        ({"method": "lm", "weights": (1.0,)}, optik.ShapeError),
        ({"method": "nlp", "weights": (-1.0, 1.0)}, optik.InvalidArgumentError),
        ({"method": "nlp", "hessian": "bfgs"}, optik.InvalidArgumentError),
        ({"seed": "x"}, optik.InvalidArgumentError),
    ],
)
def test_bad_input_raises_named_errors(kwargs: dict, error: type) -> None:
    m = _arm("planar_3r")
    args = {"target": optik.Pose2D(1.0, 0.5, 0.3), **kwargs}
    with pytest.raises(error):
        optik.solve_ik(m, **args)


def test_closed_form_does_not_apply_to_other_tasks() -> None:
    with pytest.raises(optik.SolverUnavailableError):
        optik.solve_ik(_arm("planar_3r"), optik.Position(1.0, 0.5), method="closed_form")


@pytest.mark.parametrize(
    ("method", "name", "value"),
    [
        ("lm", "mu0", 0.0),
        ("lm", "stall", "a"),
        ("lm", "posture_gain", float("nan")),
        ("lm", "closure_weight", -1.0),
        ("lm", "max_restarts", float("nan")),
        ("nlp", "posture", "a"),
        ("nlp", "damping", -1.0),
        ("nlp", "ipopt_tol", -1.0),
        ("nlp", "stall", float("nan")),
        ("nlp", "max_restarts", -1),
        ("nlp", "solver_options", {"no_such_option": 1}),
    ],
)
def test_bad_numeric_option_values_raise_named_errors(method, name, value):
    """They used to leak ValueError from float()/int() or casadi's RuntimeError from nlpsol."""
    m = optik.catalog.planar_2r()
    with pytest.raises(optik.InvalidArgumentError, match=rf"^{name}:"):
        optik.solve_ik(m, optik.Position(0.5, 0.5, 0.0), method=method, **{name: value})
