"""The robot-independent QP stack of differential IK (optik.diffik.generic_stack): its terms equal
the per-robot stack's, it answers the first step of a robot never compiled and hands over, and
it declines what it does not model."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import diffik, native
from optik.diffik import generic_stack
from optik.diffik.problem import ClosureConstraint, StackFunction, normalize_limits

pytestmark = pytest.mark.skipif(native.compiler() is None, reason="needs a C compiler")


def _built(m: optik.Mechanism, tasks: list, limits: list) -> generic_stack.ChainStack:
    if not generic_stack.machine_files(m, tasks, limits, timeout=600):
        pytest.skip("the generic stack could not be built")
    stack = generic_stack.stack_for(m, tasks, limits)
    assert stack is not None
    return stack


def test_generic_stack_terms_equal_the_per_robot_stack() -> None:
    m = optik.catalog.panda()
    tasks = [diffik.FrameTask(target=m.fk(m.random_q(seed=1)), position_cost=2.0, lm_damping=0.1)]
    limits = normalize_limits(m, None)
    generic = _built(m, tasks, limits)
    per_robot = StackFunction(m, tasks, limits, ClosureConstraint(1.0))
    parts = [tasks[0].parameters(m), tasks[0].cost, np.array([tasks[0].gain, tasks[0].lm_damping])]
    parts += [lim.parameters(m) for lim in limits] + [np.array([1e-12])]
    for q in m.random_q(5, seed=2):
        v_prev = np.zeros(7)
        for a, b in zip(generic(q, parts, 0.01, v_prev), per_robot(q, parts, 0.01, v_prev), strict=True):
            assert a.shape == b.shape
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    assert generic.slices == per_robot.slices and generic.n_closure == per_robot.n_closure == 0


def test_the_first_step_is_the_generic_stacks_then_the_robots_own() -> None:
    m = optik.Mechanism.from_urdf(optik.catalog.arms.urdf_path("panda"), "panda_link0", "panda_link8")
    target = m.fk(m.random_q(seed=3))
    _built(m, [diffik.FrameTask(target=target)], normalize_limits(m, None))
    first = diffik.step(m, m.mid_q(), [diffik.FrameTask(target=target)], 0.01)
    assert isinstance(first.problem.cache, generic_stack.ChainStack)
    assert native.wait(timeout=300)
    later = diffik.step(m, m.mid_q(), [diffik.FrameTask(target=target)], 0.01)
    assert type(later.problem.cache) is StackFunction and later.problem.cache.function.compiled
    np.testing.assert_allclose(first.q, later.q, rtol=0, atol=1e-12)
    assert first.status == later.status == "ok"


def test_what_the_generic_stack_does_not_model_is_declined() -> None:
    m = optik.catalog.panda()
    limits = normalize_limits(m, None)
    assert generic_stack.stack_for(m, [diffik.PostureTask(m.mid_q())], limits) is None
    closed = optik.catalog.five_bar()
    task = diffik.PositionTask(target=closed.fk(closed.mid_q())[:3, 3])
    assert generic_stack.stack_for(closed, [task], normalize_limits(closed, None)) is None
