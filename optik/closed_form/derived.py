"""Analytic IK derived from a mechanism's structure, registered as its closed form.

``derive`` reads the joint axes of a 6R serial chain (`optik.closed_form.structure.axes_of`),
detects its family (`optik.closed_form.structure.detect`) and returns a ``DerivedIK`` that
solves many targets at once:

1. the family's subproblem decomposition gives ``B`` candidates per target (8, or 16 with the
   wrist-singularity representatives of `optik.closed_form.three_parallel`)
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

One target at a time (`DerivedIK.solve_one`, and `optik.solve_ik_all` directly), the same steps
run in one compiled call (`optik.closed_form.ik_all`), the numpy path deciding the rare targets
with a candidate to polish or two close ones; a candidate that only stands in for another at a
singularity (`DerivedIK.stand_ins`) is dropped when that one passes the check, on every path.

Importing this module registers ``derived_rows`` with `optik.closed_form.registry`, so that
every mechanism with a detected family and no catalog closed form gets one: ``closed_form.ik``,
``solve_ik(method="closed_form")`` and ``solve_ik_all`` use it.
"""

from __future__ import annotations

import functools
import threading
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from optik.closed_form import general_6r, registry, spherical_wrist, three_parallel
from optik.closed_form import vec3 as v3
from optik.closed_form.ik_all import AllSolutionsKernel
from optik.closed_form.spherical_wrist import Branch
from optik.closed_form.structure import Axes, Structure, axes_of, detect
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism

POLISH_STEPS = 3
"""Gauss-Newton steps applied to an inexact candidate."""
POLISH_RANGE = (1e-5, 1e-3)
"""Bounds of `DerivedIK.polish_range`: candidates with errors above `CHECK_TOL` but within
the polish range (times the arm's size for the position, rad for the orientation) are polished;
those beyond are no solution (least-squares answers of subproblems without a real one)."""
CHECK_TOL = 1e-9
"""FK check: largest position error (times the arm's size) and orientation error (rad) kept."""
EXACT_TOL = 1e-12
"""A derived model is exact (`DerivedIK.exact`) when its defect is at most this: the exact
candidates of real arms are within about 1e-13."""
SAME_TOL = 1e-4
"""Upper bound of the distance under which two candidates are one solution."""
_NO_LIMIT, _NO_LIMIT_UP = np.full(6, -np.inf), np.full(6, np.inf)

_KERNELS = {
    "spherical_wrist": spherical_wrist.branches,
    "spherical_base": spherical_wrist.branches,
    "three_parallel": three_parallel.branches,
    "three_parallel_reversed": three_parallel.branches,
}
_STAND_INS = {"three_parallel": three_parallel.stand_ins, "three_parallel_reversed": three_parallel.stand_ins}


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

    @property
    def chain(self) -> Axes:
        """The chain the kernel works on: ``axes``, or its inverse for the reversed families."""
        return self.axes.reversed() if self.structure.reversed else self.axes

    def branches(self, rt: v3.Mat, pt: v3.Vec, ops: v3.Ops) -> list[Branch]:
        """The ``B`` candidate branches (component tuples) for the target rotation ``rt`` and
        position ``pt`` (components as numpy arrays or CasADi symbols, see ``ops``)."""
        kernel = _KERNELS[self.structure.family]
        chain = self.chain
        if self.structure.reversed:  # solve T^-1 on the inverse chain, q = -reverse(q')
            rt, pt = v3.transpose(rt), v3.scale(-1.0, v3.mat_t_vec(rt, pt))
        rel = v3.mat_mul(rt, tuple(v3.vec(row) for row in chain.home[:3, :3].T))
        out = kernel(chain, self.structure.position, rel, pt, ops)
        if self.structure.reversed:
            out = [tuple(-a for a in b[::-1]) for b in out]
        return out

    def stand_ins(self, count: int) -> tuple[int, ...]:
        """For each of the ``count`` candidates, the candidate it stands in for at a
        singularity (-1: none; `optik.closed_form.three_parallel.stand_ins`): it is dropped
        when that one passes the FK check."""
        family = _STAND_INS.get(self.structure.family)
        return family(count) if family is not None else (-1,) * count

    def candidates(self, t: np.ndarray) -> np.ndarray:
        """Unchecked candidates ``(N, B, 6)`` of the decomposition for targets ``t (N, 4, 4)``."""
        rt, pt = _components(t)
        rows = [
            np.stack(np.broadcast_arrays(*b, pt[0]), axis=-1)[:, :6] for b in self.branches(rt, pt, v3.NUMPY)
        ]
        return np.stack(rows, axis=1)

    def errors_c(self, q: Branch, rt: v3.Mat, pt: v3.Vec, ops: v3.Ops) -> tuple[Any, Any]:
        """Position and orientation (geodesic angle) errors of the branch ``q`` against the
        target ``(rt, pt)``, on components."""
        rr, p = self.axes.fk_c(q, ops)
        dp = v3.sub(p, pt)
        m = v3.mat_mul(rr, v3.transpose(rt))
        skew = (m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1])
        angle = ops.atan2(0.5 * v3.norm(skew, ops), 0.5 * (m[0][0] + m[1][1] + m[2][2] - 1.0))
        return v3.norm(dp, ops), angle

    def solve(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every solution for targets ``t (N, 4, 4)`` (steps 1-4 of the module docstring).

        Returns:
            ``q (N, B, 6)`` wrapped to ``(-pi, pi]`` and ``ok (N, B)``: True for the kept,
            distinct solutions (rows where ``ok`` is False are finite placeholders).
        """
        t = np.asarray(t, dtype=float).reshape(-1, 4, 4)
        q = self.candidates(t)
        q = np.where(np.isfinite(q), q, 0.0)
        rt, pt = _components(t[:, None])
        pos, ori = self.errors_c(tuple(q[..., i] for i in range(6)), rt, pt, v3.NUMPY)
        return self.finish(t, q, pos, ori)

    def finish(
        self, t: np.ndarray, q: np.ndarray, pos: np.ndarray, ori: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Steps 2-4 for candidates ``q (N, B, 6)`` with errors ``pos, ori (N, B)``: polish the
        inexact ones within `polish_range`, check, wrap, merge duplicates."""
        size = self.axes.size
        ok = (pos <= CHECK_TOL * size) & (ori <= CHECK_TOL)
        span = self.polish_range
        near = ~ok & (pos <= span * size) & (ori <= span)
        stand = np.asarray(self.stand_ins(q.shape[1]))
        if (stand >= 0).any():  # a stand-in is dropped when its regular candidate passes
            idx = np.flatnonzero(stand >= 0)
            taken = ok[:, stand[idx]]
            ok[:, idx] &= ~taken
            near[:, idx] &= ~taken
        if near.any():
            idx = np.nonzero(near)
            qq, good = self._polish(q[idx], t[idx[0]])
            q[idx] = qq
            ok[idx] = good
        q = _wrap(q)
        # pairs (j, i), i < j, of kept candidates within SAME_TOL: screened on q1, then all of q
        d0 = np.abs(q[:, :, None, 0] - q[:, None, :, 0])  # in [0, 2 pi): |wrap| = min(d, 2 pi - d)
        screen = (np.minimum(d0, 2.0 * np.pi - d0) < SAME_TOL) & ok[:, :, None] & ok[:, None, :]
        n, j, i = np.nonzero(screen & np.tri(q.shape[1], k=-1, dtype=bool))
        if n.size:
            d = np.abs(q[n, j] - q[n, i])
            dist = np.minimum(d, 2.0 * np.pi - d).max(axis=-1)
            near_pairs = dist < SAME_TOL
            if near_pairs.any():
                self._merge(t, q, ok, n[near_pairs], j[near_pairs], i[near_pairs], dist[near_pairs])
        return np.where(ok[..., None], q, 0.0), ok

    @property
    def check_position(self) -> float:
        """Largest position error the FK check keeps: `CHECK_TOL` times the arm's size (m)."""
        return CHECK_TOL * self.axes.size

    @cached_property
    def defect(self) -> float:
        """The model's defect: the largest error (position over the arm's size, or
        orientation) of the candidate nearest the generating configuration over 16 seeded FK
        targets; rounding for an exact model, the mismatch of the detected relations for models
        whose structure holds only within the detection tolerances (rounded URDF numbers,
        links far shorter than the arm)."""
        q = np.random.default_rng(0).uniform(-np.pi, np.pi, (16, 6))
        t = self.axes.fk(q)
        cand = self.candidates(t)
        rt, pt = _components(t[:, None])
        pos, ori = self.errors_c(tuple(cand[..., i] for i in range(6)), rt, pt, v3.NUMPY)
        return float(np.max(np.min(np.maximum(pos / self.axes.size, ori), axis=1)))

    @property
    def exact(self) -> bool:
        """True when the candidates are exact to rounding (`defect` at most `EXACT_TOL`); False
        when the detected structure holds only within the detection tolerances (the candidates
        then pass the check within `CHECK_TOL`, or are polished)."""
        return self.defect <= EXACT_TOL

    @cached_property
    def polish_range(self) -> float:
        """How inexact a candidate may be and still be polished: 1000 times the `defect`,
        within `POLISH_RANGE`."""
        return min(max(1e3 * self.defect, POLISH_RANGE[0]), POLISH_RANGE[1])

    @cached_property
    def _single(self) -> _Single:
        return _Single(self)

    @cached_property
    def _compiled(self) -> _Compiled:
        return _Compiled()

    def compile(self) -> None:
        """Build the compiled single-target driver now and wait for it
        (`optik.closed_form.ik_all`; otherwise its build starts in the background at the first
        single-target call). Without a C compiler nothing is built: CasADi's evaluator answers."""
        if self.structure.position == "general":
            return
        kernel = self._kernel()
        if kernel.library is not None:
            kernel.library.wait()

    def solve_one(self, t: np.ndarray) -> list[list[float]]:
        """The solutions for one target ``t (4, 4)`` as rows, the same as ``solve(t)`` but
        through the compiled driver (`optik.closed_form.ik_all`): about a hundred times cheaper
        per call than the numpy kernel on one target. While the driver builds (in the
        background, from the first call) the numpy kernel answers; without compiled code, the
        symbolic kernel on CasADi's evaluator (`_Single`). Targets with a candidate to polish or
        two close candidates take the numpy path (`finish`), as do the families solved by SP5 /
        SP6 (``general`` position case: eigenvalues, numpy only); the others return
        [`CheckedRows`][optik.closed_form.registry.CheckedRows] carrying the kernel's FK check
        of each row (the product-of-exponentials model, equal to the mechanism's FK to
        rounding: `axes_of` checks it)."""
        if self.structure.position == "general":  # SP5 / SP6 eigenvalues: numpy only
            return self._solve_numpy(t)
        driver = self.driver()
        if driver is not None:
            got = driver(t, None, _NO_LIMIT, _NO_LIMIT_UP, sort=False)
            if got is not None:
                return registry.CheckedRows(got[0].tolist(), [tuple(e) for e in got[1].tolist()], True)
            return self._solve_numpy(t)
        library = self._kernel().library
        if library is not None and library.state == "building":
            return self._solve_numpy(t)
        one = self._single  # no compiled code: CasADi's evaluator
        with one.lock:
            one.t[:] = t.reshape(16)
            one.function_call()
            flags = one.flags.tolist()
            if flags[0] > 0.0 or flags[1] < SAME_TOL:  # a candidate to polish, or two close ones
                qa = one.q.reshape(1, -1, 6).copy()
                e = one.err.reshape(1, -1, 2).copy()
            else:
                q, err, ok = one.q.tolist(), one.err.tolist(), one.ok.tolist()
                keep = [i for i, flag in enumerate(ok) if flag]
                return registry.CheckedRows(
                    [q[6 * i : 6 * i + 6] for i in keep], [(err[2 * i], err[2 * i + 1]) for i in keep], True
                )
        qa, oka = self.finish(np.asarray(t, dtype=float).reshape(1, 4, 4), qa, e[..., 0], e[..., 1])
        return qa[0][oka[0]].tolist()

    def _solve_numpy(self, t: np.ndarray) -> list[list[float]]:
        q, ok = self.solve(t)
        return q[0][ok[0]].tolist()

    def driver(self) -> AllSolutionsKernel | None:
        """The compiled single-target driver once it is loaded, else None (its build starts in
        the background at the first call). None always for the ``general`` position case
        (SP5 / SP6 eigenvalues: numpy only)."""
        if self.structure.position == "general":
            return None
        kernel = self._kernel()
        return kernel if kernel.ready else None

    def _kernel(self) -> AllSolutionsKernel:
        """The driver of `optik.closed_form.ik_all` (made once; its library is loaded from the
        cache or built in the background)."""
        holder = self._compiled
        if holder.kernel is None:
            with holder.lock:
                if holder.kernel is None:
                    holder.kernel = _driver_kernel(self)
        return holder.kernel

    def _polish(self, q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gauss-Newton on ``q (K, 6)`` for targets ``t (K, 4, 4)``; which pass the check."""
        for _ in range(POLISH_STEPS):
            pose, jac = self.axes.jacobian(q)
            q = q - _solve_steps(jac, _errors(pose, t)[0])
        res, angle = _errors(self.axes.fk(q), t)
        return q, (np.linalg.norm(res[..., :3], axis=-1) <= CHECK_TOL * self.axes.size) & (angle <= CHECK_TOL)

    def _merge(
        self, t: np.ndarray, q: np.ndarray, ok: np.ndarray, n: np.ndarray, j: np.ndarray, i: np.ndarray,
        dist: np.ndarray,
    ) -> None:  # fmt: skip
        """Drop (in ``ok``) each candidate ``j`` that is the same solution as an earlier kept
        ``i`` (pairs ``(n, j, i)`` at distance ``dist``), the distance being tied to the accuracy
        of both (module docstring, step 4)."""
        for target in np.unique(n):
            pose, jac = self.axes.jacobian(q[target])
            norm = np.linalg.norm(_errors(pose, t[target])[0], axis=-1)
            sigma = np.linalg.svd(jac, compute_uv=False)[..., -1]
            tol = np.minimum(SAME_TOL, 100.0 * norm / np.maximum(sigma, 1e-300) + 1e-9)
            sel = np.nonzero(n == target)[0]
            for k in sel[np.lexsort((i[sel], j[sel]))]:  # by j, then i
                a, b = j[k], i[k]
                if ok[target, a] and ok[target, b] and dist[k] < max(tol[a], tol[b]):
                    ok[target, a] = False


@functools.cache
def _pairs(b: int) -> list[tuple[int, int]]:
    """Pairs ``(i, j)``, ``i < j``, of ``b`` candidates."""
    return [(i, j) for j in range(b) for i in range(j)]


class _Single:
    """The kernel of a `DerivedIK` as one CasADi function of a single target, evaluated on
    preallocated buffers (``Function.buffer``): 16 target entries (row-major) in; out the ``B``
    branches wrapped to ``(-pi, pi]`` (``6 B``), their position and orientation errors (``2 B``),
    whether each passes the FK check (``B``), and two flags: the number of candidates to polish
    and the smallest wrapped max-norm distance between two passing ones. Guarded by a lock (the
    buffers are shared). CasADi's evaluator runs it where there is no compiled driver of the
    same steps (`optik.closed_form.ik_all`: no C compiler, or its build failed)."""

    def __init__(self, solver: DerivedIK) -> None:
        t = ca.SX.sym("t", 16)
        rt = tuple(tuple(t[4 * i + j] for j in range(3)) for i in range(3))
        pt = (t[3], t[7], t[11])
        ops = v3.CASADI
        raw = solver.branches(rt, pt, v3.remembering(ops))
        two_pi = 2.0 * np.pi
        wrapped = [[_wrap_sx(a) for a in b] for b in raw]  # (-pi, pi]
        errs = [solver.errors_c(b, rt, pt, ops) for b in raw]
        # the FK check and the two reasons for the numpy path, decided in the same function
        size, span = solver.axes.size, solver.polish_range
        passed = [(pos <= CHECK_TOL * size) * (ori <= CHECK_TOL) for pos, ori in errs]
        # a stand-in counts only when its regular candidate fails (DerivedIK.stand_ins)
        free = [1 if s < 0 else 1 - passed[s] for s in solver.stand_ins(len(raw))]
        ok = [p * f for p, f in zip(passed, free, strict=True)]
        near = sum(
            f * (1 - p) * (pos <= span * size) * (ori <= span)
            for p, f, (pos, ori) in zip(passed, free, errs, strict=True)
        )
        closest = ca.inf
        for i, j in _pairs(len(raw)):
            dist = 0.0
            for a, b in zip(wrapped[i], wrapped[j], strict=True):
                d = ca.fabs(a - b)
                dist = ops.fmax(dist, ops.fmin(d, two_pi - d))
            closest = ops.fmin(closest, ops.where(ok[i] * ok[j], dist, ca.inf))
        outs = [
            ca.vertcat(*[a for b in wrapped for a in b]),
            ca.vertcat(*[e for pair in errs for e in pair]),
            ca.vertcat(*ok),
            ca.vertcat(near, closest),
        ]
        self.function = f = ca.Function("derived_ik", [t], outs)
        self.t = np.zeros(16)
        self.q = np.zeros(6 * len(raw))
        self.err = np.zeros(2 * len(raw))
        self.ok = np.zeros(len(raw))
        self.flags = np.zeros(2)
        self.outputs = [self.q, self.err, self.ok, self.flags]
        self.buffer, self.function_call = f.buffer()
        self.buffer.set_arg(0, memoryview(self.t))
        for k, out in enumerate(self.outputs):
            self.buffer.set_res(k, memoryview(out))
        self.lock = threading.Lock()


class _Compiled:
    """The compiled driver of a `DerivedIK`, made at its first use (guarded by a lock)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.kernel: AllSolutionsKernel | None = None


def _driver_kernel(solver: DerivedIK) -> AllSolutionsKernel:
    """The driver of `optik.closed_form.ik_all` for ``solver``: its candidates (the symbolic
    kernel, with the cosines and sines it makes remembered, `optik.closed_form.vec3.remembering`)
    in groups (`candidate_groups`: one function for the regular candidates, one for each run of
    stand-ins, which the driver evaluates only when they are needed) and the FK check of one
    candidate (on the cosines and sines of its angles), with the check and polish tolerances of
    `finish`."""
    t = ca.SX.sym("t", 16)
    rt = tuple(tuple(t[4 * i + j] for j in range(3)) for i in range(3))
    pt = (t[3], t[7], t[11])
    raw = solver.branches(rt, pt, v3.remembering(v3.CASADI))
    stand_ins = solver.stand_ins(len(raw))
    groups = [
        (ca.Function(f"optik_ik_branches_{g}", [t], [ca.vertcat(*[a for k in ks for a in raw[k]])]), ks)
        for g, ks in enumerate(candidate_groups(stand_ins))
    ]
    # the check takes the cosines and sines of the candidate (the driver evaluates them from q)
    q, cs = ca.SX.sym("q", 6), ca.SX.sym("cs", 12)
    ops = v3.remembering(v3.CASADI)
    angles = tuple(ops.known(q[i], cs[i], cs[6 + i]) for i in range(6))
    err = solver.errors_c(angles, rt, pt, ops)
    size, span = solver.axes.size, solver.polish_range
    return AllSolutionsKernel(
        groups,
        ca.Function("optik_ik_check", [cs, t], [ca.vertcat(*err)]),
        stand_ins,
        (CHECK_TOL * size, CHECK_TOL),
        (span * size, span),
        SAME_TOL,
    )


def candidate_groups(stand_ins: tuple[int, ...]) -> list[tuple[int, ...]]:
    """The candidates split for lazy evaluation: the regular ones (``stand_ins[k] < 0``) first,
    then each maximal run of consecutive stand-ins (those of one ``(q1, q5)`` pair of
    `optik.closed_form.three_parallel`, which share their intermediate values)."""
    groups = [tuple(k for k, s in enumerate(stand_ins) if s < 0)]
    for k, s in enumerate(stand_ins):
        if s >= 0:
            if k > 0 and stand_ins[k - 1] >= 0:
                groups[-1] += (k,)
            else:
                groups.append((k,))
    return groups


def _wrap_sx(a: ca.SX) -> ca.SX:
    """``a`` to ``(-pi, pi]`` with the arithmetic of `_wrap` and
    [`Mechanism.wrap`][optik.Mechanism.wrap] (numpy's ``remainder``: ``fmod``, then ``+ 2 pi``
    for a negative remainder), so that every path gives the same numbers."""
    two_pi = 2.0 * np.pi
    r = ca.fmod(a + np.pi, two_pi)
    w = ca.if_else(r < 0, r + two_pi, r) - np.pi
    return ca.if_else(w <= -np.pi, w + two_pi, w)


def _components(t: np.ndarray) -> tuple[v3.Mat, v3.Vec]:
    """Rotation and position of transforms ``t (..., 4, 4)`` as component tuples."""
    rt = tuple(tuple(t[..., i, j] for j in range(3)) for i in range(3))
    return rt, (t[..., 0, 3], t[..., 1, 3], t[..., 2, 3])  # type: ignore[return-value]


def _solve_steps(jac: np.ndarray, res: np.ndarray) -> np.ndarray:
    """Damped Gauss-Newton steps ``(J^T J + mu I)^-1 J^T r``, ``mu`` 1e-12 times the mean
    diagonal of ``J^T J`` (relative, so that singular poses and arms with links of very
    different lengths stay solvable in floating point)."""
    jt = np.swapaxes(jac, -1, -2)
    a = jt @ jac
    n = a.shape[-1]
    mu = 1e-12 * np.maximum(np.trace(a, axis1=-2, axis2=-1) / n, 1e-300)
    a = a + mu[..., None, None] * np.eye(n)
    return np.linalg.solve(a, np.einsum("...ij,...j->...i", jt, res)[..., None])[..., 0]


def derive_axes(axes: Axes) -> DerivedIK | None:
    """The derived IK of a product-of-exponentials chain, or None when no family is detected."""
    structure = detect(axes)
    return None if structure is None else DerivedIK(axes, structure)


_AXES: PerMechanism[Axes | None] = PerMechanism()
_CACHE: PerMechanism[DerivedIK | None] = PerMechanism()


def chain_axes(m: Mechanism) -> Axes | None:
    """`axes_of` of a mechanism with task ``"pose"``, cached per mechanism (None otherwise)."""
    try:
        return _AXES[m]
    except KeyError:
        pass
    axes = axes_of(m) if m.task == "pose" else None
    _AXES[m] = axes
    return axes


def derive(m: Mechanism) -> DerivedIK | None:
    """The derived IK of a mechanism (cached per mechanism), or None when it is not a 6R serial
    chain of a decomposable family (its task must be ``"pose"``)."""
    try:
        return _CACHE[m]
    except KeyError:
        pass
    axes = chain_axes(m) if m.n_q == 6 else None
    solver = None if axes is None else derive_axes(axes)
    _CACHE[m] = solver
    return solver


def locked_axes(m: Mechanism, locked: dict[int, float]) -> Axes | None:
    """The 6R chain left when the coordinates ``locked`` (index -> value) of a serial revolute
    chain are fixed (`Axes.lock`, highest index first), or None when ``m`` is not such a chain
    or that does not leave 6 joints."""
    axes = chain_axes(m)
    if axes is None or axes.n - len(locked) != 6:
        return None
    for index in sorted(locked, reverse=True):
        axes = axes.lock(index, locked[index])
    return axes


def derive_locked(m: Mechanism, locked: dict[int, float]) -> DerivedIK | None:
    """The derived IK of the `locked_axes` chain, or None when there is none or it is not
    decomposable."""
    axes = locked_axes(m, locked)
    return None if axes is None else derive_axes(axes)


class DerivedRows:
    """The registry solver ``(m, T) -> rows`` of a `DerivedIK`
    ([`DerivedIK.solve_one`][optik.closed_form.derived.DerivedIK.solve_one]); ``solver`` lets
    callers reach the derived solver itself (`optik.solve_ik_all` calls its compiled driver)."""

    def __init__(self, solver: DerivedIK) -> None:
        self.solver = solver

    @property
    def exact(self) -> bool:
        """[`DerivedIK.exact`][optik.closed_form.derived.DerivedIK.exact]: read by
        [`optik.closed_form.registry.ik_solver`][optik.closed_form.registry.ik_solver] for the
        kinds that prefer an exact derived solver to their own."""
        return self.solver.exact

    def __call__(self, _: Mechanism, t: np.ndarray) -> list[list[float]]:
        return self.solver.solve_one(t)


def derived_rows(m: Mechanism) -> registry.IKSolver | None:
    """Registry deriver: ``(m, T) -> rows`` of every derived solution (a `DerivedRows`), or None."""
    solver = derive(m)
    return None if solver is None else DerivedRows(solver)


class GeneralRows:
    """The registry solver ``(m, T) -> rows`` of the general 6R solver
    ([`ik_general_6r`][optik.closed_form.general_6r.ik_general_6r]), marked ``costly``
    ([`registry.costly`][optik.closed_form.registry.costly]): about 0.6 ms per target, five
    times ``lm``'s median, so `optik.solve_ik` with ``method=None`` tries ``lm`` first."""

    costly = True

    def __call__(self, m: Mechanism, t: np.ndarray) -> list[np.ndarray]:
        return general_6r.ik_general_6r(m, t)


def general_rows(m: Mechanism) -> registry.IKSolver | None:
    """Registry deriver after [`derived_rows`][optik.closed_form.derived.derived_rows]: a 6R
    serial chain of no decomposable family gets the general 6R solver (a `GeneralRows`: all 16
    complex solutions' real ones, each FK-checked) when it covers the geometry
    ([`covers`][optik.closed_form.general_6r.covers]: no certified answer otherwise)."""
    if m.n_q != 6 or derive(m) is not None or chain_axes(m) is None or not general_6r.covers(m):
        return None
    return GeneralRows()


registry.register_deriver(derived_rows)
registry.register_deriver(general_rows)
