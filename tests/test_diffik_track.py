"""Path tracking with differential IK: lines, circles, the welding seam, singularities, closed
chains and the self-motion of a redundant arm."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import diffik, spatial
from optik.diffik import scenarios

TOOL_DOWN = np.diag([1.0, -1.0, -1.0])


def _start(m: optik.Mechanism, pose: np.ndarray, q0: np.ndarray) -> np.ndarray:
    res = optik.solve_ik(m, pose, q0=q0, method="qp", time_limit=2.0)
    assert res.success, res.message
    return res.q


@pytest.mark.parametrize("method", ["qp", "dls"])
def test_line_on_the_seed_arm(method: str) -> None:
    m = optik.catalog.seed_6r_arm()
    q0 = np.array([0.2, 0.6, -1.2, 0.3, 0.8, -0.2])
    start = m.fk(q0)
    end = spatial.translation(0.1, 0.1, 0.1) @ start @ spatial.transform(spatial.rot_x(0.2))
    path = diffik.line_path(start, end, np.sqrt(0.03) / 0.99, 0.01)  # 99 steps of 0.01 s
    assert len(path) == 100
    res = diffik.track(m, q0, path, 0.01, method)
    assert res.within_limits
    assert res.position_error.max() < 1e-4 and res.orientation_error.max() < 1e-4
    np.testing.assert_allclose(m.fk(res.q[-1]), path[-1], atol=1e-5)


def test_circle_with_the_planar_3r_heading_fixed() -> None:
    m = optik.catalog.planar_3r()
    q0 = np.array([0.3, 1.0, 0.5])
    pose = optik.spatial.planar_pose_of(m.fk(q0))
    path = diffik.circle_path([pose[0] - 0.2, pose[1], 0.0], 0.2, 0.85, 0.01, spatial.rot_z(pose[2]))
    res = diffik.track(m, q0, path, 0.01, "qp")
    assert res.position_error.max() < 1e-4 and res.orientation_error.max() < 1e-4
    assert res.within_limits


def test_welding_seam_constant_orientation_and_speed_on_the_panda() -> None:
    m = optik.catalog.panda()
    points = [[0.45, -0.2, 0.25], [0.6, -0.2, 0.25], [0.6, 0.15, 0.3]]
    speed, dt = 0.25, 0.01
    path = diffik.polyline_path(points, speed, dt, TOOL_DOWN)
    steps = np.linalg.norm(np.diff(path[:, :3, 3], axis=0), axis=1)
    np.testing.assert_allclose(steps[:-1], speed * dt, atol=1e-12)  # uniform motion along the seam
    q0 = _start(m, path[0], m.mid_q())
    res = diffik.track(m, q0, path, dt, "qp", tasks=[diffik.PostureTask(q0, cost=1e-3)])
    assert res.within_limits and set(res.status) == {"ok"}
    assert res.position_error.max() < 5e-4 and res.orientation_error.max() < 1e-3
    tcp = np.array([m.fk(q)[:3, 3] for q in res.q[1:]])
    speeds = np.linalg.norm(np.diff(tcp, axis=0), axis=1)[:-1] / dt
    np.testing.assert_allclose(speeds, speed, rtol=0.05)
    assert np.all(np.abs(res.v) <= m.params["velocity_limits"] + 1e-9)


def test_dls_passes_the_2r_elbow_singularity_without_velocity_blow_up() -> None:
    sc = scenarios.elbow_singularity()
    m, path = sc.m, sc.path
    q0 = _start(m, optik.Position(1.0, 0.0), sc.q0)
    dls = diffik.track(m, q0, path, sc.dt, "dls")
    pinv = diffik.track(m, q0, path, sc.dt, "pinv")
    assert dls.manipulability.min() < 1e-3  # the arm stretched out to the singularity
    assert pinv.max_speed > 2.5 * dls.max_speed
    assert dls.position_error[-1] < 1e-4  # and came back onto the path


def test_five_bar_driven_along_a_circle_keeps_the_loop_closed() -> None:
    m = optik.catalog.five_bar()
    q0 = _start(m, optik.Position(0.5, 1.5), np.array([2.0, 1.2, -1.0, 1.0]))
    path = diffik.circle_path([0.5, 1.4, 0.0], 0.1, 0.53, 0.01, start_angle=np.pi / 2)
    for method in ("qp", "dls"):
        res = diffik.track(m, q0, path, 0.01, method)
        assert res.closure_error.max() < 1e-11
        assert res.position_error.max() < 1e-4
        assert res.within_limits


def test_self_motion_of_a_7dof_arm_keeps_the_end_effector_fixed() -> None:
    sc = scenarios.self_motion()  # flange fixed, joint 3 turned by 1 rad at priority 1
    q0 = sc.q0
    res = diffik.track(sc.m, q0, sc.path, sc.dt, "priority", tasks=sc.tasks)
    assert res.position_error.max() < 2e-4 and res.orientation_error.max() < 2e-4  # second order in the step
    assert res.position_error[-1] < 1e-8 and res.q[-1][2] - q0[2] > 0.9
    assert res.within_limits


def test_doggy_body_driven_along_a_circle_keeps_both_legs_closed() -> None:
    m = optik.catalog.doggy()
    q0 = _start(m, optik.Pose2D(0.0, 0.8, 0.0), np.array([1.2, 0.8, -2.0, 1.9, -0.8]))
    path = diffik.circle_path([0.0, 0.75, 0.0], 0.05, 0.32, 0.01, start_angle=np.pi / 2)  # heading 0
    res = diffik.track(m, q0, path, 0.01, "qp")
    assert res.closure_error.max() < 1e-11
    assert res.position_error.max() < 1e-4 and res.orientation_error.max() < 1e-4
    assert res.within_limits


@pytest.mark.parametrize(
    ("secondary", "first_joint", "improved"),
    [
        (
            lambda m: diffik.ManipulabilityTask(7, space="position", gain=0.5, priority=1),
            0.3,
            lambda m, q0, q1: (
                m.manipulability(q1, None, "position") > 1.05 * m.manipulability(q0, None, "position")
            ),
        ),
        (
            lambda m: diffik.JointLimitTask(7, cost=1.0, gain=0.1, priority=1),
            2.8473,  # 0.05 rad from the limit
            lambda m, q0, q1: m.upper[0] - q1[0] > 0.5 + (m.upper[0] - q0[0]),
        ),
    ],
    ids=["manipulability", "joint_limit"],
)
def test_secondary_objectives_improve_while_the_flange_holds(secondary, first_joint, improved) -> None:
    m = optik.catalog.panda()
    q0 = np.array([first_joint, -0.3, 0.4, -2.0, 0.2, 1.8, 0.8])
    path = np.repeat(m.fk(q0)[None], 100, axis=0)
    res = diffik.track(m, q0, path, 0.01, "priority", tasks=[secondary(m)])
    assert res.position_error.max() < 5e-4 and res.orientation_error.max() < 5e-4  # second order
    assert improved(m, q0, res.q[-1])
    assert res.within_limits


def test_track_from_slightly_outside_the_limits_recovers() -> None:
    m = optik.catalog.panda()
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    q0[3] = m.upper[3] + 0.05
    path = np.repeat(m.fk(q0)[None], 10, axis=0)
    res = diffik.track(m, q0, path, 0.01, "qp")
    back = int(np.argmax(res.limit_margin >= 0))
    assert back == 3  # 0.05 rad at 2.175 rad/s: three steps of 10 ms
    assert np.all(np.diff(res.limit_margin[: back + 1]) > 0) and np.all(res.limit_margin[back:] >= 0)


def test_track_rejects_a_malformed_path() -> None:
    m = optik.catalog.planar_2r()
    with pytest.raises(optik.InvalidArgumentError, match="path"):
        diffik.track(m, m.mid_q(), np.zeros((3, 4, 3)), 0.01)  # (3, 3) is three points now
