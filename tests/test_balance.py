"""Contacts and static balance (optik.solvers.balance): frames held in the world in every
multi-target method, and the centre of mass's ground projection kept inside a support polygon
by a margin (NLP inequalities), on the free-base quadruped of test_floating_base. Every success
is re-checked from the returned ``q``: contacts and targets by FK, the centre of mass by
``m.com`` (itself checked against MuJoCo and Pinocchio in test_com)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull
from test_floating_base import FEET, URDF

import optik
from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.solvers.balance import auto_support, support_halfplanes


@pytest.fixture(scope="module")
def quad():
    m = optik.Mechanism.from_urdf(URDF, floating_base=True)
    q = m.mid_q()
    q[2] = -min(m.fk(q, f)[2, 3] for f in FEET)  # standing on z = 0
    return m, q


def _hull(points: np.ndarray) -> np.ndarray:
    return points[ConvexHull(points).vertices]  # counter-clockwise in 2-D


def _inside(m, q, polygon) -> float:
    n, b = support_halfplanes(polygon)
    return float(np.min(b - n @ m.com(q)[:2]))


def test_halfplanes_of_a_square():
    n, b = support_halfplanes([[0, 0], [1, 0], [1, 1], [0, 1]])
    np.testing.assert_allclose(n, [[0, -1], [1, 0], [0, 1], [-1, 0]], atol=1e-15)
    np.testing.assert_allclose(b, [0, 1, 1, 0], atol=1e-15)
    for bad in (
        [[0, 0], [0, 1], [1, 1], [1, 0]],
        [[0, 0], [1, 0]],
        [[0, 0], [1, 0], [2, 0]],
        [[0, 0, 0]] * 3,
    ):
        with pytest.raises(InvalidArgumentError, match="support"):
            support_halfplanes(bad)


@pytest.mark.parametrize("method", ["lm", "nlp", "qp"])
def test_contacts_hold_the_feet(quad, method):
    m, stand = quad
    feet = {f: optik.Position(m.fk(stand, f)[:3, 3]) for f in FEET}
    goal = m.fk(stand, "torso")
    goal[:3, 3] += [0.03, -0.02, -0.05]
    r = optik.solve_ik(m, {"torso": goal}, q0=stand, contacts=feet, method=method, time_limit=10.0)
    assert r.success, r.message
    assert set(r.frame_errors) == {"torso", *FEET}
    for f, p in feet.items():
        assert np.abs(m.fk(r.q, f)[:3, 3] - p.xyz).max() < 1e-6
    assert np.abs(m.fk(r.q, "torso")[:3, 3] - goal[:3, 3]).max() < 1e-6


@pytest.mark.parametrize("method", ["lm", "nlp", "qp"])
def test_balance_on_three_feet(quad, method):
    """Three feet hold, the fourth reaches out: the centre of mass must stay over the triangle
    of the three by the margin; without the balance rows the same reach leaves it outside
    (``lm`` through CasADi's evaluator, ``compile=False``: the same step as the C kernel, see
    test_lm_kernel, without a compiler run in the suite)."""
    m, stand = quad
    held = FEET[:3]
    contacts = {f: optik.Position(m.fk(stand, f)[:3, 3]) for f in held}
    polygon = _hull(np.array([m.fk(stand, f)[:2, 3] for f in held]))
    reach = m.fk(stand, FEET[3])[:3, 3] + [-0.12, -0.06, 0.08]
    target = {FEET[3]: optik.Position(reach)}
    free = optik.solve_ik(m, target, q0=stand, contacts=contacts, method="nlp", time_limit=10.0)
    assert free.success and _inside(m, free.q, polygon) < 0.0  # falls over without the rows
    options = {"compile": False} if method == "lm" else {}
    r = optik.solve_ik(
        m,
        target,
        q0=stand,
        contacts=contacts,
        support=polygon,
        com_margin=0.01,
        time_limit=10.0,
        method=method,
        **options,
    )
    assert r.success, r.message
    assert r.method == method
    if method == "lm":  # the active-set step (lm_kernel) converges from the first start; the
        assert r.restarts == 0 and r.iterations <= 12  # hinges' plain step takes 22 and a restart
    assert _inside(m, r.q, polygon) >= 0.01 - 1e-9 and r.extra["com_inside"] == pytest.approx(
        _inside(m, r.q, polygon)
    )
    np.testing.assert_allclose(r.extra["com"], m.com(r.q))
    for f, p in {**contacts, **target}.items():
        assert np.abs(m.fk(r.q, f)[:3, 3] - p.xyz).max() < 1e-6
    assert m.within_limits(r.q)


@pytest.mark.parametrize("method", ["lm", "nlp"])
def test_an_impossible_margin_fails_with_the_reason(quad, method):
    m, stand = quad
    contacts = {f: optik.Position(m.fk(stand, f)[:3, 3]) for f in FEET}
    polygon = _hull(np.array([m.fk(stand, f)[:2, 3] for f in FEET]))
    goal = m.fk(stand, "torso")
    r = optik.solve_ik(
        m,
        {"torso": goal},
        q0=stand,
        contacts=contacts,
        support=polygon,
        com_margin=0.5,
        time_limit=0.5,
        max_restarts=1,
        method=method,
        **({"compile": False} if method == "lm" else {}),
    )
    assert not r.success and r.extra["com_inside"] < 0.5
    assert "centre of mass" in r.message or "tolerances not met" in r.message


def test_rejections(quad):
    m, stand = quad
    feet = {f: m.fk(stand, f) for f in FEET}
    square = [[-1, -1], [1, -1], [1, 1], [-1, 1]]
    goal = m.fk(stand, "torso")
    with pytest.raises(InvalidArgumentError, match="contacts"):
        optik.solve_ik(m, {"torso": goal}, contacts={"torso": goal})
    with pytest.raises(InvalidArgumentError, match="contacts"):
        optik.solve_ik(m, goal, frame="torso", contacts={"FL_foot": np.eye(3)})
    with pytest.raises(InvalidArgumentError, match="contacts"):
        optik.solve_ik(m, goal, frame="torso", contacts={})
    with pytest.raises(InvalidArgumentError, match="com_margin"):
        optik.solve_ik(m, goal, frame="torso", com_margin=0.1)
    with pytest.raises(InvalidArgumentError, match="com_margin"):
        optik.solve_ik(m, goal, frame="torso", support=square, com_margin=-0.1)
    with pytest.raises(SolverUnavailableError, match="support"):
        optik.solve_ik(m, goal, frame="torso", contacts=feet, support=square, method="dls")
    with pytest.raises(InvalidArgumentError, match="support"):
        optik.solve_ik(m, goal, frame="torso", support=square[::-1])


def test_the_humanoid_benchmark_runs(capsys):
    pytest.importorskip("pinocchio", reason="the benchmark's judge is Pinocchio")
    from optik.benchmarks import bench_balance
    from optik.catalog.robots import robots_dir

    try:
        robots_dir()
    except optik.OptikError as exc:
        pytest.skip(f"the G1 comes from example-robot-data: {exc}")
    for robot in ("g1", "go2"):
        assert (
            bench_balance.main(
                [
                    "--robot",
                    robot,
                    "--n",
                    "2",
                    "--time-limit",
                    "5",
                    "--pink-com-costs",
                    "0",
                    "--methods",
                    "nlp",
                ]
            )
            == 0
        )
        out = capsys.readouterr().out
        assert "| optik nlp + balance | 2/2 |" in out


@pytest.mark.filterwarnings("ignore:Converted matrix")  # qpsolvers hands clarabel sparse copies
@pytest.mark.parametrize("solver", ["daqp", "osqp", "cvxpy", "clarabel"])
def test_a_qp_step_holds_the_balance_rows(quad, solver):
    """One diffik.step toward the fourth foot's far reach: without ``support`` the step's
    linearized centre of mass leaves the triangle of the held feet; with it every backend's
    step satisfies ``G dq <= h`` (the rows of build_qp: N (c + J_com dq) <= b - margin)."""
    if solver != "cvxpy":
        pytest.importorskip(solver)
    m, stand = quad
    held = FEET[:3]
    tasks = []
    for f in held:
        t = optik.diffik.PositionTask(f, cost=10.0)
        t.set_target(m.fk(stand, f))
        tasks.append(t)
    reach = optik.diffik.PositionTask(FEET[3])
    goal = m.fk(stand, FEET[3])
    goal[:3, 3] += [-0.12, -0.06, 0.08]
    reach.set_target(goal)
    polygon = _hull(np.array([m.fk(stand, f)[:2, 3] for f in held]))
    free = optik.diffik.step(m, stand, [*tasks, reach], 1.0, "qp", solver)
    res = optik.diffik.step(m, stand, [*tasks, reach], 1.0, "qp", solver, support=polygon, com_margin=0.01)
    g, h = res.problem.G, res.problem.h
    assert g.shape == (3, m.n_q) and res.ok, res.message
    assert np.any(g @ free.v > h + 1e-3)  # the free step leaves the polygon (linearized)
    assert np.all(g @ res.v <= h + 1e-6)
    n, b = support_halfplanes(polygon)
    np.testing.assert_allclose(h, b - 0.01 - n @ m.com(stand)[:2], atol=1e-12)
    np.testing.assert_allclose(g, n @ m.com_jacobian(stand)[:2], atol=1e-12)
    with pytest.raises(InvalidArgumentError, match="support"):
        optik.diffik.step(m, stand, tasks, 1.0, "dls", support=polygon)


def test_auto_support_of_point_feet(quad):
    """``support="auto"`` with point feet is the hull of the points; flat contacts on a body
    without collision geometry, no contacts, or another string are refused."""
    m, stand = quad
    feet = {f: optik.Position(m.fk(stand, f)[:3, 3]) for f in FEET[:3]}
    polygon = auto_support(m, feet)
    np.testing.assert_allclose(polygon, _hull(np.array([p.xyz[:2] for p in feet.values()])))
    target = {FEET[3]: optik.Position(m.fk(stand, FEET[3])[:3, 3] + [-0.12, -0.06, 0.08])}
    r = optik.solve_ik(
        m, target, q0=stand, contacts=feet, support="auto", com_margin=0.01, time_limit=10.0, compile=False
    )
    assert r.success and _inside(m, r.q, polygon) >= 0.01 - 1e-9, r.message
    with pytest.raises(InvalidArgumentError, match="collision geometry"):
        auto_support(m, {f: m.fk(stand, f) for f in FEET})
    with pytest.raises(InvalidArgumentError, match="support"):
        optik.solve_ik(m, target, q0=stand, support="auto")
    with pytest.raises(InvalidArgumentError, match="support"):
        optik.solve_ik(m, target, q0=stand, contacts=feet, support="hull")
    with pytest.raises(InvalidArgumentError, match="span no polygon"):
        auto_support(m, dict(list(feet.items())[:2]))


def test_auto_support_of_the_humanoid_soles():
    """The G1's flat feet: the hull of their collision spheres' centres (the sole corners) at
    the held poses, and a reach that keeps the centre of mass inside it."""
    try:
        m = optik.catalog.legged("g1")
    except optik.OptikError as exc:
        pytest.skip(f"the G1 comes from example-robot-data: {exc}")
    from optik.collision.robot import robot_geometry

    q = m.params["standing"]
    feet = {f: m.fk(q, f) for f in m.params["feet"]}
    polygon = auto_support(m, feet)
    geo = robot_geometry(m)
    centres = np.array(
        [
            (m.fk(q, geo.links[i]) @ p.offset)[:2, 3]
            for p, i in zip(geo.parts, geo.part_link, strict=True)
            if geo.links[i] in feet
        ]
    )
    assert len(centres) == 8
    np.testing.assert_allclose(polygon, _hull(centres), atol=1e-12)
    hand = m.fk(q, "right_rubber_hand")
    hand[:3, 3] += [0.1, -0.05, 0.15]
    r = optik.solve_ik(
        m,
        {"right_rubber_hand": hand},
        q0=q,
        contacts=feet,
        support="auto",
        com_margin=0.01,
        time_limit=10.0,
        compile=False,
    )
    assert r.success and _inside(m, r.q, polygon) >= 0.01 - 1e-9, r.message


def test_batch_with_contacts_and_balance(quad):
    """solve_ik_batch with contacts, support and com_margin: every target meets its reach with
    the three feet held and the centre of mass inside by the margin (checked from each row), the
    same answers as solve_ik per target with the row's seed; bad contacts raise before any work."""
    m, stand = quad
    held = FEET[:3]
    contacts = {f: optik.Position(m.fk(stand, f)[:3, 3]) for f in held}
    polygon = _hull(np.array([m.fk(stand, f)[:2, 3] for f in held]))
    base = m.fk(stand, FEET[3])[:3, 3]
    reaches = np.array([base + d for d in ([-0.12, -0.06, 0.08], [-0.1, -0.04, 0.1], [-0.08, -0.08, 0.06])])
    kw = {"contacts": contacts, "support": polygon, "com_margin": 0.01, "time_limit": 10.0, "compile": False}
    r = optik.solve_ik_batch(m, reaches, q0=stand, frame=FEET[3], workers=2, **kw)
    assert r.success.all(), r.status
    for i, q in enumerate(r.q):
        assert _inside(m, q, polygon) >= 0.01 - 1e-9 and m.within_limits(q)
        assert np.abs(m.fk(q, FEET[3])[:3, 3] - reaches[i]).max() < 1e-6
        for f, p in contacts.items():
            assert np.abs(m.fk(q, f)[:3, 3] - p.xyz).max() < 1e-6
        one = optik.solve_ik(m, optik.Position(reaches[i]), stand, frame=FEET[3], seed=int(r.seed[i]), **kw)
        np.testing.assert_array_equal(one.q, q)
    with pytest.raises(InvalidArgumentError, match="contacts"):
        optik.solve_ik_batch(m, reaches, q0=stand, frame=FEET[3], contacts={FEET[3]: np.eye(4)})


def test_balance_from_threads(quad):
    """Four threads solving balanced reaches at once give bit-identical answers to one thread
    (per-thread kernel buffers, the prepared-request and polygon caches under their lock)."""
    from concurrent.futures import ThreadPoolExecutor

    m, stand = quad
    held = FEET[:3]
    contacts = {f: optik.Position(m.fk(stand, f)[:3, 3]) for f in held}
    polygon = _hull(np.array([m.fk(stand, f)[:2, 3] for f in held]))
    base = m.fk(stand, FEET[3])[:3, 3]
    goals = [optik.Position(base + np.array([-0.12 + 0.01 * i, -0.06, 0.08])) for i in range(8)]

    def solve(goal):
        return optik.solve_ik(
            m,
            {FEET[3]: goal},
            q0=stand,
            contacts=contacts,
            support=polygon,
            com_margin=0.01,
            time_limit=10.0,
            compile=False,
        ).q

    alone = [solve(g) for g in goals]
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(solve, goals))
    for a, b in zip(alone, together, strict=True):
        np.testing.assert_array_equal(a, b)
