"""A normal (non-editable) wheel install runs the main job and the CLI from any folder: the
problem files, the URDFs, the C drivers and the benchmark scripts are package data found through
importlib.resources.

The wheel is built from a copy of the source tree (``pip wheel --no-deps``) and installed with its
declared dependencies into an isolated venv (no system site-packages: what the wheel does not
declare is not there); every command runs in an empty temporary folder without PYTHONPATH, with
an empty compile cache, and must not warn that a package file cannot be read.

Installing the dependencies from the registry takes most of a minute, so they are installed once
per set of declared requirements into a cached venv (`DEPS_CACHE`, rebuilt after `DEPS_MAX_AGE`
or when the wheel's ``Requires-Dist`` change): each run hard-links a copy of it, installs the new
wheel there without dependencies and runs ``pip check`` (every declared requirement satisfied).
The copy is as isolated as a fresh venv; ``OPTIK_WHEEL_DEPS_CACHE=0`` installs from the registry
every time.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
import zipfile
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


DEPS_CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "optik-tests" / "wheel-deps"
"""Folder of the cached dependency venvs, one per requirement set."""
DEPS_MAX_AGE = 7 * 86400.0
"""Seconds after which a cached dependency venv is rebuilt from the registry (newer releases)."""


def _requirements(wheel: Path) -> list[str]:
    """The wheel's ``Requires-Dist`` lines without an ``extra`` marker (what a plain install
    pulls), sorted."""
    with zipfile.ZipFile(wheel) as z:
        (meta,) = [n for n in z.namelist() if n.endswith(".dist-info/METADATA")]
        lines = z.read(meta).decode("utf-8").splitlines()
    reqs = [ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("Requires-Dist:")]
    return sorted(r for r in reqs if "extra ==" not in r)


def _new_venv(path: Path, env: dict[str, str]) -> Path:
    """A venv at ``path`` without system site-packages; its python."""
    # the interpreter behind any venv pytest may run in, so that the new venv is isolated from both
    base_python = getattr(sys, "_base_executable", sys.executable)
    _run([base_python, "-m", "venv", str(path)], path.parent, env)
    return path / "bin" / "python"


def _pip_install(python: Path, args: list[str], env: dict[str, str]) -> None:
    quiet = ["-q", "--disable-pip-version-check"]
    _run([str(python), "-m", "pip", "install", *quiet, *args], python.parent, env)


def _deps_venv(reqs: list[str], env: dict[str, str]) -> Path:
    """The cached venv holding exactly ``reqs`` (built under a file lock, moved into place
    when complete)."""
    key = hashlib.sha256("\n".join([sys.version, sys.platform, *reqs]).encode()).hexdigest()[:16]
    DEPS_CACHE.mkdir(parents=True, exist_ok=True)
    done = DEPS_CACHE / key
    with open(DEPS_CACHE / f"{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        stale = done.is_dir() and time.time() - (done / "pyvenv.cfg").stat().st_mtime > DEPS_MAX_AGE
        if stale:
            shutil.rmtree(done)
        if not done.is_dir():
            building = DEPS_CACHE / f"{key}.building"
            shutil.rmtree(building, ignore_errors=True)
            _pip_install(_new_venv(building, env), reqs, env)
            building.rename(done)
    return done


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
    if os.environ.get("OPTIK_WHEEL_DEPS_CACHE", "1") == "0":
        _pip_install(_new_venv(venv_dir, env), [str(wheel)], env)
        return venv_dir, env
    deps = _deps_venv(_requirements(wheel), env)
    try:  # hard links: instant, and what the copy adds or rewrites stays in the copy
        _run(["cp", "-al", str(deps), str(venv_dir)], base, env)
    except AssertionError:  # another file system
        shutil.rmtree(venv_dir, ignore_errors=True)
        shutil.copytree(deps, venv_dir, symlinks=True)
    python = venv_dir / "bin" / "python"
    _pip_install(python, ["--no-deps", str(wheel)], env)
    _run([str(python), "-m", "pip", "check"], base, env)
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
