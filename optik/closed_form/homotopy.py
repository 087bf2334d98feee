"""Projective homotopy continuation for square systems of homogeneous quadrics, vectorized over paths.

Solves ``F_j(z) = z^T M_j z = 0`` (``j = 1..k``) for ``z`` in complex projective space ``P^k``
(``n = k + 1`` homogeneous coordinates) by tracking the ``2^k`` paths of

``H(z, t) = (1 - t) F(z) + gamma t G(z)``,  ``G_j(z) = z_j^2 - z_0^2``,  ``t: 1 -> 0``,

on a random affine patch ``a^T z = 1``. ``G`` has the ``2^k`` (Bezout number) nonsingular
start solutions ``z = (1, +-1, ..., +-1)``. With a random complex ``gamma`` (the "gamma trick")
the paths are, with probability one, nonsingular for ``t`` in ``(0, 1]`` and every isolated
nonsingular solution of ``F`` is the end point of exactly one path. Paths of a start system that
go to a positive-dimensional (degenerate) component end there as singular points, which the
caller discards.

Tracking: fourth-order Runge-Kutta predictor on ``dz/dt = -H_z^{-1} H_t`` and Newton corrector,
with a step size per path (halved on a failed correction, doubled after three successes); all
paths advance together as numpy arrays, so the cost of one step is a handful of batched
``8 x 8`` complex solves.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

CORRECTOR_ITERATIONS = 3
"""Newton corrections per step (the last update must be at rounding level for acceptance)."""

JUMP_GUARD = 1e-3
"""Largest accepted corrector displacement relative to ``1 + |z|`` (guards against path jumping)."""


@dataclass(frozen=True)
class TrackingResult:
    """End points of all paths.

    Attributes:
        z: end points, shape ``(paths, n)`` (on the patch ``a^T z = 1``).
        converged: the path reached ``t = 0`` with a converged corrector.
        residual: max-norm of ``F(z)`` at the end point (scaled quadrics).
        condition: condition number of the patched Jacobian at the end point.
        steps: number of (batched) predictor-corrector steps.
    """

    z: np.ndarray
    converged: np.ndarray
    residual: np.ndarray
    condition: np.ndarray
    steps: int


def start_system(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadric matrices of ``G_j = z_j^2 - z_0^2`` (shape ``(k, k+1, k+1)``) and their ``2^k`` roots."""
    n = k + 1
    g = np.zeros((k, n, n))
    for j in range(k):
        g[j, 0, 0] = -1.0
        g[j, j + 1, j + 1] = 1.0
    signs = np.array(np.meshgrid(*([[1.0, -1.0]] * k), indexing="ij")).reshape(k, -1).T
    roots = np.hstack([np.ones((len(signs), 1)), signs])
    return g, roots


class _Homotopy:
    """``H(z, t)`` and its derivatives for a batch of paths."""

    def __init__(self, mats: np.ndarray, gamma: complex, patch: np.ndarray) -> None:
        k = mats.shape[0]
        self.f = mats.astype(complex)
        self.f_flat = self.f.reshape(-1, self.f.shape[-1])
        self.g, _ = start_system(k)
        self.gamma = gamma
        self.patch = patch
        d = gamma * self.g - self.f  # dH/dt as quadrics
        self.d_flat = d.reshape(-1, d.shape[-1])

    def _jacobian_rows(self, z: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The patched Jacobian ``[2 M(t) z; a^T]`` (``(P, n, n)``); rows ``< k`` hold ``2 M(t) z``."""
        p, n = z.shape
        k = n - 1
        jac = np.empty((p, n, n), dtype=complex)
        jac[:, :k] = (z @ self.f_flat.T).reshape(p, k, n)
        jac[:, :k] *= (1 - t)[:, None, None]
        gt = self.gamma * t
        rows = np.arange(k)
        jac[:, rows, rows + 1] += gt[:, None] * z[:, 1:]  # G_j z: +z_{j+1} in column j+1
        jac[:, :k, 0] -= gt[:, None] * z[:, :1]  # and -z_0 in column 0
        jac[:, :k] *= 2
        jac[:, k] = self.patch
        return jac

    def value_and_jacobian(self, z: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Patched system ``[H; a^T z - 1]`` and its Jacobian ``[2 M(t) z; a^T]``."""
        jac = self._jacobian_rows(z, t)
        val = 0.5 * (jac @ z[:, :, None])[:, :, 0]  # z^T M z = (M z) . z
        val[:, -1] = z @ self.patch - 1
        return val, jac

    def tangent(self, z: np.ndarray, t: np.ndarray) -> np.ndarray:
        """``dz/dt = -J^{-1} [dH/dt; 0]``."""
        jac = self._jacobian_rows(z, t)
        p, n = z.shape
        dz = (z @ self.d_flat.T).reshape(p, n - 1, n)
        rhs = np.zeros((p, n), dtype=complex)
        rhs[:, :-1] = (dz @ z[:, :, None])[:, :, 0]
        return -_solve(jac, rhs)


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched ``a x = b``; singular systems give ``inf`` (the step is then rejected)."""
    try:
        return np.linalg.solve(a, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.full(b.shape, np.inf + 0j)
        for i in range(len(a)):
            try:
                out[i] = np.linalg.solve(a[i], b[i])
            except np.linalg.LinAlgError:
                continue
        return out


def _newton(hom: _Homotopy, z: np.ndarray, t: np.ndarray, iters: int) -> tuple[np.ndarray, np.ndarray]:
    """``iters`` Newton steps at fixed ``t``; returns the point and the norm of the last update."""
    dz_norm = np.full(len(z), np.inf)
    for _ in range(iters):
        val, jac = hom.value_and_jacobian(z, t)
        dz = _solve(jac, val)
        dz_norm = np.linalg.norm(dz, axis=1)
        z = z - dz
    return z, dz_norm


def track(
    mats: np.ndarray,
    rng: np.random.Generator,
    *,
    time_limit: float = 5.0,
    max_step: float = 0.05,
    min_step: float = 1e-14,
    stall: float = 1e-3,
    tol: float = 1e-10,
    abandon: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> TrackingResult:
    """Track all ``2^k`` paths of the homotopy from ``G`` to ``F`` (``mats``: ``(k, k+1, k+1)``).

    Args:
        mats: symmetric quadric matrices of the target system ``F``.
        rng: generator for ``gamma`` and the affine patch.
        time_limit: wall-time budget (s); paths still running are returned as not converged.
        max_step: largest step in ``t``.
        min_step: a path whose step falls below this is abandoned.
        stall: once ``t < 0.01``, a path whose step falls below ``stall * t`` is abandoned too:
            it is heading for a singular end point (a path to a nonsingular end point is
            analytic at ``t = 0`` and never needs steps much shorter than the ``t`` still to go).
        tol: relative size of the last Newton update for a correction to be accepted.
        abandon: optional test ``(z, t) -> bool mask`` on accepted points; paths it flags stop
            (e.g. paths that have clearly entered a known degenerate set).
    """
    start = time.perf_counter()
    k, n = mats.shape[0], mats.shape[1]
    gamma = np.exp(2j * np.pi * rng.uniform())
    patch = rng.normal(size=n) + 1j * rng.normal(size=n)
    hom = _Homotopy(mats, gamma, patch)
    _, roots = start_system(k)
    z = roots.astype(complex) / (roots @ patch)[:, None]
    p = len(z)
    t = np.ones(p)
    h = np.full(p, 0.01)
    streak = np.zeros(p, dtype=int)
    active = np.ones(p, dtype=bool)
    failed = np.zeros(p, dtype=bool)
    steps = 0
    while np.any(active) and time.perf_counter() - start < time_limit:
        steps += 1
        idx = np.flatnonzero(active)
        za, ta, ha = z[idx], t[idx], h[idx]
        step = np.minimum(ha, ta)
        t_new = ta - step
        # RK4 predictor in t (dt = -step)
        k1 = hom.tangent(za, ta)
        k2 = hom.tangent(za - 0.5 * step[:, None] * k1, ta - 0.5 * step)
        k3 = hom.tangent(za - 0.5 * step[:, None] * k2, ta - 0.5 * step)
        k4 = hom.tangent(za - step[:, None] * k3, t_new)
        zp = za - (step / 6)[:, None] * (k1 + 2 * k2 + 2 * k3 + k4)
        zc, last = _newton(hom, zp, t_new, CORRECTOR_ITERATIONS)
        scale = 1 + np.linalg.norm(zc, axis=1)
        ok = np.isfinite(last) & (last <= tol * scale) & np.all(np.isfinite(zc), axis=1)
        ok &= np.linalg.norm(zc - zp, axis=1) <= JUMP_GUARD * scale
        acc, rej = idx[ok], idx[~ok]
        z[acc], t[acc] = zc[ok], t_new[ok]
        streak[acc] += 1
        grow = acc[streak[acc] >= 3]
        h[grow] = np.minimum(2 * h[grow], max_step)
        streak[grow] = 0
        h[rej] *= 0.5
        streak[rej] = 0
        if abandon is not None and len(acc):
            gone = acc[abandon(z[acc], t[acc])]
            active[gone] = False
            failed[gone] = True
        done = acc[t[acc] <= 0.0]
        active[done] = False
        floor = np.where(t[rej] < 1e-2, np.maximum(min_step, stall * t[rej]), min_step)
        dead = rej[h[rej] < floor]
        active[dead] = False
        failed[dead] = True
    converged = ~active & ~failed
    val, jac = hom.value_and_jacobian(z, np.zeros(p))
    residual = np.max(np.abs(val[:, :k]), axis=1)
    with np.errstate(all="ignore"):
        condition = np.linalg.cond(jac)
    return TrackingResult(z, converged, residual, np.nan_to_num(condition, nan=np.inf), steps)


def newton_step(mats: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The Newton update ``dz`` of each row of ``z`` on ``F(z) = (z^T M_k z)_k = 0`` with the patch
    ``conj(z)^T dz = 0``: ``[2 M_k z; conj(z)^T] dz = [z^T M_k z; 0]`` (``inf`` rows where that
    system is singular). Near a nonsingular root ``z*`` it is ``z - z*`` to first order."""
    mz = np.einsum("kij,pj->pki", mats, z)
    val = np.einsum("pki,pi->pk", mz, z)
    jac = np.concatenate([2 * mz, np.conj(z)[:, None, :]], axis=1)
    return _solve(jac, np.concatenate([val, np.zeros((len(z), 1))], axis=1))


def refine(mats: np.ndarray, z: np.ndarray, iters: int = 3) -> np.ndarray:
    """``iters`` `newton_step` updates on ``F`` at ``t = 0`` (a row whose system is singular stays)."""
    f = mats.astype(complex)
    for _ in range(iters):
        dz = newton_step(f, z)
        dz[~np.all(np.isfinite(dz), axis=1)] = 0
        z = z - dz
    return z
