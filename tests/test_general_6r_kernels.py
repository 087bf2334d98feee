"""The general 6R solver's steps in C (``general_6r.c``: the Newton polish, the back-substitution,
the whole elimination of a target) against their numpy paths: the same candidates, the same
answers and certificates of `solve_general_6r`."""

from __future__ import annotations

import ctypes
import threading
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optik.closed_form import general_6r as g6
from optik.mechanism import dh_chain


@pytest.fixture(scope="module", autouse=True)
def compiled_kernels() -> None:
    for kernel in (g6._POLISH, g6._BACK, g6._SOLVE, g6._DISTINCT, g6._POSE_ERRORS):
        kernel.get()
        assert kernel.library is not None and kernel.library.wait(120) is not None
        assert kernel.get() is not None


def _arm(rng: np.random.Generator):
    rows = [(rng.uniform(-1, 1), rng.uniform(0.1, 1), rng.uniform(-np.pi, np.pi)) for _ in range(6)]
    return dh_chain(rows, "standard")


def _numpy_polish(*args):
    """`_polish` on its numpy path."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(g6._POLISH, "get", lambda: None)
        return g6._polish(*args)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.0, 1e-3, 0.3]), st.booleans())
def test_polish_in_c_equals_numpy(seed: int, offset: float, complex_start: bool) -> None:
    """Starts near solutions (real, or with imaginary parts) of random unit-scale arms: the C
    polish keeps the dtype, and where either path converges (residual < 1e-12) both do, to the
    same angles."""
    rng = np.random.default_rng(seed)
    left = g6.General6R.from_mechanism(_arm(rng))._left
    truth = rng.uniform(-np.pi, np.pi, (8, 6))
    tp = g6._chain(left, truth)[:, 6]
    start = truth + offset * rng.normal(size=truth.shape)
    if complex_start:
        start = start + 1j * offset * rng.normal(size=truth.shape)
    ref, ref_size = _numpy_polish(left, start, tp)
    got, size = g6._polish(left, start, tp)
    assert got.dtype == ref.dtype and got.shape == ref.shape
    done = (size < 1e-12) | (ref_size < 1e-12)
    assert np.array_equal(size[done] < 1e-12, ref_size[done] < 1e-12)
    assert np.allclose(got[done], ref[done], atol=1e-9)


def test_singular_jacobian_is_left_to_numpy() -> None:
    """An arm with every axis on one line (all d, a, alpha zero): the Jacobian is exactly
    singular, the C code hands the batch back and numpy's least-squares steps answer."""
    left = SimpleNamespace(d=np.zeros(6), a=np.zeros(6), alpha=np.zeros(6))
    theta = np.full((2, 6), 0.1)
    tp = g6._chain(left, np.full((2, 6), 0.2))[:, 6]
    got = g6._polish(left, theta, tp)
    ref = _numpy_polish(left, theta, tp)
    assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1])


@pytest.mark.parametrize(
    "numpy_paths", [("_SOLVE", "_POLISH"), ("_SOLVE", "_BACK"), ("_SOLVE", "_POLISH", "_BACK"), ("_SOLVE",)]
)
def test_solve_general_6r_is_the_same_with_and_without_the_c_kernels(monkeypatch, numpy_paths) -> None:
    """40 random arms x 2 poses: the same number of solutions, complex solutions and
    certificates, the same solutions, each meeting its target by an independent FK, with the
    named steps on their numpy paths as with every step in C."""
    rng = np.random.default_rng(3)
    cases = []
    for _ in range(40):
        m = _arm(rng)
        cases += [(m, m.fk(rng.uniform(-np.pi, np.pi, 6))) for _ in range(2)]
    compiled = [g6.solve_general_6r(m, t) for m, t in cases]
    for name in numpy_paths:
        monkeypatch.setattr(getattr(g6, name), "get", lambda: None)
    for (m, t), mine in zip(cases, compiled, strict=True):
        ref = g6.solve_general_6r(m, t)
        assert (len(mine.q), mine.n_complex, mine.count_ok) == (len(ref.q), ref.n_complex, ref.count_ok)
        assert mine.count_ok
        for q in mine.q:
            assert np.min(np.max(np.abs(g6._wrap(ref.q - q)), axis=1)) < 1e-9
            assert np.allclose(m.fk(q), t, atol=1e-9)


def test_back_substitution_in_c_equals_numpy(monkeypatch) -> None:
    """The candidates the back-substitution hands to the polish (complex, and real retries) are
    the same in C and in numpy, on 20 random arms x 2 poses, to rounding: relative to
    `_magnitude` (``prod cosh(Im theta_i)``, the size of the DH products at complex angles,
    which the rounding of both grows with)."""
    rng = np.random.default_rng(8)
    cases = []
    for _ in range(20):
        m = _arm(rng)
        cases += [(m, m.fk(rng.uniform(-np.pi, np.pi, 6))) for _ in range(2)]
    seen: list[np.ndarray] = []
    polish = g6._polish

    def spy(left, theta, tp, iterations=g6.NEWTON_ITERATIONS):
        seen.append(theta.copy())
        return polish(left, theta, tp, iterations)

    monkeypatch.setattr(g6, "_polish", spy)
    monkeypatch.setattr(g6._SOLVE, "get", lambda: None)  # the candidates of the numpy pipeline
    for m, t in cases:
        g6.solve_general_6r(m, t)
    in_c, seen[:] = list(seen), []
    monkeypatch.setattr(g6._BACK, "get", lambda: None)
    for m, t in cases:
        g6.solve_general_6r(m, t)
    assert len(in_c) == len(seen)
    for a, b in zip(in_c, seen, strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape
        assert np.all(np.max(np.abs(a - b), axis=1, initial=0.0) <= 1e-11 * g6._magnitude(b))


def _same_answers(mine: g6.General6RSolutions, ref: g6.General6RSolutions, m, target) -> None:
    """The same counts and certificate, the same solutions (both ways, 1e-9 rad), each meeting the
    target by the mechanism's own FK."""
    assert (len(mine.q), mine.n_complex, mine.n_finite, mine.n_real_candidates, mine.n_rejected) == (
        len(ref.q),
        ref.n_complex,
        ref.n_finite,
        ref.n_real_candidates,
        ref.n_rejected,
    )
    assert mine.count_ok == ref.count_ok
    for a, b in ((mine.q, ref.q), (ref.q, mine.q)):
        for q in a:
            assert np.min(np.max(np.abs(g6._wrap(b - q)), axis=1)) < 1e-9
    for q in mine.q:
        assert np.allclose(m.fk(q), target, atol=1e-9)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1))
def test_whole_solve_in_c_equals_numpy(seed: int) -> None:
    """Random arms, three random poses each, solved stacked: the whole elimination in C
    (``optik_g6r_solve``) gives the same certified answers as the numpy pipeline, every solution
    meets its target by ``m.fk`` and the drawn ``q`` is among them."""
    rng = np.random.default_rng(seed)
    m = _arm(rng)
    qs = rng.uniform(-np.pi, np.pi, (3, 6))
    targets = m.fk(qs)
    mine = g6.solve_general_6r(m, targets)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(g6._SOLVE, "get", lambda: None)
        ref = g6.solve_general_6r(m, targets)
    for q, t, a, b in zip(qs, targets, mine, ref, strict=True):
        assert a.count_ok
        _same_answers(a, b, m, t)
        assert np.min(np.max(np.abs(g6._wrap(a.q - q)), axis=1)) < 1e-8


def test_whole_solve_in_c_is_used_and_hands_targets_back(monkeypatch) -> None:
    """The C solve answers (no numpy eigenvalue problem runs), and targets it hands back to
    numpy (here every other one, as for a badly conditioned leading matrix) are merged into the
    same answers: 10 random arms x 4 poses."""
    rng = np.random.default_rng(5)
    cases = []
    for _ in range(10):
        m = _arm(rng)
        cases.append((m, m.fk(rng.uniform(-np.pi, np.pi, (4, 6)))))
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(g6._SOLVE, "get", lambda: None)
        ref = [g6.solve_general_6r(m, t) for m, t in cases]
    eigen = g6._eigen
    calls: list[int] = []
    monkeypatch.setattr(g6, "_eigen", lambda mats: calls.append(len(mats)) or eigen(mats))
    for (m, t), r in zip(cases, ref, strict=True):
        for a, b, ti in zip(g6.solve_general_6r(m, t), r, t, strict=True):
            _same_answers(a, b, m, ti)
    assert not calls
    solve = g6._SOLVE.get()

    def hand_back(model, lapack, n, tp, info, *rest):
        total = solve(model, lapack, n, tp, info, *rest)
        flags = np.frombuffer((ctypes.c_double * (8 * n)).from_address(info), dtype=float).reshape(n, 8)
        flags[1::2, 0] = 1.0
        return total

    monkeypatch.setattr(g6._SOLVE, "get", lambda: hand_back)
    for (m, t), r in zip(cases, ref, strict=True):
        for a, b, ti in zip(g6.solve_general_6r(m, t), r, t, strict=True):
            _same_answers(a, b, m, ti)
    assert calls == [2] * len(cases)


def test_without_lapack_the_numpy_path_answers(monkeypatch) -> None:
    """No LAPACK addresses (scipy's capsules unreadable): the numpy pipeline answers, the same."""
    rng = np.random.default_rng(6)
    m = _arm(rng)
    t = m.fk(rng.uniform(-np.pi, np.pi, 6))
    mine = g6.solve_general_6r(m, t)
    monkeypatch.setattr(g6, "_lapack", lambda: None)
    _same_answers(mine, g6.solve_general_6r(m, t), m, t)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1))
def test_last_polish_in_the_c_solve_equals_numpy(seed: int) -> None:
    """Random arms, three random poses each: the last polish on the DH model inside the C solve
    (``optik_g6r_solve`` with the offsets) gives bit for bit what `_last_polish` gives on the
    same C candidates (its wrap is numpy's), and to rounding what the numpy pipeline gives."""
    rng = np.random.default_rng(seed)
    arm = g6.General6R.from_mechanism(_arm(rng))
    arm = g6.General6R(arm.a, arm.alpha, arm.d, rng.uniform(-4.0, 4.0, 6), arm.base, arm.tool)
    tp = g6._unit_targets(arm, arm.fk(rng.uniform(-np.pi, np.pi, (3, 6))))
    done = g6._candidates_c(arm, tp, last=True)
    raw = g6._candidates_c(arm, tp, last=False)
    at = np.flatnonzero(np.isfinite(raw.real[:, 0]))
    assert len(at) and np.array_equal(np.isfinite(done.real[:, 0]), np.isfinite(raw.real[:, 0]))
    rows = np.concatenate([raw.real[at], raw.again])
    owner = np.concatenate([raw.owner[at], raw.owner[raw.retry]])
    expected = g6._last_polish(arm, rows, tp[owner])
    got = np.concatenate([done.real[at], done.again])
    assert np.array_equal(got, expected)
    assert np.all((-np.pi < got) & (got <= np.pi))
    ref = g6._candidates(arm, tp, last=True)
    assert np.array_equal(ref.owner[np.isfinite(ref.real[:, 0])], raw.owner[at])
    assert np.max(np.abs(g6._wrap(ref.real[np.isfinite(ref.real[:, 0])] - done.real[at]))) < 1e-9


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.integers(0, 40), st.integers(1, 6))
def test_distinct_in_c_equals_numpy(seed: int, k: int, n: int) -> None:
    """Random rows (real and complex) of random targets, many of them copies of earlier rows
    moved by 2 pi in some joints or by less or more than `_SAME`: `_distinct` in C keeps the
    same rows, target by target in the same order, as its numpy path (and so as `_keep`)."""
    rng = np.random.default_rng(seed)
    rows = rng.uniform(-np.pi, np.pi, (k, 6)) + 1j * rng.uniform(-1, 1, (k, 6)) * (
        rng.uniform(size=(k, 1)) < 0.5
    )
    for i in range(1, k):
        if rng.uniform() < 0.5:
            j = rng.integers(i)
            step = rng.choice([0.0, 3e-7, 2e-6]) * rng.choice([-1, 1], 6) + 2 * np.pi * rng.integers(-1, 2, 6)
            rows[i] = rows[j] + step
    owner = rng.integers(0, n, k)
    got = g6._distinct(rows, owner, n)
    assert g6._DISTINCT.get() is not None
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(g6._DISTINCT, "get", lambda: None)
        ref = g6._distinct(rows, owner, n)
    assert len(got) == len(ref) == n
    for a, b in zip(got, ref, strict=True):
        assert np.array_equal(a, b)
    for t, kept in enumerate(got):  # kept rows pairwise apart, every dropped row near a kept one
        mine = np.flatnonzero(owner == t)
        assert set(kept) <= set(mine)
        if len(mine):
            assert np.all(g6._gap(rows[mine][:, None, :] - rows[kept][None, :, :]).min(axis=1) < g6._SAME)
        apart = g6._gap(rows[kept][:, None, :] - rows[kept][None, :, :]) + np.eye(len(kept))
        assert np.all(apart >= g6._SAME)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.integers(0, 20), st.floats(1e-12, 3.0))
def test_pose_errors_in_c_equal_numpy(seed: int, k: int, size: float) -> None:
    """Random poses near random targets (rotations up to angle ``size``, and half turns):
    `_pose_errors` in C equals its numpy path to rounding, and the angle is the rotation's."""
    rng = np.random.default_rng(seed)
    m = _arm(rng)
    q = rng.uniform(-np.pi, np.pi, (k, 6))
    target = m.fk(q).reshape(k, 4, 4)
    axis = rng.normal(size=(k, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.where(rng.uniform(size=k) < 0.2, np.pi, rng.uniform(0, size, k))
    pose = target.copy()
    for i in range(k):
        w = np.array(
            [[0, -axis[i, 2], axis[i, 1]], [axis[i, 2], 0, -axis[i, 0]], [-axis[i, 1], axis[i, 0], 0]]
        )
        rot = np.eye(3) + np.sin(angle[i]) * w + (1 - np.cos(angle[i])) * w @ w
        pose[i, :3, :3] = target[i, :3, :3] @ rot
        pose[i, :3, 3] += rng.normal(size=3) * size
    got = g6._pose_errors(pose, target)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(g6._POSE_ERRORS, "get", lambda: None)
        ref = g6._pose_errors(pose, target)
    assert got.shape == ref.shape == (k, 2)
    assert np.allclose(got, ref, rtol=1e-12, atol=1e-15)
    assert np.allclose(got[:, 1], angle, rtol=1e-9, atol=1e-7)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(
    st.integers(0, 2**32 - 1),
    st.sampled_from([{}, {"a": [0]}, {"alpha": [0]}, {"a": [0, 4]}, {"alpha": [3, 4]}]),
)
def test_c_pencil_flags_equal_numpy(seed: int, zero: dict) -> None:
    """Random arms, generic or with axes 1-2 intersecting or parallel, 1-2 and 5-6 intersecting,
    4, 5, 6 parallel (all singular pencils): the C solve's flags (Q of full rank, the
    pencil regular, from the 12 x 12 singular values of its own bidiagonalization and dlasq1)
    and counts of finite and far eigenvalues equal the numpy pipeline's (numpy's SVD)."""
    rng = np.random.default_rng(seed)
    a, alpha, d = rng.uniform(0.1, 1, 6), rng.uniform(-np.pi, np.pi, 6), rng.uniform(-1, 1, 6)
    a[zero.get("a", [])] = 0.0
    alpha[zero.get("alpha", [])] = 0.0
    arm = g6.General6R(a=a, alpha=alpha, d=d)
    tp = g6._unit_targets(arm, arm.fk(rng.uniform(-np.pi, np.pi, (3, 6))))
    mine, ref = g6._candidates_c(arm, tp), g6._candidates(arm, tp)
    assert np.array_equal(mine.rank_ok, ref.rank_ok) and np.array_equal(mine.regular, ref.regular)
    assert np.all(mine.regular) if not zero else not np.any(mine.regular)  # these special ones are singular


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1))
def test_c_candidates_from_null_vectors_equal_numpy_eigenvectors(seed: int) -> None:
    """Random arms, three random poses each: the C solve's candidates, complex ones included
    (each from the null vector of ``M(x_3)`` at its eigenvalue, a conjugate pair's second as the
    conjugate of the first's), are the numpy pipeline's (from the companion matrix's
    eigenvectors) target by target to 1e-9 after the polish, with the same per-target counts."""
    rng = np.random.default_rng(seed)
    arm = g6.General6R.from_mechanism(_arm(rng))
    tp = g6._unit_targets(arm, arm.fk(rng.uniform(-np.pi, np.pi, (3, 6))))
    mine, ref = g6._candidates_c(arm, tp), g6._candidates(arm, tp)
    assert np.array_equal(mine.n_good, ref.n_good) and np.array_equal(mine.n_far, ref.n_far)
    assert np.array_equal(np.bincount(mine.owner, minlength=3), np.bincount(ref.owner, minlength=3))
    for t in range(3):
        a, b = mine.theta[mine.owner == t], ref.theta[ref.owner == t]
        diff = a[:, None, :] - b[None, :, :]
        gap = np.maximum(np.abs(g6._wrap(diff.real)), np.abs(diff.imag)).max(axis=2)
        assert len(a) and np.max(np.min(gap, axis=1)) < 1e-9 and np.max(np.min(gap, axis=0)) < 1e-9


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.integers(0, 3 * g6._FK_ROWS + 3))
def test_batched_fk_check_equals_m_fk_row_by_row(seed: int, n: int) -> None:
    """The FK check's evaluation of the mechanism (`_MechanismRows`, chunks of `_FK_ROWS` rows)
    gives exactly ``m.fk`` of each row (and the Jacobian's, `_mechanism_jacobian`, exactly
    ``m.jacobian``), for any number of rows (none, a partial chunk, several) and rows that are
    views (reversed columns, as for the inverse chain's candidates)."""
    rng = np.random.default_rng(seed)
    m = _arm(rng)
    q = rng.uniform(-np.pi, np.pi, (n, 6))
    fk = g6._mechanism_fk(m)
    assert g6._mechanism_fk(m) is fk  # made once per mechanism
    got = fk(q)
    assert got.shape == (n, 4, 4)
    for row, pose in zip(q, got, strict=True):
        assert np.array_equal(pose, m.fk(row))
    flipped = q[:, ::-1]
    assert np.array_equal(fk(flipped), m.fk(flipped).reshape(n, 4, 4))
    jac = g6._mechanism_jacobian(m)  # the polish's Jacobian (one row a chunk)
    assert g6._mechanism_jacobian(m) is jac
    got = jac(flipped)
    assert got.shape == (n, 6, 6)
    for row, j in zip(flipped, got, strict=True):
        assert np.array_equal(j, m.jacobian(row))


def test_batched_fk_check_in_four_threads_equals_one() -> None:
    """Four threads evaluating one mechanism's `_MechanismRows` at once (each on its own buffers)
    get the single thread's poses, call for call."""
    rng = np.random.default_rng(3)
    m = _arm(rng)
    batches = [rng.uniform(-np.pi, np.pi, (int(k), 6)) for k in rng.integers(1, 3 * g6._FK_ROWS, 200)]
    fk = g6._mechanism_fk(m)
    ref = [fk(q) for q in batches]
    start = threading.Barrier(4)
    wrong: list[int] = []

    def work(shift: int) -> None:
        start.wait()
        for k in range(len(batches)):
            i = (k + 50 * shift) % len(batches)
            if not np.array_equal(fk(batches[i]), ref[i]):
                wrong.append(i)

    threads = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not wrong
