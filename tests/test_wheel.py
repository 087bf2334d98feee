"""A normal (non-editable) wheel install runs the CLI from any folder: the problem files, the
URDFs and the benchmark scripts are package data found through importlib.resources.

The wheel is built from a copy of the source tree with ``pip wheel --no-deps`` and installed
into a fresh venv that sees the system's site-packages (for casadi, numpy, ... so the test
stays fast); ``optik`` must then be imported from the venv, not from the source tree or the
editable install, and every command runs in an empty temporary folder without PYTHONPATH.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.slow


def _run(cmd: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"{cmd}\nstdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    return proc


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """A venv with the optik wheel installed, and an environment without PYTHONPATH."""
    base = tmp_path_factory.mktemp("wheel")
    src = base / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    junk = shutil.ignore_patterns("__pycache__", "*.pyc", "*.so", "*.egg-info", "build")
    shutil.copytree(ROOT / "optik", src / "optik", ignore=junk)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env["OPTIK_CACHE_DIR"] = str(base / "cache")
    wheels = base / "wheels"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", str(src), "-w", str(wheels)], base, env)
    (wheel,) = wheels.glob("optik-*.whl")
    venv_dir = base / "venv"
    _run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", str(venv_dir)], base, env)
    python = venv_dir / "bin" / "python"
    _run(
        [
            sys.executable,
            "-m",
            "pip",
            "--python",
            str(python),
            "install",
            "--no-deps",
            "--no-index",
            "-q",
            str(wheel),
        ],
        base,
        env,
    )
    return venv_dir, env


def test_wheel_install_is_imported_from_the_venv(venv, tmp_path):
    venv_dir, env = venv
    code = "import optik, optik.problem_files as pf; print(optik.__file__); print(pf.PROBLEM_DIR)"
    out = _run([str(venv_dir / "bin" / "python"), "-c", code], tmp_path, env).stdout.split()
    site = (venv_dir / "lib").resolve()
    assert Path(out[0]).resolve().is_relative_to(site), out
    assert Path(out[1]).resolve().is_relative_to(site) and Path(out[1]).name == "problems", out


def test_wheel_cli_bench_solve_and_benchmark(venv, tmp_path):
    venv_dir, env = venv
    optik = str(venv_dir / "bin" / "optik")
    bench = [optik, "bench", "--quick", "planar_3r", "panda", "--n", "3", "--solvers", "lm", "closed_form"]
    out = _run([*bench, "--out", "out", "--no-progress"], tmp_path, env).stdout
    assert "planar_3r" in out and "panda" in out
    data = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    assert [p["problem"]["name"] for p in data["problems"]] == ["planar_3r", "panda"]
    assert all(
        Path(p["problem"]["file"]).resolve().is_relative_to(venv_dir.resolve()) for p in data["problems"]
    )
    solve = _run([optik, "solve", "planar_3r", "--target", "1.2", "0.9", "0.5"], tmp_path, env).stdout
    assert "success=True" in solve
    fk = _run([optik, "fk", "panda", "--q", "0", "0", "0", "-1", "0", "1", "0"], tmp_path, env).stdout
    assert "z=+0.818897" in fk
    script = [optik, "benchmark", "parallel_fk", "--n-rpr", "2", "--n-sg", "1", "--heavy", "1", "--n-fk", "2"]
    table = _run(script, tmp_path, env).stdout
    assert "planar_3rpr" in table and "stewart_gough" in table
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # nothing else written to the folder
