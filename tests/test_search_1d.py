"""The 1-D search IK (optik.closed_form.search_1d): round trips on random arms of each family,
verified and distinct answers, agreement with derived closed forms where both apply, the
registry route for arms special at both ends (compared with the general 6R solver's perturbation
fallback on the same targets), the uncertified flag and malformed input."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import closed_form, spatial
from optik.benchmarks.bench_search_1d import special_arm
from optik.closed_form import search_1d
from optik.closed_form.general_6r import covers, solve_general_6r
from optik.closed_form.search_1d import FAMILIES, Search1D, families_of, solve_search_1d
from optik.closed_form.structure import axes_of
from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError
from optik.mechanism import Joint, Mechanism, dh_chain
from optik.spatial import angle_distance

CASES = {
    # standard-DH entries set to zero: a_i = 0 makes axes i, i+1 intersect, alpha_i = 0 parallel
    "1-2 and 5-6 intersecting": {"a": [0, 4]},
    "1-2 intersecting, 5-6 parallel": {"a": [0], "alpha": [4]},
    "1-2 parallel, 5-6 intersecting": {"a": [4], "alpha": [0]},
    "1-2 and 5-6 parallel": {"alpha": [0, 4]},
    "4, 5, 6 parallel": {"alpha": [3, 4]},
    "1, 2, 3 parallel": {"alpha": [0, 1]},
}


def _check(m: Mechanism, q: np.ndarray, target: np.ndarray) -> None:
    """Every answer reproduces the target by the mechanism's own FK; at most 16, all distinct."""
    assert len(q) <= 16
    for qi in q:
        t = m.fk(qi)
        assert np.linalg.norm(t[:3, 3] - target[:3, 3]) <= 1e-8
        assert spatial.angle_between(t[:3, :3], target[:3, :3]) <= 1e-8
    assert all(angle_distance(q[i], q[j]) > 1e-4 for i in range(len(q)) for j in range(i))


@pytest.mark.parametrize("case", list(CASES))
def test_round_trips_through_the_registry(case: str) -> None:
    """Arms special at both ends (not covered by the general 6R solver, no decomposable family)
    get the search as their closed form; the drawn configuration is among the answers on at
    least 95 % of 40 targets (measured over 1000 in ``optik benchmark search_1d``)."""
    rng = np.random.default_rng(sorted(CASES).index(case))
    hits = total = 0
    for _ in range(4):
        m = special_arm(rng, CASES[case])
        assert closed_form.derive(m) is None and not covers(m)
        assert closed_form.has_ik(m)
        qs = m.random_q(10, seed=int(rng.integers(1 << 30)))
        for q, target in zip(qs, m.fk(qs), strict=True):
            sols = closed_form.ik(m, target, respect_limits=False)
            q_all = np.array(sols).reshape(-1, 6)
            _check(m, q_all, target)
            hits += bool(len(q_all)) and bool(np.min(angle_distance(q_all, q)) < 1e-6)
            total += 1
    assert hits >= 0.95 * total, f"{hits} of {total}"


def test_every_family_round_trips() -> None:
    """Each family of `FAMILIES` on its own (the reversed ones on the inverse chain) recovers the
    drawn configuration on an arm that has it, with verified, distinct answers."""
    rng = np.random.default_rng(7)
    for fam in FAMILIES:
        m = special_arm(
            rng, CASES["1-2 and 5-6 intersecting" if "intersecting" in fam.name else "1-2 and 5-6 parallel"]
        )
        axes = axes_of(m)
        assert fam in families_of(axes)
        qs = m.random_q(12, seed=3)
        sols = Search1D(axes, fam).solve(m.fk(qs))
        hits = 0
        for q, target, s in zip(qs, m.fk(qs), sols, strict=True):
            _check(m, s.q, target)
            hits += bool(len(s.q)) and bool(np.min(angle_distance(s.q, q)) < 1e-6)
        assert hits >= 11, (fam.name, hits)


def test_agrees_with_derived_closed_forms() -> None:
    """Where a decomposable closed form exists as well, the search finds exactly its branches:
    random spherical-wrist arms (5-6 intersecting, SP5 on axes 1-3) and the seed 6R arm (its
    inverse chain by 1-2 intersecting; `family_of` picks it by measurement)."""
    rng = np.random.default_rng(11)
    arms = [optik.catalog.seed_6r_arm()]
    for _ in range(2):
        a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
        a[[3, 4]], d[4] = 0.0, 0.0  # axes 4, 5, 6 meet
        arms.append(dh_chain([(d[i], a[i], alpha[i]) for i in range(6)], "standard"))
    for m in arms:
        assert closed_form.derive(m) is not None
        qs = np.random.default_rng(1).uniform(-np.pi, np.pi, (8, 6))
        for target, sols in zip(m.fk(qs), solve_search_1d(m, m.fk(qs)), strict=True):
            ref = np.array(closed_form.ik(m, target, respect_limits=False))
            assert len(sols.q) == len(ref)
            assert all(np.min(angle_distance(sols.q, r)) < 1e-8 for r in ref)


def test_search_against_the_perturbation_fallback() -> None:
    """On arms special at both ends, compared with the general 6R solver's uncertified answer (a
    nearby generic arm's solutions polished on the arm) on the same targets: the search
    recovers the drawn configuration on at least 95 % of the targets, the fallback recovers it
    where the search does not on at most 3 of the 72 (each method misses a few that the other
    finds, and which ones moves with the LAPACK build's rounding: 0 or 1 here), and the search
    misses at most 2 % of the fallback's verified solutions (``optik benchmark search_1d``
    counts them on 1000 targets per geometry)."""
    rng = np.random.default_rng(5)
    trips_search = fallback_wins = fallback_only = fallback_total = total = 0
    for case in CASES:
        m = special_arm(rng, CASES[case])
        qs = rng.uniform(-np.pi, np.pi, (12, 6))
        targets = m.fk(qs)
        for q, s, g in zip(qs, solve_search_1d(m, targets), solve_general_6r(m, targets), strict=True):
            assert not g.count_ok
            _check(m, s.q, m.fk(q))
            fallback_total += len(g.q)
            fallback_only += sum(not len(s.q) or bool(np.min(angle_distance(s.q, x)) >= 1e-6) for x in g.q)
            by_search = bool(len(s.q)) and bool(np.min(angle_distance(s.q, q)) < 1e-6)
            by_fallback = bool(len(g.q)) and bool(np.min(angle_distance(g.q, q)) < 1e-6)
            trips_search += by_search
            fallback_wins += by_fallback and not by_search
            total += 1
    assert trips_search >= 0.95 * total, (trips_search, total)
    assert fallback_wins <= 3, (fallback_wins, total)
    assert fallback_only <= 0.02 * fallback_total, (fallback_only, fallback_total)


def test_solve_ik_all_answers_by_the_search() -> None:
    rng = np.random.default_rng(9)
    m = special_arm(rng, CASES["1-2 and 5-6 intersecting"])
    q = m.random_q(1, seed=2)[0]
    sols = optik.solve_ik_all(m, m.fk(q))
    assert sols and all(s.method == "closed_form" and s.success for s in sols)
    assert min(angle_distance(s.q, q) for s in sols) < 1e-6


def test_flag_reason_and_unreachable() -> None:
    rng = np.random.default_rng(13)
    m = special_arm(rng, CASES["1-2 and 5-6 parallel"])
    sols = solve_search_1d(m, m.fk(np.zeros(6)))
    assert not sols.certified and "not certified" in sols.reason
    assert f"spacing {2 * np.pi / search_1d.SAMPLES:.1e} rad" in sols.reason
    far = solve_search_1d(m, spatial.translation(50.0, 0.0, 0.0))
    assert len(far.q) == 0 and not far.certified


def test_bad_input_raises_named_errors() -> None:
    rng = np.random.default_rng(17)
    m = special_arm(rng, CASES["1-2 and 5-6 intersecting"])
    with pytest.raises(ShapeError, match="target"):
        solve_search_1d(m, np.eye(3))
    with pytest.raises(ShapeError, match="target"):
        solve_search_1d(m, np.zeros((0, 4, 4)))
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(NonFiniteError, match="target"):
        solve_search_1d(m, bad)
    generic = dh_chain(
        [(rng.uniform(-1, 1), rng.uniform(0.1, 1), rng.uniform(-np.pi, np.pi)) for _ in range(6)]
    )
    with pytest.raises(InvalidArgumentError, match="m"):
        solve_search_1d(generic, np.eye(4))
    with pytest.raises(InvalidArgumentError, match="m"):
        solve_search_1d("arm", np.eye(4))  # type: ignore[arg-type]


def test_benchmark_runs(capsys: pytest.CaptureFixture[str]) -> None:
    """``optik benchmark search_1d`` on one small geometry (its numbers come from the full run)."""
    from optik.benchmarks import bench_search_1d

    assert bench_search_1d.main(["--arms", "1", "--poses", "2", "--only", "4, 5, 6"]) == 0
    out = capsys.readouterr().out
    assert "| optik search_1d | 2 |" in out and "| optik general_6r | 2 |" in out


def test_chunks_give_the_same_answers() -> None:
    """Targets searched in chunks (bounded memory) give the answers of one stacked search."""
    rng = np.random.default_rng(19)
    m = special_arm(rng, CASES["1-2 and 5-6 parallel"])
    axes = axes_of(m)
    fam = search_1d.family_of(axes)
    targets = m.fk(m.random_q(5, seed=4))
    whole = Search1D(axes, fam).solve(targets)
    parts = Search1D(axes, fam, chunk=2).solve(targets)
    assert len(parts) == 5
    for a, b in zip(whole, parts, strict=True):
        assert a.q.shape == b.q.shape and np.allclose(a.q, b.q, atol=1e-12)


def test_the_registry_answers_say_they_are_not_certified() -> None:
    """closed_form.ik and solve_ik_all carry the search's flag and reason."""
    rows = [(0.3, 0.0, 1.1), (0.2, 0.5, -0.7), (-0.4, 0.6, 2.0)]
    rows += [(0.5, 0.3, 0.9), (0.1, 0.0, -1.3), (0.2, 0.4, 0.5)]  # a1 = a5 = 0: both ends intersect
    m = optik.mechanism.dh_chain(rows, "standard")
    target = m.fk(np.array([0.4, -0.8, 1.2, 0.3, -1.5, 2.0]))
    branches = optik.closed_form.ik(m, target, respect_limits=False)
    assert isinstance(branches, optik.closed_form.registry.Uncertified) and "1-D search" in branches.reason
    sols = optik.solve_ik_all(m, target)
    assert len(sols) >= 1 and not sols.certified
    assert sols.uncertified_reason == branches.reason and "not certified complete" in sols.message
    certified = optik.solve_ik_all(optik.catalog.puma560(), optik.catalog.puma560().fk(np.zeros(6)))
    assert certified.certified and "certified" not in certified.message


def _jaco_like(extra_joint: bool = False) -> Mechanism:
    """The Kinova-Jaco-like arm of issue 18 (IK-Geo's convention: joint axes ``H``, offsets ``P``
    between points on them; wrist axes bent at 55 degrees): axes 1-2, 3-4, 4-5 and 5-6 meet,
    2-3 are parallel, and no decomposable family applies."""
    h = [[0, 0, 1], [0, 1, 0], [0, 1, 0], [0, 0, -1], [0, 0.8192, -0.5736], [0, 0.9397, 0.342]]
    p = [[0, 0, -0.0074], [0, 0.1178, 0.2829], [0.41, 0, 0], [0, -0.108, -0.2829], [0, 0.0883, -0.0281]]
    p += [[0, 0.0197, 0.0281], [0, 0, 0]]
    joints, prev = [], "base"
    for i in range(6):
        origin = spatial.translation(*p[i])
        joints.append(Joint(f"q{i + 1}", "revolute", prev, f"l{i + 1}", origin=origin, axis=h[i]))
        prev = f"l{i + 1}"
    if extra_joint:  # a seventh joint before the tool: locked, it leaves the six above
        origin = spatial.translation(0.0, 0.05, 0.1)
        joints.append(Joint("q7", "revolute", prev, "l7", origin=origin, axis=[1, 0, 0]))
        prev = "l7"
    return Mechanism(joints, frames={"tool": (prev, spatial.translation(*p[6]))}, ee="tool")


def test_jaco_like_arm_is_solved_by_the_search() -> None:
    """Regression (issue 18, item 3b): on this arm the search found 0 solutions of every FK
    target and the default ``solve_ik`` answered "unreachable". Its axes 1-2 meet, which made
    the SP5 of the 5-6 family degenerate (``p0 = 0``); it is SP3 then SP2 there. Every drawn
    configuration is among the verified answers, and the default ``solve_ik`` solves them."""
    m = _jaco_like()
    assert closed_form.derive(m) is None and not covers(m) and closed_form.has_ik(m)
    qs = m.random_q(10, seed=1)
    for q, target, s in zip(qs, m.fk(qs), solve_search_1d(m, m.fk(qs)), strict=True):
        _check(m, s.q, target)
        assert np.min(angle_distance(s.q, q), initial=np.inf) < 1e-8
        res = optik.solve_ik(m, target)
        assert res.success and res.method == "closed_form"
        t = m.fk(res.q)  # independent check
        assert np.linalg.norm(t[:3, 3] - target[:3, 3]) <= 1e-6


def test_default_solve_ik_does_not_call_unreachable_on_an_uncertified_search() -> None:
    """The search is not certified complete: when it finds no branch within the limits the
    default ``solve_ik`` answers by the numerical method within the time left and says so;
    ``method="closed_form"`` asked for explicitly says "not_found", not "unreachable"."""
    m = _jaco_like()
    far = spatial.translation(3.0, 0.0, 0.0)
    res = optik.solve_ik(m, far, time_limit=0.05)
    assert not res.success and res.status != "unreachable" and res.method == "lm"
    assert "not certified complete" in res.message and res.extra["closed_form"]["status"] == "not_found"
    cf = optik.solve_ik(m, far, method="closed_form")
    assert cf.status == "not_found" and "may still be reachable" in cf.message
    every = optik.solve_ik_all(m, far, time_limit=0.1, patience=3)
    assert every.method == "lm" and not every.certified
    assert "the closed form found none" in every.uncertified_reason


def test_the_numerical_fallback_gets_the_time_that_is_left(monkeypatch: pytest.MonkeyPatch) -> None:
    """The fallback after an uncertified closed form ran with ``time_limit = remaining()`` from
    the request's own start, so the time the closed form spent was counted twice: it must get
    the request itself, whose start and limit are the deadline."""
    from optik.solvers import api

    seen = []
    real = api.get_method

    class Spy:
        def __init__(self, method):
            self.method = method

        def solve(self, request):
            seen.append(request)
            return self.method.solve(request)

    monkeypatch.setattr(api, "get_method", lambda name: Spy(real(name)) if name == "lm" else real(name))
    res = optik.solve_ik(_jaco_like(), spatial.translation(3.0, 0.0, 0.0), time_limit=0.5)
    assert not res.success and res.method == "lm" and len(seen) == 1
    assert seen[0].time_limit == 0.5  # the deadline is start + 0.5 s: the time left, counted once


def test_a_locked_joint_leaving_the_jaco_chain_gets_the_search() -> None:
    """A 7-joint arm whose first six joints are the Jaco-like chain: with the seventh locked, the
    remaining 6R (special at both ends, no decomposable family) gets the 1-D search, as the
    standalone arm does (issue 18, item 3), its answers flagged as not certified."""
    m = _jaco_like(extra_joint=True)
    q = m.random_q(seed=4)
    target = m.fk(q)
    sols = optik.solve_ik_all(m, target, fixed={"q7": float(q[6])})
    assert sols.method == "closed_form" and not sols.certified and "1-D search" in sols.uncertified_reason
    assert min(np.abs(spatial.angle_distance(s.q, q)) for s in sols) < 1e-9
    for s in sols:
        assert s.q[6] == q[6] and np.abs(m.fk(s.q) - target).max() < 1e-9
