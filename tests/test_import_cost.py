"""``import optik`` stays light: the heavy optional stacks (plots, viewer, Dask, QP modellers)
load on first use, so a script's first solve is not preceded by a second of imports."""

import subprocess
import sys

import pytest

HEAVY = ("matplotlib", "trimesh", "viser", "dask", "distributed", "scipy.linalg", "cvxpy", "pinocchio")


def test_import_optik_loads_no_heavy_stack():
    code = f"import sys, optik; print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"imported by `import optik`: {out.stdout.strip()}"


def test_the_viewer_function_and_class_are_reachable_lazily():
    pytest.importorskip("viser", reason="the view extra is not installed (pip install 'optik[view]')")
    code = "import optik; from optik.view import Viewer; print(callable(optik.view), Viewer.__name__)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "Viewer"]
