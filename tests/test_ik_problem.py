"""IKProblem: residuals, error expressions, Hessian, caching; the compiled evaluation path."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik import spatial
from optik.problem import angle_from_residual, build_ik_problem, target_parameters
from optik.solvers.base import evaluate
from optik.solvers.evaluation import errors_against

ARMS = {
    "planar_2r": optik.catalog.planar_2r(),
    "planar_3r": optik.catalog.planar_3r(),
    "seed_6r_arm": optik.catalog.seed_6r_arm(),
    "five_bar": optik.catalog.five_bar(),
}
TASKS = {"seed_6r_arm": ("pose", "position", "orientation"), "planar_3r": ("pose2d", "position2d")}


@settings(max_examples=40, deadline=None)
@given(w=st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3), angle=st.floats(0.0, np.pi))
def test_orientation_residual_norm_is_a_function_of_the_angle(w: list[float], angle: float) -> None:
    axis = np.asarray(w)
    if np.linalg.norm(axis) < 1e-3:
        axis = np.array([0.0, 0.0, 1.0])
    r_star = spatial.rpy_to_rot(0.3, -0.2, 0.9)
    r = r_star @ spatial.so3_exp(axis / np.linalg.norm(axis) * angle)
    norm = np.linalg.norm((r - r_star).reshape(-1)) / np.sqrt(2.0)
    assert norm == pytest.approx(2 * np.sin(angle / 2), abs=1e-12)
    assert angle_from_residual(norm) == pytest.approx(angle, abs=1e-6)


@pytest.mark.parametrize(("name", "task"), [(n, t) for n, ts in TASKS.items() for t in ts])
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_error_expressions_match_the_success_check(name: str, task: str, seed: int) -> None:
    m = ARMS[name]
    rng = np.random.default_rng(seed)
    q, q_target = m.random_q(seed=rng), m.random_q(seed=rng)
    target = m.fk(q_target)
    errs = errors_against(m, task, None, target)(q)
    ref = evaluate(m, q, target, task, None)
    np.testing.assert_allclose(errs, (ref.position, ref.orientation, ref.closure), atol=1e-9)


def test_closure_error_matches_for_closed_chains() -> None:
    m = ARMS["five_bar"]
    q = m.random_q(seed=3)
    target = m.fk(q)
    errs = errors_against(m, "position2d", None, target)(q)
    assert errs[2] == pytest.approx(np.max(np.abs(m.closure(q))), abs=1e-12)


@pytest.mark.parametrize(("name", "task"), [("seed_6r_arm", "pose"), ("planar_3r", "pose2d")])
def test_residual_jacobian_matches_finite_differences(name: str, task: str) -> None:
    m = ARMS[name]
    p = build_ik_problem(m, task)
    f = p.residual_function()
    target = target_parameters(m.fk(m.random_q(seed=1)))
    q = m.random_q(seed=2)
    e0, jac = (np.asarray(v) for v in f(q, target, [1.0, 1.0]))
    h = 1e-7
    steps = h * np.eye(m.n_q)
    fd = np.column_stack([(np.asarray(f(q + d, target, [1.0, 1.0])[0]) - e0).ravel() / h for d in steps])
    np.testing.assert_allclose(jac, fd, atol=1e-5)


def test_residual_vanishes_at_the_target_and_objective_is_minimal() -> None:
    m = ARMS["seed_6r_arm"]
    p = build_ik_problem(m, "pose")
    q = m.random_q(seed=4)
    params = p.parameter_values(m.fk(q), posture=0.0)
    f = ca.Function("f", [p.q, p.parameters], [p.objective])
    assert float(f(q, params)) == pytest.approx(0.0, abs=1e-24)
    assert float(f(q + 0.01, params)) > 0.0


def test_problem_is_cached_and_inspectable() -> None:
    m = ARMS["planar_3r"]
    a = build_ik_problem(m, "pose2d")
    assert build_ik_problem(m, "pose2d") is a
    assert build_ik_problem(m, "position2d") is not a
    nlp = a.nlp()
    assert set(nlp) == {"x", "p", "f", "g"}
    assert a.q.shape == (3, 1) and a.parameters.shape == (12 + 2 + 3 + 3, 1)
    np.testing.assert_array_equal(a.lower, m.lower)
    closed = build_ik_problem(ARMS["five_bar"])
    assert closed.closure.shape[0] == ARMS["five_bar"].n_closure > 0


def test_gauss_newton_hessian_is_psd_and_matches_at_the_solution() -> None:
    m = ARMS["seed_6r_arm"]
    p = build_ik_problem(m, "pose")
    lam_f, lam_g = ca.SX.sym("lam_f"), ca.SX.sym("lam_g", 0)
    gn = ca.Function("gn", [p.q, p.parameters, lam_f], [p.lagrangian_hessian(lam_f, lam_g)])
    exact = ca.Function("h", [p.q, p.parameters], [ca.hessian(p.objective, p.q)[0]])
    q = m.random_q(seed=6)
    at_target = p.parameter_values(m.fk(q), posture=1e-3)
    elsewhere = p.parameter_values(m.fk(m.random_q(seed=7)), posture=1e-3)
    h = np.asarray(gn(q, elsewhere, 1.0))
    assert np.min(np.linalg.eigvalsh(h)) >= -1e-12
    np.testing.assert_allclose(np.asarray(gn(q, at_target, 1.0)), np.asarray(exact(q, at_target)), atol=1e-9)


def test_bad_problem_arguments_raise() -> None:
    m = ARMS["planar_3r"]
    with pytest.raises(optik.InvalidArgumentError):
        build_ik_problem(m, "sideways")
    with pytest.raises(optik.InvalidArgumentError):
        build_ik_problem(m, "pose2d", secondary=("beauty",))
    with pytest.raises(optik.UnknownFrameError):
        build_ik_problem(m, "pose2d", frame="nowhere")
    p = build_ik_problem(m, "pose2d")
    with pytest.raises(optik.InvalidArgumentError):
        p.parameter_values(np.eye(4), weights=(-1.0, 1.0))
    with pytest.raises(optik.InvalidArgumentError):
        p.parameter_values(np.eye(4), manipulability=1.0)  # not built with that objective
