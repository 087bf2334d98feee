"""Contacts and static balance: frames held in the world and the centre of mass over a support polygon.

``solve_ik(m, {"hand": T}, contacts={"l_sole": T_l, "r_sole": T_r}, support=polygon,
com_margin=0.01)``:

* ``contacts`` maps frames to a 4x4 (a flat contact: the whole pose is held) or an
  `optik.Position` (a point foot: the position is held). They are frame targets with the same
  tolerances as the task targets, so every method that takes several targets (``lm``, ``nlp``,
  ``dls``, ``qp``) holds them, and success needs every contact met (`merge_contacts`).
* ``support`` is the world x-y polygon of the feet in contact, counter-clockwise, a ``(k, 2)``
  array, or ``"auto"`` (`auto_support`: the hull of the contacts' ground projections). Its
  edges ``v_i -> v_{i+1}`` give the half-planes ``n_i . x <= n_i . v_i`` with the unit outward
  normals ``n_i = (dy, -dx) / |d|`` (`support_halfplanes`); static balance asks the
  ground projection of the centre of mass, ``c_xy(q)`` of `optik.Mechanism.com`, to lie inside by
  ``com_margin`` (m):

  ```
  n_i . c_xy(q) <= n_i . v_i - com_margin,      i = 1 ... k
  ```

  Method ``"lm"`` (the default) adds the hinges ``max(0, n_i . c_xy(q) - b_i + com_margin)``
  to the compiled kernel's residual (`balance_problem`, with the active-set step of
  `optik.solvers.lm_kernel.lm_iteration_function`); method ``"qp"`` puts the linearized rows
  into each differential-IK step's QP (`optik.diffik.build_qp`); method ``"nlp"`` has them as
  inequality constraints of the IK NLP (IPOPT):

  ```
  minimize_q  1/2 (|r_p|^2 + |r_o|^2) + 1/2 w_post |q - q_ref|^2     targets and contacts
  subject to  q_min <= q <= q_max,  c(q) = 0,  N c_xy(q) <= b - margin
  ```

  solved by IPOPT (exact second derivatives, adaptive barrier; ``posture`` 0 by default: a
  positive weight biases the optimum and is then removed by a second solve from the answer)
  from ``q0`` and then from random starts until success or the time limit. Success
  needs the targets, the contacts, the limits and the balance rows (to 1e-9 m) all met; the
  result's ``extra`` holds ``"com"`` (the centre of mass) and ``"com_inside"`` (its smallest
  distance inside the polygon's edges, ``>= com_margin`` on success).
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Mapping
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_float, real_array
from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.problem import IKProblem, build_ik_problem, target_parameters
from optik.results import IKResult
from optik.solvers.base import (
    IKRequest,
    PreparedCache,
    get_method,
    make_result,
    method_options,
    restart_stop,
    start_points,
)
from optik.solvers.lm import lm_settings, request_seed
from optik.solvers.lm_kernel import STATUS, LMKernel
from optik.targets import Position

__all__ = [
    "BALANCE_METHODS",
    "BALANCE_TOL",
    "balance_problem",
    "compiled_kernels",
    "merge_contacts",
    "solve_balance",
    "support_halfplanes",
]

BALANCE_METHODS = ("lm", "nlp", "qp")
"""Methods that take ``support=`` (the first is the default)."""

BALANCE_TOL = 1e-9
"""Largest violation (m) of a balance row that still counts as met."""

LM_BUFFER = 1e-6
"""Extra margin (m) of the ``lm`` kernel's balance hinges: its stop test allows each closure row
half the closure tolerance, and the exact check of the answer then passes with room."""

_SOLVERS: PerMechanism[dict[Any, Any]] = PerMechanism()
"""Per mechanism: the nlp balance solvers (with their locks) and the lm balance kernels."""
_PREPARED: PreparedCache[tuple[LMKernel, np.ndarray]] = PreparedCache()
"""Per mechanism: the validated ``lm`` balance requests (`_prepared_lm`)."""
_SOLVERS_LOCK = threading.Lock()


def merge_contacts(m: Mechanism, target: Any, frame: str | None, contacts: Any) -> dict[str, Any]:
    """``{frame: target}`` of the task target(s) and the contacts, one dict.

    Raises:
        InvalidArgumentError: ``contacts`` is not a dict of 4x4 transforms or `Position`
            targets, or names a frame that is also a task target.
    """
    if not isinstance(contacts, Mapping) or not contacts:
        raise InvalidArgumentError(
            "contacts", f"expected a non-empty {{frame: 4x4 or Position}}, got {contacts!r}"
        )
    if isinstance(target, Mapping):
        if frame is not None:
            raise InvalidArgumentError("frame", "give the frames as the keys of the target dict")
        merged = dict(target)
    else:
        merged = {m.ee if frame is None else frame: target}
    for name, value in contacts.items():
        if name in merged:
            raise InvalidArgumentError("contacts", f"frame {name!r} is both a target and a contact")
        if not isinstance(value, Position):
            t = real_array(value, f"contacts[{name!r}]")
            if t.shape != (4, 4):
                raise InvalidArgumentError("contacts", f"contact {name!r}: expected a 4x4 or a Position")
        merged[name] = value
    return merged


_HALFPLANES: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
_HALFPLANES_MAX = 64


def auto_support(m: Mechanism, contacts: Mapping[str, Any]) -> np.ndarray:
    """``support="auto"``: the counter-clockwise convex hull ``(k, 2)`` of the contacts' ground
    projections.

    A flat contact (a 4x4 held pose ``T_f`` of frame ``f`` on body ``B``, ``m.frames[f] = (B,
    O_f)``) contributes the collision geometry of every link on ``B`` (`optik.collision.robot`,
    a link ``L`` at ``T_f O_f^-1 O_L``), projected onto the ground (x-y): a box's, cylinder's or
    mesh's vertices, a sphere's or capsule's centres (a round foot touches the ground below its
    centre); a point contact (`Position`) its point.

    Raises:
        InvalidArgumentError: no ``contacts``, a flat contact whose body has no collision
            geometry, or fewer than three points in general position.
    """
    from scipy.spatial import ConvexHull, QhullError

    from optik.collision.robot import robot_geometry
    from optik.collision.shapes import shape_vertices

    if not isinstance(contacts, Mapping) or not contacts:
        raise InvalidArgumentError("support", 'support="auto" needs contacts={frame: 4x4 or Position}')
    points: list[np.ndarray] = []
    geo = None
    for name, value in contacts.items():
        if isinstance(value, Position):
            points.append(np.asarray(value.xyz, dtype=float)[None, :2])
            continue
        geo = robot_geometry(m) if geo is None else geo
        m._frame(name)  # raises for an unknown frame
        body, offset = m.frames[name]
        body_pose = real_array(value, f"contacts[{name!r}]") @ np.linalg.inv(offset)
        found = 0
        for part, link in zip(geo.parts, geo.part_link, strict=True):
            on, link_offset = m.frames[geo.links[link]]
            if on != body:
                continue
            pose = body_pose @ link_offset @ part.offset
            local, _ = shape_vertices(part.shape)  # a sphere's centre, a capsule's two: radius dropped
            points.append((local @ pose[:3, :3].T + pose[:3, 3])[:, :2])
            found += 1
        if not found:
            raise InvalidArgumentError(
                "support", f'support="auto": the body {body!r} of contact {name!r} has no collision geometry'
            )
    pts = np.concatenate(points)
    try:
        hull = ConvexHull(pts)
    except (QhullError, ValueError) as exc:
        raise InvalidArgumentError(
            "support", f'support="auto": the contacts\' ground points span no polygon ({len(pts)} points)'
        ) from exc
    return pts[hull.vertices]


def support_halfplanes(support: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(N, b)``: the polygon's inside is ``N x <= b`` (unit outward edge normals, ``(k, 2)``, ``(k,)``;
    read-only, kept for the last polygons seen: a solve per target on one polygon checks it once).

    Raises:
        InvalidArgumentError: not a finite ``(k, 2)`` array with ``k >= 3``, or not a convex
            counter-clockwise polygon (every turn strictly to the left).
    """
    v = real_array(support, "support")
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3 or not np.all(np.isfinite(v)):
        raise InvalidArgumentError(
            "support", f"expected a finite (k, 2) polygon with k >= 3, got shape {v.shape}"
        )
    key = v.tobytes()
    with _SOLVERS_LOCK:
        hit = _HALFPLANES.get(key)
    if hit is not None:
        return hit
    d = np.roll(v, -1, axis=0) - v
    turns = d[:, 0] * np.roll(d, -1, axis=0)[:, 1] - d[:, 1] * np.roll(d, -1, axis=0)[:, 0]
    if np.any(np.linalg.norm(d, axis=1) < 1e-12) or np.any(turns <= 0):
        raise InvalidArgumentError("support", "expected a convex polygon, vertices counter-clockwise")
    n = np.column_stack([d[:, 1], -d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
    out = (n, np.einsum("ij,ij->i", n, v))
    for a in out:
        a.flags.writeable = False
    with _SOLVERS_LOCK:
        if len(_HALFPLANES) >= _HALFPLANES_MAX:
            _HALFPLANES.clear()
        _HALFPLANES[key] = out
    return out


def _balance_rows(m: Mechanism, q: ca.SX, k: int) -> tuple[ca.SX, ca.SX]:
    """``(halfplanes, rows)``: the ``k x 3`` parameter ``[n_x, n_y, b - margin]`` of the polygon's
    edges and the balance rows ``N c_xy(q) - (b - margin)`` (``<= 0`` inside)."""
    halfplanes = ca.SX.sym("halfplanes", k, 3)
    c = m.com_function(q)[0]
    return halfplanes, ca.mtimes(halfplanes[:, :2], c[:2]) - halfplanes[:, 2]


def halfplane_parameters(normals: np.ndarray, b: np.ndarray, margin: float) -> np.ndarray:
    """The values of the ``halfplanes`` parameter of `_balance_rows`, column-major (``(3 k,)``)."""
    return np.column_stack([normals, b - margin]).reshape(-1, order="F")


def balance_problem(request: IKRequest, k: int) -> tuple[IKProblem, ca.SX]:
    """The request's `IKProblem` with static balance as penalty rows, for method ``"lm"``.

    The target parameters get the ``3 k`` polygon parameters appended (`halfplane_parameters`,
    so one kernel serves every polygon of ``k`` edges and every margin) and the closure rows get
    the hinges ``max(0, n_i . c_xy(q) - (b_i - margin))``: zero wherever the centre of mass is
    inside by the margin, so the kernel's stop test (every closure row below its tolerance) holds
    only when the targets are met *and* the centre of mass is inside. Returned with the rows
    ``n_i . c_xy(q) - (b_i - margin)`` themselves (the kernel's active-set step,
    `optik.solvers.lm_kernel.lm_iteration_function`).
    """
    m = request.mechanism
    base = build_ik_problem(m, request.task, request.frame)
    halfplanes, rows = _balance_rows(m, base.q, k)
    problem = dataclasses.replace(
        base,
        target=ca.vertcat(base.target, ca.vec(halfplanes)),
        closure=ca.vertcat(base.closure, ca.fmax(0, rows)),
    )
    return problem, rows


def _nlp_solver(request: IKRequest, k: int) -> tuple[ca.Function, threading.Lock]:
    """IPOPT on the IK NLP of the request's frames plus ``k`` balance rows (built once per
    mechanism, tasks, frames and ``k``; one lock per instance: an nlpsol is not re-entrant)."""
    m = request.mechanism
    key = ("nlp", request.task, request.frame, k)
    with _SOLVERS_LOCK:
        cached = _SOLVERS.setdefault(m, {}).get(key)
    if cached is not None:
        return cached
    problem = build_ik_problem(m, request.task, request.frame)
    halfplanes, rows = _balance_rows(m, problem.q, k)
    nlp = {
        "x": problem.q,
        "p": ca.vertcat(problem.parameters, ca.vec(halfplanes)),
        "f": problem.objective,
        "g": ca.vertcat(problem.closure, rows),
    }
    options = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": 1e-12,
        "ipopt.constr_viol_tol": 1e-11,
        "ipopt.bound_relax_factor": 0.0,
        "ipopt.max_iter": 200,
        "ipopt.mu_strategy": "adaptive",
    }
    made = (ca.nlpsol("balance", "ipopt", nlp, options), threading.Lock())
    with _SOLVERS_LOCK:
        return _SOLVERS[m].setdefault(key, made)


def _lm_kernel(request: IKRequest, k: int, closure_weight: float, compile: bool | str) -> LMKernel:
    """The ``lm`` kernel of `balance_problem` (built once per mechanism, tasks, frames, ``k``,
    closure weight and ``compile``)."""
    m = request.mechanism
    key = ("lm", request.task, request.frame, k, closure_weight, compile)
    with _SOLVERS_LOCK:
        cached = _SOLVERS.setdefault(m, {}).get(key)
    if cached is not None:
        return cached
    problem, rows = balance_problem(request, k)
    made = LMKernel(
        m, request.task, request.frame, closure_weight, compile, problem=problem, inequalities=rows
    )
    with _SOLVERS_LOCK:
        return _SOLVERS[m].setdefault(key, made)


def _kernels(m: Mechanism) -> list[LMKernel]:
    """The ``lm`` balance kernels built for ``m`` so far."""
    with _SOLVERS_LOCK:
        return [v for v in _SOLVERS.get(m, {}).values() if isinstance(v, LMKernel)]


def compiled_kernels(m: Mechanism) -> list[bool]:
    """Whether each ``lm`` balance kernel built for ``m`` so far calls compiled C (False: still
    answering through CasADi's evaluator while the C compiler runs)."""
    return [k.compiled for k in _kernels(m)]


def wait_kernels(m: Mechanism) -> None:
    """Wait for the C build of every ``lm`` balance kernel built for ``m`` so far."""
    for k in _kernels(m):
        if k.library is not None:
            k.library.wait()


def _inside(m: Mechanism, q: np.ndarray, normals: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """The centre of mass and its smallest distance inside the polygon (negative outside)."""
    c = m.com(q)
    return c, float(np.min(b - normals @ c[:2]))


def _run(solver: ca.Function, lock: threading.Lock, x0: np.ndarray, p: np.ndarray, bounds: tuple) -> tuple:
    """One IPOPT solve: ``(q, iterations)``."""
    lbx, ubx, lbg, ubg = bounds
    with lock:
        sol = solver(x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        iterations = int(solver.stats().get("iter_count", 0))
    return np.asarray(sol["x"]).reshape(-1), iterations


def _judged(
    request: IKRequest,
    q: np.ndarray,
    method: str,
    iterations: int,
    restarts: int,
    normals: np.ndarray,
    b: np.ndarray,
    margin: float,
    status: str | None = None,
) -> IKResult:
    """The result of a solve, its success including the balance rows (checked again here, on
    the final answer, by `optik.Mechanism.com`)."""
    res = make_result(request, q, method, iterations, restarts, status)
    com, inside = _inside(request.mechanism, res.q, normals, b)
    res.extra.update({"com": com, "com_inside": inside})
    if res.success and inside < margin - BALANCE_TOL:
        res.success, res.status = False, status or "not_converged"
        res.message = f"the centre of mass is {inside:.3g} m inside the support polygon, less than {margin:g}"
    return res


def solve_balance(request: IKRequest, support: Any, com_margin: Any, method: str | None = None) -> IKResult:
    """Solve a request whose targets include the contacts with static balance (module docstring).

    Args:
        request: the request (its targets include the contacts, `merge_contacts`).
        support: the counter-clockwise ``(k, 2)`` support polygon.
        com_margin: the balance margin (m).
        method: one of `BALANCE_METHODS` (None: the first).

    Raises:
        InvalidArgumentError: a malformed ``support`` or ``com_margin``, or a bad option.
        SolverUnavailableError: a method without balance constraints.
        ModelError: the mechanism has no mass.
    """
    if method is None:
        method = BALANCE_METHODS[0]
    if method not in BALANCE_METHODS:
        raise SolverUnavailableError(
            f"method {method!r} does not take support= (the balance constraints); use one of "
            f"{BALANCE_METHODS}, or contacts alone, which every method that takes several targets holds"
        )
    normals, b = support_halfplanes(support)
    margin = as_float(com_margin, "com_margin", minimum=0.0)
    if method == "qp":
        return _solve_qp(request, support, normals, b, margin)
    solve = _solve_lm if method == "lm" else _solve_nlp
    return solve(request, normals, b, margin)


def _solve_qp(
    request: IKRequest, support: Any, normals: np.ndarray, b: np.ndarray, margin: float
) -> IKResult:
    """Method ``"qp"`` (iterated differential IK, `optik.diffik.ik`) with the balance rows as each
    step's QP inequalities; the answer judged again with the exact balance check."""
    options = {**request.options, "support": support, "com_margin": margin}
    res = get_method("qp").solve(dataclasses.replace(request, options=options))
    status = None if res.success else res.status
    return _judged(request, res.q, "qp", res.iterations, res.restarts, normals, b, margin, status)


def _prepared_lm(request: IKRequest, k: int) -> tuple[LMKernel, np.ndarray]:
    """The ``lm`` balance kernel and the driver's ``conf`` of a request, cached per mechanism,
    task, frames, tolerances, option values (when hashable) and ``k`` (validation costs more than
    a solve)."""
    m = request.mechanism
    key = _PREPARED.key(request, k)
    hit = _PREPARED.get(m, key)
    if hit is None:
        settings, closure_weight, compile = lm_settings(request)
        since = time.perf_counter()
        hit = (_lm_kernel(request, k, closure_weight, compile), settings.conf(m))
        request.exclude_setup(since)
        hit = _PREPARED.put(m, key, hit)
    return hit


def _solve_lm(request: IKRequest, normals: np.ndarray, b: np.ndarray, margin: float) -> IKResult:
    """Method ``"lm"`` on `balance_problem` (options as ``"lm"``'s): the whole multi-start
    loop in the compiled kernel, the answer judged again with the exact balance check."""
    kern, base = _prepared_lm(request, len(b))
    conf = base.copy()
    conf[3] = max(request.remaining(), 0.0)
    params = np.concatenate(
        [target_parameters(request.target), halfplane_parameters(normals, b, margin + LM_BUFFER)]
    )
    seed = request_seed(request.seed) & (2**64 - 1)
    q, _, iterations, restarts, code = kern.run_one(params, request.q0, seed, conf)
    status = None if code == 0 else STATUS[code]
    return _judged(request, q, "lm", iterations, restarts, normals, b, margin, status)


def _solve_nlp(request: IKRequest, normals: np.ndarray, b: np.ndarray, margin: float) -> IKResult:
    """Method ``"nlp"``: IPOPT with the balance rows as inequalities (module docstring).

    Options: ``posture`` (0: weight of ``1/2 |q - q_ref|^2``), ``q_ref`` (``q0``),
    ``max_restarts`` (None: until success or the time limit).
    """
    m = request.mechanism
    opts = method_options(request, {"posture": 0.0, "q_ref": None, "max_restarts": None})
    since = time.perf_counter()
    solver, lock = _nlp_solver(request, len(b))
    request.exclude_setup(since)
    problem = build_ik_problem(m, request.task, request.frame)
    q_ref = request.q0 if opts["q_ref"] is None else m.check_q(opts["q_ref"], "q_ref")
    p = np.concatenate(
        [
            target_parameters(request.target),
            [1.0, 1.0],
            q_ref,
            [as_float(opts["posture"], "posture", minimum=0.0), 0.0, 0.0],
            halfplane_parameters(normals, b, margin),
        ]
    )
    polish = p.copy()
    polish[len(p) - 3 * len(b) - 3] = 0.0
    n_closure = problem.closure.shape[0]
    lbg = np.concatenate([np.zeros(n_closure), np.full(len(b), -np.inf)])
    ubg = np.zeros(n_closure + len(b))
    lbx = np.where(np.isfinite(m.lower), m.lower, -1e20)
    ubx = np.where(np.isfinite(m.upper), m.upper, 1e20)
    bounds = (lbx, ubx, lbg, ubg)
    deadline = request.start + request.time_limit
    best: tuple[float, IKResult] | None = None
    restarts = iterations = 0
    stop = "time_limit"

    def judged(x0: np.ndarray, p: np.ndarray) -> IKResult:
        q, its = _run(solver, lock, x0, p, bounds)
        return _judged(request, q, "nlp", iterations + its, restarts, normals, b, margin)

    for x0 in start_points(request):
        res = judged(x0, p)
        iterations = res.iterations
        if not res.success:  # again without the posture term, which biases the optimum
            res = judged(res.q, polish)
            iterations = res.iterations
        badness = (
            0.0
            if res.success
            else max(res.position_error, res.orientation_error, margin - res.extra["com_inside"], 1e-300)
        )
        if best is None or badness < best[0]:
            best = (badness, res)
        if res.success:
            stop = ""
            break
        why = restart_stop(deadline, restarts, opts["max_restarts"])
        if why is not None:
            stop = why
            break
        restarts += 1
    assert best is not None  # start_points yields at least q0
    out = best[1]
    out.restarts, out.solve_time = restarts, request.elapsed()
    if not out.success and stop and stop not in out.message:
        out.message = f"{out.message} ({stop})" if out.message else stop
    return out
