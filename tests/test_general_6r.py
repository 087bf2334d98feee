"""General 6R IK (optik.closed_form.general_6r): round trips on random arms, the 16-solution
count check, a certified 16-real-solution reference arm, completeness against a numerical
multi-start, degenerate and malformed input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares

import optik
from optik import catalog, closed_form, spatial
from optik.closed_form import derived, registry, search_1d
from optik.closed_form.general_6r import (
    FK_TOL,
    General6R,
    General6RSolutions,
    covers,
    ik_general_6r,
    solve_general_6r,
)
from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError
from optik.mechanism import Joint, Mechanism, dh_chain
from optik.spatial import angle_distance

# A 6R arm and a pose with 16 real solutions (the most a 6R can have), found by a random search
# over arms and poses with this solver (`optik benchmark general_6r --search-16`), parameters
# rounded to two decimals; standard DH rows (d, a, alpha).
REF_DH = [
    (0.57, 1.40, -1.49),
    (1.70, 0.36, -2.25),
    (1.69, 0.77, 2.05),
    (1.32, 1.61, -0.39),
    (-0.96, 0.95, 1.99),
    (0.35, 1.82, 2.35),
]
REF_Q = np.array([0.86, 0.99, -0.84, -2.66, -0.31, 0.22])


def _random_arm(rng: np.random.Generator) -> Mechanism:
    """Random standard DH rows: no two axes parallel or intersecting (with probability one)."""
    rows = [(rng.uniform(-1, 1), rng.uniform(0.1, 1), rng.uniform(-np.pi, np.pi)) for _ in range(6)]
    return dh_chain(rows, "standard")


def _check_fk(m: Mechanism, sols: General6RSolutions, target: np.ndarray) -> None:
    """Every returned q reproduces the target by the mechanism's own FK, recomputed here."""
    for q in sols.q:
        t = m.fk(q)
        assert np.linalg.norm(t[:3, 3] - target[:3, 3]) <= FK_TOL * 2
        assert spatial.angle_between(t[:3, :3], target[:3, :3]) <= FK_TOL
        assert np.all(q > -np.pi) and np.all(q <= np.pi)


def test_round_trips_on_random_arms() -> None:
    rng = np.random.default_rng(12)
    counts = []
    for _ in range(12):
        m = _random_arm(rng)
        qs = rng.uniform(-np.pi, np.pi, (3, 6))
        targets = m.fk(qs)
        for q, target, sols in zip(qs, targets, solve_general_6r(m, targets), strict=True):
            assert sols.count_ok, sols.reason
            assert sols.n_finite == 16
            assert len(sols.q) + sols.n_complex == 16
            assert len(sols.q) % 2 == 0 and 2 <= len(sols.q) <= 16
            assert min(angle_distance(s, q) for s in sols.q) < 1e-8
            _check_fk(m, sols, target)
            # distinct solutions
            assert all(angle_distance(a, b) > 1e-6 for i, a in enumerate(sols.q) for b in sols.q[:i])
            counts.append(len(sols.q))
    assert len(set(counts)) >= 3  # the random arms really differ (2, 4, 6, ... real solutions)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_round_trip_property(seed: int) -> None:
    """Random generic arms (a General6R, no mechanism) from a drawn seed: hypothesis shrinks
    numbers toward special values (zero offsets, equal twists), which are not general arms."""
    rng = np.random.default_rng(seed)
    arm = General6R(a=rng.uniform(0.05, 2, 6), alpha=rng.uniform(-np.pi, np.pi, 6), d=rng.uniform(-2, 2, 6))
    q = rng.uniform(-np.pi, np.pi, 6)
    target = arm.fk(q)
    sols = solve_general_6r(arm, target)
    assert sols.count_ok, sols.reason
    assert len(sols.q) <= 16 and len(sols.q) % 2 == 0
    assert min(angle_distance(s, q) for s in sols.q) < 1e-8
    for s in sols.q:
        dp = np.linalg.norm(arm.fk(s)[:3, 3] - target[:3, 3]) / arm.scale
        assert dp <= FK_TOL and spatial.angle_between(arm.fk(s)[:3, :3], target[:3, :3]) <= FK_TOL


def test_reference_arm_with_16_real_solutions() -> None:
    m = dh_chain(REF_DH, "standard")
    target = m.fk(REF_Q)
    sols = solve_general_6r(m, target)
    assert sols.count_ok and sols.n_complex == 0
    assert len(sols.q) == 16  # 16 distinct verified real solutions: all of them (Bezout bound)
    _check_fk(m, sols, target)
    assert min(angle_distance(a, b) for i, a in enumerate(sols.q) for b in sols.q[:i]) > 0.1
    assert min(angle_distance(s, REF_Q) for s in sols.q) < 1e-8


def test_numerical_multistart_finds_nothing_more() -> None:
    """Independent completeness evidence: Gauss-Newton from random starts on ``m.fk`` converges
    only to solutions in the returned set."""
    m = dh_chain(REF_DH, "standard")
    target = m.fk(REF_Q)
    sols = solve_general_6r(m, target).q
    rng = np.random.default_rng(3)

    def residual(q: np.ndarray) -> np.ndarray:
        return spatial.pose_error(m.fk(q), target)

    found = 0
    for q0 in rng.uniform(-np.pi, np.pi, (25, 6)):
        r = least_squares(residual, q0, xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)
        if np.linalg.norm(r.fun) < 1e-10:
            found += 1
            assert min(angle_distance(s, r.x) for s in sols) < 1e-6
    assert found >= 5


def test_general_joint_frames_base_and_tool() -> None:
    """Axes in arbitrary directions through arbitrary points, a fixed joint in the chain, a tool
    frame: the DH description is derived from the joint lines and reproduces m.fk."""
    rng = np.random.default_rng(5)
    joints, parent = [], "base"
    for i in range(6):
        origin = spatial.transform(
            spatial.rpy_to_rot(*rng.uniform(-np.pi, np.pi, 3)), rng.uniform(-0.5, 0.5, 3)
        )
        joints.append(Joint(f"j{i}", "revolute", parent, f"b{i}", origin=origin, axis=rng.normal(size=3)))
        parent = f"b{i}"
        if i == 2:
            joints.append(Joint("fix", "fixed", parent, "bf", origin=spatial.translation(0.1, 0.2, 0.3)))
            parent = "bf"
    tool = spatial.transform(spatial.rot_x(0.4), [0.1, 0.0, 0.2])
    m = Mechanism(joints, frames={"tool": (parent, tool)}, ee="tool")
    for q in rng.uniform(-np.pi, np.pi, (3, 6)):
        target = m.fk(q)
        sols = solve_general_6r(m, target)
        assert sols.count_ok, sols.reason
        assert min(angle_distance(s, q) for s in sols.q) < 1e-8
        _check_fk(m, sols, target)
    assert isinstance(ik_general_6r(m, target), list)


def test_batch_matches_single_targets() -> None:
    m = _random_arm(np.random.default_rng(8))
    targets = m.fk(np.random.default_rng(9).uniform(-np.pi, np.pi, (4, 6)))
    batch = solve_general_6r(m, targets)
    assert isinstance(batch, list) and len(batch) == 4
    for t, b in zip(targets, batch, strict=True):
        one = solve_general_6r(m, t)
        assert len(one.q) == len(b.q)
        assert all(min(angle_distance(x, y) for y in b.q) < 1e-9 for x in one.q)


@settings(max_examples=20, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1))
def test_checked_rows_carry_the_fk_errors_of_each_solution(seed: int) -> None:
    """A certified answer reaches the solvers layer as `registry.CheckedRows` whose errors are
    each row's position and orientation errors by ``m.fk`` (evaluated here independently), and
    `optik.solve_ik_all` reports those errors for the same solutions."""
    from optik.solvers.base import task_errors

    rng = np.random.default_rng(seed)
    m = _random_arm(rng)
    target = m.fk(rng.uniform(-np.pi, np.pi, 6))
    rows = ik_general_6r(m, target)
    assert isinstance(rows, registry.CheckedRows) and rows.wrapped
    assert np.array_equal(np.array(rows).reshape(-1, 6), solve_general_6r(m, target).q)
    for row, (pos, ori) in zip(rows, rows.errors, strict=True):
        ref = task_errors("pose", m.fk(row), target)
        assert abs(pos - ref[0]) < 1e-15 and abs(ori - ref[1]) < 1e-14
    found = optik.solve_ik_all(m, target)
    assert found.certified and len(found) == len(rows)
    for r in found:
        assert abs(r.position_error - task_errors("pose", m.fk(r.q), target)[0]) < 1e-15


def test_unreachable_pose_is_an_empty_answer_with_a_reason() -> None:
    m = dh_chain(REF_DH, "standard")
    far = spatial.translation(50.0, 0.0, 0.0)
    sols = solve_general_6r(m, far)
    assert len(sols.q) == 0 and sols.reason
    assert ik_general_6r(m, far) == []


@pytest.mark.parametrize("special", ["a1 = 0", "alpha1 = 0"])
def test_first_axes_intersecting_or_parallel(special: str) -> None:
    """Axes 1-2 intersecting or parallel make the elimination singular from the base end; the
    solver then solves the inverse chain from the other end (count check passes there)."""
    rng = np.random.default_rng(21)
    for _ in range(3):
        a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
        (a if special == "a1 = 0" else alpha)[0] = 0.0
        arm = General6R(a=a, alpha=alpha, d=d)
        q = rng.uniform(-np.pi, np.pi, 6)
        sols = solve_general_6r(arm, arm.fk(q))
        assert sols.count_ok, sols.reason
        assert min(angle_distance(s, q) for s in sols.q) < 1e-8
        assert sols.fk_error <= FK_TOL


def test_batch_through_the_inverse_chain() -> None:
    """Stacked targets on a mechanism whose axes 1-2 intersect: every target goes through the
    inverse chain, and each answer belongs to its own target."""
    rng = np.random.default_rng(23)
    rows = [(rng.uniform(-1, 1), rng.uniform(0.1, 1), rng.uniform(-np.pi, np.pi)) for _ in range(6)]
    rows[0] = (rows[0][0], 0.0, rows[0][2])
    m = dh_chain(rows, "standard")
    qs = rng.uniform(-np.pi, np.pi, (5, 6))
    targets = m.fk(qs)
    for q, target, sols in zip(qs, targets, solve_general_6r(m, targets), strict=True):
        assert sols.count_ok, sols.reason
        assert min(angle_distance(s, q) for s in sols.q) < 1e-8
        _check_fk(m, sols, target)


def test_nearly_parallel_axes_are_polished_on_the_mechanism() -> None:
    """Axes 1-2 at 1e-4 rad from parallel (large DH offsets on the common normal, and the
    inverse chain's DH description loses digits): every drawn q comes back to 1e-8, checked by
    ``m.fk``."""
    rng = np.random.default_rng(31)
    rows = [(rng.uniform(-1, 1), rng.uniform(0.1, 1), rng.uniform(-np.pi, np.pi)) for _ in range(6)]
    rows[0] = (rows[0][0], rows[0][1], 1e-4)
    rows[4] = (rows[4][0], rows[4][1], 1e-7)  # and axes 5-6 within 1e-7 (a URDF's rounding)
    m = dh_chain(rows, "standard")
    for q in rng.uniform(-np.pi, np.pi, (4, 6)):
        sols = solve_general_6r(m, m.fk(q))
        assert sols.count_ok, sols.reason
        assert min(angle_distance(s, q) for s in sols.q) < 1e-8
        _check_fk(m, sols, m.fk(q))


def test_both_ends_special_is_flagged() -> None:
    """Axes 1-2 and 5-6 intersecting (a Jaco-like arm without a spherical wrist): the
    elimination is singular from both ends; the answer is flagged, and what it holds is verified."""
    rng = np.random.default_rng(41)
    a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
    a[[0, 4]] = 0.0
    arm = General6R(a=a, alpha=alpha, d=d)
    target = arm.fk(rng.uniform(-np.pi, np.pi, 6))
    sols = solve_general_6r(arm, target)
    assert not sols.count_ok and "singular 12 x 12" in sols.reason and "other end" in sols.reason
    assert "from a generic arm" in sols.reason
    assert sols.fk_error <= FK_TOL
    assert not covers(arm)


def test_registry_routes_only_covered_arms() -> None:
    """The closed-form registry answers a generic 6R arm by this solver, and not an arm with
    special geometry at both ends (no certified answer): that one gets the 1-D search
    (`optik.closed_form.search_1d`, tests/test_search_1d.py)."""
    rng = np.random.default_rng(47)
    generic = _random_arm(rng)
    assert closed_form.has_ik(generic)
    q = rng.uniform(-np.pi, np.pi, 6)
    branches = closed_form.ik(generic, generic.fk(q), respect_limits=False)
    assert min(angle_distance(s, q) for s in branches) < 1e-8
    rows = [(rng.uniform(-1, 1), rng.uniform(0.1, 1), rng.uniform(-np.pi, np.pi)) for _ in range(6)]
    rows[0], rows[4] = (rows[0][0], 0.0, rows[0][2]), (rows[4][0], 0.0, rows[4][2])  # 1-2, 5-6 meet
    special = dh_chain(rows, "standard")
    assert closed_form.derive(special) is None and not covers(special)
    assert derived.general_rows(special) is None and search_1d.search_rows(special) is not None


def test_covers() -> None:
    rng = np.random.default_rng(43)
    assert covers(_random_arm(rng))
    a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
    a[0] = 0.0  # one special end: the other end is regular
    assert covers(General6R(a=a, alpha=alpha, d=d))
    alpha[[3, 4]] = 0.0  # and axes 4, 5, 6 parallel at the other
    assert not covers(General6R(a=a, alpha=alpha, d=d))
    assert not covers(dh_chain(REF_DH[:5], "standard"))  # not a 6R chain: False, no exception


@pytest.mark.parametrize("twist", [1e-4, 1e-6, 1e-8])
def test_nearly_parallel_axes_at_both_ends(twist: float) -> None:
    """Axes 1-2 and 5-6 within 1e-4 rad of parallel: the DH frames stay orthonormal (building
    the inverse chain raised before), the inverse chain's DH description is only approximate,
    and every returned solution is still polished on the arm itself and verified."""
    rng = np.random.default_rng(51)
    a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
    alpha[[0, 4]] = twist
    arm = General6R(a=a, alpha=alpha, d=d)
    q = rng.uniform(-np.pi, np.pi, (4, 6))
    assert np.allclose(arm.reversed.fk(q[:, ::-1]), np.linalg.inv(arm.fk(q)), atol=1e-3)
    sols = solve_general_6r(arm, arm.fk(q))
    assert all(s.fk_error <= FK_TOL for s in sols)
    for qi, sol in zip(q, sols, strict=True):  # an empty answer fails here, not in min()
        assert np.min(angle_distance(sol.q, qi), initial=np.inf) < 1e-8, sol.reason


def test_drifted_real_roots_are_polished_back_not_called_complex() -> None:
    """Axes 1-2 and 5-6 at 1e-6 rad from parallel make the pencil nearly singular: eigenvalues of
    real solutions drift up to 0.5 rad into the complex plane (before, 0 solutions of a
    reachable target were certified complete on 39 of 300 targets). Polished in complex space
    they come back to the real axis; every target's drawn configuration is among the answers,
    and a certified answer's real and complex solutions add up to 16."""
    rng = np.random.default_rng(51)
    a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
    alpha[[0, 4]] = 1e-6
    arm = General6R(a=a, alpha=alpha, d=d)
    q = np.random.default_rng(7).uniform(-np.pi, np.pi, (60, 6))
    sols = solve_general_6r(arm, arm.fk(q))
    for qi, sol in zip(q, sols, strict=True):
        assert np.min(angle_distance(sol.q, qi), initial=np.inf) < 1e-8, (sol.count_ok, sol.reason)
        assert sol.fk_error <= FK_TOL
        assert not sol.count_ok or len(sol.q) + sol.n_complex == 16


def test_reversed_chain_is_the_inverse() -> None:
    arm = General6R(a=[0.3, 0.5, 0.2, 0.4, 0.1, 0.6], alpha=[1.0, -0.5, 2.0, 0.7, -1.2, 0.3], d=[0.1] * 6)
    q = np.random.default_rng(2).uniform(-np.pi, np.pi, (4, 6))
    assert np.allclose(arm.reversed.fk(q[:, ::-1]), np.linalg.inv(arm.fk(q)), atol=1e-12)


def test_special_geometry_is_flagged_and_matches_the_closed_form() -> None:
    """The seed's 6R arm (parallel axes 2-3-4 and a spherical wrist: 8 solutions) is not a
    general arm: the count check fails and says so. The solutions continued from a nearby
    generic arm are exactly the branches of the seed's closed form (an independent reference)."""
    m = catalog.seed_6r_arm()
    rng = np.random.default_rng(0)
    for q in rng.uniform(-np.pi, np.pi, (4, 6)):
        target = m.fk(q)
        sols = solve_general_6r(m, target)
        assert not sols.count_ok and "count check failed" in sols.reason and "not certified" in sols.reason
        _check_fk(m, sols, target)
        ref = closed_form.ik(m, target, respect_limits=False)
        assert len(sols.q) == len(ref)
        assert all(min(angle_distance(s, r) for s in sols.q) < 1e-8 for r in ref)


def test_bad_input_raises_named_errors() -> None:
    m = dh_chain(REF_DH, "standard")
    with pytest.raises(ShapeError, match="target"):
        solve_general_6r(m, np.eye(3))
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(NonFiniteError, match="target"):
        solve_general_6r(m, bad)
    with pytest.raises(InvalidArgumentError, match="m"):
        solve_general_6r(dh_chain(REF_DH[:5], "standard"), np.eye(4))
    with pytest.raises(InvalidArgumentError, match="six revolute"):
        solve_general_6r(dh_chain(REF_DH, "standard", types="RRPRRR"), np.eye(4))
    with pytest.raises(InvalidArgumentError, match="arm"):
        solve_general_6r("arm", np.eye(4))  # type: ignore[arg-type]
    with pytest.raises(ShapeError, match="a"):
        General6R(a=[1.0] * 5, alpha=[0.5] * 6, d=[0.0] * 6)


def test_default_solve_ik_tries_lm_before_the_costly_general_solver() -> None:
    """The general 6R solver takes tens of ms, ``lm`` a fraction of one: ``method=None`` answers
    by ``lm`` when it succeeds, by the (certified) closed form when it does not, and
    ``method="closed_form"`` still gets the closed form."""
    m = dh_chain(REF_DH, "standard")
    assert registry.costly(m) and not registry.costly(catalog.puma560())
    for q in np.random.default_rng(3).uniform(-np.pi, np.pi, (4, 6)):
        target = m.fk(q)
        res = optik.solve_ik(m, target, time_limit=1.0)
        assert res.method == "lm" and res.success
        np.testing.assert_allclose(m.fk(res.q), target, atol=1e-6)  # independent FK check
        assert optik.solve_ik(m, target, method="closed_form").method == "closed_form"
    far = spatial.translation(50.0, 0.0, 0.0)
    res = optik.solve_ik(m, far, time_limit=0.02)
    assert res.method == "closed_form" and not res.success and "lm found no solution" in res.message
    assert res.extra["lm"]["status"] != "solved"


def test_solve_ik_does_not_call_a_reachable_target_unreachable() -> None:
    """Regression (issue 18, item 2): on the mechanism of the 1e-6 twist arm, ``solve_ik`` by the
    closed form answered "unreachable" (certified) for FK targets of configurations within the
    limits. Now every such target is solved, by the closed form asked for and by default."""
    rng = np.random.default_rng(51)
    a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
    alpha[[0, 4]] = 1e-6
    m = dh_chain([(d[i], a[i], alpha[i]) for i in range(6)], "standard")
    for q in m.random_q(40, seed=7):
        target = m.fk(q)
        res = optik.solve_ik(m, target, method="closed_form")
        assert res.success and res.status == "solved", res.message
        assert np.abs(m.fk(res.q) - target).max() < 1e-9  # independent FK check
        assert optik.solve_ik(m, target).success


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.booleans())
def test_distinct_is_dedup_per_target(seed: int, n: int, complex_rows: bool) -> None:
    """`_distinct` (all targets at once) keeps exactly the rows that `_dedup` keeps of each
    target's rows in their order: with owners out of order, copies within 1e-9, copies shifted
    by 2 pi, and chains of rows 0.6e-6 apart (the second dropped, the third kept)."""
    from optik.closed_form import general_6r as g6

    rng = np.random.default_rng(seed)
    rows = rng.uniform(-np.pi, np.pi, (int(rng.integers(0, 20)), 6)).astype(
        complex if complex_rows else float
    )
    if complex_rows:
        rows += 1j * rng.normal(size=rows.shape) * (rng.uniform(size=(len(rows), 1)) < 0.5)
    picks = rng.integers(0, max(len(rows), 1), size=int(rng.integers(0, 6))) if len(rows) else []
    extra = [
        rows[i] + rng.choice([1e-9, 2.0 * np.pi, 0.6e-6, 1.2e-6]) * (np.arange(6) == rng.integers(6))
        for i in picks
    ]
    rows = np.concatenate([rows, *[e[None] for e in extra]]) if extra else rows
    owner = rng.integers(0, n, size=len(rows))
    got = g6._distinct(rows, owner, n)
    assert len(got) == n
    for k in range(n):
        ref = g6._dedup(rows[owner == k])
        assert np.all(owner[got[k]] == k)
        assert rows[got[k]].shape == ref.shape and np.array_equal(rows[got[k]], ref)
