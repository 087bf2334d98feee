"""``optik.AllSolutions``: every solution of one target as one array, the same rows as
``solve_ik_all(m, T, q0).q``, each re-checked by FK and the limits, the same from many threads,
and the named errors of bad input."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik.closed_form.derived import candidate_groups


def _shifted_seed_arm() -> optik.Mechanism:
    """The seed arm with limits that need the 2 pi shift and drop solutions."""
    m = optik.catalog.seed_6r_arm()
    lo, hi = np.zeros(6), np.full(6, 2 * np.pi)
    lo[1], hi[1] = -3 * np.pi, -np.pi
    return m.with_limits(lo, hi)


ARMS = {"puma560": optik.catalog.puma560(), "seed_6r_arm": optik.catalog.seed_6r_arm(),
        "seed_6r_arm_shifted": _shifted_seed_arm()}  # fmt: skip
SOLVERS: dict[str, optik.AllSolutions] = {}


def _solver(name: str) -> optik.AllSolutions:
    if name not in SOLVERS:
        SOLVERS[name] = optik.AllSolutions(ARMS[name])
    return SOLVERS[name]


def _targets(m: optik.Mechanism, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random joint vectors (the first 8 at the wrist singularity q5 = 0: stand-ins and close
    candidates) and their targets, plus one unreachable target."""
    qs = np.random.default_rng(seed).uniform(-np.pi, np.pi, (40, 6))
    qs[:8, 4] = 0.0
    targets = m.fk(qs)
    far = targets[0].copy()
    far[:3, 3] *= 10.0
    return qs, np.concatenate([targets, far[None]])


@pytest.mark.parametrize("name", list(ARMS))
def test_rows_are_those_of_solve_ik_all(name: str) -> None:
    """Bit for bit the rows of solve_ik_all(m, T, q0).q and its outside_limits, nearest q0
    first; every row passes an independent FK and limit check."""
    m, ik = ARMS[name], _solver(name)
    if not ik.compiled:
        pytest.skip("no C compiler: every call is solve_ik_all")
    _, targets = _targets(m, 1)
    starts = np.random.default_rng(2).uniform(-np.pi, np.pi, (len(targets), 6))
    for t, q0 in zip(targets, starts, strict=True):
        for start in (None, q0):
            want = optik.solve_ik_all(m, t, start)
            q, outside = ik(t, start, outside=True)
            assert q.shape == (len(want), 6) and q.dtype == np.float64
            np.testing.assert_array_equal(q, want.q.reshape(-1, 6))
            np.testing.assert_array_equal(outside, np.array(want.outside_limits).reshape(-1, 6))
            np.testing.assert_array_equal(ik(t, start), q)
            for row in q:
                assert m.within_limits(row)
                np.testing.assert_allclose(m.fk(row), t, atol=1e-9)
    assert ik(targets[-1]).shape == (0, 6)  # unreachable: no solution, an empty (0, 6) array


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    st.lists(st.floats(-np.pi, np.pi), min_size=5, max_size=5),
    st.floats(0.05, np.pi - 0.05),
    st.sampled_from([-1.0, 1.0]),
)
def test_every_branch_round_trips(q: list[float], q5: float, sign: float) -> None:
    """The joint vector a target was made from is one of the solutions (after the 2 pi shift
    into the limits), and every solution reproduces the target (away from the wrist
    singularity q5 = 0 or pi, where the solutions form a family and one stands for it)."""
    m, ik = ARMS["seed_6r_arm"], _solver("seed_6r_arm")
    q = [*q[:4], sign * q5, q[4]]
    t = m.fk(np.array(q))
    sols = ik(t)
    assert len(sols)
    for row in sols:
        np.testing.assert_allclose(m.fk(row), t, atol=1e-9)
    gap = np.abs((sols - m.wrap(np.array(q)) + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
    assert gap.min() < 1e-6


def test_threads_give_the_same_answers() -> None:
    """One object called from two threads at once: every answer as from one thread."""
    m, ik = ARMS["seed_6r_arm"], _solver("seed_6r_arm")
    _, targets = _targets(m, 3)
    many = np.concatenate([targets] * 5)
    want = [ik(t) for t in many]
    with ThreadPoolExecutor(2) as pool:
        got = list(pool.map(ik, many))
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def test_any_layout_and_a_mechanism_without_a_compiled_closed_form() -> None:
    """Targets of another layout or type take the general path (same rows); a mechanism whose
    closed form is not a derived one answers by solve_ik_all alone, as an (K, n) array."""
    m, ik = ARMS["puma560"], _solver("puma560")
    t = m.fk(m.random_q(seed=4))
    want = ik(t)
    for other in (np.asfortranarray(t), t.tolist(), t[::-1, ::-1][::-1, ::-1], np.ascontiguousarray(t.T).T):
        np.testing.assert_array_equal(ik(other), want)
    arm = optik.catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    planar = optik.AllSolutions(arm)
    assert not planar.compiled
    target = optik.Pose2D(1.2, 0.4, 0.3)
    q, outside = planar(target, outside=True)
    sols = optik.solve_ik_all(arm, target)
    np.testing.assert_array_equal(q, sols.q.reshape(-1, 3))
    assert q.shape[1] == 3 and outside.shape == (len(sols.outside_limits), 3)


def test_bad_input_raises_the_named_error() -> None:
    m, ik = ARMS["puma560"], _solver("puma560")
    t = m.fk(m.mid_q())
    bad = t.copy()
    bad[0, 0] = np.nan
    with pytest.raises(optik.NonFiniteError, match=r"^target"):
        ik(bad)
    skew = t.copy()
    skew[:3, :3] *= 1.1
    with pytest.raises(optik.InvalidArgumentError, match=r"^target"):
        ik(skew)
    with pytest.raises(optik.ShapeError, match=r"^target"):
        ik(np.eye(3))
    with pytest.raises(optik.NonFiniteError, match=r"^q0"):
        ik(t, np.full(6, np.inf))
    with pytest.raises(optik.ShapeError, match=r"^q0"):
        ik(t, np.zeros(5))
    with pytest.raises(optik.InvalidArgumentError, match=r"^m"):
        optik.AllSolutions("puma560")  # type: ignore[arg-type]


def test_candidate_groups_split_the_stand_ins_in_runs() -> None:
    """The regular candidates first, then each run of consecutive stand-ins (one per (q1, q5)
    pair of the three-parallel family); no stand-in: one group."""
    three_parallel = optik.closed_form.derived.three_parallel.stand_ins(16)
    assert candidate_groups(three_parallel) == [
        (0, 1, 4, 5, 8, 9, 12, 13), (2, 3), (6, 7), (10, 11), (14, 15)]  # fmt: skip
    assert candidate_groups((-1,) * 8) == [tuple(range(8))]


@pytest.mark.parametrize("name", ["puma560", "seed_6r_arm"])
def test_driver_errors_are_those_of_an_independent_fk(name: str) -> None:
    """The FK check of the compiled driver (its own cosines and sines of the candidates'
    angles, `optik_sincos` of ik_all.c) reports the errors that the mechanism's FK gives for
    the returned q, to rounding: a cosine off by more than a few ulp would show here."""
    from optik.solvers.closed import binding_of

    m = ARMS[name]
    _solver(name)
    fast = binding_of(m)
    if fast is None:
        pytest.skip("no C compiler: no driver")
    qs = np.random.default_rng(6).uniform(-4 * np.pi, 4 * np.pi, (300, 6))  # raw angles of several turns
    checked = 0
    for t in m.fk(qs):
        got = fast(t, None, m.lower, m.upper, True)
        if not got:
            continue
        for q, (pos, ori) in zip(got[0], got[1], strict=True):
            f = m.fk(q)
            rel = f[:3, :3] @ t[:3, :3].T
            skew = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
            angle = np.arctan2(0.5 * np.linalg.norm(skew), 0.5 * (np.trace(rel) - 1.0))
            assert abs(pos - np.linalg.norm(f[:3, 3] - t[:3, 3])) <= 1e-14
            assert abs(ori - angle) <= 1e-14
            checked += 1
    assert checked >= 300  # at least the one each target was made from


def test_without_a_compiler_every_call_is_solve_ik_all(monkeypatch: pytest.MonkeyPatch) -> None:
    """No C compiler: the object says so and answers by solve_ik_all (CasADi's evaluator)."""
    from optik import native

    monkeypatch.setattr(native, "compiler", lambda: None)
    arm = optik.catalog.seed_6r_arm(0.9, 0.7, 0.25)  # a new mechanism: its own derived solver
    ik = optik.AllSolutions(arm)
    assert not ik.compiled
    for t in arm.fk(arm.random_q(5, seed=1)):
        q = ik(t)
        assert q.shape[1] == 6 and len(q)
        np.testing.assert_array_equal(q, optik.solve_ik_all(arm, t).q)


def test_no_solution_is_an_empty_row_array_on_every_path() -> None:
    """An unreachable target gives ``q`` of shape ``(0, n)`` whichever path answered: a
    compiled closed form, a closed form's rows (the planar 3R), the numerical multi-start and
    a locked joint (the Panda); ``AllSolutions`` of a mechanism without a compiled closed form
    answers ``(0, n)`` too."""
    far = np.eye(4)
    far[:3, 3] = 50.0
    panda, planar = optik.catalog.panda(), optik.catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    cases = {
        "compiled closed form": (ARMS["seed_6r_arm"], far, {}),
        "closed-form rows": (planar, optik.Pose2D(50.0, 0.0, 0.3), {}),
        "numerical multi-start": (panda, far, {"method": "lm", "time_limit": 0.05}),
        "locked joint": (panda, far, {"fixed": {"q1": 0.3}, "time_limit": 0.05}),
    }
    for name, (m, target, options) in cases.items():
        sols = optik.solve_ik_all(m, target, **options)
        assert len(sols) == 0, name
        assert sols.q.shape == (0, m.n_q), name
    assert optik.AllSolutions(planar)(optik.Pose2D(50.0, 0.0, 0.3)).shape == (0, 3)
