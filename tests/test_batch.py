"""solve_ik_batch and fk_batch: answers equal to solve_ik, independent of chunks and threads."""

from __future__ import annotations

import os
import pickle
import signal
import threading

import numpy as np
import pytest

import optik
from optik.batch import BatchResult, fk_batch, solve_ik_batch
from optik.batch.fk import CHUNK

PANDA = optik.catalog.panda()


def _panda_targets(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    return fk_batch(PANDA, PANDA.random_q(n, seed=seed)), PANDA.random_q(n, seed=seed + 1)


def test_batch_equals_solve_ik_with_each_targets_seed() -> None:
    targets, q0 = _panda_targets(40, 11)
    res = solve_ik_batch(PANDA, targets, q0, tol=1e-5, seed=3, time_limit=0.5)
    assert len(res) == 40 and res.success.all() and res.restarts.sum() > 0
    assert len(set(res.seed.tolist())) == 40
    for i in range(40):
        one = optik.solve_ik(
            PANDA, targets[i], q0[i], method="lm", tol=1e-5, seed=int(res.seed[i]), time_limit=0.5
        )
        np.testing.assert_array_equal(one.q, res.q[i])
        assert one.iterations == res.iterations[i] and one.restarts == res.restarts[i]
        assert one.status == res.status[i] == "solved"
        assert one.position_error == res.position_error[i]
        assert one.orientation_error == res.orientation_error[i]
    # the success is real: FK of the answers, limits
    pose = fk_batch(PANDA, res.q)
    assert np.abs(pose[:, :3, 3] - targets[:, :3, 3]).max() <= 1e-5
    assert ((res.q >= PANDA.lower) & (res.q <= PANDA.upper)).all()


def test_answers_do_not_depend_on_chunks_or_threads() -> None:
    targets, q0 = _panda_targets(60, 21)
    T = 2.0  # no target may stop on the clock: under load a 5 ms limit would make answers timing-dependent
    a = solve_ik_batch(PANDA, targets, q0, tol=1e-6, seed=9, workers=1, time_limit=T)
    b = solve_ik_batch(PANDA, targets, q0, tol=1e-6, seed=9, workers=2, chunk_size=7, time_limit=T)
    for name in ("q", "success", "iterations", "restarts", "status", "seed", "position_error"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    c = solve_ik_batch(PANDA, targets, q0, tol=1e-6, seed=10, workers=2)
    assert not np.array_equal(a.seed, c.seed)
    # a slice solved again with its own seeds gives the same rows
    part = solve_ik_batch(PANDA, targets[20:30], q0[20:30], tol=1e-6, seed=a.seed[20:30], time_limit=T)
    np.testing.assert_array_equal(part.q, a.q[20:30])
    assert part.base_seed is None and a.base_seed == 9


def test_ctrl_c_while_the_pool_works_is_a_keyboard_interrupt_every_time() -> None:
    """SIGINT in the middle of a threaded batch raises ``KeyboardInterrupt`` in the caller (never
    ``RuntimeError: release unlocked lock`` from an interrupted condition wait), the chunks not
    started are cancelled, and Python's SIGINT handler is back afterwards."""
    targets, q0 = _panda_targets(80, 31)
    targets[:, :3, 3] += 5.0  # out of reach: every target runs to its 10 ms limit, 8 per chunk
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        for _ in range(3):
            timer = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT))
            timer.start()
            with pytest.raises(KeyboardInterrupt):
                solve_ik_batch(PANDA, targets, q0, workers=2, chunk_size=8, time_limit=0.01)
            timer.join()
            assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, previous)


def test_unreachable_targets_fail_within_their_time_limit(cpu_clock) -> None:
    """Each target has its own clock: the reachable one, solved after two that spent their
    whole limit, still has a full limit (ample on a busy machine: it needs a small fraction of
    it). The two that stop on the clock do no work past it: their CPU seconds, not their
    wall-clock `solve_time`, which a busy machine lengthens, are bounded above."""
    far = np.tile(np.eye(4), (3, 1, 1))
    far[:, :3, 3] = [[2.0, 0, 0.3], [0, 2.5, 0.3], [0.1, 0.0, 0.5]]
    far[2] = PANDA.fk(PANDA.random_q(seed=1))  # reachable, in the middle
    T = 0.25
    with cpu_clock() as cpu:
        res = solve_ik_batch(PANDA, far, time_limit=T, workers=2, chunk_size=1)
    assert res.success.tolist() == [False, False, True]
    assert res.status.tolist()[:2] == ["time_limit", "time_limit"]
    assert (res.solve_time[:2] >= T).all()
    assert cpu.seconds < 2 * (T + 0.13), f"{cpu.seconds:.3f} CPU s for two targets of {T} s"
    assert (res.position_error[:2] > 0.5).all()
    capped = solve_ik_batch(PANDA, far[:1], max_restarts=2, time_limit=2.0)  # ends on the cap, not the clock
    assert capped.status.tolist() == ["max_restarts"] and capped.restarts.tolist() == [2]
    assert capped.result(0).message and not capped.result(0).success


def test_positions_pose2d_and_shared_start() -> None:
    arm = optik.catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    qs = arm.random_q(12, seed=4)
    poses = fk_batch(arm, qs)
    targets = [optik.Pose2D(t[0, 3], t[1, 3], np.arctan2(t[1, 0], t[0, 0])) for t in poses]
    res = solve_ik_batch(arm, targets, q0=[0.1, 0.2, 0.3], seed=1)
    assert res.success.all()
    np.testing.assert_allclose(fk_batch(arm, res.q)[:, :2, 3], poses[:, :2, 3], atol=1e-6)
    one = optik.solve_ik(arm, targets[5], [0.1, 0.2, 0.3], method="lm", seed=int(res.seed[5]))
    np.testing.assert_array_equal(one.q, res.q[5])
    pos = solve_ik_batch(PANDA, fk_batch(PANDA, PANDA.random_q(5, seed=2))[:, :3, 3], tol=1e-6)
    assert pos.success.all() and (pos.orientation_error == 0).all()


def test_other_methods_loop_over_solve_ik() -> None:
    arm = optik.catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    targets = fk_batch(arm, arm.random_q(4, seed=7))
    res = solve_ik_batch(arm, targets, method="closed_form")
    assert res.method == "closed_form" and res.success.all()
    for i in range(4):
        np.testing.assert_array_equal(optik.solve_ik(arm, targets[i], method="closed_form").q, res.q[i])


def test_closed_form_batch_of_a_derived_arm_takes_the_compiled_driver(monkeypatch) -> None:
    import optik.batch.chunk as chunk

    arm = optik.catalog.puma560()
    q = arm.random_q(60, seed=4)
    targets = fk_batch(arm, q)
    targets[5, :3, 3] = [3.0, 0.0, 0.0]  # out of reach: the driver leaves it to solve_ik
    looped = []

    def counted(*args, **kwargs):
        looped.append(args[1])
        return optik.solve_ik(*args, **kwargs)

    monkeypatch.setattr(chunk, "solve_ik", counted)
    res = solve_ik_batch(arm, targets, method="closed_form")
    assert len(looped) == 1 and np.array_equal(looped[0], targets[5])  # every other target: the driver
    assert res.workers == 1 and 0 < res.compile_time <= res.wall_time
    assert res.throughput == pytest.approx(len(res) / (res.wall_time - res.compile_time))
    assert res.success.sum() == 59 and not res.success[5] and res.status[5] == "unreachable"
    for i in range(60):
        one = optik.solve_ik(arm, targets[i], method="closed_form")
        np.testing.assert_array_equal(one.q, res.q[i])
        assert one.success == res.success[i] and one.status == res.status[i]
        assert one.position_error == pytest.approx(res.position_error[i], abs=1e-12)
        assert one.orientation_error == pytest.approx(res.orientation_error[i], abs=1e-12)
    # the successes are real: one independent FK, exact limits
    ok = res.success
    pose = np.array([arm.fk(row) for row in res.q[ok]])
    assert np.abs(pose[:, :3, 3] - targets[ok, :3, 3]).max() <= 1e-6
    assert ((res.q >= arm.lower) & (res.q <= arm.upper)).all()


def test_the_compile_is_reported_apart_from_the_throughput() -> None:
    arm = optik.catalog.planar_3r(lengths=(1.0, 0.7, 0.4))  # a new mechanism: its kernel is built now
    targets = fk_batch(arm, arm.random_q(20, seed=2))
    first = solve_ik_batch(arm, targets, tol=1e-8)
    again = solve_ik_batch(arm, targets, tol=1e-8)
    assert 0 < first.compile_time <= first.wall_time
    assert again.compile_time < first.compile_time
    for res in (first, again):
        assert res.throughput == pytest.approx(len(res) / (res.wall_time - res.compile_time))


def test_table_records_and_concatenation(capsys: pytest.CaptureFixture) -> None:
    targets, _ = _panda_targets(3, 5)
    res = solve_ik_batch(PANDA, targets, progress=True)
    assert "100%  3/3" in capsys.readouterr().err
    rows = res.records()
    assert len(rows) == 3 and rows[1]["status"] == res.status[1] and rows[1]["q"] == res.q[1].tolist()
    both = BatchResult.concatenate([res, res])
    assert len(both) == 6 and both.success_rate == res.success_rate
    # the non-array fields come from meta: the throughput is the rows over the given solving time
    timed = BatchResult.concatenate([res, res], wall_time=2.5, compile_time=0.5)
    assert timed.throughput == pytest.approx(3.0) and timed.wall_time == 2.5
    empty = solve_ik_batch(PANDA, np.zeros((0, 4, 4)))
    assert len(empty) == 0 and empty.q.shape == (0, 7)


@pytest.mark.parametrize(
    ("kwargs", "error", "name"),
    [
        ({"targets": np.zeros((3, 4))}, optik.ShapeError, "targets"),
        ({"targets": np.full((2, 4, 4), np.nan)}, optik.NonFiniteError, "targets"),
        ({"targets": np.tile(2 * np.eye(4), (2, 1, 1))}, optik.InvalidArgumentError, "targets"),
        ({"q0": np.zeros((3, 7))}, optik.ShapeError, "q0"),
        ({"bogus": 1}, optik.InvalidArgumentError, "bogus"),
        ({"workers": 0}, optik.InvalidArgumentError, "workers"),
        ({"seed": -1}, optik.InvalidArgumentError, "seed"),
        ({"seed": [1, 2, 3]}, optik.ShapeError, "seed"),
        ({"seed": [1, -2]}, optik.InvalidArgumentError, "seed"),
        ({"time_limit": 0.0}, optik.InvalidArgumentError, "time_limit"),
        ({"scheduler": 3}, optik.InvalidArgumentError, "scheduler"),
    ],
)
def test_bad_input_names_the_argument(kwargs: dict, error: type, name: str) -> None:
    args = {"targets": np.tile(np.eye(4), (2, 1, 1)), **kwargs}
    with pytest.raises(error, match=f"^{name}"):
        solve_ik_batch(PANDA, **args)


def test_fk_batch_matches_fk_and_wrap_of_rows_matches_wrap() -> None:
    q = PANDA.random_q(CHUNK * 2 + 17, seed=3)
    np.testing.assert_array_equal(fk_batch(PANDA, q, workers=2), PANDA.fk(q))
    np.testing.assert_array_equal(fk_batch(PANDA, q[:3], frame="ee"), PANDA.fk(q[:3]))
    with pytest.raises(optik.UnknownFrameError):
        fk_batch(PANDA, q, frame="nope")
    wild = np.random.default_rng(0).uniform(-12, 12, (300, 7))  # joint 6's limits exceed pi
    np.testing.assert_array_equal(PANDA.wrap(wild), np.array([PANDA.wrap(r) for r in wild]))


def test_mechanism_pickles_by_definition() -> None:
    m = optik.catalog.panda()
    m.fk(m.mid_q())  # built CasADi functions must not be pickled
    back = pickle.loads(pickle.dumps(m))
    assert back.kind == m.kind and back.params.keys() == m.params.keys() and back.name == m.name
    q = m.random_q(seed=1)
    np.testing.assert_array_equal(back.fk(q), m.fk(q))
    np.testing.assert_array_equal(back.lower, m.lower)
    closed = optik.catalog.five_bar()
    assert pickle.loads(pickle.dumps(closed)).n_closure == closed.n_closure
