"""The compiled chunk kernel of "lm": the C driver against its Python twin, limits, seeds."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik.problem import target_parameters
from optik.solvers.lm_kernel import STATUS, LMKernel, Settings, target_seeds


def _settings(m: optik.Mechanism, **over: object) -> Settings:
    base = {
        "block": 5,
        "max_iter": 100,
        "max_restarts": -1,
        "time_limit": 1.0,
        "mu0": 1e-2,
        "stall": 0.7,
        "stop": (5e-7, 5e-7, 5e-10),
        "gain": 0.0,
        "weights": (1.0, 1.0),
        "q_ref": m.mid_q(),
    }
    return Settings(**{**base, **over})


def test_compiled_driver_and_python_loop_agree() -> None:
    m = optik.catalog.panda()
    n = 6
    targets = np.stack([target_parameters(t) for t in m.fk(m.random_q(n, seed=3))])
    q0 = m.random_q(n, seed=4)  # random starts: restarts happen
    seeds = target_seeds(7, 0, n)
    conf = _settings(m).conf(m)
    compiled = LMKernel(m, "pose", None, 100.0, True)
    python = LMKernel(m, "pose", None, 100.0, False)
    assert compiled.compiled and not python.compiled
    a, b = compiled.run(targets, q0, seeds, conf), python.run(targets, q0, seeds, conf)
    np.testing.assert_allclose(a.q, b.q, atol=1e-12)
    np.testing.assert_array_equal(a.iterations, b.iterations)
    np.testing.assert_array_equal(a.restarts, b.restarts)
    np.testing.assert_array_equal(a.status, b.status)
    assert (a.status == 0).all() and a.restarts.sum() > 0
    assert (a.errors[:, :2] <= 5e-7).all()
    # the reported errors are those of the answer, recomputed independently
    for i in range(n):
        assert m.within_limits(a.q[i])
        pos = np.linalg.norm(m.fk(a.q[i])[:3, 3] - targets[i][9:])
        assert pos == pytest.approx(a.errors[i, 0], abs=1e-12)


def test_time_limit_and_restart_cap_are_honoured_per_target(cpu_clock) -> None:
    m = optik.catalog.panda()
    far = np.eye(4)
    far[:3, 3] = [3.0, 0.0, 0.5]  # out of reach
    k = LMKernel(m, "pose", None, 100.0, "auto")
    targets = np.stack([target_parameters(far)] * 2)
    q0 = np.stack([m.mid_q()] * 2)
    with cpu_clock() as cpu:  # the work done, which a busy machine does not lengthen (conftest)
        out = k.run(targets, q0, target_seeds(0, 0, 2), _settings(m, time_limit=0.02).conf(m))
    assert [STATUS[s] for s in out.status] == ["time_limit", "time_limit"]
    assert (out.solve_time >= 0.02).all()
    assert cpu.seconds < 2 * (0.02 + 0.13), f"{cpu.seconds:.3f} CPU s for two targets of 0.02 s"
    out = k.run(targets, q0, target_seeds(0, 0, 2), _settings(m, max_restarts=3).conf(m))
    assert [STATUS[s] for s in out.status] == ["max_restarts"] * 2
    assert (out.restarts == 3).all()


def test_target_seeds_are_a_splitmix64_stream() -> None:
    def splitmix(state: int) -> tuple[int, int]:
        mask = (1 << 64) - 1
        state = (state + 0x9E3779B97F4A7C15) & mask
        z = ((state ^ (state >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return state, z ^ (z >> 31)

    state, expected = 12345, []
    for _ in range(5):
        state, z = splitmix(state)
        expected.append(z >> 1)
    assert target_seeds(12345, 0, 5).tolist() == expected
    assert target_seeds(12345, 2, 3).tolist() == expected[2:]  # independent of chunking
    assert len(set(target_seeds(0, 0, 10000).tolist())) == 10000


def test_limits_are_inputs_of_one_kernel_per_geometry() -> None:
    """Copies of one arm that differ only by their limits (a joint pinned at many values, as
    ``solve_ik_all(..., fixed=)`` makes them) share one kernel, and each run projects onto its own
    limits, compiled and in the Python loop alike."""
    from optik.solvers.lm_kernel import kernel

    m = optik.catalog.panda()
    q_true = m.random_q(seed=5)
    targets = target_parameters(m.fk(q_true))[None]
    shared = kernel(m, "pose", None, 100.0, True)
    python = LMKernel(m, "pose", None, 100.0, False)
    for v in (q_true[0], -1.0, 0.5):
        lo, hi = m.lower.copy(), m.upper.copy()
        lo[0] = hi[0] = v
        lo[3], hi[3] = q_true[3] - 0.3, q_true[3] + 0.3  # a narrower second limit
        pinned = m.with_limits(lower=lo, upper=hi).with_limits()
        assert pinned.geometry is m and kernel(pinned, "pose", None, 100.0, True) is shared
        conf = _settings(pinned, max_restarts=20).conf(pinned)
        q0 = np.clip(m.mid_q(), lo, hi)[None]
        a = shared.run(targets, q0, target_seeds(1, 0, 1), conf)
        b = python.run(targets, q0, target_seeds(1, 0, 1), conf)
        np.testing.assert_allclose(a.q, b.q, atol=1e-12)
        assert a.q[0, 0] == v and pinned.within_limits(a.q[0])
        pos = np.linalg.norm(m.fk(a.q[0])[:3, 3] - m.fk(q_true)[:3, 3])
        assert pos == pytest.approx(a.errors[0, 0], abs=1e-12)
        if v == q_true[0]:  # q_true is within the pinned limits
            assert a.status[0] == 0


def test_one_target_path_equals_the_chunk_run() -> None:
    """``run_one`` (the packed one-target call of ``solve_ik``) gives what ``run`` gives, on the
    compiled driver and in the Python loop, from threads that each use their own buffers."""
    from concurrent.futures import ThreadPoolExecutor

    m = optik.catalog.iiwa14()
    targets = np.stack([target_parameters(t) for t in m.fk(m.random_q(6, seed=8))])
    q0 = m.random_q(6, seed=9)
    seeds = target_seeds(3, 0, 6)
    conf = _settings(m).conf(m)
    for k in (LMKernel(m, "pose", None, 100.0, True), LMKernel(m, "pose", None, 100.0, False)):
        want = k.run(targets, q0, seeds, conf)
        with ThreadPoolExecutor(2) as pool:
            got = list(pool.map(lambda i, k=k: k.run_one(targets[i], q0[i], int(seeds[i]), conf), range(6)))
        for i, (q, err, iterations, restarts, status) in enumerate(got):
            np.testing.assert_array_equal(q, want.q[i])
            assert err == tuple(want.errors[i])
            assert (iterations, restarts, status) == (want.iterations[i], want.restarts[i], want.status[i])
            assert status == 0 and m.within_limits(q)
            np.testing.assert_allclose(m.fk(q)[:3, 3], targets[i][9:], atol=1e-6)  # independent FK


def test_cholesky_solve_of_the_step_matches_a_dense_solve() -> None:
    """The step's Cholesky solve (`optik.solvers.lm_kernel._cholesky_solve`) against numpy on LM
    matrices ``J^T J + mu I`` of rank-deficient ``J`` (a redundant arm's), down to ``mu = 1e-9``."""
    import casadi as ca

    from optik.solvers.lm_kernel import _cholesky_solve

    n = 7
    a, b = ca.SX.sym("a", n, n), ca.SX.sym("b", n)
    f = ca.Function("f", [a, b], [_cholesky_solve([[a[i, j] for j in range(i + 1)] for i in range(n)], b)])
    rng = np.random.default_rng(0)
    for mu in (1.0, 1e-3, 1e-6, 1e-9):
        jac = rng.normal(size=(12, 6)) @ rng.normal(size=(6, n))  # rank 6
        lhs, rhs = jac.T @ jac + mu * np.eye(n), rng.normal(size=n)
        x = np.asarray(f(lhs, rhs)).ravel()
        np.testing.assert_allclose(lhs @ x, rhs, atol=1e-7 * np.linalg.norm(lhs) * np.linalg.norm(x))
        forward = 1e-12 * np.linalg.cond(lhs) + 1e-9  # a backward-stable solve's bound, with room
        np.testing.assert_allclose(x, np.linalg.solve(lhs, rhs), rtol=forward)
