"""solve_ik_batch on a two-process Dask LocalCluster: the answers of the local run, in order."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

import optik
from optik.batch import fk_batch, solve_ik_batch

distributed = pytest.importorskip("distributed", reason="needs the dist extra (pip install 'optik[dist]')")


def test_two_process_cluster(tmp_path) -> None:
    """One cluster for every check (pytest-xdist would start one per test process otherwise):
    answers, one kernel per worker, capability maps, then a worker killed mid-run."""
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
    )
    with distributed.Client(cluster) as client:
        _answers_equal_the_local_run(client)
        _capability_map_equals_the_local_one(client, tmp_path)
        _chunks_of_a_lost_worker_are_rerun(client)
    cluster.close()


def _kernels_built() -> int:
    """In a worker: the LM kernels built for the mechanisms it was shipped (each is cached on
    its mechanism, `optik.mechanism.memo.PerMechanism`)."""
    from optik.batch import distributed
    from optik.solvers import lm_kernel

    return sum(len(lm_kernel._KERNELS.get(m.geometry) or {}) for m in distributed._ON_WORKER.values())


def _answers_equal_the_local_run(client) -> None:
    m = optik.catalog.panda()
    targets = fk_batch(m, m.random_q(300, seed=5))
    q0 = m.random_q(300, seed=6)
    local = solve_ik_batch(m, targets, q0, tol=1e-5, seed=2, time_limit=2.0)
    remote = solve_ik_batch(m, targets, q0, tol=1e-5, seed=2, scheduler=client, chunk_size=16, time_limit=2.0)
    assert remote.workers == 2 and remote.success.all()
    for name in ("q", "success", "iterations", "restarts", "status", "seed", "position_error"):
        np.testing.assert_array_equal(getattr(remote, name), getattr(local, name))
    # both workers solved chunks, each from its own unpickled mechanism
    who = client.run(_kernels_built)
    assert sorted(who.values()) == [1, 1]
    again = solve_ik_batch(m, targets[:20], q0[:20], tol=1e-5, seed=2, scheduler=client, time_limit=2.0)
    np.testing.assert_array_equal(again.q, local.q[:20])
    assert client.run(_kernels_built) == who


def _chunks_of_a_lost_worker_are_rerun(client) -> None:
    m = optik.catalog.panda()
    targets = fk_batch(m, m.random_q(300, seed=8))
    local = solve_ik_batch(m, targets, tol=1e-5, seed=4, time_limit=2.0)
    solve_ik_batch(m, targets[:4], scheduler=client)  # ship the mechanism first
    pids = client.run(os.getpid)
    box: dict = {}
    run = threading.Thread(
        target=lambda: box.update(
            res=solve_ik_batch(m, targets, tol=1e-5, seed=4, scheduler=client, chunk_size=1, time_limit=2.0)
        )
    )
    before = set(client.nthreads())
    run.start()
    time.sleep(0.5)
    assert run.is_alive()  # the kill lands in the middle of the run
    victim = sorted(before)[0]
    os.kill(pids[victim], signal.SIGKILL)
    run.join(timeout=120)
    assert not run.is_alive()
    np.testing.assert_array_equal(box["res"].q, local.q)
    np.testing.assert_array_equal(box["res"].iterations, local.iterations)
    client.wait_for_workers(2, timeout=60)
    assert victim not in set(client.nthreads())  # the nanny started a new worker


def _capability_map_equals_the_local_one(client, tmp_path) -> None:
    arm = optik.catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    settings = {"resolution": 0.3, "orientations": 4, "samples": 10_000, "time_limit": 1.0}
    local = optik.reach(arm, **settings)
    remote = optik.reach(arm, **settings, scheduler=client)
    np.testing.assert_array_equal(remote.success, local.success)
    # the command line connects to a scheduler address
    from optik.cli import main

    args = ["reach", "planar_3r", "--resolution", "0.3", "--orientations", "4", "--samples", "10000"]
    assert main([*args, "--time-limit", "1.0", "--out", str(tmp_path), "--no-progress"]) == 0
    again = tmp_path / "again"
    out = [
        *args,
        "--time-limit",
        "1.0",
        "--out",
        str(again),
        "--no-progress",
        "--scheduler",
        client.scheduler.address,
    ]
    assert main(out) == 0
    with np.load(tmp_path / "reach.npz") as a, np.load(again / "reach.npz") as b:
        np.testing.assert_array_equal(a["success"], b["success"])
