"""Stewart-Gough FK in 40 paths: a parameter homotopy from a generic complex start instance.

The start instance (complex base and platform points ``b0, p0`` and leg constants ``c0``, see
`optik.closed_form.parallel.study.study_matrices`) and its 40 solutions are computed once, by
the 128-path total-degree homotopy, and shipped with the package (`START_FILE`; `generate`
and ``scripts/make_stewart_start.py`` rebuild it). *Certificate:* 40 distinct nonsingular
solutions, each Newton-refined to a residual at rounding level; 40 bounds the isolated
nonsingular solutions of every instance of the family (the generic count), so none is missing.

For a target ``(b, p, c)`` the parameters move on the line ``(b, p, c) + s (b0 - b, p0 - p,
c0 - c)``, so the matrices are quadratic in ``s``: ``M(s) = C0 + s C1 + s^2 C2``.
`optik.closed_form.parameter_homotopy.track` follows the 40 paths, evaluating the seven quadrics
from that line of points and constants (`optik.closed_form.parameter_homotopy.LegLine`) without
forming the matrices.
"""

from __future__ import annotations

import json
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from optik.closed_form import homotopy, parameter_homotopy
from optik.closed_form.parallel.study import study_matrices

START_FILE = Path(__file__).resolve().parents[2] / "data" / "stewart_gough_start.json"
"""The shipped start instance and its 40 solutions (JSON, real and imaginary parts)."""

START_SEED = 2026
"""Seed of the shipped start instance (`generate`)."""

GENERAL_SOLUTIONS = 40
"""Isolated solutions of a general (complex) Stewart-Gough instance."""

SAME_POINT = 1e-7
"""Two projective points can be the same only when ``1 - |<u, v>| / (|u| |v|)`` is below this
(projective distance below ``sqrt(2e-7) = 4.5e-4``); `same_points` decides those pairs."""

SAME_ERRORS = 10.0
"""Two end points are the same solution when their projective distance is at most this many
times the sum of their error estimates (`error_estimates`) plus `ROUNDING`."""

ROUNDING = 1e-11
"""The projective distance under which two unit end points always count as the same (rounding
of a converged point, whose Newton step can be exactly zero)."""

SINGULAR_CONDITION = parameter_homotopy.SINGULAR_CONDITION
"""End points whose Jacobian condition number exceeds this count as singular."""


@dataclass(frozen=True)
class StartInstance:
    """A complex Stewart-Gough instance and all its solutions in Study's coordinates.

    Attributes:
        base: ``(6, 3)`` complex base points ``b0``.
        platform: ``(6, 3)`` complex platform points ``p0``.
        constants: ``(6,)`` complex leg constants ``c0`` (``|p|^2 + |b|^2 - rho^2``).
        solutions: ``(40, 8)`` complex solutions ``z = (e, g)``, unit norm.
        seed: seed it was drawn with.
    """

    base: np.ndarray
    platform: np.ndarray
    constants: np.ndarray
    solutions: np.ndarray
    seed: int

    def residual(self) -> float:
        """Largest ``|z^T M_j z|`` over the (unit) solutions and the 7 equations."""
        mats = study_matrices(self.base, self.platform, self.constants)
        return float(np.max(np.abs(np.einsum("kij,pi,pj->pk", mats, self.solutions, self.solutions))))


def error_estimates(mats: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Relative error estimate ``|dz| / |z|`` of each row of ``z`` as a root of the quadrics
    ``mats``: the length of one Newton step (`optik.closed_form.homotopy.newton_step`), which is
    the distance to a nonsingular root to first order and about half the distance to a double one
    (``inf`` where the Jacobian is singular)."""
    dz = homotopy.newton_step(mats, z)
    err = np.linalg.norm(dz, axis=1) / np.linalg.norm(z, axis=1)
    return np.where(np.isfinite(err), err, np.inf)


def projective_distance(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``min_phi |u - e^{i phi} v|`` of unit rows ``u``, ``v`` with ``<v, u> != 0`` (from the aligned
    difference, so it resolves distances down to rounding, which ``1 - |<u, v>|`` does not below
    about ``1e-8``)."""
    inner = np.sum(np.conj(v) * u, axis=1)
    return np.linalg.norm(u - (inner / np.abs(inner))[:, None] * v, axis=1)


Quadrics = np.ndarray | Callable[[], np.ndarray]
"""The quadrics ``M_k`` of a system, or a function that builds them (called only when needed)."""


def same_points(mats: Quadrics, z: np.ndarray) -> np.ndarray:
    """The symmetric boolean matrix "rows ``i`` and ``j`` of ``z`` are the same solution" of the
    quadrics ``mats`` (built only when two rows are that close and not equal to rounding).

    Rows are the same when their projective distance (`projective_distance`) is
    ``d_ij <= min(sqrt(2 SAME_POINT), SAME_ERRORS (e_i + e_j) + ROUNDING)`` with ``e`` the
    `error_estimates`. Two end points are thus the same only when their
    distance is explained by their own errors: two nonsingular roots ``1e-4`` apart, with errors
    near ``1e-10``, are two solutions (a fixed distance would merge them), while two paths
    converging to one double root (errors of the order of their distance) are one."""
    u = z / np.linalg.norm(z, axis=1, keepdims=True)
    same = np.abs(np.conj(u) @ u.T) > 1 - SAME_POINT
    if np.count_nonzero(same) > len(z):  # usually not: distinct solutions are far apart
        i, j = np.nonzero(np.triu(same, 1))
        far = ~_within_errors(mats, z, i, j, projective_distance(u[i], u[j]))
        same[i[far], j[far]] = same[j[far], i[far]] = False
    return same


def self_conjugate(mats: Quadrics, z: np.ndarray) -> np.ndarray:
    """Which rows of ``z`` are the same solution (`same_points`) as their complex conjugate: the
    real solutions of real quadrics ``mats`` (``conj(z)`` is a solution too, with the same error
    estimate). A near-real pair ``z, conj(z)`` whose distance exceeds what their errors explain is
    two complex solutions; a real root known only to ``1e-6`` (ill-conditioned) is real."""
    u = z / np.linalg.norm(z, axis=1, keepdims=True)
    real = np.abs(np.einsum("ij,ij->i", u, u)) > 1 - SAME_POINT  # |<conj(u), u>|: candidates
    k = np.flatnonzero(real)
    real[k] = _within_errors(mats, z, k, k, projective_distance(u[k], np.conj(u[k])))
    return real


def _within_errors(mats: Quadrics, z: np.ndarray, i: np.ndarray, j: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``d <= SAME_ERRORS (e_i + e_j) + ROUNDING`` with ``e`` the `error_estimates` of the rows
    of ``z`` (computed only when some ``d`` exceeds ``ROUNDING``, for those rows only)."""
    ok = d <= ROUNDING
    if not np.all(ok):
        rows, inverse = np.unique(np.r_[i[~ok], j[~ok]], return_inverse=True)
        err = error_estimates(mats() if callable(mats) else mats, z[rows])
        e_i, e_j = np.split(err[inverse], 2)
        ok[~ok] = d[~ok] <= SAME_ERRORS * (e_i + e_j) + ROUNDING
    return ok


def distinct(mats: Quadrics, z: np.ndarray) -> np.ndarray:
    """Indices of the rows of ``z`` that are distinct solutions of the quadrics ``mats``
    (`same_points`; the first of each group)."""
    return first_of_groups(same_points(mats, z))


def first_of_groups(same: np.ndarray) -> np.ndarray:
    """Indices kept by the greedy rule "keep row ``i`` unless it is the same as a row kept before"
    for the symmetric boolean matrix ``same`` (one Python step per row only when some pair is
    the same)."""
    earlier = np.triu(same, 1)
    if not earlier.any():
        return np.arange(len(same))
    keep = np.zeros(len(same), dtype=bool)
    for i in range(len(same)):
        keep[i] = not np.any(same[i, :i] & keep[:i])
    return np.flatnonzero(keep)


def relative_residual(mats: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``max_j |z^T M_j z| / |z|^2`` per row of ``z``."""
    val = np.einsum("kij,pi,pj->pk", mats, z, z)
    return np.max(np.abs(val), axis=1) / np.sum(np.abs(z) ** 2, axis=1)


def _canonical(z: np.ndarray) -> np.ndarray:
    """Unit norm, the largest coordinate real positive, rows in a fixed order."""
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    big = z[np.arange(len(z)), np.argmax(np.abs(z), axis=1)]
    z = z * (np.abs(big) / big)[:, None]
    return z[np.lexsort(np.round(z.real.T[::-1], 6))]


def generate(seed: int = START_SEED, max_rounds: int = 20, time_limit: float = 60.0) -> StartInstance:
    """Draw a generic complex instance and solve it by the 128-path total-degree homotopy
    (rounds with fresh gamma and patch merged until 40 distinct nonsingular solutions).

    Raises:
        RuntimeError: 40 certified solutions were not found within ``max_rounds``.
    """
    rng = np.random.default_rng(seed)
    b = (rng.normal(size=(6, 3)) + 1j * rng.normal(size=(6, 3))) / np.sqrt(2)
    p = (rng.normal(size=(6, 3)) + 1j * rng.normal(size=(6, 3))) / np.sqrt(2)
    c = rng.normal(size=6) + 1j * rng.normal(size=6)
    mats = study_matrices(b, p, c)
    scaled = mats / np.linalg.norm(mats, axis=(1, 2))[:, None, None]
    sols = np.zeros((0, 8), dtype=complex)
    for _ in range(max_rounds):
        res = homotopy.track(scaled, rng, time_limit=time_limit)
        z = homotopy.refine(mats, res.z, iters=6)
        good = (relative_residual(mats, z) < 1e-13) & (parameter_homotopy.condition_numbers(mats, z) < 1e6)
        sols = np.concatenate([sols, z[good]])
        sols = sols[distinct(mats, sols)]
        if len(sols) >= GENERAL_SOLUTIONS:
            break
    if len(sols) != GENERAL_SOLUTIONS:
        raise RuntimeError(f"found {len(sols)} certified solutions of the start instance, expected 40")
    return StartInstance(b, p, c, _canonical(sols), seed)


def write(instance: StartInstance, path: Path = START_FILE) -> None:
    """Write ``instance`` as JSON (atomically: a temporary file renamed into place)."""

    def parts(a: np.ndarray) -> dict[str, list]:
        return {"re": a.real.tolist(), "im": a.imag.tolist()}

    data = {
        "description": "Generic complex Stewart-Gough start instance and its 40 solutions in Study's "
        "coordinates z = (e, g); see optik.closed_form.parallel.stewart_parameter",
        "seed": instance.seed,
        "base": parts(instance.base),
        "platform": parts(instance.platform),
        "constants": parts(instance.constants),
        "solutions": parts(instance.solutions),
    }
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        tmp.write_text(json.dumps(data, indent=1), encoding="utf-8")  # a plain write's mode (umask)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@lru_cache(maxsize=4)
def load(path: Path = START_FILE) -> StartInstance:
    """The start instance stored at ``path`` (cached)."""
    data = json.loads(Path(path).read_text())

    def arr(key: str) -> np.ndarray:
        return np.array(data[key]["re"]) + 1j * np.array(data[key]["im"])

    return StartInstance(arr("base"), arr("platform"), arr("constants"), arr("solutions"), int(data["seed"]))


@dataclass(frozen=True)
class ParameterSolve:
    """Outcome of the 40-path parameter homotopy on one (scaled) instance.

    Attributes:
        solutions: distinct end points that solve the target (nonsingular ones first).
        condition: condition number of each solution (below `SINGULAR_CONDITION`: nonsingular).
        nonsingular: how many of them are nonsingular.
        complete: the count check: 40 distinct nonsingular end points (all isolated solutions).
        status: per path ``"regular"``, ``"endgame"`` or ``"failed"``.
        steps: predictor-corrector steps.
    """

    solutions: np.ndarray
    condition: np.ndarray
    nonsingular: int
    complete: bool
    status: np.ndarray
    steps: int


DEGENERATE_STALL = 0.05
"""A path that stalls near ``t = 0`` with ``|e| / |z|`` below this heads for the degenerate set
``e = 0`` (where every leg quadric reduces to ``|g|^2 = 0``), which holds no posture; it skips
the endgame."""


def _degenerate(z: np.ndarray) -> np.ndarray:
    return np.linalg.norm(z[:, :4], axis=1) / np.linalg.norm(z, axis=1) < DEGENERATE_STALL


def solve(
    b: np.ndarray, p: np.ndarray, c: np.ndarray, rng: np.random.Generator, time_limit: float
) -> ParameterSolve:
    """All solutions of the (scaled) instance ``(b, p, c)`` by the 40-path parameter homotopy.

    End points are refined by two Newton steps on the target (the tracker's ``refine``; it ends
    them within 1e-8 already) and kept when they solve it (relative residual below 1e-8); the
    count check asks for `GENERAL_SOLUTIONS` distinct nonsingular ones (condition number below
    `SINGULAR_CONDITION`).
    """
    start = load()
    legs = parameter_homotopy.LegLine(b, start.base - b, p, start.platform - p, c, start.constants - c)
    res = parameter_homotopy.track(
        legs, start.solutions, rng, time_limit=time_limit, abandon=_degenerate, refine=2
    )
    solves = res.residual < 1e-8  # inf for failed and abandoned paths
    z, cond = res.z[solves], res.condition[solves]
    order = np.argsort(cond)  # nonsingular representatives first
    z, cond = z[order], cond[order]
    keep = distinct(lambda: study_matrices(b, p, c), z)
    nonsingular = int(np.sum(cond[keep] < SINGULAR_CONDITION))
    return ParameterSolve(
        z[keep], cond[keep], nonsingular, nonsingular == GENERAL_SOLUTIONS, res.status, res.steps
    )
