"""Capability maps: SO(3) samples, the index against geometry, resume, the command line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import optik
from optik.cli import main
from optik.reach import reach, so3_samples

ARM = optik.catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
SMALL = {"resolution": 0.3, "orientations": 4, "samples": 10_000, "chunk_voxels": 30}
EXACT = {**SMALL, "time_limit": 1.0}  # max_restarts ends every search, not the clock: exact reruns


def test_so3_samples_are_rotations_spread_uniformly() -> None:
    r = so3_samples(500)
    np.testing.assert_allclose(
        np.einsum("nki,nkj->nij", r, r), np.broadcast_to(np.eye(3), r.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
    assert np.abs(r.mean(axis=0)).max() < 0.01  # E[R] = 0 under the uniform (Haar) measure
    # no two samples close: the angle between neighbours stays near the mean spacing
    rel = np.einsum("ikj,mkl->imjl", r[:100], r[:100])
    angle = np.arccos(np.clip((np.trace(rel, axis1=2, axis2=3) - 1) / 2, -1, 1))
    np.fill_diagonal(angle, np.inf)
    assert angle.min(axis=1).min() > 0.2


def test_index_follows_the_geometry_of_a_planar_3r() -> None:
    rmap = reach(ARM, **SMALL, max_restarts=100, time_limit=0.5)  # enough starts near the +-pi limits
    assert rmap.complete and rmap.success.shape == (len(rmap.voxels), 4)
    radius = np.linalg.norm(rmap.centers[:, :2], axis=1)
    # wrist p - 0.5 (cos phi, sin phi) within [0.2, 1.8] for every heading: the dexterous annulus
    dexterous = (radius >= 0.75) & (radius <= 1.25)
    assert dexterous.sum() > 5 and (rmap.index[dexterous] == 1.0).all()
    assert (rmap.index[radius > 2.3] == 0).all()  # beyond reach
    assert np.isfinite(rmap.grid()[tuple(rmap.voxels.T)]).all()
    assert rmap.shape[2] == 1 and (rmap.centers[:, 2] == 0).all()


def test_resume_after_a_chunk_limit_equals_one_run(tmp_path: Path) -> None:
    part = reach(ARM, out=tmp_path / "a", max_chunks=2, **EXACT)
    assert not part.complete and not (tmp_path / "a" / "reach.npz").exists()
    assert len(list((tmp_path / "a" / "chunks").glob("chunk_*.npz"))) == 2
    whole = reach(ARM, out=tmp_path / "a", **EXACT)
    one_go = reach(ARM, out=tmp_path / "b", **EXACT)
    assert whole.complete
    np.testing.assert_array_equal(whole.success, one_go.success)
    meta = json.loads((tmp_path / "a" / "meta.json").read_text())
    assert [r["chunks_solved"] for r in meta["runs"]] == [2, meta["settings"]["n_chunks"] - 2]
    assert meta["optik_version"] == optik.__version__ and meta["settings"]["tol"] == 1e-4
    with np.load(tmp_path / "a" / "reach.npz") as data:
        np.testing.assert_array_equal(data["index"], whole.index)
        assert data["grid"].shape == whole.shape
    for name in ("reach_slices.png", "reach_3d.png"):
        assert (tmp_path / "a" / name).stat().st_size > 10_000
    with pytest.raises(optik.InvalidArgumentError, match=r"^out.*resolution"):
        reach(ARM, out=tmp_path / "a", **{**EXACT, "resolution": 0.25})


def test_bad_settings_name_the_argument() -> None:
    with pytest.raises(optik.InvalidArgumentError, match=r"^resolution"):
        reach(ARM, resolution=-1.0)
    with pytest.raises(optik.InvalidArgumentError, match=r"^orientations"):
        reach(ARM, orientations=0)


def test_cli_stops_resumes_and_keeps_chunks_on_ctrl_c(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "map"
    args = ["reach", "planar_3r", "--resolution", "0.25", "--orientations", "16", "--samples", "20000"]
    assert main([*args, "--out", str(out), "--max-chunks", "1", "--no-progress"]) == 1
    assert "run the same command again" in capsys.readouterr().out
    assert main([*args, "--out", str(out), "--no-progress"]) == 0
    assert "planar_3r" in capsys.readouterr().out and (out / "reach.npz").exists()
    # Ctrl-C in the middle: exit code 130, every chunk file on disk is complete
    slow = tmp_path / "slow"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parent.parent)}
    cmd = [sys.executable, "-m", "optik.cli", *args[:2], "--resolution", "0.05", "--orientations", "16"]
    cmd += ["--samples", "20000"]
    proc = subprocess.Popen(
        [*cmd, "--out", str(slow), "--no-progress"], env=env, stdout=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 60
    while not list((slow / "chunks").glob("chunk_*.npz")) and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    stdout, _ = proc.communicate(timeout=60)
    assert proc.returncode == 130, stdout
    chunks = sorted((slow / "chunks").glob("chunk_*.npz"))
    assert chunks and not list((slow / "chunks").glob(".*tmp"))
    for c in chunks:
        with np.load(c) as data:
            assert data["success"].shape[1] == 16


def test_a_saved_map_loads_back(tmp_path):
    m = optik.catalog.planar_2r()
    rmap = optik.reach(m, resolution=0.25, orientations=4, samples=2000, workers=1, out=tmp_path)
    for path in (tmp_path, tmp_path / "reach.npz"):
        back = optik.ReachMap.load(path)
        for name in ("voxels", "centers", "index", "success", "rotations", "origin"):
            np.testing.assert_array_equal(getattr(back, name), getattr(rmap, name))
        assert back.resolution == rmap.resolution and back.shape == rmap.shape
        assert back.complete and back.meta["settings"] == rmap.meta["settings"]
        np.testing.assert_array_equal(back.grid(), rmap.grid())
    with pytest.raises(optik.InvalidArgumentError, match=r"^path: no capability map at .*no such file"):
        optik.ReachMap.load(tmp_path / "nothing")
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(optik.InvalidArgumentError, match=r"^path: .*bad\.npz is not a reach\.npz"):
        optik.ReachMap.load(tmp_path / "bad.npz")
