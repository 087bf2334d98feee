"""``solve_ik_all_batch``: every solution of many targets in one call, target by target the same
answer as ``solve_ik_all``, each solution re-checked by FK and the limits."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import closed_form


def _shifted_seed_arm() -> optik.Mechanism:
    """The seed arm with limits that need the 2 pi shift and drop solutions."""
    m = optik.catalog.seed_6r_arm()
    lo, hi = np.zeros(6), np.full(6, 2 * np.pi)
    lo[1], hi[1] = -3 * np.pi, -np.pi
    return m.with_limits(lo, hi)


def _targets(m: optik.Mechanism, count: int, seed: int) -> np.ndarray:
    """FK targets, a few at the wrist singularity (stand-ins, close candidates: the general
    path) and one out of reach."""
    qs = np.random.default_rng(seed).uniform(-np.pi, np.pi, (count, 6))
    qs[:4, 4] = 0.0
    t = m.fk(qs)
    t[-1, :3, 3] *= 10.0
    return t


def _assert_same(m: optik.Mechanism, batch: optik.IKSolutionsBatch, one: optik.IKSolutions, i: int) -> None:
    a, b = batch.offsets[i : i + 2]
    np.testing.assert_array_equal(batch.q[a:b], one.q.reshape(-1, 6))
    np.testing.assert_array_equal(
        batch.errors[a:b], np.array([(r.position_error, r.orientation_error) for r in one]).reshape(-1, 2)
    )
    np.testing.assert_array_equal(np.array(batch[i].outside_limits).reshape(-1, 6),
                                  np.array(one.outside_limits).reshape(-1, 6))  # fmt: skip
    assert batch.certified[i] == one.certified
    assert np.all(batch.target[a:b] == i)


@pytest.mark.parametrize("m", [optik.catalog.puma560(), _shifted_seed_arm()], ids=["puma560", "seed_shifted"])
def test_batch_equals_solve_ik_all_target_by_target(m: optik.Mechanism) -> None:
    """The one C call over all targets answers each as ``solve_ik_all`` does (same rows, order,
    errors, solutions outside the limits), with one start for all and one per target; every
    solution passes an independent FK and limit check."""
    solver = closed_form.derive(m)
    solver.compile()
    targets = _targets(m, 40, 3)
    starts = np.random.default_rng(4).uniform(-np.pi, np.pi, (40, 6))
    for q0 in (None, starts[0], starts):
        batch = optik.solve_ik_all_batch(m, targets, q0)
        assert len(batch) == 40 and batch.offsets[-1] == len(batch.q)
        for i, t in enumerate(targets):
            start = q0 if q0 is None or q0.ndim == 1 else q0[i]
            _assert_same(m, batch, optik.solve_ik_all(m, t, start), i)
        for q, i in zip(batch.q, batch.target, strict=True):
            assert m.within_limits(q)
            np.testing.assert_allclose(m.fk(q), targets[i], atol=1e-9)
        assert batch.counts[-1] == 0  # out of reach: no solution, no error
        if solver.driver() is not None:  # the regular targets went through the compiled loop
            assert len(batch.general) < 10


def test_batch_of_a_mechanism_without_a_derived_closed_form() -> None:
    """Without a compiled driver every target goes through ``solve_ik_all`` (options forwarded)."""
    m = optik.catalog.planar_3r()
    targets = np.stack([m.fk(q) for q in m.random_q(3, seed=0)])
    with pytest.raises(optik.errors.ShapeError, match=r"^targets"):
        optik.solve_ik_all_batch(m, targets[:, :3])
    m6 = optik.catalog.seed_6r_arm()
    t6 = m6.fk(m6.random_q(3, seed=1))
    batch = optik.solve_ik_all_batch(m6, t6, method="lm", seed=0, time_limit=0.5, patience=3)
    assert len(batch.general) == 3 and not batch.certified.any()
    for i, t in enumerate(t6):
        for q in batch[i].q:
            np.testing.assert_allclose(m6.fk(q), t, atol=1e-5)


def test_batch_validates_its_arguments() -> None:
    m = optik.catalog.puma560()
    closed_form.derive(m).compile()
    targets = m.fk(m.random_q(5, seed=2))
    bad = targets.copy()
    bad[3, 0, 0] = np.nan
    with pytest.raises(optik.errors.NonFiniteError, match=r"^targets\[3\]"):
        optik.solve_ik_all_batch(m, bad)
    skew = targets.copy()
    skew[2, :3, :3] *= 1.1
    with pytest.raises(optik.errors.InvalidArgumentError, match=r"^targets\[2\]"):
        optik.solve_ik_all_batch(m, skew)
    with pytest.raises(optik.errors.ShapeError, match=r"^q0"):
        optik.solve_ik_all_batch(m, targets, np.zeros((4, 6)))
    with pytest.raises(optik.errors.NonFiniteError, match=r"^q0"):
        optik.solve_ik_all_batch(m, targets, np.full(6, np.inf))
    one = optik.solve_ik_all_batch(m, targets[0])  # one (4, 4) target
    assert len(one) == 1
    np.testing.assert_array_equal(one[0].q, optik.solve_ik_all(m, targets[0]).q)
    strided = np.asfortranarray(targets)  # any layout: the same answer
    want = optik.solve_ik_all_batch(m, targets).q
    np.testing.assert_array_equal(optik.solve_ik_all_batch(m, strided).q, want)
