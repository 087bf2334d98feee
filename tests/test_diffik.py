"""Differential IK: task Jacobians, step methods, QP backends, limits and fallbacks."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik import diffik, spatial
from optik.diffik.linalg import pinv_pair
from optik.diffik.step import DLS_DAMPING

SEED_6R = optik.catalog.seed_6r_arm()
PANDA = optik.catalog.panda()
PLANAR_3R = optik.catalog.planar_3r()


def _fd_jacobian(task: diffik.Task, m: optik.Mechanism, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of the task error (one CasADi function, evaluated 2 n times)."""
    p = task.parameters(m)
    ps = ca.SX.sym("p", p.shape[0])
    error = ca.Function("e", [m.q_sym, ps], [task.expressions(m, m.q_sym, ps)[0]])
    cols = []
    for k in range(m.n_q):
        d = np.zeros(m.n_q)
        d[k] = h
        cols.append((np.asarray(error(q + d, p)) - np.asarray(error(q - d, p))).ravel() / (2 * h))
    return np.stack(cols, axis=1)


def _target_near(m: optik.Mechanism, q: np.ndarray, rng: np.random.Generator, angle: float) -> np.ndarray:
    """A pose offset from fk(q) by up to ``angle`` rad and 0.3 m."""
    t = m.fk(q)
    w = rng.normal(size=3)
    w *= angle / np.linalg.norm(w)
    return spatial.transform(spatial.so3_exp(w) @ t[:3, :3], t[:3, 3] + rng.uniform(-0.3, 0.3, 3))


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000), angle=st.floats(0.0, 2.8))
def test_frame_task_jacobian_matches_finite_differences(seed: int, angle: float) -> None:
    rng = np.random.default_rng(seed)
    q = SEED_6R.random_q(seed=rng)
    target = _target_near(SEED_6R, SEED_6R.random_q(seed=rng), rng, angle)
    task = diffik.FrameTask(target=target)
    e, jac = task.compute(SEED_6R, q)
    assert np.linalg.norm(e[3:]) < np.pi
    np.testing.assert_allclose(jac, _fd_jacobian(task, SEED_6R, q), atol=2e-6)


@pytest.mark.parametrize(
    ("m", "task"),
    [
        (SEED_6R, diffik.PositionTask(target=[0.5, 0.2, 0.7])),
        (SEED_6R, diffik.OrientationTask(target=spatial.rpy_to_rot(0.3, -0.4, 1.2))),
        (PLANAR_3R, diffik.Pose2DTask(target=optik.Pose2D(0.8, 0.9, 2.0))),
        (PLANAR_3R, diffik.PositionTask(target=[1.0, 0.5], axes="xy")),
        (PANDA, diffik.PostureTask(PANDA.mid_q(), cost=[1, 2, 3, 4, 5, 6, 7])),
        (PANDA, diffik.JointLimitTask(7)),
    ],
    ids=["position", "orientation", "pose2d", "position_xy", "posture", "joint_limit"],
)
def test_task_jacobians_match_finite_differences(m: optik.Mechanism, task: diffik.Task) -> None:
    rng = np.random.default_rng(1)
    for _ in range(3):
        q = m.random_q(seed=rng) * 0.9
        e, jac = task.compute(m, q)
        assert e.shape == (task.dim,) and jac.shape == (task.dim, m.n_q)
        np.testing.assert_allclose(jac, _fd_jacobian(task, m, q), atol=1e-5)


@pytest.mark.parametrize(("m", "space"), [(PLANAR_3R, "position2d"), (SEED_6R, "position"), (PANDA, "pose")])
def test_manipulability_task_asks_for_the_gradient_of_w(m: optik.Mechanism, space: str) -> None:
    task = diffik.ManipulabilityTask(m.n_q, space=space)
    q = m.random_q(seed=2) * 0.9
    e, jac = task.compute(m, q)
    h = 1e-6
    grad = [
        (
            m.manipulability(q + h * np.eye(m.n_q)[k], None, space)
            - m.manipulability(q - h * np.eye(m.n_q)[k], None, space)
        )
        / (2 * h)
        for k in range(m.n_q)
    ]
    np.testing.assert_allclose(-e, grad, atol=1e-6)
    np.testing.assert_allclose(jac, np.eye(m.n_q))


def test_pose2d_error_is_wrapped_heading_difference() -> None:
    q = np.array([0.3, 0.5, -0.2])
    pose = optik.spatial.planar_pose_of(PLANAR_3R.fk(q))
    task = diffik.Pose2DTask(target=optik.Pose2D(pose[0] - 0.1, pose[1], pose[2] + 3.0))
    e, _ = task.compute(PLANAR_3R, q)
    np.testing.assert_allclose(e, [0.1, 0.0, spatial.wrap_angle(-3.0)], atol=1e-12)


def test_dls_velocity_stays_bounded_at_a_singularity() -> None:
    m = optik.catalog.planar_2r()
    q = np.array([0.4, 1e-4])  # elbow stretched: sigma_min ~ 1e-4
    tip = m.fk(q)[:2, 3]
    radial = tip / np.linalg.norm(tip)
    task = diffik.PositionTask(target=tip - 0.01 * radial + [0.002, 0.0], axes="xy")
    free = [diffik.ConfigurationLimit()]
    pinv = diffik.step(m, q, [task], 0.01, "pinv", limits=free)
    dls = diffik.step(m, q, [task], 0.01, "dls", limits=free)
    lam = DLS_DAMPING
    err = np.linalg.norm(task.compute(m, q)[0])
    assert np.max(np.abs(dls.v)) * 0.01 <= err / (2 * lam) + 1e-9  # |dq| <= |t| / (2 lambda)
    assert np.max(np.abs(pinv.v)) > 20 * np.max(np.abs(dls.v))


def test_adaptive_damping_is_exact_away_from_singularities() -> None:
    jac = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.5]])
    damped, exact = pinv_pair(jac, damping=0.05, threshold=0.05)
    np.testing.assert_allclose(damped, exact)
    np.testing.assert_allclose(jac @ damped, np.eye(2), atol=1e-12)
    fixed, _ = pinv_pair(jac, damping=0.05)
    assert not np.allclose(fixed, exact)


def test_joint_weights_shift_motion_to_light_joints_and_fixed_damping_damps() -> None:
    q = np.array([0.3, -0.4, 0.2, -1.8, 0.1, 1.6, 0.4])
    task = diffik.PositionTask(target=PANDA.fk(q)[:3, 3] + [0.01, 0.0, 0.0])
    free = [diffik.ConfigurationLimit()]
    plain = diffik.step(PANDA, q, [task], 1.0, "pinv", limits=free)
    heavy = diffik.step(PANDA, q, [task], 1.0, "pinv", limits=free, joint_weights=[100, 1, 1, 1, 1, 1, 1])
    p = heavy.problem
    np.testing.assert_allclose(p.jacobian @ heavy.v, p.target, atol=1e-10)  # still exact
    assert abs(heavy.v[0]) < 0.2 * abs(plain.v[0])
    fixed = diffik.step(PANDA, q, [task], 1.0, "dls", limits=free, damping=0.5, adaptive=False)
    assert np.linalg.norm(fixed.v) < np.linalg.norm(plain.v)
    assert np.linalg.norm(p.jacobian @ fixed.v - p.target) > 1e-4  # damped: not exact


def test_priority_top_level_exact_and_lower_level_in_null_space() -> None:
    q = np.array([0.3, -0.4, 0.2, -1.8, 0.1, 1.6, 0.4])
    target = PANDA.fk(q) @ spatial.translation(0.01, -0.02, 0.01)
    frame = diffik.FrameTask(target=target)
    posture = diffik.PostureTask(q + 0.3, cost=1.0, priority=1)
    res = diffik.step(PANDA, q, [frame, posture], 1.0, "priority", limits=[diffik.ConfigurationLimit()])
    p = res.problem
    dq = res.v * p.dt
    top = p.slices[0]
    np.testing.assert_allclose(p.jacobian[top] @ dq, p.target[top], atol=1e-10)
    # the secondary task improves as far as the null space allows: better than the top level alone
    alone = diffik.step(PANDA, q, [frame], 1.0, "priority", limits=[diffik.ConfigurationLimit()])
    sec = p.slices[1]
    assert np.linalg.norm(p.jacobian[sec] @ dq - p.target[sec]) < np.linalg.norm(
        p.jacobian[sec] @ (alone.v * p.dt) - p.target[sec]
    )


def test_dls_projects_secondary_task_without_disturbing_primary() -> None:
    q = np.array([0.3, -0.4, 0.2, -1.8, 0.1, 1.6, 0.4])
    target = PANDA.fk(q) @ spatial.translation(0.005, 0.0, 0.0)
    frame = diffik.FrameTask(target=target)
    posture = diffik.PostureTask(q + 0.2, cost=1.0, priority=1)
    res = diffik.step(PANDA, q, [frame, posture], 1.0, "pinv", limits=[diffik.ConfigurationLimit()])
    p = res.problem
    top = p.slices[0]
    np.testing.assert_allclose(p.jacobian[top] @ (res.v * p.dt), p.target[top], atol=1e-10)


def _panda_problem_tasks(seed: int) -> tuple[np.ndarray, list[diffik.Task]]:
    rng = np.random.default_rng(seed)
    q = PANDA.random_q(seed=rng)
    frame = diffik.FrameTask(target=PANDA.fk(PANDA.random_q(seed=rng)))
    return q, [frame, diffik.PostureTask(PANDA.mid_q(), cost=1e-2)]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_qp_backends_agree_with_cvxpy(seed: int) -> None:
    q, tasks = _panda_problem_tasks(seed)
    results = {s: diffik.step(PANDA, q, tasks, 0.01, "qp", s) for s in ("daqp", "osqp", "cvxpy")}
    p = results["daqp"].problem
    assert np.any(np.isclose(results["daqp"].v * 0.01, p.lb) | np.isclose(results["daqp"].v * 0.01, p.ub))
    for name, res in results.items():
        assert res.status == "ok", name
        np.testing.assert_allclose(res.v, results["cvxpy"].v, atol=2e-4, err_msg=name)
    # the exact active-set answer is optimal: no other backend's (feasible) answer does better
    best = p.objective(results["daqp"].v * 0.01)
    assert all(best <= p.objective(res.v * 0.01) + 1e-9 for res in results.values())


def test_qpsolvers_backend_by_name_and_missing_backend() -> None:
    q, tasks = _panda_problem_tasks(3)
    a = diffik.step(PANDA, q, tasks, 0.01, "qp", "clarabel")
    b = diffik.step(PANDA, q, tasks, 0.01, "qp", "daqp")
    np.testing.assert_allclose(a.v, b.v, atol=1e-5)
    with pytest.raises(optik.SolverUnavailableError, match="not installed"):
        diffik.step(PANDA, q, tasks, 0.01, "qp", "no_such_solver")
    for solver in ("daqp", "osqp"):
        with pytest.raises(optik.InvalidArgumentError, match="options"):
            diffik.step(PANDA, q, tasks, 0.01, "qp", solver, no_such_setting=1)


def test_qp_equals_dls_when_no_limit_is_active() -> None:
    q = np.array([0.2, 0.9, -0.6, 0.3, 0.8, -0.2])
    task = diffik.FrameTask(target=SEED_6R.fk(q) @ spatial.translation(0.01, 0.02, -0.01))
    free = [diffik.ConfigurationLimit()]
    qp = diffik.step(SEED_6R, q, [task], 1.0, "qp", limits=free, damping=0.0)
    dls = diffik.step(SEED_6R, q, [task], 1.0, "dls", limits=free)
    assert qp.status == dls.status == "ok"
    np.testing.assert_allclose(qp.v, dls.v, atol=1e-8)
    np.testing.assert_allclose(qp.problem.jacobian @ qp.v, qp.problem.target, atol=1e-8)


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), method=st.sampled_from(diffik.METHODS))
def test_limits_never_violated_even_from_outside(seed: int, method: str) -> None:
    rng = np.random.default_rng(seed)
    q0 = PANDA.random_q(seed=rng)
    out = rng.integers(0, 7, size=2)
    q0[out[0]] = PANDA.lower[out[0]] - 0.03
    q0[out[1]] = PANDA.upper[out[1]] + 0.03
    tasks = [diffik.FrameTask(target=PANDA.fk(PANDA.random_q(seed=rng))), diffik.PostureTask(PANDA.mid_q())]
    q = q0
    lo, hi = np.minimum(PANDA.lower, q0), np.maximum(PANDA.upper, q0)
    for k in range(6):
        q_prev = q
        res = diffik.step(PANDA, q, tasks, 0.01, method)
        q = res.q
        assert np.all(q >= lo) and np.all(q <= hi)
        outside = (q_prev < PANDA.lower) | (q_prev > PANDA.upper)
        # outside coordinates move back in at full speed; inside ones never leave
        assert np.all(np.abs(res.v) <= PANDA.params["velocity_limits"] + 1e-9)
        assert np.all((q >= PANDA.lower) & (q <= PANDA.upper) | outside)
        if k >= 3:
            assert PANDA.within_limits(q)


def test_acceleration_limit_bounds_velocity_change() -> None:
    q, tasks = _panda_problem_tasks(4)
    v_prev = np.full(7, 0.1)
    lim = [diffik.VelocityLimit.of(PANDA), diffik.AccelerationLimit(5.0)]
    res = diffik.step(PANDA, q, tasks, 0.01, "qp", limits=lim, v_prev=v_prev)
    assert np.all(np.abs(res.v - v_prev) <= 5.0 * 0.01 + 1e-9)


def _assembled_five_bar(m: optik.Mechanism) -> np.ndarray:
    res = optik.solve_ik(m, optik.Position(0.5, 1.5), q0=[2.0, 1.2, -1.0, 1.0], method="qp", time_limit=2.0)
    assert res.success, res.message
    return res.q


def test_infeasible_qp_falls_back_with_status() -> None:
    m = optik.catalog.five_bar()
    q = _assembled_five_bar(m)
    broken = q + np.array([0.0, 0.0, 0.05, 0.0])  # loop open by ~5 cm
    task = diffik.PositionTask(target=optik.Position(0.5, 1.5), axes="xy")
    for solver in ("daqp", "osqp"):
        res = diffik.step(m, broken, [task], 0.01, "qp", solver, limits=[diffik.VelocityLimit(1e-3)])
        assert res.status == "qp_infeasible_fallback" and not res.ok
        assert "infeasible" in res.message
        assert np.all(np.abs(res.v) <= 1e-3 + 1e-12)
        assert m.within_limits(res.q)


def test_closed_chain_step_keeps_the_loop_closed() -> None:
    m = optik.catalog.five_bar()
    q = _assembled_five_bar(m)
    task = diffik.PositionTask(target=optik.Position(0.51, 1.49), axes="xy")
    for method in diffik.METHODS:
        res = diffik.step(m, q, [task], 0.01, method)
        p = res.problem
        np.testing.assert_allclose(p.A @ (res.v * p.dt), p.b, atol=1e-9)
        assert np.max(np.abs(m.closure(res.q))) < 1e-11


def test_build_qp_is_inspectable_and_consistent() -> None:
    q, tasks = _panda_problem_tasks(5)
    p = diffik.build_qp(PANDA, q, tasks, 0.01)
    np.testing.assert_allclose(p.H, p.jacobian.T @ p.jacobian + p.mu * np.eye(7), atol=1e-12)
    np.testing.assert_allclose(p.c, -p.jacobian.T @ p.target, atol=1e-12)
    e, _ = tasks[0].compute(PANDA, q)
    np.testing.assert_allclose(p.task_errors()[0], e, atol=1e-12)
    assert np.all(p.lb <= 0) and np.all(p.ub >= 0)
    assert p.A.shape == (0, 7)


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"dt": 0.0}, "dt"),
        ({"method": "newton"}, "method"),
        ({"q": np.full(7, np.nan)}, "q"),
    ],
)
def test_malformed_input_names_the_argument(kwargs: dict, argument: str) -> None:
    args = {"m": PANDA, "q": PANDA.mid_q(), "tasks": [diffik.PostureTask(PANDA.mid_q())], "dt": 0.01}
    args.update(kwargs)
    with pytest.raises(optik.InvalidArgumentError) as info:
        diffik.step(**args)
    assert info.value.argument == argument


def test_task_without_target_and_unknown_frame_raise() -> None:
    with pytest.raises(optik.InvalidArgumentError, match="target"):
        diffik.step(PANDA, PANDA.mid_q(), [diffik.FrameTask()], 0.01)
    with pytest.raises(optik.UnknownFrameError):
        diffik.step(PANDA, PANDA.mid_q(), [diffik.FrameTask("nope", target=np.eye(4))], 0.01)
    with pytest.raises(optik.InvalidArgumentError, match="gain"):
        diffik.FrameTask(gain=2.0)


def test_benchmark_script_runs(capsys: pytest.CaptureFixture[str]) -> None:
    from optik.benchmarks import bench_diffik as bench

    assert bench.main(["--goals", "2", "--steps", "5", "--no-pink"]) == 0
    out = capsys.readouterr().out
    assert "| optik qp (default: " in out and "| optik qp osqp" in out


@pytest.mark.parametrize(
    ("name", "tasks", "limits"),
    [
        ("tasks", None, None),
        ("tasks", 3, None),
        ("tasks", [], None),
        ("tasks", ["zz"], None),
        ("limits", "task", 3),
        ("limits", "task", diffik.VelocityLimit(1.0)),
        ("limits", "task", [None]),
    ],
)
def test_step_rejects_malformed_tasks_and_limits(name, tasks, limits):
    """Non-iterables used to leak TypeError (``'int' object is not iterable``)."""
    m = optik.catalog.planar_2r()
    tasks = diffik.tracking_task(m) if tasks == "task" else tasks
    with pytest.raises(optik.InvalidArgumentError, match=rf"^{name}:"):
        diffik.step(m, [0.1, 0.2], tasks, 0.01, limits=limits)
