"""All inverse-kinematics solutions of a general 6R serial arm (no special axes), by an eigenvalue
problem in the style of Raghavan-Roth and Manocha-Canny.

Any chain of six revolute joints is first written in standard Denavit-Hartenberg form

``T(q) = B A1(theta_1) ... A6(theta_6) E``,  ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``,
``theta_i = q_i + o_i``,

from its joint lines at ``q = 0`` (`General6R.from_mechanism`; the common normals of
consecutive axes give ``a_i, alpha_i, d_i`` and the offsets ``o_i``). With ``T' = B^-1 T E^-1``:

1. **Fourteen equations.** ``A3 A4 A5 = A2^-1 A1^-1 T' A6^-1``; the third and fourth columns of
   ``A6^-1`` do not depend on ``theta_6``, so the axis ``l`` and the point ``p`` of frame 5 seen
   from frame 2 give six equations without ``theta_6``. With ``p.p``, ``p.l``, ``p x l`` and
   ``(p.p) l - 2 (p.l) p`` (computed on each side) there are fourteen, and every one is
   trigonometric of degree at most one in each of ``theta_3, theta_4, theta_5`` (left side) and
   in each of ``theta_1, theta_2`` (right side). The coefficients are computed exactly by a
   five-point discrete Fourier transform per angle (a check that the degree-two coefficients
   vanish guards this); no symbolic expansion is written out by hand.
2. **Eliminate theta_1, theta_2.** The right sides are ``Q x_R`` with ``x_R`` the eight
   non-constant products of ``(1, c1, s1) (x) (1, c2, s2)``; the six left null vectors of the
   ``14 x 8`` matrix ``Q`` (an SVD) leave six equations ``Sigma(theta_3) x_L = 0`` in the nine
   products of ``(theta_4, theta_5)``.
3. **12 x 12 resultant.** With half-angle tangents ``x_k = tan(phi_k / 2)`` and the six
   equations multiplied by ``(1 + x_3^2)(1 + x_4^2)(1 + x_5^2)`` and then by ``1`` and
   ``x_4``, one gets ``M(x_3) w = 0``, ``M(x_3) = A x_3^2 + B x_3 + C`` (``12 x 12``) and
   ``w = (x_4^i x_5^j)``, ``i <= 3``, ``j <= 2``. ``det M(x_3)`` has degree 24 and the factor
   ``(1 + x_3^2)^4``; its 16 other roots are the solutions. They are the eigenvalues of the
   ``24 x 24`` companion matrix of ``A^-1 M`` (the eigenvectors give ``x_4`` and ``x_5``); the
   8 eigenvalues nearest ``+-i`` are the spurious factor.
4. **Back-substitution.** ``x_R`` follows by least squares from the fourteen equations
   (``theta_1, theta_2`` from its ``c, s`` entries), ``theta_6`` from ``A6 = (A1..A5)^-1 T'``.

The angles in steps 1-3 are ``phi_k = theta_k - delta_k`` for fixed pseudo-random rotations
``delta_3, delta_4, delta_5`` (`ROTATIONS`): a real Moebius change of the half-angle
variables that keeps ``+-i`` fixed and moves the poles ``x_k = inf`` away from any special angle
of a designed arm, so that ``A`` is invertible and the eigenvectors are well scaled unless a
solution lies exactly at the rotated pole (probability zero; then, and whenever ``A`` is badly
conditioned, the ``24 x 24`` generalized eigenproblem is solved by QZ instead).

When the count check fails, the inverse chain (`General6R.reversed`) is solved too: axes 1-2
intersecting or parallel make ``M(x_3)`` singular for every ``x_3``, and the inverse chain has
them at positions 5-6, where the elimination is regular. When both ends fail, the real solutions
of a nearby generic arm (`General6R.perturbed`) are polished on the arm and added, without a
certificate (the count check stays failed). `covers` tells beforehand whether an arm's geometry
is covered (regular from one end).

**Certification.** Every finite eigenvalue is a candidate, except those far from the real axis
(``|Im(phi_3)| > _FAR``) of a well-posed pencil (`_WELL_POSED`), which count as complex. Each
candidate (``theta_1 .. theta_6`` complex, from the eigenvector and the back-substitution) is
Newton-polished in complex space on the full pose residual (six equations, six unknowns) of the
DH model: a real root that rounding moved off the real axis (which happens when the pencil is
nearly singular, e.g. axes within 1e-5 rad of parallel) converges back to it, a complex root
converges where it is. A candidate near the real axis (``|Im(phi_3)| <= _REAL_RETRY``) whose
polish does not end real is polished from its real part as well (on a singular pencil the
eigenvalues mean nothing, but their real parts often lie next to real solutions). A candidate
whose angles are real to `IMAG_TOL` is a real candidate: it is polished on the real model (for a
mechanism on ``m.fk`` / ``m.jacobian`` where still needed), kept only when the final forward
kinematics matches the target to `FK_TOL` (position relative to the arm's size, orientation in
radians) and deduplicated (1e-6 rad, angles modulo 2 pi). The count check: a 6R arm has at most
16 isolated solutions in complex space (16 for a generic arm), so 16 distinct verified ones are
all of them. The result reports the number of finite eigenvalues (``n_finite``, 16 expected), of
distinct real and complex solutions, and flags (``count_ok = False``) any instance where they do
not add up to 16, where fewer than 16 finite eigenvalues were found, where ``M(x_3)`` is
singular at two test points (a singular pencil, whose eigenvalues mean nothing), or where a
candidate did not converge or a real one failed its check: the arm or the pose is then
degenerate (special geometry, a pose on a singular boundary, a root that cannot be decided) and
solutions may be missing.

**In C.** Steps 1-3, the eigenvalues, the candidates' back-substitution and complex polish and
the real candidates' last polish on the DH model run for each target in one C call
(``general_6r.c``, ``optik_g6r_solve``, built once per machine in the background,
`optik.native.CFunction`; its linear algebra is scipy's LAPACK, ``dgesdd``, ``dgetrf``,
``dgetrs``, ``dlasq1`` (after our own bidiagonalization, for the singular values of the
12 x 12 probes and of ``A``) and, for the eigenvalues alone, ``dgebal``, ``dgehd2``, ``dlahqr``,
run on one OpenBLAS thread; each candidate's ``w`` is the null vector of its ``M(x_3)`` by complete
pivoting, not the companion matrix's eigenvector); numpy answers until it is built,
without a compiler (logged), for a badly conditioned ``A`` (QZ) and for an exactly singular
Jacobian. Both give the same candidates to rounding; the polish on ``m.fk``, the FK check (the
mechanism's own FK expression on all candidates of a batch at once, `_MechanismRows`, reused from
that polish) and the count check are common, the count
check for all targets of a batch at once (counts by ``np.bincount`` over the candidates' targets,
`_distinct` for the deduplication).
"""

from __future__ import annotations

import ctypes
import functools
import itertools
import logging
import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from optik import native
from optik.checks import as_transform, as_vector
from optik.closed_form import registry
from optik.closed_form.structure import Axes, axes_of
from optik.errors import InvalidArgumentError, ShapeError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism

__all__ = [
    "FK_TOL",
    "IMAG_TOL",
    "PERTURBATION",
    "ROTATIONS",
    "General6R",
    "General6RSolutions",
    "covers",
    "ik_general_6r",
    "solve_general_6r",
]

FK_TOL = 1e-9
"""Largest accepted FK mismatch of a returned solution (position / arm size, orientation rad)."""

IMAG_TOL = 1e-8
"""A candidate polished in complex space is a real solution when every ``|Im(theta_i)|`` is
below this (a complex solution otherwise); the FK check on the real part then decides."""

_CONVERGED = 1e-10
"""Largest pose residual (unit scale, times `_magnitude`) of a converged candidate."""

_REAL_RETRY = 1e-3
"""A candidate with ``|Im(phi_3)| <= _REAL_RETRY`` whose complex polish does not end real is
polished from its real part as well."""

_FAR = 1.0
"""An eigenvalue with ``|Im(phi_3)| > _FAR`` of a well-posed pencil (`_WELL_POSED`) is counted
complex without polishing; every other one is polished and verified (or the count fails)."""

_WELL_POSED = 1e-7
"""``M(x)`` is well posed when its smallest singular value relative to its largest exceeds this
at one of the test points (`_PROBES`). Generic arms measure above 1e-4; the eigenvalues of
arms below 1e-7 (axes within 1e-5 rad of parallel at both ends) move by up to 0.2 rad off the
real axis, and much more below that."""

ROTATIONS = (0.7853981633974483 + 0.2718281828, -0.5772156649, 0.4142135624)
"""The fixed rotations ``delta_3, delta_4, delta_5`` (rad) of the eliminated angles."""

PERTURBATION = 1e-4
"""Relative size of the change that makes a special arm generic (`General6R.perturbed`)."""

NEWTON_ITERATIONS = 12
"""Newton iterations on the pose residual per candidate (converged candidates stop early)."""

_EXACT = 1e-14
"""FK error (relative position, rad) below which a polished solution counts as exact."""

_PARALLEL = 1e-5
"""Consecutive axes with ``|h_i x h_j|`` below this get a DH frame as if they were parallel.
The DH description of nearly parallel axes is ill-conditioned either way (a common normal of
length ``~ 1 / |h_i x h_j|``, or a model off by ``~ |h_i x h_j|``); it only generates the
candidates, which are polished on the exact model."""

_MODEL_TOL = 1e-4
"""Largest accepted mismatch (relative to the arm's size) between a mechanism and its DH
description (rounding, or axes within `_PARALLEL` of parallel)."""

_SAME = 1e-6
"""Two polished solutions closer than this (rad, modulo 2 pi) are the same."""

_DFT_TOL = 1e-9
"""Relative size of the degree-two Fourier coefficients above which the structure check fails."""

_COND_QZ = 1e10
"""Condition number of the leading matrix ``A`` above which QZ replaces the companion matrix."""

_PROBES = np.array([[1.0, 0.5773502692, 0.3333333333], [1.0, -1.7320508076, 3.0]])
"""``(1, x, x^2)`` at two test points where ``M(x)`` is checked for being nonsingular."""

_SINGULAR_PENCIL = 1e-10
"""``M(x)`` is singular for every ``x`` when its smallest singular value relative to its largest
is below this at both test points."""

# (1 + x^2) e^{i k phi} = (1 + i x)^(1 + k) (1 - i x)^(1 - k), k = -1, 0, 1 -> powers x^0, x^1, x^2
_HALF = np.array([[1.0, 1.0, 1.0], [-2j, 0.0, 2j], [-1.0, 1.0, -1.0]])
_GRID = 2.0 * np.pi * np.arange(5) / 5.0
_GRID3 = 2.0 * np.pi * np.arange(3) / 3.0
"""Three samples per angle: exact for the right sides (trigonometric of degree one), in C."""
_TWO_PI = 2.0 * np.pi
_LOG = logging.getLogger(__name__)
_SOURCE = Path(__file__).with_name("general_6r.c")
_POLISH = native.CFunction(
    _SOURCE,
    "optik_general_6r",
    "optik_g6r_polish",
    [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p],
)
"""`_polish` in C."""
_BACK = native.CFunction(
    _SOURCE, "optik_general_6r", "optik_g6r_back", [ctypes.c_void_p, ctypes.c_int, *[ctypes.c_void_p] * 5]
)
"""The back-substitution of `_candidates` in C."""
_SOLVE = native.CFunction(
    _SOURCE,
    "optik_general_6r",
    "optik_g6r_solve",
    [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, *[ctypes.c_void_p] * 9],
)
"""`_candidates` in C, the whole elimination of many targets in one call (`_candidates_c`)."""
_DISTINCT = native.CFunction(
    _SOURCE,
    "optik_general_6r",
    "optik_g6r_distinct",
    [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_int, *[ctypes.c_void_p] * 3],
)
"""`_distinct` in C."""
_POSE_ERRORS = native.CFunction(
    _SOURCE,
    "optik_general_6r",
    "optik_g6r_pose_errors",
    [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p],
)
"""`_pose_errors` in C."""
_MAX_CANDIDATES = 24
"""Candidates per target the C solve has room for (at most 16 eigenvalues are candidates)."""
_LAPACK_ROUTINES = ("dgesdd", "dgebal", "dgehd2", "dlahqr", "dgetrf", "dgetrs", "dlasq1")


_EMPTY_CHARS = ctypes.c_char * 0


def _address(a: np.ndarray) -> int:
    """The address of the first element of a C-contiguous array, for the C kernels: through a
    buffer export (``ctypes`` over the array's memory, about 0.15 us) where the array is
    writable, else ``a.ctypes.data`` (which builds a ``ctypes`` helper object per read, about
    1.3 us: a dozen reads a solve made a tenth of a single target's call)."""
    try:
        return ctypes.addressof(_EMPTY_CHARS.from_buffer(a))
    except TypeError:  # read-only (e.g. a caller's array passed through as it is)
        return a.ctypes.data


# ---------------------------------------------------------------------------- DH kinematics
def _dh(theta: np.ndarray, d: Any, a: Any, alpha: Any) -> np.ndarray:
    """``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` for an array of angles: shape ``theta.shape + (4, 4)``;
    ``d, a, alpha`` are numbers, or arrays along the last axis of ``theta`` (one joint each:
    all the joints' transforms in one go)."""
    c, s = np.cos(theta), np.sin(theta)
    if np.ndim(alpha):  # math.cos per joint: the same numbers as for one joint
        ca, sa = (np.array([f(v) for v in np.asarray(alpha).tolist()]) for f in (math.cos, math.sin))
    else:
        ca, sa = math.cos(alpha), math.sin(alpha)
    out = np.zeros((*np.shape(theta), 4, 4), dtype=np.result_type(theta, float))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2], out[..., 0, 3] = c, -s * ca, s * sa, a * c
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2], out[..., 1, 3] = s, c * ca, -c * sa, a * s
    out[..., 2, 1], out[..., 2, 2], out[..., 2, 3] = sa, ca, d
    out[..., 3, 3] = 1.0
    return out


def _inv(t: np.ndarray) -> np.ndarray:
    """Inverse of homogeneous transforms ``(..., 4, 4)``."""
    out = np.zeros_like(t)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -(rt @ t[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def _fourteen(l: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The 14 Raghavan-Roth quantities ``(l, p, p.p, p.l, p x l, (p.p) l - 2 (p.l) p)``: ``(..., 14)``."""
    pp = np.sum(p * p, axis=-1, keepdims=True)
    pl = np.sum(p * l, axis=-1, keepdims=True)
    return np.concatenate([l, p, pp, pl, np.cross(p, l), pp * l - 2.0 * pl * p], axis=-1)


def _fourier(samples: np.ndarray, axes: Sequence[int]) -> np.ndarray:
    """Trigonometric coefficients ``k = -1, 0, 1`` along ``axes`` (five samples each, exact for
    degree <= 2) after checking that the degree-two coefficients vanish."""
    c = samples.astype(complex)
    for ax in axes:
        c = np.fft.fft(c, axis=ax) / 5.0
    scale = max(float(np.max(np.abs(c))), 1e-300)
    for ax in axes:
        high = np.take(c, [2, 3], axis=ax)
        if float(np.max(np.abs(high))) > _DFT_TOL * scale:  # pragma: no cover - a derivation check
            raise RuntimeError("general 6R: an elimination equation has trigonometric degree > 1")
    for ax in axes:
        c = np.take(c, [4, 0, 1], axis=ax)  # k = -1, 0, 1
    return c


@dataclass(frozen=True)
class General6R:
    """A 6R arm in standard DH form with base and tool transforms.

    ``T(q) = base A1(q_1 + offset_1) ... A6(q_6 + offset_6) tool`` with
    ``A_i(theta) = Rz(theta) Tz(d_i) Tx(a_i) Rx(alpha_i)``.

    Attributes:
        a, alpha, d, offset: DH parameters, six each (lengths in m, angles in rad).
        base, tool: 4x4 transforms before the first and after the last DH matrix.
        scale: characteristic length (largest translation of the description, at least 1e-12);
            the elimination runs on the arm scaled to unit size.
    """

    a: np.ndarray
    alpha: np.ndarray
    d: np.ndarray
    offset: np.ndarray = field(default_factory=lambda: np.zeros(6))
    base: np.ndarray = field(default_factory=lambda: np.eye(4))
    tool: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        for key in ("a", "alpha", "d", "offset"):
            object.__setattr__(self, key, as_vector(getattr(self, key), key, 6).copy())
        for key in ("base", "tool"):
            object.__setattr__(self, key, as_transform(getattr(self, key), key).copy())

    @classmethod
    def from_mechanism(cls, m: Mechanism) -> General6R:
        """The DH description of an optik mechanism with exactly six revolute coordinates in one
        serial chain from the base to the end effector (fixed joints in between are allowed).

        The joint lines at ``q = 0`` (`optik.closed_form.structure.axes_of`: a point and a
        direction per axis in the base frame, checked against ``m.fk``) give the common normals
        of consecutive axes; parallel axes take the normal through the previous frame's origin
        (``d_i = 0``), intersecting axes ``x_i = z_{i-1} x z_i``. The DH model is checked
        against ``m.fk`` at seeded random ``q`` too, to `_MODEL_TOL` (it generates candidates;
        the solutions are polished on ``m.fk`` itself).

        Raises:
            InvalidArgumentError: (argument ``m``) not a serial chain of six revolute joints,
                or the DH description does not reproduce ``m.fk``.
        """
        axes = axes_of(m) if m.n_q == 6 else None
        if axes is None:
            raise InvalidArgumentError(
                "m", f"{m.name!r}: expected a serial chain of six revolute joints (n_q={m.n_q})"
            )
        return cls._checked(axes, m.fk, "m", f"{m.name!r}: its DH description does not reproduce m.fk")

    @classmethod
    def from_axes(cls, axes: Axes) -> General6R:
        """The DH description of six joint lines in product-of-exponentials form (an
        `optik.closed_form.structure.Axes`, e.g. a 7-DOF arm's chain with one joint locked,
        `Axes.lock`), checked against ``axes.fk`` at seeded random ``q`` to `_MODEL_TOL`.

        Raises:
            InvalidArgumentError: (argument ``axes``) not six axes, or the DH description does
                not reproduce ``axes.fk``.
        """
        if axes.n != 6:
            raise InvalidArgumentError("axes", f"expected six joint axes, got {axes.n}")
        return cls._checked(axes, axes.fk, "axes", "the DH description does not reproduce axes.fk")

    @classmethod
    def _checked(cls, axes: Axes, fk: Any, argument: str, complaint: str) -> General6R:
        """`_dh_from_lines` of ``axes``, compared with ``fk`` at four seeded random ``q``."""
        arm = _dh_from_lines(axes.r, axes.h, axes.home)
        q = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(4, 6))
        err = float(np.max(np.abs(arm.fk(q) - fk(q))))
        if err > _MODEL_TOL * max(1.0, arm.scale):
            raise InvalidArgumentError(argument, f"{complaint} ({err:.1e})")
        return arm

    @cached_property
    def scale(self) -> float:
        """The characteristic length of the arm (computed once: a solve reads it several times)."""
        lengths = np.concatenate([self.a, self.d, self.base[:3, 3], self.tool[:3, 3]])
        return max(float(np.max(np.abs(lengths))), 1e-12)

    def fk(self, q: Any) -> np.ndarray:
        """``T(q)``: 4x4, or ``(N, 4, 4)`` for ``q`` of shape ``(N, 6)``."""
        theta = np.asarray(q, dtype=float) + self.offset
        t = np.broadcast_to(self.base, (*theta.shape[:-1], 4, 4)).copy()
        for i in range(6):
            t = t @ _dh(theta[..., i], self.d[i], self.a[i], self.alpha[i])
        return t @ self.tool

    @cached_property
    def _base_inv(self) -> np.ndarray:
        return _inv(self.base)

    @cached_property
    def _tool_inv(self) -> np.ndarray:
        return _inv(self.tool)

    def _unit(self) -> tuple[np.ndarray, np.ndarray]:
        """Scaled ``(a, d)``: the arm at unit size."""
        return self.a / self.scale, self.d / self.scale

    @cached_property
    def _left(self) -> _Left:
        """The arm-only part of the elimination (computed once)."""
        return _Left(self)

    @cached_property
    def covered(self) -> bool:
        """Whether the eigenvalue method covers this geometry: at three seeded random poses the
        elimination is regular (``Q`` of full rank and ``M(x_3)`` not singular for every
        ``x_3``) from at least one end of the chain. False for e.g. axes 1-2 and 5-6 both
        intersecting, three consecutive parallel axes at an end, and most decomposable families;
        a router should send only covered arms to `solve_general_6r`."""
        targets = self.fk(np.random.default_rng(0).uniform(-np.pi, np.pi, (3, 6)))
        fwd = _matrices(self, _unit_targets(self, targets))
        back = _matrices(self.reversed, _unit_targets(self.reversed, _inv(targets)))
        return bool(np.all((fwd[5] & fwd[6]) | (back[5] & back[6])))

    @cached_property
    def perturbed(self) -> General6R:
        """A generic arm near this one: every DH length moved by `PERTURBATION` times the arm's
        size and every twist by `PERTURBATION` rad, in fixed pseudo-random directions. Its real
        solutions, polished on this arm, recover the nonsingular real solutions of special
        geometry that the elimination cannot treat (no certificate: the count check stays
        failed)."""
        r = np.random.default_rng(0).normal(size=(3, 6))
        step = PERTURBATION * self.scale
        return General6R(
            self.a + step * r[0],
            self.alpha + PERTURBATION * r[1],
            self.d + step * r[2],
            self.offset,
            self.base,
            self.tool,
        )

    @cached_property
    def reversed(self) -> General6R:
        """The inverse chain: ``T(q)^-1 = reversed.fk(q[::-1])``, as its own DH description.

        In product-of-exponentials form ``T(q) = exp(xi_1 q_1) ... exp(xi_6 q_6) M``, so
        ``T^-1 = exp(-xi'_6 q_6) ... exp(-xi'_1 q_1) M^-1`` with the joint lines ``xi'`` seen from
        the end effector at ``q = 0``: the same arm solved from its other end.
        """
        home = self.fk(np.zeros(6))
        pre = self.base.copy()
        points, dirs = np.zeros((6, 3)), np.zeros((6, 3))
        for i in range(6):
            points[i], dirs[i] = pre[:3, 3], pre[:3, 2]
            pre = pre @ _dh(np.array(self.offset[i]), self.d[i], self.a[i], self.alpha[i])
        inv = _inv(home)
        pts = (points @ inv[:3, :3].T + inv[:3, 3])[::-1]
        return _dh_from_lines(pts, -(dirs @ inv[:3, :3].T)[::-1], inv)


def _perpendicular(z: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to ``z``: ``hint`` made perpendicular, else any."""
    for v in (hint, np.eye(3)[int(np.argmin(np.abs(z)))]):
        w = v - (v @ z) * z
        if np.linalg.norm(w) > 1e-9:
            return w / np.linalg.norm(w)
    raise AssertionError("unreachable: the least aligned unit axis is never parallel to z")


def _frame(x: np.ndarray, z: np.ndarray, o: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, 0], t[:3, 1], t[:3, 2], t[:3, 3] = x, np.cross(z, x), z, o
    return t


def _dh_from_lines(points: np.ndarray, dirs: np.ndarray, ee: np.ndarray) -> General6R:
    """Standard DH parameters of six joint lines (frame ``i`` has ``z_i`` on axis ``i + 1`` and
    ``x_i`` on the common normal of axes ``i`` and ``i + 1``; frame 6 = frame 5 turned by
    ``theta_6``). Exact up to rounding except for axes within `_PARALLEL` of parallel."""
    u = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    scale = max(1.0, float(np.max(np.abs(points))))
    feet, origins, xs = [], [], []
    prev_origin, prev_x = points[0], _perpendicular(u[0], np.array([1.0, 0.0, 0.0]))
    for i in range(5):  # common normal of axis i (u[i]) and axis i + 1
        p1, u1, p2, u2 = points[i], u[i], points[i + 1], u[i + 1]
        n = np.cross(u1, u2)
        if np.linalg.norm(n) > _PARALLEL:
            w, b = p2 - p1, u1 @ u2
            den = n @ n  # 1 - b^2 without the cancellation
            s, t = (u1 @ w - b * (u2 @ w)) / den, (b * (u1 @ w) - u2 @ w) / den
            f, o = p1 + s * u1, p2 + t * u2
            x = n / np.linalg.norm(n)  # exactly normal to both axes, even nearly parallel ones
            if (o - f) @ x < 0:
                x = -x
        else:  # parallel: the normal through the previous origin
            f = p1 + ((prev_origin - p1) @ u1) * u1
            o = p2 + ((f - p2) @ u2) * u2
            x = _perpendicular(u2, o - f if np.linalg.norm(o - f) > 1e-12 * scale else prev_x)
        feet.append(f)
        origins.append(o)
        xs.append(x)
        prev_origin, prev_x = o, x
    z = [*u, u[5]]  # z_0 .. z_6
    x_all = [_perpendicular(u[0], xs[0]), *xs, xs[4]]  # x_0 .. x_6
    o_all = [feet[0], *origins, origins[4]]  # o_0 .. o_6
    f_all = [*feet, origins[4]]  # foot of x_i on axis i, i = 1..6
    a, alpha, d, off = (np.zeros(6) for _ in range(4))
    for i in range(1, 7):
        zp, xp, xi = z[i - 1], x_all[i - 1], x_all[i]
        d[i - 1] = (f_all[i - 1] - o_all[i - 1]) @ zp
        off[i - 1] = math.atan2(np.cross(xp, xi) @ zp, xp @ xi)
        a[i - 1] = (o_all[i] - f_all[i - 1]) @ xi
        alpha[i - 1] = math.atan2(np.cross(zp, z[i]) @ xi, zp @ z[i])
    base = _frame(x_all[0], z[0], o_all[0])
    tool = _inv(_frame(x_all[6], z[6], o_all[6])) @ ee
    return General6R(a, alpha, d, off, base, tool)


# ---------------------------------------------------------------------------- elimination
class _Left:
    """The arm-only part: coefficients of the 14 left sides in ``(phi_3, phi_4, phi_5)``."""

    def __init__(self, arm: General6R) -> None:
        a, d = arm._unit()
        self.a, self.d, self.alpha = a, d, arm.alpha
        lhs = self.values(*np.meshgrid(_GRID, _GRID, _GRID, indexing="ij"))  # (5, 5, 5, 14)
        c = _fourier(np.moveaxis(lhs, -1, 0), (1, 2, 3))  # (14, 3, 3, 3) in k = -1, 0, 1
        for ax in (1, 2, 3):
            c = np.moveaxis(np.tensordot(_HALF, c, axes=([1], [ax])), 0, ax)
        self.coef = c.real  # (14, p3, p4, p5): (1 + x3^2)(1 + x4^2)(1 + x5^2) * left side
        # the last columns of A6^-1 (independent of theta_6)
        self.inv6 = _inv(_dh(np.array(0.0), d[5], a[5], arm.alpha[5]))
        self.l6, self.p6 = self.inv6[:, 2], self.inv6[:, 3]
        self.packed = np.concatenate([d, a, arm.alpha, ROTATIONS, self.inv6.reshape(-1)]).astype(float)
        """``d, a, alpha, ROTATIONS, A6^-1`` in one array: the arm as the C code takes it."""
        g1, g2 = np.meshgrid(_GRID, _GRID, indexing="ij")
        self.grid12 = _inv(_dh(g2, d[1], a[1], arm.alpha[1])) @ _inv(_dh(g1, d[0], a[0], arm.alpha[0]))
        """``A2^-1 A1^-1`` on the ``5 x 5`` grid of ``(theta_1, theta_2)``."""
        g1, g2 = np.meshgrid(_GRID3, _GRID3, indexing="ij")
        grid3 = _inv(_dh(g2, d[1], a[1], arm.alpha[1])) @ _inv(_dh(g1, d[0], a[0], arm.alpha[0]))
        self.model = np.concatenate([self.packed, self.coef.reshape(-1), grid3.reshape(-1)])
        """`packed`, `coef` and ``A2^-1 A1^-1`` on the ``3 x 3`` grid of ``(theta_1, theta_2)``
        (`_GRID3`): the arm as the whole solve in C (``optik_g6r_solve``) takes it."""
        self.offset = np.ascontiguousarray(arm.offset, dtype=float)
        self.addresses = (self.model.ctypes.data, self.offset.ctypes.data)
        """The addresses of `model` and `offset` (for the C solve: read once, not per call)."""

    def values(self, phi3: np.ndarray, phi4: np.ndarray, phi5: np.ndarray) -> np.ndarray:
        """The 14 left sides at ``theta_k = phi_k + delta_k``: shape ``phi.shape + (14,)``."""
        a, d, al = self.a, self.d, self.alpha
        t = _dh(phi3 + ROTATIONS[0], d[2], a[2], al[2])
        t = t @ _dh(phi4 + ROTATIONS[1], d[3], a[3], al[3])
        t = t @ _dh(phi5 + ROTATIONS[2], d[4], a[4], al[4])
        return _fourteen(t[..., :3, 2], t[..., :3, 3])


@dataclass
class General6RSolutions:
    """All real IK solutions of one target and the evidence that none is missing.

    Attributes:
        q: the verified solutions, ``(k, 6)``, angles wrapped to ``(-pi, pi]``.
        n_finite: finite non-spurious eigenvalues (16 for a generic arm and pose).
        n_real_candidates: candidates whose polished angles are real (to `IMAG_TOL`).
        n_complex: distinct complex solutions: verified by polishing, or far from the real axis.
        n_rejected: candidates that did not converge, or real ones that failed the FK check.
        fk_error: largest FK error of a returned solution.
        count_ok: the count check passed (see the module docstring).
        reason: why the list is empty or the count check failed ("" otherwise).
        errors: ``(k, 2)`` position (m) and orientation (rad) errors of each solution by the
            independent forward kinematics that checked it (the mechanism's own, or
            `General6R.fk`), or None where a merged answer did not keep them.
    """

    q: np.ndarray
    n_finite: int
    n_real_candidates: int
    n_complex: int
    n_rejected: int
    fk_error: float
    count_ok: bool
    reason: str = ""
    errors: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.q)

    def __iter__(self) -> Any:
        return iter(list(self.q))


_ARMS: PerMechanism[General6R] = PerMechanism()

_FK_ROWS = 8
"""Rows per evaluation of `_mechanism_fk` (a batch is evaluated in chunks of this many rows)."""


class _MechanismRows:
    """``q (K, 6) -> f(q) (K, r, c)`` on the validated rows of the internal path, for an
    ``r x c`` expression ``f`` of a mechanism's joints (its FK, `_mechanism_fk`, or its
    Jacobian, `_mechanism_jacobian`): ``f`` transposed and densified (CasADi's column-major
    result is then the row-major matrix), mapped over ``rows, rows / 2, ..., 1`` rows (``rows``
    a power of two) and evaluated by CasADi on preallocated buffers (``Function.buffer``): the
    batch in chunks of ``rows``, the remainder by its binary digits (5 rows: 4 + 1), so that no
    unused row is evaluated (about a microsecond each); instead of the tens of microseconds that
    each ``m.fk`` or ``m.jacobian`` call spends validating and converting its argument. The same
    expression as ``m.fk`` / ``m.jacobian`` (their function's, evaluated row by row), so the
    same numbers. Thread-safe: each thread evaluates on its own buffers (made at its first
    call)."""

    def __init__(self, expr: ca.SX, q_sym: ca.SX, rows: int) -> None:
        self.shape = expr.shape
        one = ca.Function("rows", [q_sym], [ca.densify(expr.T)])
        self.functions = [one.map(rows >> i) if rows >> i > 1 else one for i in range(rows.bit_length())]
        self._local = threading.local()

    def _buffers(self) -> list[tuple[np.ndarray, np.ndarray, Any, Any]]:
        """This thread's ``(q, out, call, buffer)`` of each chunk size, largest first: the input
        rows, the values (row-major), the evaluation on them and the buffer that they live with."""
        mine = getattr(self._local, "buffers", None)
        if mine is None:
            mine = []
            for f in self.functions:
                q = np.zeros((f.size2_in(0), 6))  # k rows (the mapped input is 6 x k)
                out = np.zeros((len(q), *self.shape))
                buffer, call = f.buffer()
                buffer.set_arg(0, memoryview(q))
                buffer.set_res(0, memoryview(out))
                mine.append((q, out, call, buffer))
            self._local.buffers = mine
        return mine

    def __call__(self, q: np.ndarray) -> np.ndarray:
        out = np.empty((len(q), *self.shape))
        start = 0
        for q_in, values, call, _ in self._buffers():
            k = len(q_in)
            while len(q) - start >= k:  # repeats for the largest size only
                q_in[:] = q[start : start + k]
                call()
                out[start : start + k] = values
                start += k
        return out


_FKS: PerMechanism[_MechanismRows] = PerMechanism()
_JACOBIANS: PerMechanism[_MechanismRows] = PerMechanism()


def _mechanism_fk(m: Mechanism) -> _MechanismRows:
    """``q (K, 6) -> m.fk(q) (K, 4, 4)``: the `_MechanismRows` of ``m``'s end-effector pose
    (`_FK_ROWS` rows a chunk; made once per mechanism)."""
    fk = _FKS.get(m)
    return fk if fk is not None else _FKS.setdefault(m, _MechanismRows(m.frame_expr(m.ee), m.q_sym, _FK_ROWS))


def _mechanism_jacobian(m: Mechanism) -> _MechanismRows:
    """``q (K, 6) -> m.jacobian(q) (K, 6, 6)``: the `_MechanismRows` of ``m``'s geometric Jacobian
    (one row a chunk: the polish of `_refine` takes a row at a time; made at the first need,
    once per mechanism)."""
    jac = _JACOBIANS.get(m)
    return jac if jac is not None else _JACOBIANS.setdefault(m, _MechanismRows(m.jacobian_expr(), m.q_sym, 1))


def _arm(arm: Mechanism | General6R) -> General6R:
    if isinstance(arm, General6R):
        return arm
    if not isinstance(arm, Mechanism):
        raise InvalidArgumentError(
            "arm", f"expected an optik Mechanism or a General6R, got {type(arm).__name__}"
        )
    try:
        return _ARMS[arm]
    except KeyError:
        _ARMS[arm] = out = General6R.from_mechanism(arm)
        return out


def _targets(arm: General6R, target: Any) -> tuple[np.ndarray, bool]:
    """Validated targets as ``(N, 4, 4)`` and whether a single 4x4 was given."""
    t = np.asarray(target, dtype=float) if not isinstance(target, np.ndarray) else target
    if t.ndim == 2:
        return as_transform(t, "target")[None], True
    if t.ndim != 3 or t.shape[1:] != (4, 4):
        raise ShapeError("target", f"expected a 4x4 transform or (N, 4, 4), got shape {t.shape}")
    return np.stack([as_transform(ti, f"target[{i}]") for i, ti in enumerate(t)]), False


def _right(left: _Left, tp: np.ndarray) -> np.ndarray:
    """Real coefficients ``(N, 14, 3, 3)`` of the 14 right sides in ``(1, c1, s1) (x) (1, c2, s2)``
    for the unit-scale targets ``tp = B^-1 T E^-1``."""
    m = left.grid12
    lv = tp @ left.l6  # (N, 4)
    pv = tp @ left.p6
    l = np.einsum("ijab,nb->nija", m, lv)[..., :3]
    p = np.einsum("ijab,nb->nija", m, pv)[..., :3]
    c = _fourier(np.moveaxis(_fourteen(l, p), -1, 1), (2, 3))  # (N, 14, 3, 3), k = -1, 0, 1
    real = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 1.0], [-1j, 0.0, 1j]])  # (1, cos, sin) <- (k=-1, 0, 1)
    c = np.einsum("ak,nekl->neal", real, c)
    return np.einsum("bl,neal->neab", real, c).real


def _eigen(m_poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues ``(N, 24)`` and the ``w`` parts ``(N, 24, 12)`` of the eigenvectors of
    ``(A x^2 + B x + C) w = 0`` for ``m_poly = (C, B, A)`` of shape ``(N, 3, 12, 12)``."""
    import scipy.linalg  # QZ for a badly conditioned A; imported on first use: slow to import

    n = len(m_poly)
    c, b, a = m_poly[:, 0], m_poly[:, 1], m_poly[:, 2]
    vals = np.empty((n, 24), dtype=complex)
    vecs = np.empty((n, 24, 12), dtype=complex)
    cond = np.linalg.cond(a)
    good = np.flatnonzero(cond < _COND_QZ)
    if len(good):
        ainv = np.linalg.inv(a[good])
        comp = np.zeros((len(good), 24, 24))
        comp[:, :12, 12:] = np.eye(12)
        comp[:, 12:, :12] = -ainv @ c[good]
        comp[:, 12:, 12:] = -ainv @ b[good]
        w, v = np.linalg.eig(comp)
        vals[good], vecs[good] = w, np.swapaxes(v, 1, 2)[..., :12]
        big = np.abs(w) > 1.0  # the lower block (x w) is the better scaled part for |x| > 1
        lower = np.swapaxes(v, 1, 2)[..., 12:]
        vecs[good] = np.where(big[..., None], lower, vecs[good])
    for k in np.flatnonzero(cond >= _COND_QZ):
        lhs = np.zeros((24, 24))
        rhs = np.eye(24)
        lhs[:12, 12:] = np.eye(12)
        lhs[12:, :12], lhs[12:, 12:] = -c[k], -b[k]
        rhs[12:, 12:] = a[k]
        w, v = scipy.linalg.eig(lhs, rhs)
        vals[k] = w
        vecs[k] = np.where((np.abs(w) > 1.0)[:, None], v[12:].T, v[:12].T)
    return vals, vecs


def _half_angle(w: np.ndarray, real: bool = False) -> np.ndarray:
    """``phi = 2 atan(x)`` from the eigenvector blocks ``w = (x^i y^j)``: least-squares ratios,
    taken the way round that keeps them bounded. ``w``: ``(..., 4, 3)`` -> ``(phi_4, phi_5)``,
    complex (real up to rounding for a real root), or with ``real`` from the ratios' real parts."""

    def angle(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        fwd = np.sum(np.conj(lo) * hi, axis=(-2, -1)) / np.maximum(
            np.sum(np.abs(lo) ** 2, axis=(-2, -1)), 1e-300
        )
        rev = np.sum(np.conj(hi) * lo, axis=(-2, -1)) / np.maximum(
            np.sum(np.abs(hi) ** 2, axis=(-2, -1)), 1e-300
        )
        if real:
            fwd, rev = fwd.real, rev.real
        # 2 atan(1 / rev) = pi - 2 atan(rev) modulo 2 pi, analytic: complex roots keep their value
        return np.where(np.abs(fwd) <= 1.0, 2.0 * np.arctan(fwd), np.pi - 2.0 * np.arctan(rev))

    return np.stack([angle(w[..., :3, :], w[..., 1:, :]), angle(w[..., :, :2], w[..., :, 1:])], axis=-1)


def _chain(left: _Left, theta: np.ndarray) -> np.ndarray:
    """Prefix products ``A1 ... A_k`` (unit scale), ``k = 0..6``: shape ``(..., 7, 4, 4)``."""
    out = np.empty((*theta.shape[:-1], 7, 4, 4), dtype=theta.dtype)
    out[..., 0, :, :] = np.eye(4)
    joints = _dh(theta, np.asarray(left.d), np.asarray(left.a), np.asarray(left.alpha))  # (..., 6, 4, 4)
    for i in range(6):
        out[..., i + 1, :, :] = out[..., i, :, :] @ joints[..., i, :, :]
    return out


def _polish(
    left: _Left, theta: np.ndarray, tp: np.ndarray, iterations: int = NEWTON_ITERATIONS
) -> tuple[np.ndarray, np.ndarray]:
    """Newton on ``A1 ... A6 (theta) = tp`` (unit scale), ``theta (K, 6)`` real or complex,
    ``tp (K, 4, 4)``: residual ``r = [p - p*; vee(R R*^T - R* R^T) / 2]``, geometric Jacobian
    ``[z_{i-1} x (p - o_{i-1}); z_{i-1}]`` (exact at a solution, so convergence is quadratic;
    the algebra holds for complex angles too, where it converges to complex solutions). Steps
    are bounded to 0.5 per entry; a candidate stops once ``max |r| < 1e-15``, or once it no
    longer halves below ``1e-9`` times its `_magnitude` (rounding). Returns the polished angles
    and ``max |r|`` of each at them.

    In C (``general_6r.c``, built once per machine in the background,
    `optik.native.CFunction`) when it is loaded; numpy otherwise, and for a batch with an exactly
    singular Jacobian (numpy then takes least-squares steps)."""
    fn = _POLISH.get()
    if fn is not None and len(theta):
        out = np.array(theta, dtype=complex)  # a copy, C-contiguous
        targets = np.ascontiguousarray(tp, dtype=float)
        size = np.empty(len(out))
        dh = np.ascontiguousarray(np.concatenate([left.d, left.a, left.alpha]), dtype=float)
        args = (_address(dh), len(out), iterations, _address(out), _address(targets), _address(size))
        if fn(*args) == 0:
            return (out if np.iscomplexobj(theta) else out.real.copy()), size
    theta = theta.copy()
    err, pre = _residual(left, theta, tp)
    size = np.max(np.abs(err), axis=1, initial=0.0)
    todo = np.flatnonzero(size >= 1e-15)
    err, pre = err[todo], pre[todo]
    before = size[todo]
    for _ in range(iterations):
        if not len(todo):
            break
        z, o = pre[:, :6, :3, 2], pre[:, :6, :3, 3]
        jac = np.empty((len(todo), 6, 6), dtype=theta.dtype)
        jac[:, :3] = np.swapaxes(np.cross(z, pre[:, 6, None, :3, 3] - o), 1, 2)
        jac[:, 3:] = np.swapaxes(z, 1, 2)
        try:
            step = np.linalg.solve(jac, err[..., None])[..., 0]
        except np.linalg.LinAlgError:
            step = np.stack([np.linalg.lstsq(j, e, rcond=None)[0] for j, e in zip(jac, err, strict=True)])
        theta[todo] -= step / np.maximum(1.0, 2.0 * np.abs(step))  # bounded: never flies off
        err, pre = _residual(left, theta[todo], tp[todo])
        now = size[todo] = np.max(np.abs(err), axis=1, initial=0.0)
        stalled = (now > 0.5 * before) & (now < 1e-9 * _magnitude(theta[todo]))
        keep = (now >= 1e-15) & ~stalled
        todo, err, pre, before = todo[keep], err[keep], pre[keep], now[keep]
    return theta, size


def _magnitude(theta: np.ndarray) -> np.ndarray:
    """``prod_i cosh(Im theta_i)``: a bound on the entries of ``A1 ... A6`` at complex angles
    (1 for real ones), the scale of the rounding error of their residual."""
    return np.multiply.reduce(np.cosh(theta.imag), axis=-1)


def _residual(left: _Left, theta: np.ndarray, tp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pose residual ``(K, 6)`` of `_polish` and the prefix products (`_chain`) at ``theta``."""
    pre = _chain(left, theta)
    t = pre[:, 6]
    rot = 0.5 * _skew(t[:, :3, :3] @ np.swapaxes(tp[:, :3, :3], 1, 2))
    return np.concatenate([t[:, :3, 3] - tp[:, :3, 3], rot], 1), pre


def _skew(r: np.ndarray) -> np.ndarray:
    """``vee(R - R^T)`` of rotations ``(..., 3, 3)``: ``2 sin(angle) axis``."""
    return np.stack(
        [r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], -1
    )


def _wrap(q: np.ndarray) -> np.ndarray:
    w = (q + np.pi) % _TWO_PI - np.pi
    return np.where(w <= -np.pi, w + _TWO_PI, w)


def _pose_errors(t: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Position and orientation errors of poses ``t`` against ``target`` (batched, ``(..., 2)``):
    ``|p - p*|`` (m) and the geodesic angle of ``R = R*^T R(q)``,
    ``atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2)`` (rad). The sums are written out in the order
    of ``np.linalg.norm`` and ``np.trace`` (the same numbers, without their per-call cost). For
    ``(K, 4, 4)`` stacks of one shape in C (``optik_g6r_pose_errors``: the same operations, but
    the product ``R*^T R`` in plain sums where numpy's matmul may use BLAS, so equal to
    rounding) once its library is loaded, else (and for broadcast shapes) in numpy."""
    fn = _POSE_ERRORS.get()
    if fn is not None and t.ndim == 3 and t.shape == target.shape:
        t, target = np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(target, dtype=float)
        out = np.empty((len(t), 2))
        fn(_address(t), _address(target), len(t), _address(out))
        return out
    d = t[..., :3, 3] - target[..., :3, 3]
    dp = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2])
    r = np.swapaxes(target[..., :3, :3], -1, -2) @ t[..., :3, :3]
    x, y, z = r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]
    cos = np.minimum(np.maximum((r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2] - 1.0) / 2.0, -1.0), 1.0)
    out = np.empty((*dp.shape, 2))
    out[..., 0] = dp
    out[..., 1] = np.arctan2(0.5 * np.sqrt(x * x + y * y + z * z), cos)
    return out


def _fk_error(errors: np.ndarray, scale: float) -> np.ndarray:
    """The FK error that `FK_TOL` bounds, of `_pose_errors` ``errors``: the position error
    relative to ``scale`` or the angle, whichever is larger."""
    return np.maximum(errors[..., 0] / scale, errors[..., 1])


def _fk_errors(t: np.ndarray, target: np.ndarray, scale: float) -> np.ndarray:
    """`_fk_error` of poses ``t`` against ``target`` (batched)."""
    return _fk_error(_pose_errors(t, target), scale)


def _gap(diff: np.ndarray) -> np.ndarray:
    """The distance of rows of angle differences ``diff (..., 6)`` (real or complex): the
    largest ``|wrap(Re)| + |Im|`` of a joint, with ``|wrap(x)| = |(x + pi) mod 2 pi - pi|``
    (the last step of `_wrap`, from ``-pi`` to ``pi``, leaves the absolute value alone)."""
    wrapped = np.abs((diff.real + np.pi) % _TWO_PI - np.pi)
    return np.maximum.reduce(wrapped + np.abs(diff.imag), axis=-1, initial=0.0)


def _keep(q: np.ndarray) -> np.ndarray:
    """The indices of the distinct rows of ``q (K, 6)`` (real or complex angles; real parts
    compared modulo 2 pi): the first of each group of rows closer than `_SAME`."""
    if len(q) < 2:
        return np.arange(len(q))
    close = _gap(q[:, None, :] - q[None, :, :]) < _SAME
    keep: list[int] = []
    for i in range(len(q)):
        if not close[i, keep].any():
            keep.append(i)
    return np.array(keep, dtype=int)


def _dedup(q: np.ndarray) -> np.ndarray:
    """The distinct rows of ``q`` (`_keep`)."""
    q = q.reshape(-1, 6)
    return q[_keep(q)]


def _distinct(rows: np.ndarray, owner: np.ndarray, n: int) -> list[np.ndarray]:
    """The indices into ``rows`` of `_dedup` of the rows of each target ``0 .. n-1``
    (``owner``: each row's target), in their order: a list of ``n`` index arrays. In C
    (``optik_g6r_distinct``: a stable counting sort by target, then each row against the kept
    rows of its target, `_gap`'s floating operations, so the same decisions) once its library
    is loaded, else `_distinct_numpy`."""
    fn = _DISTINCT.get()
    if fn is None:
        return _distinct_numpy(rows, owner, n)
    rows = np.ascontiguousarray(rows, dtype=complex)
    owner = np.ascontiguousarray(owner, dtype=np.int64)
    k = len(owner)
    # one buffer (one address read): the sort's scratch (k), the indices (k), the bounds (n + 1)
    out = np.empty(2 * k + n + 1, dtype=np.int64)
    base, idx = _address(out), out[k : 2 * k]
    fn(_address(rows), _address(owner), k, n, base, base + 8 * k, base + 16 * k)
    return [idx[i:j] for i, j in itertools.pairwise(out[2 * k :].tolist())]


def _distinct_numpy(rows: np.ndarray, owner: np.ndarray, n: int) -> list[np.ndarray]:
    """`_distinct` in numpy: the rows grouped by target (a stable sort), then `_keep` per group."""
    order = np.argsort(owner, kind="stable")
    bounds = np.searchsorted(owner[order], np.arange(n + 1)).tolist()
    return [order[i:j][_keep(rows[order[i:j]])] for i, j in itertools.pairwise(bounds)]


def _unit_targets(arm: General6R, targets: np.ndarray) -> np.ndarray:
    """``T' = B^-1 T E^-1`` of targets ``(N, 4, 4)``, scaled to the unit-size arm."""
    tp = arm._base_inv @ targets @ arm._tool_inv
    tp[:, :3, 3] /= arm.scale
    return tp


def _matrices(arm: General6R, tp: np.ndarray) -> tuple[np.ndarray, ...]:
    """Steps 1-3 for unit-scale targets ``tp`` (`_unit_targets`, ``(N, 4, 4)``): the SVD
    ``u, sv, vt`` of ``Q``, the constants ``r0``, the coefficients ``(C, B, A)`` of ``M(x_3)``
    (``(N, 3, 12, 12)``) and the masks ``rank_ok`` (``Q`` of rank 8), ``regular`` (``M`` not
    singular for all x) and ``well`` (well posed, `_WELL_POSED`)."""
    left = arm._left
    n = len(tp)
    rhs = _right(left, tp)
    q_mat, r0 = rhs.reshape(n, 14, 9)[:, :, 1:], rhs[:, :, 0, 0]
    u, sv, vt = np.linalg.svd(q_mat)
    rank_ok = sv[:, 7] > 1e-11 * sv[:, 0]
    one = np.array([1.0, 0.0, 1.0])  # 1 + x^2
    g = left.coef[None] - r0[:, :, None, None, None] * np.einsum("a,b,c->abc", one, one, one)
    sigma = np.einsum("nke,nkabc->naebc", u[:, :, 8:], g).reshape(n, 3, 6, 9)
    mats = np.zeros((n, 3, 12, 12))
    mats[:, :, :6, :9] = sigma
    mats[:, :, 6:, 3:] = sigma
    # a singular pencil (det M(x) = 0 for every x: special geometry) has meaningless eigenvalues
    probe = np.einsum("nkab,pk->npab", mats, _PROBES)
    probe_sv = np.linalg.svd(probe, compute_uv=False)
    ratio = np.max(probe_sv[..., -1] / probe_sv[..., 0], axis=1)
    return u, sv, vt, r0, mats, rank_ok, ratio > _SINGULAR_PENCIL, ratio > _WELL_POSED


@dataclass
class _Candidates:
    """The polished candidates of targets ``0 .. N-1`` (steps 1-3, the eigenvalues, the
    back-substitution and the complex polish), what `_solve` decides on.

    Attributes:
        rank_ok, regular: per target, ``Q`` of full rank and the pencil regular.
        n_good, n_far: per target, finite non-spurious eigenvalues and those counted complex
            without polishing (`_FAR`).
        owner: per candidate, its target.
        theta, residual: per candidate, the polished (complex) angles and ``max |r|`` at them.
        retry: the candidates also polished from their real parts (`_REAL_RETRY`), ascending.
        again: their polished real angles in joint coordinates (`_joint_rows`), ``(len(retry), 6)``.
        real: per candidate real to `IMAG_TOL`, its real part in joint coordinates (`_joint_rows`;
            NaN for the others).
    """

    rank_ok: np.ndarray
    regular: np.ndarray
    n_good: np.ndarray
    n_far: np.ndarray
    owner: np.ndarray
    theta: np.ndarray
    residual: np.ndarray
    retry: np.ndarray
    again: np.ndarray
    real: np.ndarray


def _joint_rows(
    arm: General6R,
    theta: np.ndarray,
    owner: np.ndarray,
    retry: np.ndarray,
    again: np.ndarray,
    tp: np.ndarray,
    last: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """`_Candidates.real` and `_Candidates.again` of polished candidates ``theta`` (DH angles,
    complex; ``owner``: their targets) and the real retries ``again`` of the candidates
    ``retry``: joint angles ``_wrap(theta - offset)``, after `_last_polish` (unit-scale targets
    ``tp``) with ``last``."""
    rows = np.flatnonzero(np.max(np.abs(theta.imag), axis=1, initial=0.0) <= IMAG_TOL)
    q = _wrap(np.concatenate([theta[rows].real, again]) - arm.offset)
    if last and len(q):
        q = _last_polish(arm, q, tp[np.concatenate([owner[rows], owner[retry]])])
    real = np.full((len(theta), 6), np.nan)
    real[rows] = q[: len(rows)]
    return real, q[len(rows) :]


def _last_polish(arm: General6R, q: np.ndarray, tp: np.ndarray) -> np.ndarray:
    """`_polish` of real joint angles ``q (K, 6)`` on the DH model towards the unit-scale targets
    ``tp (K, 4, 4)``, wrapped: the first step of `_refine`."""
    return _wrap(_polish(arm._left, q + arm.offset, tp)[0] - arm.offset)


def _candidates(arm: General6R, tp: np.ndarray, last: bool = False) -> _Candidates:
    """`_Candidates` of the unit-scale targets ``tp`` in numpy (the C kernels `_BACK` and
    `_POLISH` where loaded): the path without the whole solve in C (`_candidates_c`); with
    ``last`` the real ones (and the real retries) after `_last_polish` too."""
    left = arm._left
    u, sv, vt, r0, mats, rank_ok, regular, well = _matrices(arm, tp)
    vals, vecs = _eigen(mats)
    finite = np.isfinite(vals) & (np.abs(vals) < 1e12)
    spurious = np.zeros_like(finite)
    for sign in (1j, -1j):
        dist = np.where(finite & ~spurious, np.abs(vals - sign), np.inf)
        near = np.argsort(dist, axis=1)[:, :4]
        np.put_along_axis(spurious, near, True, axis=1)
    good = finite & ~spurious
    phi3 = 2.0 * np.arctan(np.where(good, vals, 0.0))
    # far from the real axis (near x_3 = +-i, where roots run off to infinity as an arm nears
    # special geometry): complex on the word of the eigenvalue, when the pencil is well posed
    far = good & (np.abs(phi3.imag) > _FAR) & well[:, None]
    # every other eigenvalue is a candidate, polished in complex space: a real root that
    # rounding moved off the real axis comes back to it, a complex one converges where it is
    idx_n, idx_e = np.nonzero(good & ~far)
    flat = vecs[idx_n, idx_e]  # (K, 12), normalized by the largest entry: real for a real root
    flat = flat / flat[np.arange(len(flat)), np.argmax(np.abs(flat), axis=1)][:, None]
    w = flat.reshape(-1, 4, 3)
    phi = np.concatenate([phi3[idx_n, idx_e][:, None], _half_angle(w)], 1)
    pinv = np.swapaxes(vt[:, :8], 1, 2) @ (u[:, :, :8] / sv[:, None, :8]).transpose(0, 2, 1)

    def back_substitute(phi: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """``theta (K, 6)`` (complex) of ``(phi_3, phi_4, phi_5)`` of targets ``rows`` (in C,
        `optik_g6r_back`, when its library is loaded)."""
        fn = _BACK.get()
        if fn is not None and len(rows):
            theta = np.empty((len(rows), 6), dtype=complex)
            given = [
                np.ascontiguousarray(phi, dtype=complex),
                *(np.ascontiguousarray(v[rows]) for v in (pinv, r0, tp)),
            ]
            fn(_address(left.packed), len(rows), *(_address(v) for v in given), _address(theta))
            return theta
        lhs = left.values(phi[:, 0], phi[:, 1], phi[:, 2])
        x_r = np.einsum("kij,kj->ki", pinv[rows], lhs - r0[rows])
        theta = np.zeros((len(rows), 6), dtype=complex)
        theta[:, 0] = _angle(x_r[:, 2], x_r[:, 5])
        theta[:, 1] = _angle(x_r[:, 0], x_r[:, 1])
        theta[:, 2:5] = phi + np.array(ROTATIONS)
        a6 = _inv(_chain(left, theta)[:, 5]) @ tp[rows] @ left.inv6
        theta[:, 5] = _angle(a6[:, 0, 0], a6[:, 1, 0])
        return np.where(np.isfinite(theta), theta, 0.0)

    theta, residual = _polish(left, back_substitute(phi, idx_n), tp[idx_n])
    real = np.max(np.abs(theta.imag), axis=1, initial=0.0) <= IMAG_TOL
    # a candidate near the real axis that did not end real is polished from its real part too
    # (on a singular pencil the eigenvalues mean nothing, yet their real parts often lie next
    # to real solutions)
    retry = np.flatnonzero(~real & (np.abs(phi[:, 0].imag) <= _REAL_RETRY))
    flat_phi = np.concatenate([phi[retry, :1].real, _half_angle(w[retry], real=True)], 1)
    again = _polish(left, back_substitute(flat_phi, idx_n[retry]).real, tp[idx_n[retry]])[0]
    real_rows, again = _joint_rows(arm, theta, idx_n, retry, again, tp, last)
    return _Candidates(
        rank_ok,
        regular,
        np.sum(good, axis=1),
        np.sum(far, axis=1),
        idx_n,
        theta,
        residual,
        retry,
        again,
        real_rows,
    )


@functools.cache
def _lapack() -> tuple[np.ndarray, int] | None:
    """The addresses of scipy's LAPACK routines `_LAPACK_ROUTINES` (``scipy.linalg.cython_lapack``,
    the library scipy itself calls) and of ``openblas_set_num_threads_local`` of the library that
    holds them (0 when it has none: not OpenBLAS, or older than 0.3.27), with the address of that
    array, or None when the routines cannot be read (logged)."""
    try:
        from scipy.linalg import cython_lapack

        name_of = ctypes.pythonapi.PyCapsule_GetName
        name_of.restype, name_of.argtypes = ctypes.c_char_p, [ctypes.py_object]
        pointer = ctypes.pythonapi.PyCapsule_GetPointer
        pointer.restype, pointer.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
        capsules = [cython_lapack.__pyx_capi__[r] for r in _LAPACK_ROUTINES]
        found = [pointer(c, name_of(c)) for c in capsules]
    except Exception as exc:  # any failure: the numpy path answers
        _LOG.warning("general 6R: scipy's LAPACK is not reachable from C (%s); numpy path", exc)
        return None
    table = np.array([*found, _threads_local(found[0])], dtype=np.uintp)
    return table, table.ctypes.data


def _threads_local(address: int) -> int:
    """The address of ``openblas_set_num_threads_local`` in the shared library that holds
    ``address`` (found by ``dladdr``), 0 when there is none."""

    class DlInfo(ctypes.Structure):
        _fields_ = [(k, ctypes.c_void_p) for k in ("fname", "fbase", "sname", "saddr")]

    try:
        libc = ctypes.CDLL(None)
        info = DlInfo()
        if not libc.dladdr(ctypes.c_void_p(address), ctypes.byref(info)) or not info.fname:
            return 0
        lib = ctypes.CDLL(ctypes.string_at(info.fname).decode())
        return int(ctypes.cast(lib.openblas_set_num_threads_local, ctypes.c_void_p).value or 0)
    except (OSError, AttributeError, UnicodeDecodeError):
        return 0


def _candidates_c(arm: General6R, tp: np.ndarray, last: bool = False) -> _Candidates:
    """`_candidates` with the whole solve of each target in C (``optik_g6r_solve``: one call for
    all targets, `_last_polish` included with ``last``) when its library and scipy's LAPACK are
    loaded; targets that it hands back (QZ needed, a LAPACK failure, an exactly singular
    Jacobian) and every target without the library take the numpy path."""
    fn, lapack = _SOLVE.get(), _lapack()
    if fn is None or lapack is None or not len(tp):
        return _candidates(arm, tp, last)
    n, cap = len(tp), _MAX_CANDIDATES
    tp = np.ascontiguousarray(tp)
    # the float outputs in one buffer (one address read): info (n, 8), then room for `cap`
    # candidates per target, written one after the other: theta (6 complex each), size, again and
    # real (6 each)
    slots = n * cap
    ends = list(itertools.accumulate([8 * n, 12 * slots, slots, 6 * slots, 6 * slots]))
    out = np.empty(ends[-1])
    retry, owner = np.empty(slots, dtype=np.intc), np.empty(slots, dtype=np.int64)
    base, (model, offset) = _address(out), arm._left.addresses
    total = fn(
        model,
        lapack[1],
        n,
        _address(tp),
        base,
        base + 8 * ends[0],
        base + 8 * ends[1],
        _address(retry),
        base + 8 * ends[2],
        offset if last else None,
        base + 8 * ends[3],
        _address(owner),
    )
    # the views of what was written: `total` candidates of each kind
    info, size = out[: ends[0]].reshape(n, 8), out[ends[1] : ends[1] + total]
    theta = out[ends[0] : ends[0] + 12 * total].view(complex).reshape(total, 6)
    again = out[ends[2] : ends[2] + 6 * total].reshape(total, 6)
    real = out[ends[3] : ends[3] + 6 * total].reshape(total, 6)
    owner, retry = owner[:total], retry[:total]
    handed_back = np.count_nonzero(info[:, 0]) > 0  # the usual case, none: no mask to build
    if handed_back:  # keep the candidates of the done targets (the C code writes no others)
        done = info[:, 0] == 0
        pick = np.flatnonzero(done[owner])
        owner, size, retry, theta, real, again = (x[pick] for x in (owner, size, retry, theta, real, again))
    retried = retry.nonzero()[0]
    again = again[retried]
    if not last:
        real, again = _joint_rows(arm, theta, owner, retried, again, tp, last)
    flags = info[:, 1:3] > 0
    counts = info[:, 4:6].astype(int)
    cand = _Candidates(
        flags[:, 0],
        flags[:, 1],
        counts[:, 0],
        counts[:, 1],
        owner,
        theta,
        size,
        retried,
        again,
        real,
    )
    rest = np.flatnonzero(~done) if handed_back else ()
    if len(rest):
        cand = _join(cand, rest, _candidates(arm, tp[rest], last))
    return cand


def _join(cand: _Candidates, rows: np.ndarray, other: _Candidates) -> _Candidates:
    """``cand`` with the targets ``rows`` answered by ``other`` (the candidates of ``tp[rows]``)."""
    per = (cand.rank_ok, cand.regular, cand.n_good, cand.n_far)
    for mine, theirs in zip(per, (other.rank_ok, other.regular, other.n_good, other.n_far), strict=True):
        mine[rows] = theirs
    return _Candidates(
        *per,
        np.concatenate([cand.owner, rows[other.owner]]),
        np.concatenate([cand.theta, other.theta]),
        np.concatenate([cand.residual, other.residual]),
        np.concatenate([cand.retry, len(cand.owner) + other.retry]),
        np.concatenate([cand.again, other.again]),
        np.concatenate([cand.real, other.real]),
    )


def _solve(
    arm: General6R,
    targets: np.ndarray,
    check: Any,
    last: bool,
    candidates: Callable[[General6R, np.ndarray, bool], _Candidates] = _candidates_c,
) -> list[General6RSolutions]:
    """The eigenvalue solver on validated targets ``(N, 4, 4)``; ``check`` polishes the real
    candidates last on the exact model and measures them by the independent forward kinematics
    (``(q, target index) -> (q, errors)``, errors as `_pose_errors` on ``arm``'s targets), after
    `_last_polish` on ``arm`` with ``last`` (which ``check`` then leaves out). The per-target
    counts are taken for all targets at once (``np.bincount`` over the candidates' targets).
    ``candidates``: the elimination (`_candidates_c`, or `_candidates` for the numpy
    pipeline alone)."""
    n = len(targets)
    cand = candidates(arm, _unit_targets(arm, targets), last)
    idx_n, theta = cand.owner, cand.theta
    converged = cand.residual <= _CONVERGED * _magnitude(theta)
    # real to IMAG_TOL: a real candidate, which the last polish and the FK check decide (the DH
    # description of an inverse chain may be too coarse for its residual to converge); a
    # retried one that passes the FK check is a real solution, not a complex one
    real = np.maximum.reduce(np.abs(theta.imag), axis=1, initial=0.0) <= IMAG_TOL
    retry = cand.retry
    at = real.nonzero()[0]
    owner = np.concatenate([idx_n[at], idx_n[retry]])
    q, errors = check(np.concatenate([cand.real[at], cand.again]), owner)
    fk_err = _fk_error(errors, arm.scale)
    ok = fk_err <= FK_TOL
    decided = real.copy()  # real, or rescued: a retried one that passed the FK check
    decided[retry[ok[len(at) :]]] = True
    # the distinct real solutions (rows 2k) and complex ones (rows 2k + 1) of each target k in one go
    complex_ = converged & ~decided
    q_ok, owner_ok = q[ok], owner[ok]
    rows = np.concatenate([q_ok, theta[complex_]])
    groups = _distinct(rows, np.concatenate([2 * owner_ok, 2 * idx_n[complex_] + 1]), 2 * n)
    sols = [q_ok[x] for x in groups[0::2]]  # real rows come first: indices into q_ok
    errors_ok = errors[ok]
    n_complex = np.array([len(x) for x in groups[1::2]], dtype=int) + cand.n_far
    failed = ~ok[: len(at)]  # real candidates (the first rows of the check) that failed it
    n_rejected = np.bincount(idx_n[~(decided | converged)], minlength=n) + np.bincount(
        owner[: len(at)][failed], minlength=n
    )
    n_real = np.bincount(idx_n[decided], minlength=n)
    err = np.zeros(n)
    np.maximum.at(err, owner_ok, fk_err[ok])
    out = []
    for k in range(n):
        n_sols, n_finite = len(sols[k]), int(cand.n_good[k])
        count_ok = bool(
            cand.rank_ok[k]
            and cand.regular[k]
            and n_finite == 16
            and n_rejected[k] == 0
            and n_sols + n_complex[k] == 16
        )
        reason = ""
        if not count_ok:
            reason = (
                f"count check failed: {n_finite} finite eigenvalues (16 expected), {n_sols} distinct real "
                f"and {n_complex[k]} distinct complex solutions verified, {n_rejected[k]} candidates that "
                "did not converge or failed the FK check"
                + ("" if cand.rank_ok[k] else ", rank-deficient elimination (special geometry)")
                + ("" if cand.regular[k] else ", singular 12 x 12 matrix for every x_3 (special geometry)")
            )
        elif not n_sols:
            reason = "unreachable: all 16 solutions are complex"
        out.append(
            General6RSolutions(
                sols[k],
                n_finite,
                int(n_real[k]),
                int(n_complex[k]),
                int(n_rejected[k]),
                float(err[k]),
                count_ok,
                reason,
                errors_ok[groups[2 * k]],
            )
        )
    return out


def _angle(c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The angle whose cosine and sine are proportional to ``c, s``: ``arctan2(s, c)`` for real
    input, continued analytically to complex input, ``-i log((c + i s) / sqrt(c^2 + s^2))``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return -1j * np.log((c + 1j * s) / np.sqrt(c * c + s * s))


def solve_general_6r(
    arm: Mechanism | General6R, target: Any
) -> General6RSolutions | list[General6RSolutions]:
    """All real IK solutions of a 6R arm with their count check.

    Args:
        arm: an optik `Mechanism` whose base-to-end-effector path has six revolute joints (any
            geometry; meant for arms that no decomposable closed form covers), or a `General6R`.
        target: a 4x4 end-effector pose, or ``(N, 4, 4)`` poses.

    Returns:
        A `General6RSolutions` (a list of ``N`` for stacked targets): ``q`` holds every real
        solution, each Newton-polished and checked by the arm's own forward kinematics
        (``m.fk`` for a mechanism) to `FK_TOL`; an unreachable pose gives an empty ``q`` and a
        ``reason``, never an exception.

    Raises:
        InvalidArgumentError: ``arm`` is not a 6R serial chain, or a target is not a proper
            4x4 transform (``ShapeError``, ``NonFiniteError``).
    """
    g = _arm(arm)
    targets, single = _targets(g, target)
    m = arm if isinstance(arm, Mechanism) else None
    fk = arm.fk if m is not None else g.fk
    out = _both_ends(g, targets, fk, m)
    bad = [k for k, s in enumerate(out) if not s.count_ok]
    if bad and _compiled():  # a second opinion: the numpy pipeline's own eigen-solutions
        again = _both_ends(g, targets[bad], fk, m, _candidates)
        for k, sol in zip(bad, again, strict=True):
            out[k] = sol if sol.count_ok else _union(out[k], sol)
        bad = [k for k in bad if not out[k].count_ok]
    if bad:  # special geometry at both ends: candidates from a nearby generic arm
        near = _both_ends(g.perturbed, targets[bad], g.perturbed.fk, None)
        for k, sol in zip(bad, near, strict=True):
            q, _, errors = _refine(g, m, sol.q.copy(), np.repeat(targets[k][None], len(sol.q), axis=0))
            out[k] = _add(out[k], q, _fk_error(errors, g.scale))
    return out[0] if single else out


def _both_ends(
    g: General6R,
    targets: np.ndarray,
    fk: Any,
    m: Mechanism | None,
    candidates: Callable[[General6R, np.ndarray, bool], _Candidates] = _candidates_c,
) -> list[General6RSolutions]:
    """The eigenvalue solver on ``g``, then on its inverse chain for the targets whose count
    check failed (``m``: the mechanism whose ``m.fk`` polishes the solutions last, or None;
    ``candidates``: the elimination, as for `_solve`)."""

    def check(q: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`_refine` after `_last_polish` (in `_solve`)."""
        q, _, errors = _refine(g, m, q, targets[idx], dh=False)
        return q, errors

    def check_reversed(q: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`check` of the inverse chain's candidates ``q`` (reversed) of the targets ``bad[idx]``,
        its errors measured on the inverse chain."""
        fwd, pose, _ = _refine(g, m, q[:, ::-1], bad_targets[idx])
        return fwd[:, ::-1], _pose_errors(_inv(pose), inverse[idx])

    out = _solve(g, targets, check, True, candidates)
    bad = [k for k, s in enumerate(out) if not s.count_ok]
    if bad:  # special geometry at the first axes: solve the inverse chain from the other end
        bad_targets = targets[bad]
        inverse = _inv(bad_targets)
        back = _solve(g.reversed, inverse, check_reversed, False, candidates)
        for k, rev in zip(bad, back, strict=True):
            out[k] = _merge(out[k], rev, targets[k], fk, g.scale)
    return out


def _compiled() -> bool:
    """Whether `_candidates_c` runs the C elimination (its library and scipy's LAPACK loaded)."""
    return _SOLVE.get() is not None and _lapack() is not None


def _flagged(base: General6RSolutions, q: np.ndarray, fk_error: float, reason: str) -> General6RSolutions:
    """``base``'s counts with another set of verified rows ``q``, flagged (count check not
    passed): the answer of a union of two pipelines or of an added perturbed arm's rows."""
    return replace(base, q=q, fk_error=fk_error, count_ok=False, reason=reason, errors=None)


def _union(first: General6RSolutions, second: General6RSolutions) -> General6RSolutions:
    """Both verified sets of one target (each row passed the FK check), deduplicated, flagged:
    near special geometry the compiled and the numpy eliminations (the same algebra, other
    LAPACK builds and rounding) can each miss a solution that the other finds."""
    merged = _dedup(np.vstack([first.q, second.q]))
    reason = (
        f"{first.reason}; {len(merged) - len(first.q)} more from the numpy pipeline "
        f"({second.reason.removeprefix('count check failed: ')})"
    )
    return _flagged(first, merged, max(first.fk_error, second.fk_error), reason)


def _add(sols: General6RSolutions, q: np.ndarray, err: np.ndarray) -> General6RSolutions:
    """``sols`` (flagged) with the candidates ``q`` whose FK errors ``err`` pass the FK check
    added (deduplicated)."""
    q = q[err <= FK_TOL]
    merged = _dedup(np.vstack([sols.q, q]))
    added = len(merged) - len(sols.q)
    fk_error = max(sols.fk_error, float(np.max(err[err <= FK_TOL], initial=0.0)))
    reason = f"{sols.reason}; {added} more from a generic arm {PERTURBATION:g} away (not certified)"
    return _flagged(sols, merged, fk_error, reason)


def _refine(
    g: General6R, m: Mechanism | None, q: np.ndarray, targets: np.ndarray, dh: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The last Newton polish on the exact model: the DH model ``g`` (`_last_polish`, unless
    ``dh`` is False: the candidates had it; exact for a `General6R`;
    candidates of the inverse chain come from its own, less accurate, DH description), then for
    a mechanism a few steps on ``m.fk`` and ``m.jacobian`` wherever the FK error is still above
    rounding (the DH description of near-parallel axes loses digits). Returns the polished
    angles (wrapped), their poses by the independent forward kinematics (the mechanism's own,
    `_MechanismRows`, or ``g.fk`` for a `General6R`; the last evaluation of the polish when no
    step was left to take, the usual case) and their position and orientation errors
    (`_pose_errors`), which the FK check reads."""
    if not len(q):
        return q, np.zeros((0, 4, 4)), np.zeros((0, 2))
    if dh:
        q = _last_polish(g, q, _unit_targets(g, targets))
    fk = g.fk if m is None else _mechanism_fk(m)
    for _ in range(3 if m is not None else 0):
        pose = fk(q)
        errors = _pose_errors(pose, targets)
        todo = (_fk_error(errors, g.scale) > _EXACT).nonzero()[0]
        if not len(todo):
            return q, pose, errors
        for k in todo:
            rot = pose[k, :3, :3] @ targets[k, :3, :3].T
            err = np.concatenate([pose[k, :3, 3] - targets[k, :3, 3], 0.5 * _skew(rot)])
            q[k] = q[k] - np.linalg.lstsq(_mechanism_jacobian(m)(q[k][None])[0], err, rcond=None)[0]
        q = _wrap(q)
    pose = fk(q).reshape(-1, 4, 4)
    return q, pose, _pose_errors(pose, targets)


def _merge(
    fwd: General6RSolutions, rev: General6RSolutions, target: np.ndarray, fk: Any, scale: float
) -> General6RSolutions:
    """The answer of the reversed chain if its count check passed, else the union of both
    verified sets (still flagged); the FK error is recomputed on the forward chain."""
    q = rev.q[:, ::-1] if rev.count_ok else _dedup(np.vstack([fwd.q, rev.q[:, ::-1]]))
    err = float(np.max(_fk_errors(fk(q), target, scale), initial=0.0)) if len(q) else 0.0
    if rev.count_ok:
        return replace(rev, q=q, fk_error=err, errors=None)
    reason = f"{fwd.reason}; from the other end: {rev.reason.removeprefix('count check failed: ')}"
    return _flagged(fwd, q, err, reason)


def covers(arm: Mechanism | General6R) -> bool:
    """Whether `solve_general_6r` covers the arm's geometry (`General6R.covered`): False for
    chains that are not 6R (no exception) and for special geometry where the elimination is
    singular from both ends, whose answers would fail the count check."""
    try:
        return _arm(arm).covered
    except InvalidArgumentError:
        return False


def ik_general_6r(m: Mechanism, target: Any) -> list[list[float]]:
    """All real IK solutions of a 6R mechanism for one 4x4 target, as rows ``q`` (the
    closed-form registry's solver contract ``(m, T) -> list[q]``; ``[]`` when unreachable).
    `solve_general_6r` returns the same solutions with the count check and the reason; when the
    count check fails the list is a [`registry.Uncertified`][optik.closed_form.registry.Uncertified]
    carrying that reason (route only arms for which `covers` is True here), else a
    [`registry.CheckedRows`][optik.closed_form.registry.CheckedRows] carrying each row's
    position and orientation errors by ``m``'s FK (the FK check's own evaluation), which
    `optik.solve_ik_all` then reports instead of evaluating the FK of every row again."""
    sols = solve_general_6r(m, target)
    if not sols.count_ok:
        return registry.Uncertified(sols.q.tolist(), sols.reason)
    if sols.errors is None:
        return sols.q.tolist()
    return registry.CheckedRows(sols.q.tolist(), [tuple(e) for e in sols.errors.tolist()], True)
