"""The generic lm kernels compiled at install (setup.py, optik.solvers.generic_chain.PREBUILT):
a fresh process on an empty cache answers its first solve within 5 ms through them (the answer
checked by FK and limits here), and a damaged, unrecorded or stale shipped library is never loaded:
it is logged and the kernel is built in the cache instead."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import optik
from optik import native, spatial
from optik.catalog.arms import urdf_path
from optik.solvers import generic_chain

needs_cc = pytest.mark.skipif(native.compiler() is None, reason="needs a C compiler")
N = 7
_FIRST = """
import json, sys
import numpy as np
import optik
from optik.solvers import generic_chain
m = optik.Mechanism.from_urdf(sys.argv[1], "panda_link0", "panda_link8")
r = optik.solve_ik(m, np.asarray(json.loads(sys.argv[2])), time_limit=0.005)
k = generic_chain.chain_kernel(m.n_q)
out = {"q": r.q.tolist(), "success": r.success, "message": r.message, "time": r.solve_time}
print(json.dumps({**out, "shipped": k.library.shipped, "calls": k.calls}))
"""


def _shipped(n: int) -> Path:
    """The installed kernel of ``n`` joints, or skip (fail: none at all though a compiler exists)."""
    path = native.prebuilt_path(generic_chain.PREBUILT_DIR, generic_chain.prebuilt_name(n))
    assert path.exists(), f"{path} was not built at install (pip install -e . builds it)"
    key = generic_chain.prebuilt_key(n)
    lib = native.prebuilt_library(generic_chain.PREBUILT_DIR, generic_chain.prebuilt_name(n), key)
    if lib is None:
        pytest.skip(f"{path.name} is stale: its sources changed since the install (re-run pip install -e .)")
    return path


@needs_cc
def test_a_fresh_process_on_an_empty_cache_solves_at_5_ms(tmp_path) -> None:
    _shipped(N)
    m = optik.Mechanism.from_urdf(urdf_path("panda"), "panda_link0", "panda_link8")
    env = {**os.environ, "OPTIK_CACHE_DIR": str(tmp_path / "cache")}
    for q_true in m.random_q(2, seed=21):
        target = m.fk(q_true)
        out = subprocess.run(
            [sys.executable, "-c", _FIRST, str(urdf_path("panda")), json.dumps(target.tolist())],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
            check=True,
        )
        answer = json.loads(out.stdout.strip().splitlines()[-1])
        assert answer["shipped"] and answer["calls"] == 1, answer  # the package's kernel answered
        q = np.asarray(answer["q"])
        assert answer["success"], answer
        reached = m.fk(q)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) <= 1e-6
        assert spatial.angle_between(reached[:3, :3], target[:3, :3]) <= 1e-6
        assert np.all(q >= m.lower) and np.all(q <= m.upper)
        shutil.rmtree(tmp_path / "cache", ignore_errors=True)  # empty again for the next process


def _copy(tmp_path: Path, n: int) -> tuple[Path, str]:
    """A copy of the shipped kernel of ``n`` joints and its manifest in ``tmp_path``."""
    path = _shipped(n)
    tmp_path.mkdir(parents=True, exist_ok=True)
    shutil.copy(path, tmp_path / path.name)
    shutil.copy(path.with_name(path.name + ".json"), tmp_path / (path.name + ".json"))
    return tmp_path / path.name, generic_chain.prebuilt_name(n)


@needs_cc
def test_a_sound_copy_loads_and_a_damaged_unrecorded_or_stale_one_does_not(tmp_path, caplog) -> None:
    key = generic_chain.prebuilt_key(6)
    sound, name = _copy(tmp_path / "sound", 6)  # each case its own file: a loaded one is never rewritten
    lib = native.prebuilt_library(sound.parent, name, key)
    assert lib is not None and lib.shipped and lib.state == "ready" and lib.files() == []
    with caplog.at_level("INFO", logger="optik.native"):
        assert native.prebuilt_library(sound.parent, name, "0" * len(key)) is None  # other sources
    assert "made from other sources" in caplog.text
    caplog.clear()
    truncated, _ = _copy(tmp_path / "truncated", 6)
    truncated.write_bytes(truncated.read_bytes()[:100_000])  # loading it could end the process
    with caplog.at_level("WARNING", logger="optik.native"):
        assert native.prebuilt_library(truncated.parent, name, key) is None
    assert "damaged" in caplog.text and "size" in caplog.text
    caplog.clear()
    unrecorded, _ = _copy(tmp_path / "unrecorded", 6)
    unrecorded.with_name(unrecorded.name + ".json").unlink()
    with caplog.at_level("WARNING", logger="optik.native"):
        assert native.prebuilt_library(unrecorded.parent, name, key) is None
    assert "no readable manifest" in caplog.text
    assert native.prebuilt_library(tmp_path / "none", name, key) is None  # not built: no warning


@needs_cc
def test_a_damaged_shipped_kernel_is_rebuilt_in_the_cache_logged(tmp_path, monkeypatch, caplog) -> None:
    path, _ = _copy(tmp_path, 6)
    path.write_bytes(bytes(path.stat().st_size))  # zeroed, same size: the hash tells
    monkeypatch.setattr(generic_chain, "PREBUILT_DIR", tmp_path)
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path / "cache"))
    with caplog.at_level("WARNING", logger="optik.native"):
        k = generic_chain.ChainKernel(6)
    assert "damaged" in caplog.text and "SHA-256" in caplog.text
    assert k.library is not None and not k.library.shipped
    assert k.library.wait(600) is not None and k.ready
    assert k.library.path.parent == tmp_path / "cache"
