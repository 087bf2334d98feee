"""The ik-geo adapter of the general 6R benchmark: the same arm, the same targets, a fair call.

ik-geo's general 6-DOF solver is approximate by design (a grid search refined by Nelder-Mead),
so its answers are checked at the benchmark's rule (FK error <= 1e-3), after checking that its
own FK of the adapted model equals optik's FK to rounding (axes, offsets, zero, angle signs,
tool rotation and the binding's transposition all right).
"""

from __future__ import annotations

import numpy as np
import pytest

ik_geo = pytest.importorskip("ik_geo", reason="ik-geo is the optional peer of the general 6R benchmark")

from optik.benchmarks import bench_general_6r as bench  # noqa: E402
from optik.closed_form.general_6r import solve_general_6r  # noqa: E402
from optik.spatial import angle_distance  # noqa: E402


def _arms(n: int) -> list:
    rng = np.random.default_rng(3)
    return [(bench._random_arm(rng), rng.uniform(-np.pi, np.pi, (3, 6))) for _ in range(n)]


def test_ik_geo_fk_of_the_adapted_model_is_optiks_fk() -> None:
    for m, qs in _arms(5):
        robot, home = bench.ik_geo_robot(m)
        for q in qs:
            t = m.fk(q)
            rot_t, pos = robot.forward_kinematics(q.tolist())
            r, p = bench.ik_geo_target(t, home)
            # the binding returns its rotation transposed, as it reads the one we pass
            np.testing.assert_allclose(np.asarray(rot_t), r, atol=1e-12)
            np.testing.assert_allclose(np.asarray(pos), p, atol=1e-12)


def test_ik_geo_answers_fk_back_to_the_target_and_are_solutions_optik_finds() -> None:
    answers = close = matched = trips = targets = 0
    for m, qs in _arms(8):
        robot, home = bench.ik_geo_robot(m)
        for q in qs:
            t = m.fk(q)
            cand = [np.asarray(s, dtype=float) for s, _ in robot.get_ik(*bench.ik_geo_target(t, home))]
            err = bench.fk_errors(m, cand, t)
            ours = solve_general_6r(m, t).q
            good = [s for s, e in zip(cand, err, strict=True) if e <= bench.GEO_FK_TOL]
            answers += len(cand)
            close += len(good)
            matched += sum(min(angle_distance(s, o) for o in ours) < bench.GEO_SAME for s in good)
            trips += any(angle_distance(s, q) < bench.GEO_SAME for s in good)
            targets += 1
    # its answers are real solutions, approximately: nearly all within 1e-3 and each of those
    # is one of the eigenvalue solver's branches (same arm, same target, so the adapter is right)
    assert answers >= targets
    assert close >= 0.9 * answers
    assert matched == close
    assert trips >= 0.5 * targets
