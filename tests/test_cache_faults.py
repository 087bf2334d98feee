"""A damaged compile cache (issue 18, item 8): a truncated, a zeroed and a foreign cached
library are each detected before loading (size and SHA-256 recorded at build time), removed and
rebuilt with a logged warning, and the same process answers correctly. Loading a damaged
library can end a process with SIGBUS, so the loads run in subprocesses; the cache is bounded
by pruning the least recently used libraries."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from optik import native

pytestmark = pytest.mark.skipif(native.compiler() is None, reason="needs a C compiler")

SOLVE = """
import logging, sys, numpy as np, optik
from optik import native
logging.basicConfig(level=logging.WARNING, stream=sys.stdout, format="LOG %(name)s %(message)s")
for length in [float(a) for a in sys.argv[1:]]:
    m = optik.catalog.planar_2r(lengths=(length, 0.5))
    q = np.array([0.3, 0.6])
    before = set(native._BUILDS)
    r = optik.solve_ik(m, m.fk(q), method="lm", compile=True, seed=1)
    new = [p for p in native._BUILDS if p not in before]
    err = np.abs(m.fk(r.q) - m.fk(q)).max()
    states = ",".join(native._BUILDS[p].state for p in new)
    print("RESULT", length, r.success, states, f"{err:.1e}", *[p.name for p in new])
"""


def _solve(cache: Path, *lengths: float) -> tuple[dict[float, list[str]], list[str]]:
    """Solve on planar 2R arms of these first link lengths in a new process: per length the
    result fields, and the log lines."""
    env = {**os.environ, "OPTIK_CACHE_DIR": str(cache)}
    out = subprocess.run(
        [sys.executable, "-c", SOLVE, *map(str, lengths)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, f"the process died ({out.returncode}): {out.stderr[-2000:]}"
    lines = out.stdout.splitlines()
    results = {float(w[1]): w[2:] for w in (line.split() for line in lines if line.startswith("RESULT"))}
    return results, [line for line in lines if line.startswith("LOG")]


def test_truncated_zeroed_and_foreign_libraries_are_rebuilt_with_a_warning(tmp_path):
    lengths = (0.7, 0.8, 0.9, 1.1)
    built, logs = _solve(tmp_path, *lengths)
    assert not logs
    files = {length: tmp_path / fields[3] for length, fields in built.items()}
    for length in lengths:
        assert built[length][:2] == ["True", "ready"]
        assert files[length].exists() and Path(f"{files[length]}.json").exists()
    truncated, zeroed, foreign, donor = (files[length] for length in lengths)
    os.truncate(truncated, 1000)  # `truncate -s 1000`: the SIGBUS of issue 18
    zeroed.write_bytes(bytes(zeroed.stat().st_size))
    foreign.write_bytes(donor.read_bytes())  # another arm's library: loads, answers for the wrong arm
    again, logs = _solve(tmp_path, *lengths[:3])
    for length in lengths[:3]:
        ok, state, err, name = again[length]
        assert (ok, state, name) == ("True", "ready", files[length].name)  # rebuilt in place, compiled
        assert float(err) < 1e-6  # the answer checked by FK in that same process
    assert len(logs) == 3, logs
    for path, why in ((truncated, "size"), (zeroed, "SHA-256"), (foreign, "SHA-256")):
        assert any(path.name in line and "damaged" in line and why in line for line in logs), logs
    assert truncated.stat().st_size == donor.stat().st_size  # whole again
    _, logs = _solve(tmp_path, *lengths[:3])
    assert not logs  # rebuilt once: the next process loads them


def test_a_library_without_its_manifest_is_rebuilt(tmp_path):
    built, _ = _solve(tmp_path, 0.6)
    Path(f"{tmp_path / built[0.6][3]}.json").unlink()
    again, logs = _solve(tmp_path, 0.6)
    assert again[0.6][:2] == ["True", "ready"]
    assert len(logs) == 1 and "no readable manifest" in logs[0]


def test_the_cache_is_pruned_least_recently_used_first(tmp_path):
    files = []
    for i in range(4):
        f = tmp_path / f"optik_x_{i}.so"
        f.write_bytes(bytes(1000))
        Path(f"{f}.json").write_text("{}")
        os.utime(f, (time.time() - 100 + i, time.time() - 100 + i))  # 0 oldest, 3 newest
        files.append(f)
    os.utime(files[0])  # 0 used just now
    removed = native.prune_cache(tmp_path, 3000, keep=files[1])
    assert removed == [files[2]]  # the oldest but the kept one, until 3 x 1000 bytes ...
    removed = native.prune_cache(tmp_path, 2000)
    assert removed == [files[1]]
    assert sorted(p.name for p in tmp_path.glob("*.so")) == ["optik_x_0.so", "optik_x_3.so"]
    assert not Path(f"{files[2]}.json").exists()
