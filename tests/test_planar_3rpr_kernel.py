"""The compiled 3-RPR FK (``planar_3rpr.c``) against the general float path, and the compiled
condition numbers against numpy: same modes, same counts, every mode checked independently."""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik import native
from optik.closed_form.parallel import planar_3rpr as rpr
from optik.closed_form.parallel.common import rot2
from optik.solvers import conditions
from optik.solvers.base import BRANCH_TOL
from optik.solvers.fk import SINGULAR_CONDITION, _compiled, _distinct, same_mode


@pytest.fixture(scope="module", autouse=True)
def compiled_kernels() -> None:
    """Both C kernels loaded (built in the background on first use)."""
    for kernel in (rpr._KERNEL, conditions._KERNEL):
        kernel.get()
        assert kernel.library is not None and kernel.library.wait(120) is not None
        assert kernel.get() is not None


def _geometry(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Random base, platform, a pose and its leg lengths."""
    rng = np.random.default_rng(seed)
    b, p = rng.normal(size=(3, 2)), 0.7 * rng.normal(size=(3, 2))
    x = np.array([*rng.normal(size=2), rng.uniform(-np.pi, np.pi)])
    rho = np.linalg.norm(x[:2] + p @ rot2(x[2]).T - b, axis=1)
    return b, p, rho, x


def _pose_of(row: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``(x, y, phi)`` recomputed from a coordinate row: leg 1's end minus the rotated ``p_1``."""
    phi = optik.spatial.wrap_angle(row[0] + row[2])
    end = b[0] + row[1] * np.array([np.cos(row[0]), np.sin(row[0])])
    return np.array([*(end - rot2(phi) @ p[0]), phi])


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_compiled_modes_equal_the_general_path(seed: int, drawn: bool) -> None:
    """Leg lengths of a drawn pose, or random ones (often no mode): the C kernel (when it answers)
    returns as many modes as `planar_3rpr_poses`, the same poses in the same order, each closing
    the model's loops, meeting the legs and, for a drawn pose, containing it."""
    b, p, rho, x = _geometry(seed)
    if not drawn:
        rho = np.abs(np.random.default_rng(seed + 1).normal(size=3)) * 2
    rows = rpr.compiled_rows(b, p, rho)
    general = rpr.planar_3rpr_poses(b, p, rho)
    if rows is None:  # handed back: the general path answers (rare: a near-double root)
        return
    assert len(rows) == len(general)
    m = optik.catalog.planar_3rpr(base=b, platform=p, leg_limits=(0.0, 100.0))
    for row, pose in zip(rows, general, strict=True):
        mine = _pose_of(row, b, p)
        assert np.allclose(mine[:2], pose[:2], atol=1e-8)
        assert abs(optik.spatial.wrap_angle(mine[2] - pose[2])) < 1e-8
        legs = np.linalg.norm(mine[:2] + p @ rot2(mine[2]).T - b, axis=1)
        assert np.allclose(legs, rho, atol=1e-9 * max(1.0, float(np.max(rho))))
        assert np.max(np.abs(m.closure(m.wrap(row)))) <= 1e-9
    assert rpr.planar_3rpr_fk(m, rho) == rows.tolist()
    if drawn:
        assert any(
            np.allclose(_pose_of(r, b, p)[:2], x[:2], atol=1e-8)
            and abs(optik.spatial.wrap_angle(_pose_of(r, b, p)[2] - x[2])) < 1e-8
            for r in rows
        )


def test_compiled_kernel_answers_almost_every_random_case() -> None:
    """Over 2,000 random geometries (half with a drawn pose) the kernel hands back at most 2 %
    (the general path answers those); it finds 0, 2, 4 and 6 modes."""
    counts, handed_back = set(), 0
    for seed in range(2000):
        b, p, rho, _ = _geometry(seed)
        if seed % 2:
            rho = np.abs(np.random.default_rng(seed + 1).normal(size=3)) * 2
        rows = rpr.compiled_rows(b, p, rho)
        if rows is None:
            handed_back += 1
        else:
            counts.add(len(rows))
    assert handed_back <= 40
    assert {0, 2, 4, 6} <= counts


def test_singular_assembly_is_handed_back_to_the_general_path() -> None:
    """Legs whose lines meet in one point (a singular assembly: two modes merge, a double root
    of F): the bounds cannot separate the roots, the kernel hands the call back, and
    `planar_3rpr_fk` still returns the drawn pose, as the general path does."""
    rng = np.random.default_rng(5)
    p = 0.7 * rng.normal(size=(3, 2))
    x = np.array([0.2, -0.1, 0.4])
    ends = x[:2] + p @ rot2(x[2]).T
    centre = np.array([0.3, 2.0])
    b = ends + rng.uniform(0.5, 1.5, size=(3, 1)) * (ends - centre)  # each leg on a line through centre
    rho = np.linalg.norm(ends - b, axis=1)
    assert rpr.compiled_rows(b, p, rho) is None
    m = optik.catalog.planar_3rpr(base=b, platform=p, leg_limits=(0.0, 100.0))
    rows = rpr.planar_3rpr_fk(m, rho)
    assert any(np.allclose(_pose_of(np.array(r), b, p), x, atol=1e-6) for r in rows)


def test_continuum_is_handed_back_to_the_general_path() -> None:
    """A platform congruent to the base (a continuum of modes at phi = 0): the general path's
    representatives, not the kernel's."""
    b = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert rpr.compiled_rows(b, b.copy(), np.ones(3)) is None
    m = optik.catalog.planar_3rpr(base=b, platform=b.copy(), leg_limits=(0.0, 100.0))
    assert len(rpr.planar_3rpr_fk(m, np.ones(3))) == rpr.CONTINUUM_SAMPLES + 2


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.sampled_from([(4, 4), (2, 1), (1, 3), (6, 5), (3, 7)]), st.floats(0, 8))
def test_condition_numbers_equal_numpy(seed: int, shape: tuple[int, int], decades: float) -> None:
    """Random stacks with singular values spread over ``decades`` decades: the compiled
    condition numbers equal ``numpy.linalg.cond`` to its own accuracy."""
    rng = np.random.default_rng(seed)
    k = min(shape)
    u, _ = np.linalg.qr(rng.normal(size=(shape[0], shape[0])))
    v, _ = np.linalg.qr(rng.normal(size=(shape[1], shape[1])))
    s = np.logspace(0, -decades, k)
    a = np.stack([u[:, :k] @ np.diag(s * rng.uniform(0.5, 2)) @ v[:k] for _ in range(3)])
    got = np.array(conditions.condition_numbers(a))
    assert np.allclose(got, np.linalg.cond(a), rtol=1e-12 * 10**decades + 1e-12, atol=0)


def test_condition_numbers_edge_cases() -> None:
    """A zero or rank-deficient matrix is infinitely ill-conditioned; a stack the C code does not
    take (too large) and a non-finite entry go to numpy (which raises for the latter)."""
    assert conditions.condition_numbers(np.zeros((1, 4, 4))) == [np.inf]
    assert conditions.condition_numbers(np.eye(4)[None]) == [1.0]
    big = np.random.default_rng(0).normal(size=(2, 70, 3))
    assert np.allclose(conditions.condition_numbers(big), np.linalg.cond(big), rtol=1e-12)
    bad = np.eye(3)[None].copy()
    bad[0, 1, 1] = np.nan
    with pytest.raises(np.linalg.LinAlgError):
        conditions.condition_numbers(bad)


def test_solve_fk_all_results_are_checked_independently() -> None:
    """Every mode of `solve_fk_all` (compiled kernels): residual, condition number and pose equal
    what the model says at its ``q`` (closure, the SVD of its passive Jacobian, FK)."""
    for seed in range(40):
        b, p, rho, _ = _geometry(seed)
        m = optik.catalog.planar_3rpr(base=b, platform=p, leg_limits=(0.0, 100.0))
        modes = optik.solve_fk_all(m, rho)
        assert len(modes) == len(rpr.planar_3rpr_poses(b, p, rho))
        cm = _compiled(m)
        for r in modes:
            c, jac = cm.evaluate(r.q[None])
            assert r.residual == pytest.approx(float(np.max(np.abs(c))), abs=1e-15)
            assert r.residual <= 1e-9 and r.success and r.limits_ok
            assert r.condition_number == pytest.approx(float(np.linalg.cond(jac[0])), rel=1e-6)
            assert np.allclose(r.pose, m.fk(r.q), atol=1e-14)
            assert r.extra["singular"] == (r.condition_number > SINGULAR_CONDITION)


def test_unreadable_or_uncompilable_kernel_is_none(tmp_path, monkeypatch, caplog) -> None:
    """A C file that cannot be read, or no compiler: `CFunction.get` answers None (logged for
    the file), and the callers take their Python paths."""
    missing = native.CFunction(tmp_path / "missing.c", "optik_missing", "f", [])
    with caplog.at_level(logging.WARNING, logger="optik.native"):
        assert missing.get() is None
    assert "cannot be read" in caplog.text
    monkeypatch.setenv("OPTIK_NO_CODEGEN", "1")
    assert native.CFunction(rpr.SOURCE, "optik_planar_3rpr_nocc", "optik_rpr_fk", []).get() is None


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.integers(1, 8))
def test_distinct_modes_follow_the_branch_rule(seed: int, k: int) -> None:
    """`_distinct` keeps the rows a greedy pass with `same_mode` keeps: rows copied with whole
    turns added to angles, offsets just under and over the branch tolerance, other rows."""
    rng = np.random.default_rng(seed)
    m = optik.catalog.planar_3rpr()
    rows = [m.random_q(seed=rng)]
    for _ in range(k - 1):
        base = rows[rng.integers(len(rows))].copy()
        kind = rng.integers(3)
        if kind == 0:
            base[m.revolute_mask] += 2 * np.pi * rng.integers(-2, 3, size=int(m.revolute_mask.sum()))
        elif kind == 1:
            base[rng.integers(m.n_q)] += rng.choice([0.99, 1.01]) * BRANCH_TOL
        else:
            base = m.random_q(seed=rng)
        rows.append(base)
    qs = np.array(rows)
    greedy: list[int] = []
    for i, q in enumerate(qs):
        if not any(same_mode(m, q, qs[j]) for j in greedy):
            greedy.append(i)
    assert _distinct(m, qs) == greedy


def test_solve_fk_all_is_the_same_with_and_without_the_kernels(monkeypatch) -> None:
    """`solve_fk_all` on 150 random 3-RPRs (limits that drop some modes): the compiled kernels and
    the Python paths (the float FK with ``numpy.roots``, numpy's SVD) give the same modes in the
    same order, the same dropped ones, flags, condition numbers and messages."""
    cases = []
    for seed in range(150):
        b, p, rho, _ = _geometry(seed)
        if seed % 3 == 0:
            rho = np.abs(np.random.default_rng(seed + 1).normal(size=3)) * 2
        cases.append((optik.catalog.planar_3rpr(base=b, platform=p, leg_limits=(0.1, 3.0)), rho))
    compiled = [
        optik.solve_fk_all(m, rho, within_limits=seed % 2 == 0) for seed, (m, rho) in enumerate(cases)
    ]
    monkeypatch.setattr(rpr._KERNEL, "get", lambda: None)
    monkeypatch.setattr(conditions._KERNEL, "get", lambda: None)
    for seed, ((m, rho), mine) in enumerate(zip(cases, compiled, strict=True)):
        general = optik.solve_fk_all(m, rho, within_limits=seed % 2 == 0)
        assert mine.message == general.message
        for a, b in zip([*mine, *mine.dropped], [*general, *general.dropped], strict=True):
            assert np.allclose(a.q, b.q, atol=1e-9) and np.allclose(a.pose, b.pose, atol=1e-9)
            assert (a.success, a.limits_ok, a.limits_violated) == (b.success, b.limits_ok, b.limits_violated)
            assert a.residual <= 1e-9 and b.residual <= 1e-9
            assert a.condition_number == pytest.approx(b.condition_number, rel=1e-6)
            assert a.extra["singular"] == b.extra["singular"]


def test_kernels_are_thread_safe() -> None:
    """Four threads solving different 3-RPRs at once get what one thread gets."""
    cases = [_geometry(seed) for seed in range(40)]
    mechs = [optik.catalog.planar_3rpr(base=b, platform=p, leg_limits=(0.0, 100.0)) for b, p, _, _ in cases]
    expected = [[r.q for r in optik.solve_fk_all(m, c[2])] for m, c in zip(mechs, cases, strict=True)]

    def work(offset: int) -> bool:
        ok = True
        for _ in range(5):
            for i in range(offset, len(cases), 4):
                got = [r.q for r in optik.solve_fk_all(mechs[i], cases[i][2])]
                ok &= len(got) == len(expected[i]) and all(
                    np.array_equal(a, b) for a, b in zip(got, expected[i], strict=True)
                )
        return ok

    with ThreadPoolExecutor(4) as pool:
        assert all(pool.map(work, range(4)))


@pytest.mark.parametrize("name", ["planar_3rpr", "doggy", "five_bar", "slider_crank", "stewart_gough"])
def test_mode_check_of_several_rows_equals_the_model(name: str) -> None:
    """The mapped mode check of ``K`` rows: each row's closure and passive Jacobian (in the
    orientation ``(m, p)``) equal the closure function's, and its pose equals ``m.fk``."""
    m = getattr(optik.catalog, name)()
    cm = _compiled(m)
    for k in (1, 3):
        qs = np.array([m.random_q(seed=i) for i in range(k)])
        c, jac, pose = cm.modes(qs)  # type: ignore[misc]
        c_ref, jac_ref = cm.evaluate(qs)
        assert np.array_equal(c, c_ref) and np.array_equal(jac, jac_ref)
        assert all(np.array_equal(pose[i], m.fk(qs[i])) for i in range(k))
