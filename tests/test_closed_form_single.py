"""The single-target path of the closed forms equals the vectorized kernels and the Mechanism API.

``closed_form.ik`` and the ``closed_form`` method solve one target with scalar twins of the
vectorized kernels and wrap / filter the branches with plain floats; here they are compared with
the batched kernels followed by ``Mechanism.wrap`` / ``Mechanism.within_limits`` per branch and
with ``optik.solvers.base.evaluate`` (behaviour only, no timing).
"""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import catalog, closed_form, spatial
from optik.closed_form import ik_planar_2r, ik_planar_3r, ik_pp, ik_rp, registry
from optik.solvers.base import evaluate, joint_distance, make_request

SAME_BRANCH = 1e-4

RAW = {
    "planar_2r": lambda m, t: ik_planar_2r(m.params["lengths"], t[0, 3], t[1, 3]),
    "planar_3r": lambda m, t: ik_planar_3r(m.params["lengths"], *spatial.planar_pose_of(t)),
    "rp_arm": lambda m, t: ik_rp(t[0, 3], t[1, 3]),
    "pp_arm": lambda m, t: ik_pp(t[0, 3], t[1, 3]),
}
"""The scalar single-target kernels and their vectorized twins (the seed 6R arm's registered closed
form is the derived one, cross-checked against ``ik_seed_6r`` in tests/test_derived.py)."""


def arms():
    """Catalog arms, some with limits that make Mechanism.wrap shift angles by 2 pi or 4 pi."""
    out = [
        catalog.planar_2r((1.0, 0.8)),
        catalog.planar_2r((1.0, 1.0)),
        catalog.planar_3r((1.0, 0.8, 0.5)),
        catalog.rp_arm(),
        catalog.pp_arm(),
    ]
    shifted = []
    for m in out:
        lo, hi = m.lower.copy(), m.upper.copy()
        ang = m.revolute_mask
        lo[ang], hi[ang] = 0.0, 2 * np.pi  # angles in [0, 2 pi]: negative branches shift by 2 pi
        if ang.sum() > 1:
            k = np.flatnonzero(ang)[1]
            lo[k], hi[k] = -3 * np.pi, -np.pi  # shift by -2 pi
        shifted.append(m.with_limits(lo, hi))
    return out + shifted


def reference_branches(m, t, respect_limits):
    """The batched kernel, merged by the same-branch rule, then Mechanism.wrap / within_limits per branch."""
    q, ok = RAW[m.kind](m, t)
    kept = []
    for b in np.flatnonzero(ok[0]):
        cand = q[0, b]
        if all(joint_distance(m, cand, prev) >= SAME_BRANCH for prev in kept):
            kept.append(cand)
    wrapped = [m.wrap(c) for c in kept]
    return [w for w in wrapped if not respect_limits or m.within_limits(w)]


def targets(m, rng, n):
    """Reachable targets (FK of random q), random ones (some unreachable) and the base singularity."""
    ts = [m.fk(q) for q in rng.uniform(m.lower, m.upper, size=(n, m.n_q))]
    reach = 1.2 * sum(m.params.get("lengths", (1.0, 1.0)))
    ts += [spatial.planar_pose(*xy, phi) for *xy, phi in rng.uniform(-reach, reach, size=(n, 3))]
    ts.append(spatial.planar_pose(0.0, 0.0, 0.3))  # base singularity
    return ts


@pytest.mark.parametrize("m", arms(), ids=lambda m: f"{m.kind}{tuple(np.round(m.lower[:2], 2))}")
def test_single_target_path_equals_batched_kernel(m):
    rng = np.random.default_rng(7)
    for t in targets(m, rng, 40):
        for respect in (False, True):
            got = closed_form.ik(m, t, respect_limits=respect)
            want = reference_branches(m, t, respect)
            assert len(got) == len(want)
            for g, w in zip(got, want, strict=True):
                assert g.shape == (m.n_q,)
                assert joint_distance(m, g, w) <= 1e-12
                assert np.all(g >= m.lower) and np.all(g <= m.upper) if respect else True


def test_wrap_rows_equals_mechanism_wrap():
    rng = np.random.default_rng(3)
    m = catalog.seed_6r_arm()
    lo = np.array([-np.pi, 0.0, -3 * np.pi, 2 * np.pi, -4.5 * np.pi, -1.0])
    hi = np.array([np.pi, 2 * np.pi, -np.pi, 4 * np.pi, -2.5 * np.pi, 1.0])
    mm = m.with_limits(lo, hi)
    rows = rng.uniform(-15.0, 15.0, size=(200, 6))
    rows[:10] = np.pi
    rows[10:20] = -np.pi
    got = registry.wrap_rows(mm, rows)
    want = [mm.wrap(r) for r in rows]
    np.testing.assert_array_equal(np.array(got), np.array(want))
    assert registry.within_limits(mm, got) == [w.tolist() for w in want if mm.within_limits(w)]


def test_wrap_rows_equals_mechanism_wrap_with_spherical_joints():
    rng = np.random.default_rng(5)
    m = catalog.stewart_gough()
    rows = rng.uniform(m.lower, m.upper, size=(100, m.n_q))
    for sl in m.spherical_slices:
        rows[:, sl] *= rng.uniform(0.5, 4.0, size=(100, 1))  # rotation angles above pi too
    got = registry.wrap_rows(m, rows)
    np.testing.assert_array_equal(np.array(got), np.array([m.wrap(r) for r in rows]))


MECHANISMS = [
    catalog.planar_2r,
    catalog.planar_3r,
    catalog.rp_arm,
    catalog.pp_arm,
    catalog.seed_6r_arm,
    catalog.five_bar,
    catalog.doggy,
    catalog.planar_3rpr,
    catalog.slider_crank,
    catalog.stewart_gough,
]


@pytest.mark.parametrize("make", MECHANISMS, ids=lambda f: f.__name__)
def test_closed_form_method_equals_reference(make):
    """solve_ik(method="closed_form"): the nearest branch within limits, errors as evaluate."""
    m = make()
    rng = np.random.default_rng(11)
    for q in rng.uniform(m.lower, m.upper, size=(30, m.n_q)):
        t = m.fk(q)
        q0 = rng.uniform(m.lower, m.upper)
        res = optik.solve_ik(m, t, q0, method="closed_form")
        inside = closed_form.ik(m, t)
        every = inside or closed_form.ik(m, t, respect_limits=False)
        if every:
            want = min(every, key=lambda b: joint_distance(m, b, q0))
            np.testing.assert_array_equal(res.q, np.clip(m.wrap(want), m.lower, m.upper))
        else:
            assert res.status == "unreachable"
        req = make_request(m, t)
        err = evaluate(m, res.q, req.target, req.task, req.frame)
        assert res.position_error == err.position
        assert res.orientation_error == err.orientation
        assert res.closure_error == err.closure
        assert res.limits_ok == err.limits_ok


def test_answers_on_a_limit_are_not_lost_to_rounding() -> None:
    """Regression (issue 18, item 10): the R-P arm's FK of a slide at its limit came back a hair
    outside it and the branch was dropped (40 of 800 such targets had no branch). One tolerance
    (`registry.LIMIT_TOL`) clips such a coordinate onto the limit; the FK check decides, as the
    success check does; a branch really outside stays outside."""
    m = catalog.rp_arm()
    for a in np.linspace(-3.1, 3.1, 100):
        for r in (m.lower[1], m.upper[1]):
            target = m.fk([a, r])
            branches = closed_form.ik(m, target)
            assert len(branches) == 1 and m.within_limits(branches[0])
            assert joint_distance(m, branches[0], np.array([a, r])) < 1e-12
            assert optik.solve_ik(m, target).success
            sols = optik.solve_ik_all(m, target)
            assert len(sols) == 1 and sols[0].limits_ok
    row = [0.3, float(m.lower[1]) - 10 * registry.LIMIT_TOL]
    assert registry.clip_to_limits(m, row) is None
    inside = registry.clip_to_limits(m, [0.3, float(m.lower[1]) - 0.1 * registry.LIMIT_TOL])
    assert inside == [0.3, float(m.lower[1])]


@pytest.mark.parametrize("flag", ["no", 0, 1, None, "False"])
def test_boolean_options_take_booleans_only(flag: object) -> None:
    """Regression (issue 18, item 10): ``respect_limits="no"`` was taken as True."""
    m = catalog.rp_arm()
    target = m.fk([0.3, 0.5])
    with pytest.raises(optik.OptikError, match=r"^respect_limits"):
        closed_form.ik(m, target, respect_limits=flag)
    with pytest.raises(optik.OptikError, match=r"^closed_form"):
        optik.solve_ik_all(m, target, closed_form=flag)
    five = catalog.five_bar()
    with pytest.raises(optik.OptikError, match=r"^within_limits"):
        optik.solve_fk_all(five, [1.0, 2.0], within_limits=flag)
    with pytest.raises(optik.OptikError, match=r"^respect_limits"):
        closed_form.fk(five, [1.0, 2.0], respect_limits=flag)
    assert closed_form.ik(m, target, respect_limits=np.bool_(False))  # numpy's booleans are booleans
