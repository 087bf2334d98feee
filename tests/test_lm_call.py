"""The prepared call of "lm" (`optik.solvers.lm.LMCall`): the later `solve_ik` calls with the
same options answer as the general path, and refuse bad input with the same named errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import optik
from optik import native
from optik.checks import as_transform
from optik.errors import InvalidArgumentError, NonFiniteError, ShapeError
from optik.solvers import api
from optik.solvers.base import make_request
from optik.solvers.lm import LMCall, solve_lm

M = optik.catalog.panda()
OPTIONS = {"time_limit": 0.5, "tol": 1e-5}


def _warm(m: optik.Mechanism, **options: object) -> LMCall:
    """The prepared call of ``m`` with ``options``, once its library is loaded."""
    optik.solve_ik(m, m.fk(m.mid_q()), method="lm", **options)
    native.wait()
    calls = [c for c in api._CALLS.get(m, {}).values() if isinstance(c, LMCall)]
    assert calls and calls[-1].kernel.call_entry() is not None
    return calls[-1]


def _same(a: optik.IKResult, b: optik.IKResult) -> None:
    np.testing.assert_array_equal(a.q, b.q)
    assert (a.success, a.status, a.message, a.iterations, a.restarts, a.limits_ok) == (
        b.success, b.status, b.message, b.iterations, b.restarts, b.limits_ok
    )  # fmt: skip
    assert (a.position_error, a.orientation_error, a.closure_error) == (
        b.position_error, b.orientation_error, b.closure_error
    )  # fmt: skip
    assert a.extra == b.extra and a.method == b.method == "lm"


def test_prepared_calls_answer_as_the_general_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """Reachable targets from random starts (restarts happen), unreachable ones with a restart
    cap (failures), and an answer outside ``(-pi, pi)`` that is wrapped: the prepared call gives
    the general path's result field by field, without building a request (the general path's
    `make_request` is not called)."""
    wide = M.with_limits(lower=np.r_[-2 * math.pi, M.lower[1:]], upper=np.r_[2 * math.pi, M.upper[1:]])
    far = np.eye(4)
    far[:3, 3] = [2.0, 0.0, 0.5]
    q_out = wide.mid_q()
    q_out[0] = 3.5  # within the wide limits, not canonical: wrapped to 3.5 - 2 pi
    cases = [(M, t, q, {}) for t, q in zip(M.fk(M.random_q(12, seed=1)), M.random_q(12, seed=2), strict=True)]
    cases += [(M, far, M.mid_q(), {"max_restarts": 2}), (wide, wide.fk(q_out), q_out, {})]
    for m, _, _, opts in cases:
        _warm(m, **OPTIONS, **opts)
    general = []
    for i, (m, t, q0, opts) in enumerate(cases):
        request = make_request(m, t, q0, None, None, OPTIONS["time_limit"], OPTIONS["tol"], i, opts)
        general.append(solve_lm(request))

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the general path was taken")

    monkeypatch.setattr(api, "make_request", refuse)
    for i, ((m, t, q0, opts), want) in enumerate(zip(cases, general, strict=True)):
        _same(optik.solve_ik(m, t, q0, method="lm", seed=i, **OPTIONS, **opts), want)
    assert sum(r.restarts for r in general) > 0 and not general[-2].success and general[-1].success
    assert general[-1].q[0] == pytest.approx(3.5 - 2 * math.pi)


def test_an_answer_beyond_pi_within_short_limits_is_canonical_in_c(monkeypatch: pytest.MonkeyPatch) -> None:
    """The Panda's joint 6 (limits about ``[-0.02, 3.75]``, less than a turn) is its own wrap
    anywhere within its limits: the C call's canonical test (the bands of `Settings.conf`) calls
    an answer with ``q6 = 3.5`` canonical, so the prepared call returns it without the general
    result code, equal to the general path's result (the ``wide`` case of the test above checks
    the other side: 3.5 within limits that span more than a turn is wrapped)."""
    from optik.solvers import lm

    q = M.mid_q()
    q[5] = 3.5
    target = M.fk(q)
    call = _warm(M, **OPTIONS)
    want = solve_lm(make_request(M, target, q, None, None, OPTIONS["time_limit"], OPTIONS["tol"], 0, {}))

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the general result code was taken")

    monkeypatch.setattr(lm, "lm_result", refuse)
    got = optik.solve_ik(M, target, q, method="lm", seed=0, **OPTIONS)
    _same(got, want)
    assert got.success and got.q[5] > math.pi
    assert call._local.one.counts.tolist()[3] == 1  # the C call's own canonical flag


def test_list_starts_and_generator_seeds_take_the_prepared_call(monkeypatch: pytest.MonkeyPatch) -> None:
    """A ``q0`` given as a list or tuple and a seed given as a numpy Generator are solved by the
    prepared call too (no request built), with the general path's answer: the start converted
    as `optik.Mechanism.check_q` converts it and one draw from the Generator, which is left in
    the general path's state."""
    _warm(M, **OPTIONS)
    targets, starts = M.fk(M.random_q(6, seed=5)), M.random_q(6, seed=6)
    general, after = [], []
    for i, (t, q0) in enumerate(zip(targets, starts, strict=True)):
        rng = np.random.default_rng(i)
        general.append(
            solve_lm(make_request(M, t, q0, None, None, OPTIONS["time_limit"], OPTIONS["tol"], rng, {}))
        )
        after.append(rng.integers(2**63))

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the general path was taken")

    monkeypatch.setattr(api, "make_request", refuse)
    for i, (t, q0) in enumerate(zip(targets, starts, strict=True)):
        rng = np.random.default_rng(i)
        start = q0.tolist() if i % 2 else tuple(q0.tolist())
        _same(optik.solve_ik(M, t, start, method="lm", seed=rng, **OPTIONS), general[i])
        assert rng.integers(2**63) == after[i]
    assert sum(r.restarts for r in general) > 0  # the drawn seeds were used


def _bad_rotation() -> np.ndarray:
    t = M.fk(M.mid_q())
    t[:3, 0] *= 1.001
    return t


def _reflection() -> np.ndarray:
    t = M.fk(M.mid_q())
    t[:3, 2] *= -1.0
    return t


def _bad_row() -> np.ndarray:
    t = M.fk(M.mid_q())
    t[3, 0] = 1e-3
    return t


def _with(t: np.ndarray, i: tuple[int, int], v: float) -> np.ndarray:
    t = t.copy()
    t[i] = v
    return t


@pytest.mark.parametrize(
    ("target", "q0", "seed", "error", "argument"),
    [
        (_with(M.fk(M.mid_q()), (0, 3), math.nan), None, None, NonFiniteError, "target"),
        (_with(M.fk(M.mid_q()), (1, 1), math.inf), None, None, NonFiniteError, "target"),
        (_bad_rotation(), None, None, InvalidArgumentError, "target"),
        (_reflection(), None, None, InvalidArgumentError, "target"),
        (_bad_row(), None, None, InvalidArgumentError, "target"),
        (np.eye(3), None, None, ShapeError, "target"),
        (M.fk(M.mid_q()), np.r_[M.mid_q()[:-1], math.nan], None, NonFiniteError, "q0"),
        (M.fk(M.mid_q()), np.r_[M.mid_q(), 0.0], None, ShapeError, "q0"),
        (M.fk(M.mid_q()), [*M.mid_q()[:-1].tolist(), math.nan], None, NonFiniteError, "q0"),
        (M.fk(M.mid_q()), M.mid_q()[:-1].tolist(), None, ShapeError, "q0"),
        (M.fk(M.mid_q()), ["a"] * M.n_q, None, InvalidArgumentError, "q0"),
        (_bad_rotation(), M.mid_q().tolist(), np.random.default_rng(0), InvalidArgumentError, "target"),
        (M.fk(M.mid_q()), None, -1, InvalidArgumentError, "seed"),
        (M.fk(M.mid_q()), None, 1.5, InvalidArgumentError, "seed"),
    ],
)
def test_bad_input_is_refused_after_the_call_is_prepared(target, q0, seed, error, argument) -> None:
    _warm(M, **OPTIONS)
    with pytest.raises(error) as info:
        optik.solve_ik(M, target, q0, method="lm", seed=seed, **OPTIONS)
    assert info.value.argument == argument


def _checked(t: np.ndarray) -> bool:
    try:
        as_transform(t, "target")
    except InvalidArgumentError:
        return False
    return True


@given(
    st.integers(0, 2**32 - 1),
    st.integers(0, 15),
    st.sampled_from([0.0, 1e-9, 2e-9, 5e-7, 1e-6, 2e-6, 5e-6, 1e-5, 1.1e-5, 2e-5, 1e-3]),
    st.booleans(),
)
def test_the_compiled_transform_check_is_as_transform(
    seed: int, entry: int, size: float, negative: bool
) -> None:
    """A transform with one entry moved by about the check's tolerances is solved by the prepared
    call exactly when `optik.checks.as_transform` takes it, and refused with its error otherwise."""
    _warm(M, time_limit=1e-4, max_restarts=0)
    t = M.fk(M.random_q(seed=seed))
    t[entry // 4, entry % 4] += -size if negative else size
    if _checked(t):
        assert isinstance(optik.solve_ik(M, t, method="lm", time_limit=1e-4, max_restarts=0), optik.IKResult)
    else:
        with pytest.raises(InvalidArgumentError) as info:
            optik.solve_ik(M, t, method="lm", time_limit=1e-4, max_restarts=0)
        assert info.value.argument == "target"


def test_a_method_registered_again_is_not_served_by_an_old_prepared_call() -> None:
    """Registering a method anew (here "lm" itself, with a solve that marks its results) makes
    `solve_ik` take the new registration, not a call prepared for the old one."""
    from optik.solvers.base import get_method, register_method

    _warm(M, **OPTIONS)
    old = get_method("lm")

    def marked(request):  # type: ignore[no-untyped-def]
        res = old.solve(request)
        res.extra["marked"] = True
        return res

    try:
        register_method("lm", marked, old.applies, old.description, old.multi_target)
        assert optik.solve_ik(M, M.fk(M.mid_q()), method="lm", **OPTIONS).extra == {"marked": True}
    finally:
        register_method("lm", old.solve, old.applies, old.description, old.multi_target, old.prepare)
    assert optik.solve_ik(M, M.fk(M.mid_q()), method="lm", **OPTIONS).extra == {}
