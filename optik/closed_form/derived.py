"""Analytic IK derived from a mechanism's structure, registered as its closed form.

``derive`` reads the joint axes of a 6R serial chain (`optik.closed_form.structure.axes_of`),
detects its family (`optik.closed_form.structure.detect`) and returns a ``DerivedIK`` that
solves many targets at once:

1. the family's subproblem decomposition gives up to 8 candidates per target
   (`optik.closed_form.spherical_wrist`, `optik.closed_form.three_parallel`; chains of the
   reversed families are solved as their inverse chain, ``q = -reverse(q')``);
2. every candidate is polished by ``POLISH_STEPS`` vectorized Gauss-Newton steps on the exact
   product-of-exponentials residual ``[p - p*; log(R R*^T)]`` (a no-op for exact candidates, and
   it makes least-squares candidates at the edge of the workspace exact where they can be);
3. the FK check: a candidate is kept when its position error is at most ``CHECK_TOL`` times
   the arm's size and its orientation error at most ``CHECK_TOL`` rad; the others are dropped;
4. duplicates are merged: two kept candidates of one target are one solution when their joint
   distance (max-norm, angles modulo 2 pi) is below ``min(1e-4, 100 e / sigma + 1e-9)``, ``e``
   the polished residual and ``sigma`` the smallest singular value of the Jacobian there (the
   accuracy to which the polished candidate is determined).

Importing this module registers ``derived_rows`` with `optik.closed_form.registry`, so that
every mechanism with a detected family and no catalog closed form gets one: ``closed_form.ik``,
``solve_ik(method="closed_form")`` and ``solve_ik_all`` use it.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from optik.closed_form import registry, spherical_wrist, three_parallel
from optik.closed_form.structure import Axes, Structure, axes_of, detect
from optik.mechanism import Mechanism

POLISH_STEPS = 2
"""Gauss-Newton steps applied to every candidate."""
CHECK_TOL = 1e-9
"""FK check: largest position error (times the arm's size) and orientation error (rad) kept."""
SAME_TOL = 1e-4
"""Upper bound of the distance under which two candidates are one solution."""

_KERNELS = {
    "spherical_wrist": spherical_wrist.candidates,
    "spherical_base": spherical_wrist.candidates,
    "three_parallel": three_parallel.candidates,
    "three_parallel_reversed": three_parallel.candidates,
}


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles to ``(-pi, pi]``."""
    w = np.remainder(a + np.pi, 2.0 * np.pi) - np.pi
    return np.where(w <= -np.pi, w + 2.0 * np.pi, w)


def _errors(pose: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Residual ``(..., 6)`` ``[p - p*; log(R R*^T)]`` (small-angle log) and the orientation error."""
    dp = pose[..., :3, 3] - t[..., :3, 3]
    m = pose[..., :3, :3] @ np.swapaxes(t[..., :3, :3], -1, -2)
    s = 0.5 * np.stack(
        [m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], axis=-1
    )
    cos = 0.5 * (np.trace(m, axis1=-2, axis2=-1) - 1.0)
    sin = np.linalg.norm(s, axis=-1)
    angle = np.arctan2(sin, cos)
    scale = np.divide(angle, sin, out=np.ones_like(angle), where=sin > 1e-12)
    return np.concatenate([dp, s * scale[..., None]], axis=-1), angle


@dataclass(frozen=True)
class DerivedIK:
    """The derived analytic IK of one 6R chain.

    Attributes:
        axes: the chain (product-of-exponentials model at ``q = 0``).
        structure: its detected family.
    """

    axes: Axes
    structure: Structure

    def candidates(self, t: np.ndarray) -> np.ndarray:
        """Unchecked candidates ``(N, 8, 6)`` of the decomposition for targets ``t (N, 4, 4)``."""
        kernel = _KERNELS[self.structure.family]
        if not self.structure.reversed:
            return kernel(self.axes, self.structure.position, t)
        inv = np.zeros_like(t)
        rt = np.swapaxes(t[:, :3, :3], -1, -2)
        inv[:, :3, :3] = rt
        inv[:, :3, 3] = -np.einsum("nij,nj->ni", rt, t[:, :3, 3])
        inv[:, 3, 3] = 1.0
        return -kernel(self.axes.reversed(), self.structure.position, inv)[..., ::-1]

    def solve(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every solution for targets ``t (N, 4, 4)`` (steps 1-4 of the module docstring).

        Returns:
            ``q (N, 8, 6)`` wrapped to ``(-pi, pi]`` and ``ok (N, 8)``: True for the kept,
            distinct solutions (rows where ``ok`` is False are finite placeholders).
        """
        t = np.asarray(t, dtype=float).reshape(-1, 4, 4)
        q = self.candidates(t)
        q = np.where(np.isfinite(q), q, 0.0)
        tt = t[:, None]
        for _ in range(POLISH_STEPS):
            pose, jac = self.axes.jacobian(q)
            res, _ = _errors(pose, tt)
            q = q - _solve_steps(jac, res)
        pose, jac = self.axes.jacobian(q)
        res, angle = _errors(pose, tt)
        pos = np.linalg.norm(res[..., :3], axis=-1)
        ok = (pos <= CHECK_TOL * self.axes.size) & (angle <= CHECK_TOL)
        q = _wrap(q)
        sigma = np.linalg.svd(jac, compute_uv=False)[..., -1]
        norm = np.linalg.norm(res, axis=-1)
        tol = np.minimum(SAME_TOL, 100.0 * norm / np.maximum(sigma, 1e-300) + 1e-9)
        diff = np.abs(_wrap(q[:, :, None, :] - q[:, None, :, :])).max(axis=-1)  # (N, 8, 8)
        same = diff < np.maximum(tol[:, :, None], tol[:, None, :])
        earlier = np.tril(np.ones((8, 8), dtype=bool), -1)
        for j in range(1, 8):  # drop j when an earlier kept candidate is the same solution
            dup = np.any(same[:, j, :j] & ok[:, :j] & earlier[j, :j], axis=-1)
            ok[:, j] &= ~dup
        return np.where(ok[..., None], q, 0.0), ok


def _solve_steps(jac: np.ndarray, res: np.ndarray) -> np.ndarray:
    """Damped Gauss-Newton steps ``(J^T J + mu I)^-1 J^T r`` (``mu`` tiny, for singular poses)."""
    jt = np.swapaxes(jac, -1, -2)
    a = jt @ jac
    a = a + 1e-12 * np.eye(a.shape[-1])
    return np.linalg.solve(a, np.einsum("...ij,...j->...i", jt, res)[..., None])[..., 0]


def derive_axes(axes: Axes) -> DerivedIK | None:
    """The derived IK of a product-of-exponentials chain, or None when no family is detected."""
    structure = detect(axes)
    return None if structure is None else DerivedIK(axes, structure)


_CACHE: weakref.WeakKeyDictionary[Mechanism, DerivedIK | None] = weakref.WeakKeyDictionary()


def derive(m: Mechanism) -> DerivedIK | None:
    """The derived IK of a mechanism (cached per mechanism), or None when it is not a 6R serial
    chain of a decomposable family (its task must be ``"pose"``)."""
    try:
        return _CACHE[m]
    except KeyError:
        pass
    axes = axes_of(m) if m.task == "pose" and m.n_q == 6 else None
    solver = None if axes is None else derive_axes(axes)
    _CACHE[m] = solver
    return solver


def derived_rows(m: Mechanism) -> registry.IKSolver | None:
    """Registry deriver: ``(m, T) -> rows`` of every derived solution, or None."""
    solver = derive(m)
    if solver is None:
        return None

    def rows(_: Mechanism, t: np.ndarray) -> list[list[float]]:
        q, ok = solver.solve(t[None])
        return q[0][ok[0]].tolist()

    return rows


registry.register_deriver(derived_rows)
