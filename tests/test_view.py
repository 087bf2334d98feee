"""The browser viewer driven from Python (no browser): every answer it shows is checked
independently (FK of the shown q against the target, loop closures, limits, branch counts)."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest

pytest.importorskip("viser", reason="the view extra (viser) is not installed")

import optik
from optik import catalog, closed_form, spatial
from optik.cli import main
from optik.view import Viewer
from optik.view.latest import Latest


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def open_viewer():
    """``open_viewer(m, **options)``: a Viewer on a free port, closed after the test."""
    viewers: list[Viewer] = []

    def make(m, q=None, **options):
        v = optik.view(m, q, port=free_port(), **options)
        viewers.append(v)
        return v

    yield make
    for v in viewers:
        v.close()


def test_gizmo_target_moves_the_arm_to_a_solved_configuration(open_viewer):
    m = catalog.panda()
    v = open_viewer(m)
    assert v.url.startswith("http://127.0.0.1:")  # localhost by default
    assert v.method == "lm" and {"lm", "nlp", "dls", "qp"} <= set(v.methods)
    for seed in range(5):
        target = m.fk(m.random_q(seed=seed))
        res = v.set_target(target)
        assert res.success, res.message
        np.testing.assert_allclose(v.target, target, atol=1e-12)  # the gizmo is at the target
        shown = m.fk(v.q)  # independent check of what is displayed
        assert np.linalg.norm(shown[:3, 3] - target[:3, 3]) < 1e-6
        assert spatial.angle_between(shown[:3, :3], target[:3, :3]) < 1e-6
        assert m.within_limits(v.q)
        assert "solved" in v.panel.status.content and "ms" in v.panel.status.content


def test_the_last_answer_seeds_the_next_solve(open_viewer):
    m = catalog.panda()
    v = open_viewer(m)
    v.set_target(m.fk(m.random_q(seed=1)))
    before = v.q
    res = v.set_target(m.fk(before + 0.01))  # a small gizmo move of a redundant arm
    assert res.success
    assert np.max(np.abs(v.q - before)) < 0.05  # seeded by the last answer: no jump to another branch


def test_unreachable_target_is_shown_as_not_solved(open_viewer):
    m = catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    v = open_viewer(m)
    res = v.set_target(optik.Pose2D(5.0, 0.0, 0.0))
    assert not res.success
    assert "not solved" in v.panel.status.content
    assert m.within_limits(v.q)


def test_planar_gizmo_is_projected_on_the_plane(open_viewer):
    m = catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    v = open_viewer(m)
    res = v.set_target(optik.Pose2D(1.2, 0.8, 0.5))
    assert res.success
    np.testing.assert_allclose(spatial.planar_pose_of(m.fk(v.q)), (1.2, 0.8, 0.5), atol=1e-9)
    np.testing.assert_allclose(spatial.planar_pose_of(v.target), (1.2, 0.8, 0.5), atol=1e-12)


def test_all_solutions_draws_every_closed_form_branch(open_viewer):
    m = catalog.seed_6r_arm()
    target = m.fk(m.random_q(seed=4))
    v = open_viewer(m)
    v.set_target(target)
    branches = v.show_all_solutions(True)
    expected = closed_form.ik(m, target)
    assert len(branches) == len(expected) >= 2
    for r in branches:
        assert np.linalg.norm(m.fk(r.q)[:3, 3] - target[:3, 3]) < 1e-6
    assert sum(g.visible for g in v._ghosts) == len(branches)
    assert f"**{len(branches)}** branches" in v.panel.branches.content
    assert v.show_all_solutions(False) == [] and not any(g.visible for g in v._ghosts)


def test_joint_sliders_follow_fk(open_viewer):
    m = catalog.panda()
    v = open_viewer(m)
    q = m.random_q(seed=7)
    pose = v.set_q(q)
    np.testing.assert_allclose(pose, m.fk(q), atol=1e-12)
    np.testing.assert_allclose(v.target, m.fk(q), atol=1e-9)  # the gizmo sits on the end effector
    np.testing.assert_allclose([s.value for s in v.panel.sliders], q, atol=1e-12)


def test_actuator_sliders_show_every_assembly_mode_of_the_five_bar(open_viewer):
    m = catalog.five_bar()
    v = open_viewer(m)
    assert np.max(np.abs(m.closure(v.q))) < 1e-9  # the first configuration is assembled
    modes = v.set_actuated([1.5, 1.0])
    assert len(modes) == 2 == len(closed_form.fk(m, [1.5, 1.0]))
    for q in modes:
        assert np.max(np.abs(m.closure(q))) < 1e-9
        np.testing.assert_allclose(q[m.actuated_indices], [1.5, 1.0], atol=1e-12)
    shown = v.q
    other = v.show_mode(1 - next(i for i, q in enumerate(modes) if np.allclose(q, shown)))
    assert not np.allclose(other, shown) and np.allclose(v.q, other)
    assert sum(g.visible for g in v._ghosts) == 1
    assert "**2** assembly modes" in v.panel.modes.content
    assert v.set_actuated([np.pi, 0.0]) == []  # the proximal ends are 3 apart: the distal links reach 2.4
    assert "does not assemble" in v.panel.modes.content


def test_stewart_gough_modes_close_their_loops(open_viewer):
    m = catalog.stewart_gough()
    v = open_viewer(m)
    legs = [1.2, 1.1, 1.15, 1.25, 1.2, 1.1]
    modes = v.set_actuated(legs)
    assert len(modes) >= 2
    for q in modes:
        assert np.max(np.abs(m.closure(q))) < 1e-9 and m.within_limits(q)


def test_tracked_path_plays_back_on_the_sample_slider(open_viewer):
    m = catalog.panda()
    v = open_viewer(m)
    result = v.track()
    assert result.within_limits and np.max(result.position_error) < 1e-3
    assert v.panel.sample.max == len(result.q) - 1 and not v.panel.play.disabled
    k = 40
    np.testing.assert_allclose(v.show_path_sample(k), result.q[k])
    assert np.linalg.norm(m.fk(v.q)[:3, 3] - v.target[:3, 3]) < 1e-3  # the gizmo shows sample k's target


def test_bad_input_raises_named_errors(open_viewer):
    m = catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    with pytest.raises(optik.InvalidArgumentError, match=r"^method"):
        open_viewer(m, method="warp")
    with pytest.raises(optik.SolverUnavailableError):
        open_viewer(catalog.panda(), method="closed_form")
    v = open_viewer(m)
    with pytest.raises(optik.ShapeError):
        v.set_q([0.0, 1.0])
    with pytest.raises(optik.InvalidArgumentError, match=r"^values"):
        v.set_actuated([1.0])
    with pytest.raises(optik.InvalidArgumentError, match=r"^k"):
        v.show_path_sample(0)
    with pytest.raises(optik.InvalidArgumentError, match=r"^time_limit"):
        open_viewer(m, time_limit=0)


def test_a_busy_port_gives_the_next_free_one(open_viewer):
    m = catalog.planar_2r()
    a = open_viewer(m)
    b = optik.view(m, port=a.port)
    try:
        assert b.port != a.port
    finally:
        b.close()


def test_latest_runs_the_newest_request_and_drops_the_stale_ones():
    seen: list[int] = []
    release = threading.Event()

    def slow(x: int) -> None:
        if x == 0:
            release.wait(5)
        seen.append(x)

    latest = Latest(slow)
    first = threading.Thread(target=latest, args=(0,))
    first.start()
    time.sleep(0.05)
    for x in (1, 2, 3):
        latest(x)  # return at once: a run is going on
    release.set()
    first.join(5)
    assert seen == [0, 3]


@pytest.mark.parametrize(
    ("argv", "argument"),
    [
        (["view", "no_such_problem", "--no-browser"], "PROBLEM|ROBOT|URDF"),
        (["view", "robot.urdf", "--no-browser"], "PROBLEM|ROBOT|URDF"),  # no such file
        (["view", str(optik.catalog.urdf_path("panda")), "--no-browser"], "--base"),
        (["view", "planar_3r", "--no-browser", "--method", "warp"], "method"),
        (["view", "planar_3r", "--no-browser", "--port", "70000"], "--port"),
        (["view", "planar_3r", "--no-browser", "--reach", "no/such/map"], "--reach"),
    ],
)
def test_view_command_errors_exit_2_naming_the_argument(argv, argument, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"optik view: error: {argument}: ") and len(err.splitlines()) == 1


def test_view_help(capsys):
    with pytest.raises(SystemExit) as info:
        main(["view", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "usage: optik view" in out and "127.0.0.1" in out


def _pose(handle) -> np.ndarray:
    from optik.view.shapes import rotation

    return spatial.transform(rotation(handle.wxyz), np.asarray(handle.position, dtype=float))


@pytest.mark.parametrize("name", ["panda", "stewart_gough"])
def test_scene_nodes_compose_to_the_model_poses(open_viewer, name):
    """Each body node sits at T_b(q); a joint frame drawn as the child node ``origin_j`` of its parent
    body lands on A_j(q) = T_parent(q) origin_j, the end-effector frame on FK(q)."""
    from optik.view.scene import poses

    m = getattr(catalog, name)()
    v = open_viewer(m)
    q = v.q if m.is_closed else m.random_q(seed=2)
    v.set_q(q)
    p = poses(m, q)
    nodes = v.robot._bodies
    for body, t in p.bodies.items():
        np.testing.assert_allclose(_pose(nodes[body]) if body != m.base else np.eye(4), t, atol=1e-9)
    for k, j in enumerate(m.joints):
        np.testing.assert_allclose(
            _pose(nodes[j.parent]) @ j.origin if j.parent != m.base else j.origin,
            p.joint_frames[k],
            atol=1e-9,
        )
    body, offset = m.frames[m.ee]
    np.testing.assert_allclose(_pose(nodes[body]) @ offset, m.fk(q), atol=1e-9)


def test_capability_map_is_a_point_cloud_coloured_by_the_index(open_viewer, tmp_path):
    from matplotlib import colormaps

    m = catalog.planar_2r()
    rmap = optik.reach(m, resolution=0.25, orientations=4, samples=2000, workers=1, out=tmp_path)
    v = open_viewer(m)
    assert v.show_reach(rmap) == len(rmap.centers) == int(np.isfinite(rmap.index).sum())
    np.testing.assert_allclose(v._reach.points, rmap.centers, atol=1e-3)  # float16 on the wire
    k = int(np.argmax(rmap.index))
    np.testing.assert_array_equal(
        v._reach.colors[k], (255 * np.asarray(colormaps["viridis"](rmap.index[k]))[:3]).astype(np.uint8)
    )
    assert "mean reachability index" in v.panel.reach_text.content and not v.panel.reach.disabled
    assert v.show_reach(tmp_path) == len(rmap.centers)  # the saved reach.npz (its folder)
    v.set_reach_visible(False)
    assert not v._reach.visible
    with pytest.raises(optik.InvalidArgumentError, match=r"^source"):
        v.show_reach(tmp_path / "nothing")
    (tmp_path / "bad.npz").write_bytes(b"not a map")
    with pytest.raises(optik.InvalidArgumentError, match=r"^source"):
        v.show_reach(tmp_path / "bad.npz")


def test_a_spatial_map_is_drawn_one_small_layer_at_a_time(open_viewer):
    from optik.view.viewer import REACH_POINT

    m = catalog.panda()
    rmap = optik.reach(m, resolution=0.3, orientations=2, samples=3000, workers=1, time_limit=0.002)
    v = open_viewer(m)
    levels = np.unique(np.round(rmap.centers[:, 2], 6))
    assert len(levels) > 2
    ee_z = m.fk(v.q)[2, 3]
    first = v.show_reach(rmap)
    nearest = levels[np.argmin(np.abs(levels - ee_z))]
    assert first == int(np.sum(np.isclose(rmap.centers[:, 2], nearest))) < len(rmap.centers)
    assert np.allclose(v._reach.points[:, 2], nearest, atol=1e-2)  # float16 on the wire
    assert v._reach.point_size == pytest.approx(REACH_POINT * rmap.resolution) and REACH_POINT <= 0.2
    assert f"layer z = {nearest:.3f} m" in v.panel.layer_text.content and not v.panel.reach_layer.disabled
    drawn = sum(v.set_reach_layer(z) for z in levels)
    assert drawn == len(rmap.centers)  # the layers partition the map
    v.set_reach_visible(False)
    v.set_reach_layer(levels[0])
    assert not v._reach.visible  # moving the layer keeps the box's choice
    with pytest.raises(optik.InvalidArgumentError, match=r"^z"):
        v.set_reach_layer(float("nan"))


URDF = """<robot name="two">
  <link name="base"><visual><geometry><box size="0.2 0.2 0.1"/></geometry></visual></link>
  <link name="upper">
    <visual><origin xyz="0 0 0.25"/><geometry><mesh filename="upper.stl"/></geometry></visual>
  </link>
  <link name="lower"><visual><geometry><mesh filename="missing.stl"/></geometry></visual></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="upper"/><child link="lower"/><origin xyz="0 0 0.5"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


def test_urdf_visuals_are_drawn_where_their_files_resolve(open_viewer, tmp_path):
    import trimesh

    trimesh.creation.cylinder(radius=0.04, height=0.5).export(tmp_path / "upper.stl")
    (tmp_path / "two.urdf").write_text(URDF)
    m = optik.Mechanism.from_urdf(tmp_path / "two.urdf", "base", "lower")
    v = open_viewer(m)
    assert v.robot.visual_bodies == ("base", "upper")  # the box and the STL; lower is a capsule chain
    assert len(v.notes) == 1 and "missing.stl: file not found" in v.notes[0]
    assert "1 URDF visuals not drawn" in v.panel.notes.content


def test_urdf_meshes_of_example_robot_data_resolve():
    from test_urdf_ros import _robots_dir

    from optik.view.visuals import body_visuals

    path = _robots_dir() / "panda_description" / "urdf" / "panda.urdf"
    m = optik.Mechanism.from_urdf(path, "panda_link0", "panda_hand")
    meshes, notes = body_visuals(m)
    assert notes == []
    visuals = m.params["visuals"]
    # link0..link7, the hand and its two fingers (carried by the chain off its path, joints held at 0),
    # the hand and fingers on the body of link7
    assert [v.link for v in visuals] == [
        *(f"panda_link{i}" for i in range(8)),
        "panda_hand",
        "panda_leftfinger",
        "panda_rightfinger",
    ]
    assert set(meshes) == {m.frames[v.link][0] for v in visuals}
    assert all(len(mesh.faces) > 1000 for mesh in meshes.values())


def test_method_dropdown_selects_the_solver(open_viewer):
    m = catalog.panda()
    v = open_viewer(m)
    target = m.fk(m.random_q(seed=9))
    for name in ("nlp", "dls", "lm"):
        v.method = name
        res = v.set_target(target)
        assert res.method == name and f"**{name}**" in v.panel.status.content
        if res.success:
            assert np.linalg.norm(m.fk(v.q)[:3, 3] - target[:3, 3]) < 1e-6
    with pytest.raises(optik.SolverUnavailableError):
        v.method = "closed_form"


def test_gizmo_ik_of_a_closed_chain_keeps_its_loops_closed(open_viewer):
    m = catalog.five_bar()
    v = open_viewer(m)
    res = v.set_target(optik.Position([0.6, 1.3, 0.0]))
    assert res.success
    np.testing.assert_allclose(m.fk(v.q)[:2, 3], (0.6, 1.3), atol=1e-6)
    assert np.max(np.abs(m.closure(v.q))) < 1e-9 and "closure error" in v.panel.status.content


def test_play_runs_through_the_tracked_path(open_viewer):
    m = catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    v = open_viewer(m)
    v.set_q([0.3, 0.8, -0.6])
    result = v.track(dt=0.001)
    v.panel._play()
    v.panel._player.join(10)
    np.testing.assert_allclose(v.q, result.q[-1])
    assert v.panel.sample.value == len(result.q) - 1


def test_play_after_a_stop_plays_again(open_viewer):
    """`stop` ends the playback at once (mid-wait); the next play still runs to the end."""
    m = catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    v = open_viewer(m)
    v.set_q([0.3, 0.8, -0.6])
    result = v.track(dt=0.001)
    v.path.t[:] = np.arange(len(v.path.t)) * 30.0  # 30 s per sample: only a stop ends it
    v.play()
    v.panel.stop()
    assert not v.panel._player.is_alive()  # its 30 s wait ended (stop waits 5 s at most)
    assert v.panel.sample.value < len(result.q) - 1
    v.path.t[:] = np.arange(len(v.path.t)) * 1e-4
    v.play(wait=True)
    np.testing.assert_allclose(v.q, result.q[-1])
    assert v.panel.sample.value == len(result.q) - 1


def test_planned_path_plays_back(open_viewer):
    """A `JointPath` of `plan_path` loads on the slider and plays back to its last sample,
    the gizmo on that sample's pose; anything else is refused naming the argument."""
    m = catalog.puma560()
    poses = np.repeat(m.fk(np.array([-0.44, 1.29, -1.77, 0.34, -0.13, 0.14]))[None], 20, axis=0)
    poses[:, :3, 3] += np.linspace(0.0, 1.0, 20)[:, None] * [0.0, 0.05, 0.0]
    path = optik.plan_path(m, poses, np.arange(20) * 0.001)
    assert path.success, path.message
    v = open_viewer(m)
    v.show_path(path)
    np.testing.assert_allclose(v.q, path.q[0])
    assert v.panel.sample.max == 19 and not v.panel.play.disabled
    assert "planned: 20 samples" in v.panel.path_text.content
    v.play(wait=True)
    np.testing.assert_allclose(v.q, path.q[-1])
    assert v.panel.sample.value == 19
    np.testing.assert_allclose(v.target, poses[-1], atol=1e-9)
    for bad in (path.q, optik.plan_path(catalog.planar_3r(), [np.eye(4)])):
        with pytest.raises(optik.InvalidArgumentError) as err:
            v.show_path(bad)
        assert err.value.argument == "path"


def test_optik_view_path_needs_a_problem_with_a_path(capsys):
    assert main(["view", "panda", "--path", "--no-browser"]) != 0
    assert "[path]" in capsys.readouterr().err


def test_optik_view_stops_on_sigterm():
    import os
    import select
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "optik.cli", "view", "planar_2r", "--no-browser", "--port", str(free_port())],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
    )
    try:
        assert select.select([proc.stdout], [], [], 60)[0], "optik view printed nothing within 60 s"
        assert "http://127.0.0.1:" in proc.stdout.readline()
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    assert proc.returncode == 0 and "Traceback" not in err, err
    assert "optik view: stopped" in out
