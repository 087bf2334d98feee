"""Tests of the optik command: help everywhere, one-line errors with exit code 2, each subcommand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from optik import spatial
from optik.cli import UsageError, build_parser, main, parse_target

SUBCOMMANDS = ("bench", "solve", "fk", "plot", "benchmark")


@pytest.mark.parametrize("argv", [["--help"], *[[c, "--help"] for c in SUBCOMMANDS]])
def test_help_everywhere(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 0
    assert "usage: optik" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "argument"),
    [
        (["solve", "planar_3r", "--target", "1", "2"], "--target"),
        (["solve", "no_such_problem", "--target", "1", "2"], "PROBLEM"),
        (["solve", "planar_3r", "--target", "1", "2", "0.3", "--method", "warp"], "--method"),
        (["solve", "planar_3r", "--target", "1", "x", "0.3"], "--target"),
        (["solve", "planar_3r", "--target", "1", "0.5", "0.3", "--q0", "0"], "--q0"),
        (["fk", "panda", "--q", "1", "2"], "--q"),
        (["bench", "--n", "0"], "--n"),
        (["bench", "planar_2r", "--solvers", "warp"], "--solvers"),
        (["bench", "--time-limit", "-1"], "--time-limit"),
        (["plot", "planar_2r", "--mode", "assembly"], "--mode"),
        (["plot", "planar_2r", "--mode", "sideways"], "--mode"),
        (["launch"], "COMMAND"),
        (["benchmark", "no_such_benchmark"], "NAME"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(argv, argument, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse-level errors
        code = exc.code
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 or err.splitlines()[0].startswith("usage:"), err
    assert argument in err.splitlines()[-1], err


def test_solve_prints_every_branch(capsys):
    assert main(["solve", "planar_2r", "--target", "1.2", "0.6", "--all"]) == 0
    out = capsys.readouterr().out
    assert out.count("success=True") == 2  # elbow up and elbow down


def test_solve_unreachable_is_exit_1(capsys):
    assert main(["solve", "planar_2r", "--target", "5", "0", "--time-limit", "0.05"]) == 1
    assert "success=False" in capsys.readouterr().out


def test_fk_of_actuated_values_lists_assembly_modes(capsys, tmp_path):
    png = tmp_path / "fk.png"
    assert main(["fk", "five_bar", "--q", "0.5", "2.0", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "assembly mode" in out and png.is_file()


def test_fk_of_full_q_matches_the_model(capsys):
    assert main(["fk", "planar_3r", "--q", "0.1", "0.2", "0.3", "--matrix"]) == 0
    out = capsys.readouterr().out
    x = 1.0 * np.cos(0.1) + 0.8 * np.cos(0.3) + 0.5 * np.cos(0.6)
    assert f"x={x:+.6f}" in out


def test_plot_writes_pngs(tmp_path, capsys):
    assert main(["plot", "planar_3r", "--mode", "all", "--n", "50", "--out", str(tmp_path)]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["planar_3r_branches.png", "planar_3r_config.png", "planar_3r_workspace.png"]


def test_bench_command_writes_outputs(tmp_path, capsys):
    out = tmp_path / "b"
    code = main(
        ["bench", "pp_arm", "--n", "2", "--solvers", "lm,closed_form", "--out", str(out), "--no-progress"]
    )
    assert code == 0
    data = json.loads((out / "results.json").read_text())
    assert data["meta"]["command"].startswith("optik bench pp_arm")
    assert "pp_arm" in capsys.readouterr().out


def test_parse_target_conventions():
    np.testing.assert_allclose(parse_target("pose2d", [1, 2, 0.5]), spatial.planar_pose(1, 2, 0.5))
    t = parse_target("pose", [1, 2, 3, 0.1, 0.2, 0.3])
    np.testing.assert_allclose(t[:3, :3], spatial.rpy_to_rot(0.1, 0.2, 0.3))
    np.testing.assert_allclose(parse_target("pose", list(t.reshape(-1))), t)
    with pytest.raises(UsageError, match="--target"):
        parse_target("position", [1, 2])


def test_parser_lists_the_subcommands():
    text = build_parser().format_help()
    assert all(c in text for c in SUBCOMMANDS)


def test_benchmark_runs_a_script_of_benchmarks_folder(capsys):
    argv = ["benchmark", "parallel_fk", "--n-rpr", "2", "--n-sg", "1", "--heavy", "1", "--n-fk", "2"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    # the tables it prints hold the results: the drawn Stewart-Gough pose among the postures found,
    # every numerical FK case solved, and the optional peer named as skipped
    assert "| 40-path parameter (auto) | 1 | 1/1 | 0 |" in out
    assert "| 128-path total degree | 1 | 1/1 | 0 |" in out
    starts = tuple(f"| {m} | {s}" for m in ("planar_3rpr", "stewart_gough") for s in ("tracking", "cold"))
    rows = [line for line in out.splitlines() if line.startswith(starts)]
    assert len(rows) == 4 and all("| 100.0% |" in line for line in rows), rows
    assert "fkSGP skipped: no checkout given" in out


def test_problems_dir_overrides_the_shipped_problems(tmp_path, capsys):
    mine = tmp_path / "problems"
    mine.mkdir()
    (mine / "mine.toml").write_text(
        '[problem]\ndescription = "a long 2R"\ndefault = true\n[mechanism]\nconstructor = "planar_2r"\n'
        "[mechanism.params]\nlengths = [3.0, 2.0]\n",
        encoding="utf-8",
    )
    assert main(["solve", "mine", "--problems-dir", str(mine), "--target", "4.0", "1.5"]) == 0
    assert "mine: IK of" in capsys.readouterr().out  # reachable with these lengths only
    assert main(["solve", "mine", "--target", "4.0", "1.5"]) == 2  # not a shipped problem
    assert "unknown problem 'mine'" in capsys.readouterr().err
    out = tmp_path / "out"
    argv = ["bench", "--problems-dir", str(mine), "--quick", "--n", "2", "--solvers", "lm", "--out", str(out)]
    assert main([*argv, "--no-progress"]) == 0
    data = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert [p["problem"]["name"] for p in data["problems"]] == ["mine"]
    assert main(["solve", "mine", "--problems-dir", str(tmp_path / "absent"), "--target", "1", "1"]) == 2
    assert "no problem directory" in capsys.readouterr().err
