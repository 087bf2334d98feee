"""The clutter benchmark (benchmarks/bench_collision.py) judges every solver's answer the same way:
wrapped and clipped into the limits (`settle`, what `solve_ik` does to optik's answers) before the
Pinocchio + coal judge, so a peer's answer a float32 rounding past a limit is not failed."""

from __future__ import annotations

import numpy as np
import pytest

import optik

pytest.importorskip("coal", reason="collision checks need coal (extra 'collision')")
pytest.importorskip("pinocchio", reason="the judge is Pinocchio + coal (extra 'peers')")

MARGIN = 0.01
TOL = 1e-6


@pytest.fixture(scope="module")
def panda_judge():
    from optik.benchmarks.bench_collision import scene
    from optik.benchmarks.judge import PinocchioJudge
    from optik.catalog.robots import robots_dir

    d = robots_dir() / "panda_description"
    urdf, srdf = d / "urdf" / "panda.urdf", d / "srdf" / "panda.srdf"
    m = optik.Mechanism.from_urdf(urdf, "panda_link0", "panda_hand_tcp", srdf=srdf)
    w = scene()
    return m, w, PinocchioJudge(m, urdf, srdf, ["panda_hand_tcp"], d.parents[2], w)


@pytest.mark.parametrize("joint", [0, 3, 6])
@pytest.mark.parametrize("side", ["lower", "upper"])
def test_an_answer_5e9_past_a_limit_is_settled_onto_it_and_accepted(panda_judge, joint, side):
    m, w, judge = panda_judge
    rng = np.random.default_rng(joint)
    limit = getattr(m, side)[joint]
    for q in m.random_q(200, seed=rng):  # a configuration on the limit, clear of the clutter
        q[joint] = limit
        if not optik.collision.check(m, q, w, margin=1.5 * MARGIN).in_collision:
            break
    else:
        pytest.fail("no clear configuration on the limit")
    target = m.fk(q)
    raw = q.copy()
    raw[joint] += 5e-9 if side == "upper" else -5e-9  # TRAC-IK's float32 limit overshoot
    assert not judge.ok(raw, target, TOL, MARGIN)  # the judge itself is exact: outside is outside
    assert judge.accepts(raw, target, TOL, MARGIN)  # the benchmark's path settles it first
    assert judge.accepts(q, target, TOL, MARGIN) and judge.ok(q, target, TOL, MARGIN)


def test_a_real_miss_stays_a_failure_after_settling(panda_judge):
    m, _, judge = panda_judge
    q = m.mid_q()
    target = m.fk(q)
    far = q.copy()
    far[0] = m.upper[0] + 0.3  # past the limit by far more than a rounding: clipped, then misses
    assert not judge.accepts(far, target, TOL, MARGIN)
    assert not judge.accepts(None, target, TOL, MARGIN)


def test_optik_answers_take_the_same_path_and_pass_it(panda_judge):
    from optik.benchmarks.bench_collision import optik_solver

    m, w, judge = panda_judge
    solve = optik_solver(m, w, MARGIN, TOL)
    rng = np.random.default_rng(3)
    accepted = 0
    for q in m.random_q(30, seed=rng):
        if optik.collision.check(m, q, w, margin=MARGIN).in_collision:
            continue
        target = m.fk(q)
        answer = solve(target, 1.0, 0)
        if answer is not None:
            assert judge.ok(answer, target, TOL, MARGIN)  # optik's answers are settled already
            accepted += judge.accepts(answer, target, TOL, MARGIN)
    assert accepted >= 5


def _srdf_pairs(urdf, srdf, coordinates):
    """Pinocchio's pairs of the URDF minus the SRDF's, and those of them some solved joint moves apart."""
    import pinocchio as pin

    from optik.mechanism.urdf_visuals import cmeel_share

    model = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(
        model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(cmeel_share())]
    )
    geom.addAllCollisionPairs()
    pin.removeCollisionPairs(model, geom, str(srdf))
    solved = {model.getJointId(n) for n in coordinates}
    moved = [frozenset(solved & set(model.supports[g.parentJoint])) for g in geom.geometryObjects]
    pairs = {(p.first, p.second) for p in geom.collisionPairs}
    return pairs, {(a, b) for a, b in pairs if moved[a] != moved[b]}


def test_the_judge_checks_every_srdf_pair_but_those_no_solved_joint_moves(panda_judge):
    """The Panda judge checks every pair the SRDF leaves (none is moved by no arm joint); TALOS's
    (right arm and legs held at zero) leaves out exactly the pairs that keep a constant distance."""
    from optik.benchmarks.bench_collision_self import workload
    from optik.benchmarks.judge import PinocchioJudge
    from optik.catalog.robots import robots_dir

    m, _, judge = panda_judge
    d = robots_dir() / "panda_description"
    pairs, moving = _srdf_pairs(d / "urdf" / "panda.urdf", d / "srdf" / "panda.srdf", m.coordinate_names)
    assert {(p.first, p.second) for p in judge.geom.collisionPairs} == moving == pairs
    w = workload("talos")
    talos = PinocchioJudge(w.m, w.urdf, w.srdf, w.frames)
    pairs, moving = _srdf_pairs(w.urdf, w.srdf, w.m.coordinate_names)
    assert {(p.first, p.second) for p in talos.geom.collisionPairs} == moving != pairs
