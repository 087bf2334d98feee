"""The robot-independent lm kernel (optik.solvers.generic_chain): its FK and Jacobian equal each
catalog arm's model, its answers pass the referee, it answers the first solve of a robot never
compiled and hands over to the per-robot kernel, its threads agree, and it declines what it
does not model."""

from __future__ import annotations

import threading

import casadi as ca
import numpy as np
import pytest

import optik
from optik import native
from optik.catalog import robots
from optik.errors import MissingExtraError
from optik.harness.peers.rules import Referee
from optik.mechanism import Joint, Mechanism
from optik.mechanism.joint import Mimic
from optik.solvers import generic_chain, lm_kernel
from optik.solvers.base import Tolerances

needs_cc = pytest.mark.skipif(native.compiler() is None, reason="needs a C compiler")


def _catalog_arms() -> list[tuple[str, Mechanism]]:
    arms = [
        ("panda", optik.catalog.panda()),
        ("iiwa14", optik.catalog.iiwa14()),
        ("puma560", optik.catalog.puma560()),
        ("seed_6r_arm", optik.catalog.seed_6r_arm()),
        ("rp_arm", optik.catalog.rp_arm()),
    ]
    try:
        names = robots.robot_names() if robots.robots_dir() else ()
    except MissingExtraError:
        names = ()
    return arms + [(n, optik.catalog.robot(n)) for n in names]


def _chain_functions(n: int) -> ca.Function:
    """``(q, chain) -> (vec T, d vec T / dq)`` of the generic chain."""
    q, chain = ca.SX.sym("q", n), ca.SX.sym("chain", generic_chain.n_chain_parameters(n))
    t = ca.vec(generic_chain.chain_pose(q, chain))
    return ca.Function("chain", [q, chain], [t, ca.jacobian(t, q)])


def test_chain_fk_and_jacobian_equal_the_model_on_every_catalog_serial_arm() -> None:
    arms = _catalog_arms()
    assert len(arms) >= 5
    for name, m in arms:
        chain = generic_chain.chain_parameters(m, None)
        assert chain is not None, name
        f = _chain_functions(m.n_q)
        t = ca.vec(m.frame_expr())
        ref = ca.Function("ref", [m.q_sym], [t, ca.jacobian(t, m.q_sym)])
        for q in m.random_q(5, seed=3):
            fk, jac = (np.asarray(v) for v in f(q, chain))
            fk_ref, jac_ref = (np.asarray(v) for v in ref(q))
            np.testing.assert_allclose(fk, fk_ref, rtol=0, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(jac, jac_ref, rtol=0, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(fk.reshape(4, 4, order="F"), m.fk(q), rtol=0, atol=1e-12)


def test_chain_of_an_inner_frame_and_of_a_named_tool_frame() -> None:
    m = optik.catalog.panda()
    tool = np.eye(4)
    tool[:3, 3] = [0.01, -0.02, 0.1]
    body, ee = m.frames[m.ee]
    with_tool = Mechanism(m.joints, m.base, {"tool": (body, ee @ tool)}, None, "panda+tool", "pose")
    chain = generic_chain.chain_parameters(with_tool, "tool")
    f = _chain_functions(7)
    for q in m.random_q(3, seed=4):
        pose = np.asarray(f(q, chain)[0]).reshape(4, 4, order="F")
        np.testing.assert_allclose(pose, with_tool.fk(q, "tool"), rtol=0, atol=1e-12)
    # a frame before the last joint leaves coordinates off its path: not a chain of all of q
    inner = m.topology.bodies[3]
    assert generic_chain.chain_parameters(m, inner) is None


def test_what_the_generic_kernel_does_not_model_is_declined() -> None:
    assert generic_chain.chain_parameters(optik.catalog.five_bar(), None) is None  # a loop
    joints = [
        Joint("a", "revolute", "base", "l1", axis=[0, 0, 1]),
        Joint("b", "revolute", "l1", "l2", origin=np.eye(4), axis=[0, 1, 0], mimic=Mimic("a", 2.0)),
        Joint("c", "revolute", "l2", "l3", axis=[1, 0, 0]),
    ]
    assert generic_chain.chain_parameters(Mechanism(joints, "base"), None) is None  # a mimic joint
    ball = [Joint("s", "spherical", "base", "l1"), Joint("r", "revolute", "l1", "l2")]
    assert generic_chain.chain_parameters(Mechanism(ball, "base"), None) is None


def _ready(n: int) -> generic_chain.ChainKernel:
    if not generic_chain.build(n, timeout=600):
        pytest.skip(f"the generic kernel of {n} joints could not be built")
    return generic_chain.chain_kernel(n)


@needs_cc
def test_generic_answers_pass_the_referee() -> None:
    k = _ready(7)
    tol = Tolerances()
    for m, urdf, base, tip in (
        (optik.catalog.panda(), optik.catalog.arms.urdf_path("panda"), "panda_link0", "panda_link8"),
        (optik.catalog.iiwa14(), None, "", ""),
    ):
        try:
            ref = Referee(m, urdf, base, tip)
        except optik.OptikError:
            ref = Referee(m)
        chain = generic_chain.chain_parameters(m, None)
        conf = lm_kernel.Settings(5, 100, -1, 1.0, 0.1, 0.7, (5e-7, 5e-7, 5e-10), 0.0, (1.0, 1.0), m.mid_q())
        conf = conf.conf(m)
        for i, q in enumerate(m.random_q(25, seed=5)):
            target = ref.fk(q)
            params = np.concatenate([optik.problem.target_parameters(target), chain])
            answer, err, _, _, status = k.run_one(params, m.mid_q(), i, conf)
            verdict = ref.judge(answer, target, tol)
            assert status == 0 and verdict.success, (m.name, i, verdict)
            assert np.all(answer >= m.lower) and np.all(answer <= m.upper)  # exactly: no clipping needed
            assert k.final_errors(answer, params) == err  # the error check of the answer is the kernel's


@needs_cc
def test_the_first_solve_is_the_generic_kernels_then_the_per_robot_kernel_takes_over() -> None:
    k = _ready(7)
    m = Mechanism.from_urdf(optik.catalog.arms.urdf_path("panda"), "panda_link0", "panda_link8")  # new
    targets = [m.fk(q) for q in m.random_q(6, seed=8)]
    calls = k.calls
    first = optik.solve_ik(m, targets[0], seed=0, time_limit=1.0)
    assert k.calls == calls + 1 and first.success and first.method == "lm"
    assert np.abs(m.fk(first.q) - targets[0]).max() < 1e-5 and m.within_limits(first.q)
    per_robot = None
    for _ in range(600):  # the per-robot kernel is built in the background (cached or compiled)
        per_robot = lm_kernel.cached_kernel(m, "pose", None, 100.0, "auto")
        if per_robot is not None and per_robot.library is not None:
            break
        threading.Event().wait(0.05)
    assert per_robot is not None and native.wait(timeout=300) and per_robot.compiled
    calls = k.calls
    later = [optik.solve_ik(m, t, seed=0) for t in targets]
    assert k.calls == calls  # the compiled per-robot kernel answers now
    assert all(r.success for r in later)
    # a copy with other limits (a locked joint) shares the geometry: no generic answer either
    locked = m.with_limits(lower=np.r_[0.3, m.lower[1:]], upper=np.r_[0.3, m.upper[1:]])
    assert optik.solve_ik(locked, m.fk(np.r_[0.3, m.mid_q()[1:]]), seed=0).success and k.calls == calls


@needs_cc
def test_threads_get_the_answers_of_one_thread() -> None:
    k = _ready(7)
    m = optik.catalog.panda()
    chain = generic_chain.chain_parameters(m, None)
    conf = lm_kernel.Settings(5, 100, -1, 1.0, 0.1, 0.7, (5e-7, 5e-7, 5e-10), 0.0, (1.0, 1.0), m.mid_q())
    conf = conf.conf(m)
    params = [
        np.concatenate([optik.problem.target_parameters(m.fk(q)), chain]) for q in m.random_q(40, seed=9)
    ]
    one = [k.run_one(p, m.mid_q(), i, conf)[0] for i, p in enumerate(params)]
    out: dict[int, list[np.ndarray]] = {}

    def work(t: int) -> None:
        out[t] = [k.run_one(p, m.mid_q(), i, conf)[0] for i, p in enumerate(params)]

    threads = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for t in range(4):
        for a, b in zip(one, out[t], strict=True):
            np.testing.assert_array_equal(a, b)


def test_unreadable_sources_mean_no_generic_kernel_logged(monkeypatch, tmp_path, caplog) -> None:
    monkeypatch.setattr(generic_chain, "_SOURCES", ("solvers/missing.py",))  # a partial install
    with caplog.at_level("WARNING", logger="optik.solvers.generic_chain"):
        k = generic_chain.ChainKernel(3)
    assert k.library is None and not k.ready
    assert "sources cannot be read" in caplog.text
