"""Fuzz of collision-aware IK over random worlds (slow): the Panda among random boxes, spheres,
capsules and cylinders, targets by FK of clear configurations; every claimed success of
``solve_ik`` (lm and nlp), ``solve_ik_all`` and ``solve_ik_batch`` is judged by Pinocchio's own
model and coal (`optik.benchmarks.judge.PinocchioJudge`), and none may fail it."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import spatial

pytestmark = pytest.mark.slow
pytest.importorskip("coal", reason="collision checks need coal (extra 'collision')")
pytest.importorskip("pinocchio", reason="the judge is Pinocchio + coal")

MARGIN = 0.01
WORLDS = 30


def _random_world(rng: np.random.Generator) -> optik.World:
    w = optik.World()
    for k in range(int(rng.integers(1, 7))):
        pose = spatial.transform(
            spatial.rpy_to_rot(*rng.uniform(-np.pi, np.pi, 3)), rng.uniform(-0.8, 0.8, 3)
        )
        kind = rng.integers(4)
        if kind == 0:
            w.add_box(f"o{k}", rng.uniform(0.03, 0.4, 3), pose)
        elif kind == 1:
            w.add_sphere(f"o{k}", rng.uniform(0.02, 0.2), pose)
        elif kind == 2:
            w.add_capsule(f"o{k}", rng.uniform(0.02, 0.1), rng.uniform(0.0, 0.4), pose)
        else:
            w.add_cylinder(f"o{k}", rng.uniform(0.02, 0.1), rng.uniform(0.05, 0.4), pose)
    return w


def test_no_claimed_success_collides_in_random_worlds():
    from optik.benchmarks.judge import PinocchioJudge
    from optik.catalog.robots import robots_dir

    d = robots_dir() / "panda_description"
    urdf, srdf = d / "urdf" / "panda.urdf", d / "srdf" / "panda.srdf"
    m = optik.Mechanism.from_urdf(urdf, "panda_link0", "panda_hand_tcp", srdf=srdf)
    rng = np.random.default_rng(11)
    judge = None
    claimed = false = 0
    for _ in range(WORLDS):
        w = _random_world(rng)
        clear = [
            q
            for q in m.random_q(20, seed=rng)
            if not optik.collision.check(m, q, w, margin=MARGIN).in_collision
        ]
        if not clear:
            continue
        if judge is None:
            judge = PinocchioJudge(m, urdf, srdf, ["panda_hand_tcp"], d.parents[2], w)
        judge.set_world(w)
        target = m.fk(clear[0])
        answers = [
            optik.solve_ik(m, target, world=w, margin=MARGIN, time_limit=0.2, seed=1),
            optik.solve_ik(m, target, world=w, margin=MARGIN, time_limit=0.5, seed=1, method="nlp"),
            *optik.solve_ik_all(m, target, world=w, margin=MARGIN, time_limit=0.2, seed=1, max_solutions=4),
        ]
        qs = [r.q for r in answers if r.success]
        batch = optik.solve_ik_batch(m, np.array([target]), world=w, margin=MARGIN, time_limit=0.2, workers=1)
        qs += [q for q, ok in zip(batch.q, batch.success, strict=True) if ok]
        for q in qs:
            claimed += 1
            false += not judge.ok(q, target, 1e-6, MARGIN)
    assert claimed >= WORLDS
    assert false == 0, f"{false} of {claimed} claimed successes collide or miss the target"
