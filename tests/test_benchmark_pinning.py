"""``optik benchmark NAME`` pins BLAS and OpenMP to one thread, as ``optik benchmark all`` does: the
script runs in a child process started with `optik.benchmarks.PINNED` in its environment (a
library reads the variables when it loads, and ``import optik`` has loaded numpy's OpenBLAS)."""

from __future__ import annotations

import ctypes
import sys
from pathlib import Path

import pytest

from optik import benchmarks
from optik.errors import InvalidArgumentError

BLAS_THREADS = """
import ctypes, numpy
libs = sorted({p for p in open("/proc/self/maps").read().split() if "openblas" in p and ".so" in p})
names = ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads")
counts = [getattr(ctypes.CDLL(lib), s)() for lib in libs for s in names if hasattr(ctypes.CDLL(lib), s)]
print("blas threads", counts)
"""


def _openblas_readable() -> bool:
    try:
        maps = Path("/proc/self/maps").read_text().split()
    except OSError:
        return False
    libs = {p for p in maps if "openblas" in p and ".so" in p}
    names = ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads")
    return any(hasattr(ctypes.CDLL(lib), s) for lib in libs for s in names)


def test_the_pinned_environment_sets_every_pool_to_one_thread():
    env = benchmarks.pinned_environment({"OMP_NUM_THREADS": "8", "HOME": "/h"})
    assert env["HOME"] == "/h" and all(env[k] == "1" for k in benchmarks.PINNED)
    assert benchmarks.is_pinned(env) and not benchmarks.is_pinned({"OMP_NUM_THREADS": "1"})
    cmd = benchmarks.command("ik", ["--n", "5"])
    assert cmd == [sys.executable, "-m", "optik.benchmarks.bench_ik", "--n", "5"]
    with pytest.raises(InvalidArgumentError, match="name"):
        benchmarks.command("no_such_benchmark")


def test_a_direct_run_is_a_child_process_whose_exit_code_is_returned(monkeypatch, capfd):
    for k in benchmarks.PINNED:
        monkeypatch.delenv(k, raising=False)
    assert benchmarks.run("time_limits", ["--calls", "not-a-number"]) == 2  # argparse, in the child
    assert "invalid int value" in capfd.readouterr().err


@pytest.mark.skipif(
    not _openblas_readable(), reason="numpy's BLAS is not an OpenBLAS whose threads ctypes reads"
)
def test_the_child_process_runs_openblas_on_one_thread(monkeypatch, capsys):
    for k in benchmarks.PINNED:
        monkeypatch.delenv(k, raising=False)
    # the benchmark replaced by a program that prints the thread count of the OpenBLAS it loads;
    # the child process, its environment and the output copied to sys.stdout are run()'s own
    monkeypatch.setattr(benchmarks, "command", lambda name, argv=(): [sys.executable, "-c", BLAS_THREADS])
    assert benchmarks.run("ik", []) == 0
    assert capsys.readouterr().out.strip() == "blas threads [1]"
