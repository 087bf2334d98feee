"""The first hour of a new user (issue 20): every error a newcomer meets is one line that says
what to do, and a failed command leaves nothing behind."""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import optik
from optik import benchmarks
from optik.cli import build_parser, main
from optik.problem_files import PROBLEM_DIR


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


# ---------------------------------------------------------------------------- the CLI
def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_subcommand_option_says_its_default_and_choices():
    commands = _subcommands()
    assert {"bench", "solve", "fk", "plot", "benchmark", "view", "reach"} <= set(commands)
    for name, parser in commands.items():
        for action in parser._actions:
            if not action.option_strings or action.help == argparse.SUPPRESS or action.dest == "help":
                continue
            where = f"optik {name} {action.option_strings[0]}"
            assert action.help and action.help.strip(), f"{where} has no help text"
            if action.default not in (None, False, argparse.SUPPRESS):
                assert "default" in action.help, f"{where}: its default {action.default!r} is not shown"
            if action.choices:
                assert action.metavar is None, f"{where} hides its choices"


@pytest.mark.parametrize("command", sorted(_subcommands()))
def test_every_subcommand_has_help(command, capsys):
    code, out, _ = _run([command, "--help"], capsys)
    assert code == 0 and out.startswith(f"usage: optik {command}")


def test_the_top_level_help_lists_every_benchmark(capsys):
    code, out, _ = _run(["--help"], capsys)
    assert code == 0 and "--problems-dir" in out
    for name in benchmarks.available():
        assert name in out


def test_optik_benchmark_lists_the_benchmarks_with_their_descriptions(capsys):
    summaries = benchmarks.summaries()
    assert len(summaries) >= 12 and all(summaries.values())
    code, out, _ = _run(["benchmark"], capsys)
    assert code == 0 and out.startswith(f"{len(summaries)} benchmarks; run one with: optik benchmark NAME")
    code, helped, _ = _run(["benchmark", "--help"], capsys)
    assert code == 0
    for name, text in summaries.items():
        first_words = " ".join(text.split()[:4])
        assert re.search(rf"^  {name} +{re.escape(first_words)}", out, re.MULTILINE), name
        assert re.search(rf"^  {name} +{re.escape(first_words)}", helped, re.MULTILINE), name


HELP_OF_EVERY_BENCHMARK = """
import contextlib, io, json, sys
from optik import benchmarks
from optik.cli import main
out = {}
for name in benchmarks.available():
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        try:
            main(["benchmark", name, "--help"])
        except SystemExit as exc:
            assert exc.code == 0, name
    out[name] = buf.getvalue()
print(json.dumps(out))
"""


def test_each_benchmark_help_is_its_own_with_defaults():
    # in a child process: importing the scripts sets process-wide state (thread counts, caches)
    proc = subprocess.run(
        [sys.executable, "-c", HELP_OF_EVERY_BENCHMARK], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    helps = json.loads(proc.stdout)
    summaries = benchmarks.summaries()
    assert set(helps) == set(summaries)
    for name, out in helps.items():
        assert out.startswith(f"usage: optik benchmark {name} ")
        assert summaries[name][:30] in " ".join(out.split())
        assert re.findall(r"^  (--[a-z0-9-]+)", out, re.MULTILINE), out
        for line in re.split(r"\n(?=  -)", out.split("options:")[1])[1:]:
            assert len(line.split()) > 1, f"optik benchmark {name}: an option without help: {line!r}"


def test_problems_dir_before_or_after_the_subcommand(capsys, tmp_path):
    (tmp_path / "mine.toml").write_text((PROBLEM_DIR / "planar_2r.toml").read_text())
    for argv in (
        ["--problems-dir", str(tmp_path), "solve", "mine", "--target", "1.2", "0.6"],
        ["solve", "mine", "--problems-dir", str(tmp_path), "--target", "1.2", "0.6"],
    ):
        code, out, err = _run(argv, capsys)
        assert code == 0, err
        assert out.startswith("mine: IK of x=+1.200000")
    code, _, err = _run(["solve", "mine", "--target", "1.2", "0.6"], capsys)
    assert code == 2 and "unknown problem 'mine'" in err


def test_bench_reports_its_whole_time(capsys, tmp_path):
    code, out, _ = _run(
        [
            "bench",
            "planar_2r",
            "--quick",
            "--solvers",
            "closed_form",
            "--n",
            "5",
            "--no-progress",
            "--out",
            str(tmp_path),
        ],
        capsys,
    )
    last = out.strip().splitlines()[-1]
    assert code == 0
    found = re.match(
        r"1 problems: solved in ([\d.]+) s, tables and charts written in ([\d.]+) s; ([\d.]+) s since the "
        r"command started \(imports and start-up included\); wrote ",
        last,
    )
    assert found, last
    solved, written, whole = map(float, found.groups())
    assert whole >= solved + written  # the process ran at least that long


def test_process_seconds_is_the_age_of_the_process():
    from optik.harness.run import process_seconds

    code = "import time\nfrom optik.harness.run import process_seconds as age\ntime.sleep(0.5)\nprint(age())"
    started = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    took = time.perf_counter() - started
    assert 0.5 <= float(out) <= took + 0.02  # clock ticks are 10 ms
    assert process_seconds() > 0


# ---------------------------------------------------------------------------- figures and docs
ROOT = Path(__file__).resolve().parent.parent


def test_every_install_line_of_the_docs_is_the_readmes_or_one_extra():
    readme = [line for line in (ROOT / "README.md").read_text().splitlines() if "pip install -e" in line]
    assert len(readme) == 2
    for page in (ROOT / "docs").rglob("*.md"):
        for line in page.read_text().splitlines():
            if "pip install -e" not in line:
                continue
            extras = re.search(r'-e "\.\[([a-zA-Z,]+)\]"', line)
            assert extras, f"{page.name}: {line}"
            if "," in extras.group(1):
                assert line.strip() in readme, f"{page.name}: {line!r} is not one of the README's"


def test_no_restructuredtext_literal_blocks_or_tables_in_docstrings():
    import ast

    for path in (ROOT / "optik").rglob("*.py"):
        tree = ast.parse(path.read_text())
        nodes = [tree, *(n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.ClassDef)))]
        for node in nodes:
            doc = ast.get_docstring(node) or ""
            for line in doc.splitlines():
                assert not line.rstrip().endswith("::"), f"{path.name}: reST literal block: {line!r}"
                assert not re.fullmatch(r"\s*=+( +=+)+\s*", line), f"{path.name}: reST table"


def test_the_workspace_figure_has_a_legend_and_a_title_within_the_figure():
    from optik.plot import workspace

    fig = workspace(optik.catalog.five_bar(), n=200)
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["assembly mode 1", "assembly mode 2"]
    fig.canvas.draw()
    box, title = fig.bbox, ax.title.get_window_extent()
    assert box.x0 <= title.x0 and title.x1 <= box.x1 and title.y1 <= box.y1


def test_a_closed_chain_is_shown_in_a_configuration_that_shows_its_shape():
    from optik.plot import geometry, showcase_q

    m = optik.catalog.five_bar()
    q = showcase_q(m)
    assert np.abs(m.closure(q)).max() < 1e-9 and (q >= m.lower).all() and (q <= m.upper).all()
    joints = geometry(m, q).parent_side
    gaps = np.linalg.norm(joints[:, None] - joints[None, :], axis=-1)[np.triu_indices(len(joints), 1)]
    assert gaps.min() > 0.2  # at theta = (0, 0) the first arm lies on the base: a gap of 0
    np.testing.assert_array_equal(showcase_q(optik.catalog.planar_3r()), optik.catalog.planar_3r().mid_q())


def test_many_branches_draw_a_readable_grid_of_the_nearest():
    from optik.plot import MAX_PANELS, draw_branches

    m = optik.catalog.planar_3r()
    qs = [m.mid_q() + 0.05 * k for k in range(20)]
    fig = draw_branches(m, qs, near=qs[11] + 0.01)
    assert len(fig.axes) == MAX_PANELS
    shown = sorted(int(ax.get_title().split()[-1]) - 1 for ax in fig.axes)
    assert shown == list(range(8, 16))  # the eight nearest a point just past branch 12
    assert "8 of 20 drawn, the nearest to the reference q; 12 more not drawn" in fig._suptitle.get_text()
    width, height = fig.get_size_inches() * 110
    assert width <= 1600 and height <= 900


def test_bench_chart_contenders_on_the_same_spot_stay_visible():
    from optik.harness.contenders import Call, ProblemRun, SolverRun
    from optik.harness.report import _chart, coinciding
    from optik.problem_files import find_problem

    assert coinciding([(0.0, 100.0), (0.01, 100.0), (1.0, 50.0)]) == [(0, 2), (1, 2), (0, 1)]
    call = Call(1e-3, True, 1e-12, 1e-12, 0.0, True, float("nan"), 0.0, "solved")
    runs = [SolverRun(name, "method", [call] * 5) for name in ("closed_form", "lm", "nlp")]
    fig = _chart(ProblemRun(find_problem("doggy"), None, runs, [], 1.0, 0.05))
    ax = fig.axes[0]
    sizes = [line.get_markersize() for line in ax.lines if line.get_marker() in ("o", "s")]
    assert sorted(sizes, reverse=True) == [18, 12, 6]  # concentric: none hides another
    assert sorted(t.get_text() for t in ax.texts) == ["closed_form", "lm", "nlp"]


# ---------------------------------------------------------------------------- the viewer
def test_view_and_reach_accept_catalog_robot_names(capsys):
    from optik.problem_files import load_source

    try:
        m, problem = load_source("ur5", None, None)
    except optik.MissingExtraError as exc:
        assert 'pip install "optik[robots]"' in str(exc)
        pytest.skip(str(exc))
    assert problem is None and m.name == "ur5" and m.n_q == 6
    m, problem = load_source("panda", None, None)  # a problem name wins over the robot of that name
    assert problem is not None and problem.name == "panda"
    code, out, _ = _run(["view", "--help"], capsys)
    assert code == 0 and "ur5" in out and "PROBLEM|ROBOT|URDF" in out


def test_the_viewer_opens_a_closed_chain_showing_its_shape():
    pytest.importorskip("viser", reason="needs the view extra (pip install 'optik[view]')")
    from optik.plot import geometry

    m = optik.catalog.five_bar()
    with optik.view(m, port=0) as v:
        q = v.q
    assert np.abs(m.closure(q)).max() < 1e-9
    joints = geometry(m, q).parent_side
    gaps = np.linalg.norm(joints[:, None] - joints[None, :], axis=-1)[np.triu_indices(len(joints), 1)]
    assert gaps.min() > 0.2  # not theta = (0, 0), where the first arm lies on the base


def test_the_three_path_builders_share_one_signature():
    import inspect

    from optik import diffik

    builders = (diffik.line_path, diffik.circle_path, diffik.polyline_path)
    for build in builders:
        names = list(inspect.signature(build).parameters)
        assert names[names.index("speed") :][:3] == ["speed", "dt", "rotation"], build.__name__
    tool = optik.spatial.rot_x(np.pi)
    paths = [
        diffik.line_path([0.3, 0.0, 0.5], [0.5, 0.0, 0.5], 0.25, 0.01, tool),
        diffik.circle_path([0.4, 0.0, 0.5], 0.1, 0.25, 0.01, tool),
        diffik.polyline_path([[0.3, 0.0, 0.5], [0.4, 0.0, 0.5], [0.4, 0.1, 0.5]], 0.25, 0.01, tool),
    ]
    for path in paths:
        steps = np.linalg.norm(np.diff(path[:, :3, 3], axis=0), axis=1)
        assert np.allclose(steps[:-1], 0.0025, rtol=1e-3) and 0 < steps[-1] <= 0.0025 + 1e-12
        np.testing.assert_allclose(path[:, :3, :3], np.broadcast_to(tool, (len(path), 3, 3)), atol=1e-12)
    assert len(paths[0]) == 81  # 0.2 m in steps of 2.5 mm, both ends
    turned = diffik.line_path(
        np.eye(4), optik.spatial.transform(optik.spatial.rot_z(0.4), [0.1, 0, 0]), 1.0, 0.01
    )
    assert len(turned) == 11 and np.isclose(optik.spatial.rotation_angle(turned[5, :3, :3]), 0.2)
