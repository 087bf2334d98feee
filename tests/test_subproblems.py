"""Subproblems 1-6 (optik.closed_form.subproblems): every solution satisfies the equations, the
generating angles are among the solutions, least-squares and degenerate cases as documented;
vectorized over a batch of random instances."""

from __future__ import annotations

import numpy as np

from optik.closed_form import subproblems as sp
from optik.mechanism.joint import axis_rotation
from optik.spatial import wrap_angle

N = 300


def _units(rng: np.random.Generator, n: int = N) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _angle_in(theta: np.ndarray, candidates: np.ndarray, tol: float = 1e-8) -> np.ndarray:
    return np.min(np.abs(wrap_angle(candidates - theta[:, None])), axis=1) < tol


def test_rot_is_rodrigues() -> None:
    rng = np.random.default_rng(0)
    k, p, t = _units(rng, 5), rng.normal(size=(5, 3)), rng.uniform(-4, 4, 5)
    for i in range(5):
        np.testing.assert_allclose(sp.rot(k[i], t[i], p[i]), axis_rotation(k[i], t[i]) @ p[i], atol=1e-14)


def test_sp1_round_trip_least_squares_and_degenerate() -> None:
    rng = np.random.default_rng(1)
    k, p1, t = _units(rng), rng.normal(size=(N, 3)), rng.uniform(-np.pi, np.pi, N)
    p2 = sp.rot(k, t, p1)
    theta, exact = sp.sp1(k, p1, p2)
    assert exact.all() and _angle_in(t, theta[:, None], 1e-10).all()
    # least squares: a scaled and shifted p2 keeps the angle of the projections
    theta_ls, exact_ls = sp.sp1(k, p1, 2.0 * p2 + 0.3 * k)
    assert not exact_ls.any() and _angle_in(t, theta_ls[:, None], 1e-10).all()
    # p1 along k: every angle solves it; 0 is returned, exact iff p2 == p1
    theta0, exact0 = sp.sp1(k[:3], 2.0 * k[:3], 2.0 * k[:3])
    assert exact0.all() and np.allclose(theta0, 0.0)


def test_sp4_both_roots_least_squares_and_degenerate() -> None:
    rng = np.random.default_rng(2)
    h, k, p, t = _units(rng), _units(rng), rng.normal(size=(N, 3)), rng.uniform(-np.pi, np.pi, N)
    d = np.sum(h * sp.rot(k, t, p), axis=1)
    theta, exact = sp.sp4(h, k, p, d)
    assert exact.all() and _angle_in(t, theta).all()
    for j in range(2):
        np.testing.assert_allclose(np.sum(h * sp.rot(k, theta[:, j], p), axis=1), d, atol=1e-10)
    # beyond reach: the least-squares root (twice) is the maximizer of h . rot(k, theta) p
    big = np.linalg.norm(p, axis=1) + 1.0
    theta_ls, exact_ls = sp.sp4(h, k, p, big)
    assert not exact_ls.any() and np.allclose(theta_ls[:, 0], theta_ls[:, 1])
    grid = np.linspace(-np.pi, np.pi, 721)
    values = np.sum(h[:, None] * sp.rot(k[:, None], grid[None], p[:, None]), axis=2)
    best = np.sum(h * sp.rot(k, theta_ls[:, 0], p), axis=1)
    assert np.all(best >= values.max(axis=1) - 1e-9)
    # h parallel to k: h . rot(k, theta) p is constant; exact only where it equals d
    const = np.sum(k * p, axis=1)
    _, exact_par = sp.sp4(k, k, p, const)
    _, exact_off = sp.sp4(k, k, p, const + 0.5)
    assert exact_par.all() and not exact_off.any()


def test_sp3_round_trip_and_out_of_reach() -> None:
    rng = np.random.default_rng(3)
    k, p1, p2 = _units(rng), rng.normal(size=(N, 3)), rng.normal(size=(N, 3))
    t = rng.uniform(-np.pi, np.pi, N)
    d = np.linalg.norm(sp.rot(k, t, p1) - p2, axis=1)
    theta, exact = sp.sp3(k, p1, p2, d)
    assert exact.all() and _angle_in(t, theta).all()
    for j in range(2):
        np.testing.assert_allclose(np.linalg.norm(sp.rot(k, theta[:, j], p1) - p2, axis=1), d, atol=1e-9)
    far = np.linalg.norm(p1, axis=1) + np.linalg.norm(p2, axis=1) + 1.0
    _, exact_far = sp.sp3(k, p1, p2, far)
    assert not exact_far.any()


def test_sp2_both_pairs_and_unequal_norms() -> None:
    rng = np.random.default_rng(4)
    k1, k2, p1 = _units(rng), _units(rng), rng.normal(size=(N, 3))
    t1, t2 = rng.uniform(-np.pi, np.pi, N), rng.uniform(-np.pi, np.pi, N)
    p2 = sp.rot(k2, -t2, sp.rot(k1, t1, p1))
    a, b, exact = sp.sp2(k1, p1, k2, p2)
    assert exact.all()
    for j in range(2):
        lhs = sp.rot(k1, a[:, j], p1)
        rhs = sp.rot(k2, b[:, j], p2)
        np.testing.assert_allclose(lhs, rhs, atol=1e-9)
    both = np.abs(wrap_angle(a - t1[:, None])) + np.abs(wrap_angle(b - t2[:, None]))
    assert np.all(both.min(axis=1) < 1e-8)
    _, _, exact_ls = sp.sp2(k1, p1, k2, 1.5 * p2)
    assert not exact_ls.any()


def test_trig_quartic_roots_are_every_sign_change() -> None:
    rng = np.random.default_rng(5)
    coef = rng.normal(size=(N, 5))
    t, ok = sp.trig_quartic(coef)

    def f(x: np.ndarray) -> np.ndarray:
        c = coef[:, :, None]
        return (
            c[:, 0]
            + c[:, 1] * np.cos(x)
            + c[:, 2] * np.sin(x)
            + c[:, 3] * np.cos(2 * x)
            + c[:, 4] * np.sin(2 * x)
        )

    vals = f(t)
    assert np.all(np.abs(vals[ok]) < 1e-10)
    grid = np.broadcast_to(np.linspace(-np.pi, np.pi, 4001), (N, 4001))
    signs = np.sign(f(grid))
    changes = np.sum(signs[:, 1:] != signs[:, :-1], axis=1)
    np.testing.assert_array_equal(ok.sum(axis=1), changes)


def test_sp6_every_pair_solves_and_the_true_pair_is_found() -> None:
    rng = np.random.default_rng(6)
    h = np.stack([_units(rng) for _ in range(4)])
    p = rng.normal(size=(4, N, 3))
    k1, k2 = _units(rng), _units(rng)
    t1, t2 = rng.uniform(-np.pi, np.pi, N), rng.uniform(-np.pi, np.pi, N)

    def lhs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        e = [
            np.sum(
                h[i][:, None]
                * sp.rot((k1 if i in (0, 2) else k2)[:, None], a if i in (0, 2) else b, p[i][:, None]),
                axis=2,
            )
            for i in range(4)
        ]
        return np.stack([e[0] + e[1], e[2] + e[3]], axis=-1)

    d = lhs(t1[:, None], t2[:, None])[:, 0]
    a, b, ok = sp.sp6(h, k1, k2, p, d)
    res = np.abs(lhs(a, b) - d[:, None]).max(axis=-1)
    assert np.all(res[ok] < 1e-8)
    found = ok & (np.abs(wrap_angle(a - t1[:, None])) < 1e-7) & (np.abs(wrap_angle(b - t2[:, None])) < 1e-7)
    assert found.any(axis=1).all()
    # no real solution: a right-hand side beyond the reach of both equations
    _, _, ok_far = sp.sp6(h, k1, k2, p, d + 100.0)
    assert not ok_far.any()


def test_sp5_every_triple_solves_and_the_true_triple_is_found() -> None:
    rng = np.random.default_rng(7)
    k1, k2, k3 = _units(rng), _units(rng), _units(rng)
    p1, p2, p3 = rng.normal(size=(3, N, 3))
    t1, t2, t3 = rng.uniform(-np.pi, np.pi, (3, N))
    p0 = sp.rot(k2, t2, p2 + sp.rot(k3, t3, p3)) - sp.rot(k1, t1, p1)
    a, b, c, ok = sp.sp5(p0, p1, p2, p3, k1, k2, k3)
    e = lambda v: v[:, None, :]  # noqa: E731
    lhs = e(p0) + sp.rot(e(k1), a, e(p1))
    rhs = sp.rot(e(k2), b, e(p2) + sp.rot(e(k3), c, e(p3)))
    assert np.all(np.linalg.norm(lhs - rhs, axis=-1)[ok] < 1e-7)
    found = ok & (np.abs(wrap_angle(a - t1[:, None])) < 1e-6) & (np.abs(wrap_angle(c - t3[:, None])) < 1e-6)
    assert found.any(axis=1).all()


def test_zero_length_and_parallel_axes_are_documented_degenerate_cases() -> None:
    rng = np.random.default_rng(8)
    k, h, p = _units(rng, 20), _units(rng, 20), rng.normal(size=(20, 3))
    zero = np.zeros((20, 3))
    # SP1 with p1 = 0: every angle maps 0 to 0 (exact, 0 returned) and nothing else (least squares)
    theta, exact = sp.sp1(k, zero, zero)
    assert exact.all() and np.all(theta == 0.0)
    assert not sp.sp1(k, zero, p)[1].any()
    # SP4 with p = 0: h . rot(k, t) 0 = 0 for every angle; exact only for d = 0
    theta4, exact4 = sp.sp4(h, k, zero, np.zeros(20))
    assert exact4.all() and np.all(np.isfinite(theta4))
    assert not sp.sp4(h, k, zero, np.ones(20))[1].any()
    # SP3 with p1 = 0: |0 - p2| = d holds for every angle exactly when d = |p2|
    assert sp.sp3(k, zero, p, np.linalg.norm(p, axis=1))[1].all()
    assert not sp.sp3(k, zero, p, np.linalg.norm(p, axis=1) + 0.1)[1].any()
    # SP2 with parallel axes: rot(k, t1) p1 = rot(k, t2) p2 has a one-parameter family when
    # consistent; the pair returned solves it, and an inconsistent instance is not exact
    t = rng.uniform(-np.pi, np.pi, 20)
    a, b, exact2 = sp.sp2(k, p, k, sp.rot(k, t, p))
    lhs = sp.rot(k[:, None], a, p[:, None])
    rhs = sp.rot(k[:, None], b, sp.rot(k, t, p)[:, None])
    np.testing.assert_allclose(lhs, rhs, atol=1e-9)
    assert exact2.all()
    assert not sp.sp2(k, p, k, sp.rot(k, t, p) + 0.5 * k)[2].any()
