"""A normal (non-editable) wheel install runs the main job and the CLI from any folder: the
problem files, the URDFs, the C drivers and the benchmark scripts are package data found through
importlib.resources.

The wheel is built from a copy of the source tree (``pip wheel --no-deps``) and installed with its
declared dependencies into an isolated venv (no system site-packages: what the wheel does not
declare is not there); every command runs in an empty temporary folder without PYTHONPATH, with
an empty compile cache, and must not warn that a package file cannot be read.
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

SOURCES = ("pyproject.toml", "setup.py", "README.md")
"""Files of the source tree that the build reads, beside the package folders `PACKAGES`."""

PACKAGES = ("optik", "problems", "benchmarks")
"""Source folders of the wheel (setup.py maps the last two into the package)."""


def _run(cmd: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"{cmd}\nstdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    return proc


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """An isolated venv with the optik wheel and its declared dependencies, and an environment
    without PYTHONPATH."""
    base = tmp_path_factory.mktemp("wheel")
    src = base / "src"
    src.mkdir()
    for name in SOURCES:
        shutil.copy2(ROOT / name, src / name)
    junk = shutil.ignore_patterns("__pycache__", "*.pyc", "*.so", "*.egg-info", "build")
    for name in PACKAGES:
        shutil.copytree(ROOT / name, src / name, ignore=junk)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["OPTIK_CACHE_DIR"] = str(base / "cache")
    env["MPLBACKEND"] = "Agg"
    wheels = base / "wheels"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", str(src), "-w", str(wheels)], base, env)
    (wheel,) = wheels.glob("optik-*.whl")
    venv_dir = base / "venv"
    # the interpreter behind any venv pytest may run in, so that the new venv is isolated from both
    base_python = getattr(sys, "_base_executable", sys.executable)
    _run([base_python, "-m", "venv", str(venv_dir)], base, env)
    python = venv_dir / "bin" / "python"
    _run([str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check", str(wheel)], base, env)
    return venv_dir, env


def test_wheel_carries_every_package_file(venv):
    """Every C driver, problem file and benchmark script of the source tree is in the install."""
    venv_dir, _ = venv
    (site,) = (venv_dir / "lib").glob("python*/site-packages")
    installed = {p.relative_to(site).as_posix() for p in (site / "optik").rglob("*") if p.is_file()}
    wanted = {f"optik/{p.relative_to(ROOT / 'optik').as_posix()}" for p in (ROOT / "optik").rglob("*.c")}
    wanted |= {f"optik/problems/{p.name}" for p in (ROOT / "problems").glob("*.toml")}
    wanted |= {f"optik/benchmarks/{p.name}" for p in (ROOT / "benchmarks").glob("*.py")}
    assert len(wanted) > 20 and wanted <= installed, sorted(wanted - installed)


def test_wheel_install_is_isolated_and_imported_from_the_venv(venv, tmp_path):
    venv_dir, env = venv
    code = (
        "import importlib.util as u, optik, optik.problem_files as pf; print(optik.__file__); "
        "print(pf.PROBLEM_DIR); print([m for m in ('pytest', 'pinocchio') if u.find_spec(m)])"
    )
    out = _run([str(venv_dir / "bin" / "python"), "-c", code], tmp_path, env).stdout.split()
    site = (venv_dir / "lib").resolve()
    assert Path(out[0]).resolve().is_relative_to(site), out
    assert Path(out[1]).resolve().is_relative_to(site) and Path(out[1]).name == "problems", out
    assert out[2] == "[]", f"the venv sees packages the wheel does not declare: {out[2]}"


def _quiet(proc: subprocess.CompletedProcess[str]) -> str:
    """The output of a command that read every package file it needed (no fallback warning)."""
    assert "cannot be read" not in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    return proc.stdout


def test_wheel_runs_the_main_job_and_the_cli(venv, tmp_path):
    venv_dir, env = venv
    optik = str(venv_dir / "bin" / "optik")
    out = _quiet(_run([optik, "bench", "--quick", "--out", "out", "--no-progress"], tmp_path, env))
    data = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    assert len(data["problems"]) == 12 and "panda" in out and "stewart_gough" in out
    assert all(
        Path(p["problem"]["file"]).resolve().is_relative_to(venv_dir.resolve()) for p in data["problems"]
    )
    solve = _quiet(_run([optik, "solve", "planar_3r", "--target", "1.2", "0.9", "0.5"], tmp_path, env))
    assert "success=True" in solve
    fk = _quiet(_run([optik, "fk", "panda", "--q", "0", "0", "0", "-1", "0", "1", "0"], tmp_path, env))
    assert "z=+0.818897" in fk
    script = [optik, "benchmark", "parallel_fk", "--n-rpr", "2", "--n-sg", "1", "--heavy", "1", "--n-fk", "2"]
    table = _quiet(_run(script, tmp_path, env))
    assert "planar_3rpr" in table and "stewart_gough" in table
    ik = _quiet(_run([optik, "benchmark", "ik", "--n", "50", "--n-nlp", "5"], tmp_path, env))
    assert "lm" in ik
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # nothing else written to the folder
