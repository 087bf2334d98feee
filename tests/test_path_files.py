"""Tool paths from a few numbers (`optik.path.shapes`), the ``[path]`` table of problem files and
``optik path PROBLEM`` (issue 24 item 4)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import optik
from optik.cli import main
from optik.path import shapes
from optik.problem_files import load_problem

START = optik.spatial.transform(optik.spatial.rpy_to_rot(0.1, 0.2, 0.3), [0.5, 0.1, 0.4])


def spacing(poses):
    return np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)


def test_line_and_polyline_are_evenly_spaced_on_their_segments():
    line = shapes.line(START, [0.1, 0.0, -0.1], 11)
    assert np.allclose(line[-1, :3, 3], START[:3, 3] + [0.1, 0.0, -0.1])
    assert np.allclose(spacing(line), np.sqrt(0.02) / 10)
    assert np.allclose(line[:, :3, :3], START[:3, :3])
    poly = shapes.polyline(START, [[0.1, 0.0, 0.0], [0.1, 0.1, 0.0]], 21)
    assert np.allclose(spacing(poly), 0.2 / 20)
    assert np.allclose(poly[10, :3, 3], START[:3, 3] + [0.1, 0.0, 0.0])  # the corner, halfway
    assert np.allclose(poly[-1, :3, 3], START[:3, 3] + [0.1, 0.1, 0.0])


def test_arc_keeps_its_radius_and_turns_the_tool():
    arc = shapes.arc(START, [0.0, 0.05, 0.0], [0, 0, 1], np.pi / 2, 31)
    centre = START[:3, 3] + [0.0, 0.05, 0.0]
    assert np.allclose(np.linalg.norm(arc[:, :3, 3] - centre, axis=1), 0.05)
    assert np.allclose(arc[-1, :3, :3], optik.spatial.rot_z(np.pi / 2) @ START[:3, :3])
    held = shapes.arc(START, [0.0, 0.05, 0.0], [0, 0, 1], np.pi / 2, 31, turn_tool=False)
    assert np.allclose(held[:, :3, :3], START[:3, :3])
    with pytest.raises(optik.InvalidArgumentError, match="axis"):
        shapes.arc(START, [0.0, 0.05, 0.0], [0, 0, 0], 1.0, 5)


def test_waypoints_interpolate_position_and_geodesic_rotation():
    end = optik.spatial.transform(optik.spatial.rot_z(0.8) @ START[:3, :3], [0.6, 0.1, 0.4])
    poses = shapes.waypoints(np.stack([START, end]), 5)
    assert np.allclose(poses[0], START) and np.allclose(poses[-1], end)
    assert np.isclose(optik.spatial.angle_between(poses[2, :3, :3], START[:3, :3]), 0.4)
    with pytest.raises(optik.ShapeError, match="waypoints"):
        shapes.waypoints(START[None], 5)


def _problem_file(tmp_path, body):
    path = tmp_path / "weld.toml"
    path.write_text('[problem]\ndescription = "a weld"\n[mechanism]\nconstructor = "puma560"\n' + body)
    return load_problem(path)


Q = "[-0.44, 1.29, -1.77, 0.34, -0.13, 0.14]"


@pytest.mark.parametrize(
    "body",
    [
        f"kind = 'line'\nstart_q = {Q}\nend = [0.0, 0.1, 0.0]",
        f"kind = 'arc'\nstart_q = {Q}\ncenter = [0.0, 0.03, 0.0]\nangle = 60.0\nturn_tool = false",
        f"kind = 'polyline'\nstart_q = {Q}\npoints = [[0.0, 0.05, 0.0], [0.0, 0.05, 0.02]]",
        "kind = 'waypoints'\nwaypoints = [[0.5, 0.1, 0.4, 3.1, 0.0, 0.0], [0.5, 0.15, 0.4, 3.1, 0.0, 0.2]]",
    ],
)
def test_path_table_kinds(tmp_path, body):
    problem = _problem_file(tmp_path, f"[path]\n{body}\nn = 40\ndt = 0.05\n")
    poses, times = problem.path_poses()
    assert poses.shape == (40, 4, 4) and np.allclose(np.diff(times), 0.05)
    if "start_q" in body:
        assert np.allclose(poses[0], problem.mechanism().fk(np.array(json.loads(Q))))
    assert problem.path_options()["tol"] == problem.tolerances


def test_path_table_errors_name_the_key(tmp_path):
    with pytest.raises(optik.ProblemFileError, match=r"path\.end"):
        _problem_file(tmp_path, f"[path]\nkind = 'line'\nstart_q = {Q}\n").path_poses()
    with pytest.raises(optik.ProblemFileError, match=r"path\.kind"):
        _problem_file(tmp_path, "[path]\nkind = 'spiral'\n")
    with pytest.raises(optik.ProblemFileError, match=r"path\.speed: unknown key"):
        _problem_file(tmp_path, "[path]\nkind = 'line'\nspeed = 1.0\n")
    with pytest.raises(optik.ProblemFileError, match=r"\[path\]"):
        _problem_file(tmp_path, "").path_poses()
    bad = _problem_file(tmp_path, f"[path]\nkind = 'line'\nstart_q = {Q}\nend = [0, 1]\n")
    with pytest.raises(optik.ProblemFileError, match=r"path\.end"):
        bad.path_poses()


def test_optik_path_command_writes_a_checked_path(tmp_path, capsys):
    assert main(["path", "puma560_weld", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "0 branch changes" in printed and "fk ok" in printed
    assert (tmp_path / "puma560_weld_path.png").stat().st_size > 10_000
    data = np.load(tmp_path / "puma560_weld_path.npz")
    problem = optik.problem_files.find_problem("puma560_weld")
    poses, _ = problem.path_poses()
    m = problem.mechanism()
    assert data["q"].shape == (len(poses), 6)
    assert np.abs(optik.fk_batch(m, data["q"])[:, :3, 3] - poses[:, :3, 3]).max() < 1e-9
    assert main(["path", "five_bar", "--out", str(tmp_path)]) == 2  # no [path] table
