"""The first hour of a new user (issue 20): every error a newcomer meets is one line that says
what to do, and a failed command leaves nothing behind."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import optik
from optik.cli import main


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of ``optik ARGV``."""
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse-level errors and --help
        code = exc.code
    out = capsys.readouterr()
    return int(code or 0), out.out, out.err


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


# ---------------------------------------------------------------------------- missing extras
@pytest.mark.parametrize(
    ("blocked", "argv", "extra"),
    [
        ("viser", ["view", "planar_3r", "--no-browser", "--port", "0"], "view"),
        ("trimesh", ["view", "planar_3r", "--no-browser", "--port", "0"], "view"),
        ("distributed", ["reach", "planar_3r", "--scheduler", "tcp://127.0.0.1:1", "--out", "x"], "dist"),
    ],
)
def test_a_missing_extra_is_one_line_naming_the_pip_command(blocked, argv, extra, capsys, monkeypatch):
    if blocked == "trimesh":  # trimesh is imported after viser: without viser, viser is named
        pytest.importorskip("viser", reason="the view extra is not installed (pip install 'optik[view]')")
    monkeypatch.setitem(sys.modules, blocked, None)  # import of `blocked` now fails as if absent
    code, _, err = _run(argv, capsys)
    line = _one_line(err)
    assert code == 2
    assert f'{blocked} (not installed): pip install "optik[{extra}]"' in line, line


def test_missing_extras_raise_missing_extra_error(monkeypatch):
    m = optik.catalog.planar_2r()
    batch = optik.solve_ik_batch(m, [optik.Position([1.0, 0.5, 0.0])], method="closed_form")
    target = [optik.Position([1.0, 0.5, 0.0])]
    for blocked, extra, call in [
        ("pandas", "pandas", batch.to_dataframe),
        ("viser", "view", lambda: optik.view(m)),
        ("distributed", "dist", lambda: optik.solve_ik_batch(m, target, scheduler="x")),
    ]:
        with monkeypatch.context() as patch:
            patch.setitem(sys.modules, blocked, None)
            with pytest.raises(optik.MissingExtraError, match=rf'pip install "optik\[{extra}\]"') as info:
                call()
        assert "\n" not in str(info.value)
        assert isinstance(info.value, ImportError)  # `except ImportError` still catches it


def test_to_dataframe_names_its_columns_after_the_coordinates():
    pd = pytest.importorskip("pandas", reason="needs the pandas extra (pip install 'optik[pandas]')")
    m = optik.catalog.planar_3r()
    targets = [optik.Pose2D(1.2, 0.8, 0.5), optik.Pose2D(0.9, -0.4, 0.1)]
    batch = optik.solve_ik_batch(m, targets, method="closed_form")
    frame = batch.to_dataframe()
    assert isinstance(frame, pd.DataFrame)
    assert list(frame.columns[: m.n_q]) == list(m.coordinate_names)
    assert "q0" not in frame.columns
    np.testing.assert_array_equal(frame[list(m.coordinate_names)].to_numpy(), batch.q)


# ---------------------------------------------------------------------------- scheduler=
def test_a_bad_scheduler_is_an_optik_error_naming_it():
    pytest.importorskip("distributed", reason="needs the dist extra (pip install 'optik[dist]')")
    m = optik.catalog.planar_2r()
    for bad in ("not-a-client", 42):
        with pytest.raises(optik.InvalidArgumentError, match=r"^scheduler: ") as info:
            optik.solve_ik_batch(m, [optik.Position([1.0, 0.5, 0.0])], scheduler=bad)
        assert info.value.argument == "scheduler"


# ---------------------------------------------------------------------------- no such file
@pytest.mark.parametrize("command", ["view", "reach"])
def test_a_missing_urdf_is_no_such_file(command, capsys, tmp_path):
    missing = tmp_path / "nonexistent.urdf"
    code, _, err = _run([command, str(missing)], capsys)
    assert code == 2
    assert _one_line(err) == f"optik {command}: error: PROBLEM|ROBOT|URDF: no such file: {missing}"


def test_an_unknown_source_lists_problems_and_robots(capsys):
    code, _, err = _run(["reach", "no_such_thing"], capsys)
    line = _one_line(err)
    assert code == 2 and "unknown problem 'no_such_thing'" in line
    assert "'five_bar'" in line and "'ur5'" in line


# ---------------------------------------------------------------------------- wrapped angles
def test_fk_says_which_actuated_angles_it_wrapped(capsys):
    code, out, _ = _run(["fk", "five_bar", "--q", "9", "0.5"], capsys)
    wrapped = 9 - 2 * np.pi
    note = f"note: theta1=9 is outside its limits [-3.14159, 3.14159]: taken modulo 2 pi as {wrapped:.6f}"
    assert note in out
    assert "theta2" not in out.split("five_bar:")[0]  # 0.5 is within its limits: no note
    code, out, _ = _run(["fk", "five_bar", "--q", "0.5", "2.0"], capsys)
    assert code == 0 and "note:" not in out


# ---------------------------------------------------------------------------- no empty folders
@pytest.mark.parametrize(
    "argv",
    [
        ["bench", "nosuch"],
        ["bench", "planar_2r", "--solvers", "warp"],
        ["plot", "planar_2r", "--mode", "assembly"],
        ["plot", "nosuch"],
        ["solve", "nosuch", "--target", "1", "2", "--plot", "figs/sol.png"],
        ["reach", "/nonexistent.urdf"],
    ],
)
def test_a_failed_command_leaves_no_folder(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = _run(argv, capsys)
    assert code == 2, err
    assert list(tmp_path.iterdir()) == []


def test_the_output_folder_appears_with_its_first_file(capsys, tmp_path):
    out = tmp_path / "new" / "plots"
    code, _, _ = _run(["plot", "planar_2r", "--mode", "config", "--out", str(out)], capsys)
    assert code == 0
    assert [p.name for p in out.iterdir()] == ["planar_2r_config.png"]
