"""The collision-aware IPOPT (optik.solvers.collision_nlp, collision_free's nlp): its functions from
mapped pieces equal the one-expression NLP, its compiled code answers as the evaluator does, and
it honours its time limit (no iteration after the deadline but the one that stops) with every
answer judged by the exact geometry."""

from __future__ import annotations

import time

import casadi as ca
import numpy as np
import pytest

import optik
from optik import spatial
from optik.collision import World, check

pytest.importorskip("coal", reason="collision checks need coal (extra 'collision')")

MARGIN = 0.01


@pytest.fixture(scope="module")
def arm(toy_arm_urdf) -> optik.Mechanism:
    return optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip")


def _world(arm) -> World:
    w = World()
    w.add_sphere("ball", 0.05, spatial.translation(*arm.fk(np.array([0.3, 1.2]), "fore")[:3, 3]))
    w.add_box("block", (0.1, 0.2, 0.3), spatial.translation(0.2, -0.5, 0.0))
    return w


def test_mapped_pieces_equal_the_one_expression_nlp(arm):
    """``g`` bitwise, its Jacobian and the Lagrangian's Hessian to rounding, with the same
    sparsity, against the rows written as one ``SX`` expression (`distance_expressions`) and CasADi's
    own derivatives of it, at random configurations, flags and multipliers."""
    from optik.collision.robot import robot_geometry
    from optik.collision.slots import SLOT_SIZE
    from optik.collision.spheres import distance_expressions
    from optik.problem import build_ik_problem
    from optik.solvers.collision_nlp import nlp_functions

    state = _world(arm).state()
    cap = state.capacity
    problem = build_ik_problem(arm, "position", None)
    geo = robot_geometry(arm)
    fns = nlp_functions(problem, geo, cap, True)
    slots = ca.SX.sym("slots", cap * SLOT_SIZE)
    rows = distance_expressions(geo, [arm.frame_expr(link) for link in geo.links], slots, True)
    bound, flags = ca.SX.sym("bound"), ca.SX.sym("flags", rows.self_rows.shape[0])
    q = problem.q
    g = ca.vertcat(arm.closure_expr, rows.active * (rows.world - bound), flags * (rows.self_rows - bound))
    p = ca.vertcat(problem.parameters, slots, bound, flags)
    lam_f, lam_g = ca.SX.sym("lam_f"), ca.SX.sym("lam_g", g.shape[0])
    ref_g = ca.Function("g", [q, p], [g])
    ref_j = ca.Function("j", [q, p], [ca.jacobian(g, q)])
    ref_h = ca.Function(
        "h", [q, p, lam_f, lam_g], [ca.triu(ca.hessian(lam_f * problem.objective + ca.dot(lam_g, g), q)[0])]
    )
    assert fns.jac_g.sparsity_out(1) == ref_j.sparsity_out(0)
    assert fns.hess_lag.sparsity_out(0) == ref_h.sparsity_out(0)
    rng = np.random.default_rng(0)
    n_pairs = rows.self_rows.shape[0]
    assert n_pairs and rows.world.shape[0]  # both kinds of rows are compared
    for _ in range(5):
        x = arm.random_q(seed=rng)
        task = problem.parameter_values(spatial.translation(*rng.standard_normal(3)), posture=1e-3)
        pv = np.concatenate([task, state.slots[: cap * SLOT_SIZE], [0.012], rng.random(n_pairs)])
        lam = rng.standard_normal(g.shape[0])
        assert np.array_equal(np.asarray(fns.g(x, pv)).ravel(), np.asarray(ref_g(x, pv)).ravel())
        for mine, ref in (
            (fns.jac_g(x, pv)[1], ref_j(x, pv)),
            (fns.hess_lag(x, pv, 0.7, lam), ref_h(x, pv, 0.7, lam)),
        ):
            a, b = np.asarray(ca.densify(mine)), np.asarray(ca.densify(ref))
            assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(b).max()))


def test_compiled_code_answers_as_the_evaluator(arm):
    """``compile=True`` (the library built here, IPOPT calling it through ``casadi.external``) and
    ``compile=False`` (CasADi's evaluator): the same answers, bitwise, on targets of the blocking
    world (C compiled without contractions computes the evaluator's operations in its order)."""
    from optik.solvers.collision_free import _CACHE

    w = _world(arm)
    rng = np.random.default_rng(4)
    targets = [arm.fk(arm.random_q(seed=rng))[:3, 3] for _ in range(4)]
    kw = {"world": w, "self_collision": True, "margin": MARGIN, "method": "nlp", "time_limit": 5.0}
    for i, target in enumerate(targets):
        a = optik.solve_ik(arm, optik.Position(target), compile=True, seed=i, **kw)
        b = optik.solve_ik(arm, optik.Position(target), compile=False, seed=i, **kw)
        assert np.array_equal(a.q, b.q) and a.iterations == b.iterations and a.success == b.success
    pools = {k[-1]: v for k, v in _CACHE.items() if k[0] == "nlp" and k[1] is arm and k[4]}
    assert pools[True].compiled and not pools[False].compiled
    with pytest.raises(optik.InvalidArgumentError, match="^compile: expected True, False or 'auto'"):
        optik.solve_ik(arm, optik.Position(targets[0]), compile="yes", **kw)


def test_no_iteration_after_the_deadline_and_answers_judged_exactly(monkeypatch):
    """At a 10 ms limit on unreachable targets (the Panda among the boxes of ``optik benchmark
    collision``, its self pairs too) the iteration callback runs at most once at or after the
    call's deadline (the one that stops IPOPT; no start begins after it), each call ends as a
    ``time_limit`` failure re-checked here; on reachable targets every success is clear by the
    exact geometry at the margin, every ``in_collision`` answer is not."""
    from optik.benchmarks.bench_collision import scene
    from optik.catalog.robots import robots_dir
    from optik.solvers.collision_free import ClearStop

    try:
        d = robots_dir() / "panda_description"
        m = optik.Mechanism.from_urdf(
            d / "urdf" / "panda.urdf", "panda_link0", "panda_hand_tcp", srdf=d / "srdf" / "panda.srdf"
        )
    except optik.OptikError:
        pytest.skip("needs example-robot-data (extra 'robots')")
    w = scene()
    kw = {"world": w, "self_collision": True, "margin": MARGIN, "method": "nlp"}
    calls: list[tuple[float, float]] = []
    seen = ClearStop.eval_buffer

    def logged(self, arg, res):
        calls.append((time.perf_counter(), self.deadline))
        return seen(self, arg, res)

    monkeypatch.setattr(ClearStop, "eval_buffer", logged)
    rng = np.random.default_rng(5)
    far = m.fk(m.random_q(seed=rng))
    far[0, 3] += 2.0
    optik.solve_ik(m, far, time_limit=0.01, **kw)  # builds the NLP (setup, not timed)
    for i in range(10):
        calls.clear()
        res = optik.solve_ik(m, far, time_limit=0.01, seed=i, **kw)
        late = [t for t, deadline in calls if t >= deadline]
        assert calls and len(late) <= 1
        assert not res.success and res.status == "time_limit"
        assert np.linalg.norm(m.fk(res.q)[:3, 3] - far[:3, 3]) > 1.0
    solved = tried = 0
    while solved < 3:
        tried += 1
        assert tried <= 20, f"only {solved} of {tried - 1} clear targets solved"
        q = m.random_q(seed=rng)
        if check(m, q, w, margin=MARGIN).in_collision:
            continue
        res = optik.solve_ik(m, m.fk(q), time_limit=2.0, seed=solved, **kw)
        exact = check(m, res.q, w, margin=MARGIN)
        if res.success:
            solved += 1
            assert not exact.in_collision and exact.min_distance >= MARGIN
            assert np.linalg.norm(m.fk(res.q)[:3, 3] - m.fk(q)[:3, 3]) <= 1e-6
        elif res.status == "in_collision":
            assert exact.in_collision
