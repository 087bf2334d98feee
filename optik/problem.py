"""IK problems: one CasADi NLP per (mechanism, task, frame, options), built once, targets as parameters.

For a mechanism with coordinates ``q``, a task frame with pose ``T(q) = [[R, p], [0, 1]]`` and a
target ``T* = [[R*, p*], [0, 1]]``, the *task residual* ``r(q; T*)`` is, per task space:

| task | residual rows |
|---|---|
| pose | ``p - p*`` (3) and ``vec(R - R*) / sqrt(2)`` (9) |
| position | ``p - p*`` (3) |
| orientation | ``vec(R - R*) / sqrt(2)`` (9) |
| pose2d | ``(x - x*, y - y*)`` and ``(cos phi - cos phi*, sin phi - sin phi*)`` |
| position2d | ``(x - x*, y - y*)`` |

The orientation rows satisfy ``|vec(R - R*)|^2 / 2 = 2 (1 - cos theta) = (2 sin(theta / 2))^2``
with ``theta`` the geodesic angle between ``R`` and ``R*``: their squared norm is a function of
``theta`` alone that is increasing on ``[0, pi]``, so its only stationary points over SO(3) are the
minimum ``theta = 0`` and the maximum ``theta = pi``. (The common ``vee(R R*^T - R* R^T)`` error
vanishes at ``theta = pi`` too and would create a spurious stationary point there.) The planar
heading rows are the same construction in SO(2): their norm is ``2 sin(|phi - phi*| / 2)``. So
for both, ``theta = 2 asin(|r_o| / 2)`` recovers the angle error
([`angle_from_residual`][optik.problem.angle_from_residual]).

The NLP ([`IKProblem`][optik.IKProblem]) is:

```text
minimize_q   1/2 (w_p^2 |r_p|^2 + w_o^2 |r_o|^2)               task error
           + 1/2 w_post |q - q_ref|^2                          posture (resolves redundancy)
           - w_manip log(det(J J^T) + eps)                     manipulability (optional)
           + 1/2 w_lim sum(((q - q_mid) / (q_max - q_min))^2)  distance to limits (optional)
subject to  q_min <= q <= q_max                                joint limits (bounds)
            c(q) = 0                                           loop closures (closed chains)
```

with the target, the weights and ``q_ref`` as NLP parameters: a new target or weight never
rebuilds anything. [`build_ik_problem`][optik.build_ik_problem] returns the problem, cached per
mechanism, task, frame and secondary-objective selection.

*Several frame targets* (a tree: both hands of a humanoid, two tools of a dual-arm robot): with
``frame`` a tuple of frames and ``task`` a tuple of task spaces, one per frame, the residual
blocks are stacked, ``r_p = [r_p,1; ...; r_p,k]`` and ``r_o = [r_o,1; ...; r_o,k]``, the target
parameters are the frames' 12 parameters one after the other, and the errors of the success
check are the largest over the frames (`frame_tasks` pairs them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from optik import spatial
from optik.checks import as_vector
from optik.errors import InvalidArgumentError
from optik.mechanism import TASK_ROWS, Mechanism
from optik.mechanism.memo import PerMechanism

__all__ = [
    "SECONDARY_OBJECTIVES",
    "IKProblem",
    "angle_from_residual",
    "build_ik_problem",
    "frame_tasks",
    "target_parameters",
]

Frames = str | None | tuple[str, ...]
"""A task frame (None: the end effector), or several frames for several targets at once."""

Tasks = str | tuple[str, ...]
"""A task space, or one per frame of a several-target problem."""

SECONDARY_OBJECTIVES = ("posture", "manipulability", "limits")
"""Secondary objectives the NLP can include (posture is always present, weight 0 disables it)."""

_MANIP_EPS = 1e-9


def angle_from_residual(norm: Any) -> Any:
    """Angle ``theta = 2 asin(|r_o| / 2)`` from the norm of an orientation residual block."""
    return 2.0 * np.arcsin(np.minimum(1.0, np.asarray(norm) / 2.0))


def target_parameters(target: np.ndarray) -> np.ndarray:
    """The 12 target parameters ``[vec(R*) (column-major); p*]`` of a 4x4 transform, or the
    ``12 k`` parameters of a ``(k, 4, 4)`` stack (several frame targets), frame after frame."""
    t = np.asarray(target, dtype=float)
    if t.ndim == 3:
        return np.concatenate([target_parameters(ti) for ti in t])
    return np.concatenate([t[:3, :3].reshape(-1, order="F"), t[:3, 3]])


def frame_tasks(frame: Frames, task: Tasks) -> tuple[tuple[str | None, str], ...]:
    """``((frame, task), ...)``: one pair for a single frame, one per frame for a tuple of frames
    (``task`` a tuple of the same length, or one task space for every frame)."""
    frames = frame if isinstance(frame, tuple) else (frame,)
    tasks = task if isinstance(task, tuple) else (task,) * len(frames)
    if len(tasks) != len(frames):
        raise InvalidArgumentError(
            "task", f"expected {len(frames)} task spaces, one per frame, got {len(tasks)}"
        )
    return tuple(zip(frames, tasks, strict=True))


def task_blocks(task: str, t: ca.SX, target: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Position and orientation residual blocks ``(r_p, r_o)`` of the pose ``t`` (4x4 ``SX``)
    against the 12 target parameters ``target`` for a task space (either may be empty)."""
    r_star = ca.reshape(target[:9], 3, 3)
    p_star = target[9:12]
    p, r = t[:3, 3], t[:3, :3]
    empty = ca.SX(0, 1)
    if task == "pose":
        return p - p_star, ca.vec(r - r_star) / np.sqrt(2.0)
    if task == "position":
        return p - p_star, empty
    if task == "orientation":
        return empty, ca.vec(r - r_star) / np.sqrt(2.0)
    if task == "pose2d":
        heading = ca.vertcat(r[0, 0] - r_star[0, 0], r[1, 0] - r_star[1, 0])
        return p[:2] - p_star[:2], heading
    return p[:2] - p_star[:2], empty


def frame_errors(task: str, t: ca.SX, target: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Position and orientation error of the pose ``t`` (4x4 ``SX``) against the 12 target
    parameters ``target`` for a task space (the definitions of `IKProblem.error_expressions`)."""
    r_star = ca.reshape(target[:9], 3, 3)
    dp = t[:3, 3] - target[9:12]
    zero = ca.SX.zeros(1, 1)
    planar = task in ("pose2d", "position2d")
    pos = zero if task == "orientation" else ca.norm_2(dp[:2] if planar else dp)
    if task in ("pose", "orientation"):
        ori = spatial.angle_between(r_star, t[:3, :3])
    elif task == "pose2d":
        dphi = ca.atan2(t[1, 0], t[0, 0]) - ca.atan2(r_star[1, 0], r_star[0, 0])
        ori = ca.fabs(spatial.wrap_angle(dphi))
    else:
        ori = zero
    return pos, ori


@dataclass(frozen=True)
class IKProblem:
    """An inspectable IK problem (see the module docstring for the formulation).

    Attributes:
        mechanism: the model.
        task: task space (a key of [`optik.mechanism.TASK_ROWS`][optik.mechanism.TASK_ROWS]), or one per
            frame when ``frame`` is a tuple.
        frame: task frame (None: end effector), or a tuple of frames (several targets at once).
        secondary: the secondary objectives included besides posture.
        q: decision variables (``SX``, ``n_q`` x 1).
        target: target parameters ``[vec(R*); p*]`` (``SX``, 12 x 1; ``12 k`` x 1 for ``k`` frames).
        weights: task weights ``[w_p, w_o]`` (``SX``, 2 x 1).
        q_ref: reference posture (``SX``, ``n_q`` x 1).
        secondary_weights: ``[w_post, w_manip, w_lim]`` (``SX``, 3 x 1).
        position_residual: ``r_p(q; target)`` (unweighted).
        orientation_residual: ``r_o(q; target)`` (unweighted).
        closure: loop-closure residual ``c(q)`` (equality constraints).
        secondary_objective: the manipulability and distance-to-limits terms of ``f``.
        objective: the NLP objective ``f``.
        lower: lower bounds of ``q``.
        upper: upper bounds of ``q``.
    """

    mechanism: Mechanism
    task: Tasks
    frame: Frames
    secondary: tuple[str, ...]
    q: ca.SX
    target: ca.SX
    weights: ca.SX
    q_ref: ca.SX
    secondary_weights: ca.SX
    position_residual: ca.SX
    orientation_residual: ca.SX
    closure: ca.SX
    secondary_objective: ca.SX
    objective: ca.SX
    lower: np.ndarray
    upper: np.ndarray

    @property
    def parameters(self) -> ca.SX:
        """All NLP parameters stacked: ``[target; weights; q_ref; secondary_weights]``."""
        return ca.vertcat(self.target, self.weights, self.q_ref, self.secondary_weights)

    @property
    def n_position_rows(self) -> int:
        """Rows of the position residual block."""
        return int(self.position_residual.shape[0])

    @property
    def n_orientation_rows(self) -> int:
        """Rows of the orientation residual block."""
        return int(self.orientation_residual.shape[0])

    def nlp(self) -> dict[str, ca.SX]:
        """The NLP as CasADi's ``nlpsol`` expects it: ``{"x", "p", "f", "g"}``."""
        return {"x": self.q, "p": self.parameters, "f": self.objective, "g": self.closure}

    def parameter_values(
        self,
        target: np.ndarray,
        weights: Any = (1.0, 1.0),
        q_ref: Any = None,
        posture: float = 1e-9,
        manipulability: float = 0.0,
        limits: float = 0.0,
    ) -> np.ndarray:
        """Numerical parameter vector for `parameters`.

        Args:
            target: 4x4 target transform.
            weights: task weights ``(w_p, w_o)``.
            q_ref: reference posture (default: mid-limit).
            posture: weight of ``1/2 |q - q_ref|^2``.
            manipulability: weight of ``-log(det(J J^T))`` (needs ``"manipulability"`` in
                `secondary`).
            limits: weight of the distance-to-limits term (needs ``"limits"`` in `secondary`).

        Raises:
            InvalidArgumentError: negative weights, or a weight for an objective not built in.
        """
        w = as_vector(weights, "weights", 2)
        sec = as_vector([posture, manipulability, limits], "secondary weights", 3)
        if np.any(w < 0) or np.any(sec < 0):
            raise InvalidArgumentError("weights", f"weights must be >= 0, got {w} and {sec}")
        for name, value in (("manipulability", sec[1]), ("limits", sec[2])):
            if value > 0 and name not in self.secondary:
                raise InvalidArgumentError(
                    name, f"the problem was built without the {name!r} objective (secondary={self.secondary})"
                )
        m = self.mechanism
        ref = m.mid_q() if q_ref is None else m.check_q(q_ref, "q_ref")
        return np.concatenate([target_parameters(target), w, ref, sec])

    def lagrangian_hessian(self, lam_f: ca.SX, lam_g: ca.SX, damping: float = 0.0) -> ca.SX:
        """Gauss-Newton Hessian of the Lagrangian ``lam_f f + lam_g^T c``.

        ``lam_f (J_w^T J_w + (w_post + damping) I + hess(secondary terms)) + sum_i lam_g,i
        hess(c_i)``, with
        ``J_w`` the Jacobian of the weighted task residual ``[w_p r_p; w_o r_o]``: the task part
        drops the residual-curvature terms ``sum_k r_k hess(r_k)``, which vanish at a reached
        target, so it is positive semidefinite and the solver needs no inertia correction there
        (the step is then Gauss-Newton's, as in ``"lm"``). ``damping`` adds a Levenberg term: it
        changes the steps (shorter along near-singular directions), not the solutions.
        """
        q = self.q
        jw = ca.jacobian(self.weighted_residual(), q)
        h = ca.mtimes(jw.T, jw) + (self.secondary_weights[0] + damping) * ca.SX.eye(q.shape[0])
        if self.secondary:
            h += ca.hessian(self.secondary_objective, q)[0]
        h = lam_f * h
        if self.closure.shape[0]:
            h += ca.hessian(ca.dot(lam_g, self.closure), q)[0]
        return h

    def error_expressions(self) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Position error, orientation error and max-norm of the closure residual, symbolically.

        The definitions of the success check
        ([`optik.solvers.base.task_errors`][optik.solvers.base.task_errors]), computed from the frame pose
        directly (not from the residual): the Euclidean distance of the origins (x-y only for planar tasks),
        the geodesic angle ``atan2(|vee(M - M^T)| / 2, (tr M - 1) / 2)`` of ``M = R*^T R`` for ``pose`` and
        ``orientation``, ``|wrap(phi - phi*)|`` for ``pose2d``, and 0 where a task has no such part.
        With several frames the position and orientation errors are the largest over the frames.
        """
        per_frame = self.frame_error_expressions()
        pos = per_frame[0][0] if len(per_frame) == 1 else ca.mmax(ca.vertcat(*(p for p, _ in per_frame)))
        ori = per_frame[0][1] if len(per_frame) == 1 else ca.mmax(ca.vertcat(*(o for _, o in per_frame)))
        c = self.closure
        clo = ca.mmax(ca.fabs(c)) if c.shape[0] else ca.SX.zeros(1, 1)
        return pos, ori, clo

    def frame_error_expressions(self) -> list[tuple[ca.SX, ca.SX]]:
        """Position and orientation error of each frame (see `error_expressions`), in frame order."""
        pairs = frame_tasks(self.frame, self.task)
        return [
            frame_errors(task, self.mechanism.frame_expr(frame), self.target[12 * i : 12 * i + 12])
            for i, (frame, task) in enumerate(pairs)
        ]

    def residual_function(self, closure_weight: float | None = None) -> ca.Function:
        """``(q, target, weights) -> (e, de/dq)`` with ``e = [w_p r_p; w_o r_o; w_c c]``.

        ``closure_weight`` ``w_c`` weighs the loop-closure rows (None: no closure rows).
        """
        e = self.weighted_residual(closure_weight)
        return ca.Function(
            "ik_residual",
            [self.q, self.target, self.weights],
            [e, ca.jacobian(e, self.q)],
            ["q", "target", "weights"],
            ["e", "J"],
        )

    def weighted_residual(self, closure_weight: float | None = None) -> ca.SX:
        """``[w_p r_p; w_o r_o; w_c c]`` (closure rows only when ``closure_weight`` is given)."""
        rows = [self.weights[0] * self.position_residual, self.weights[1] * self.orientation_residual]
        if closure_weight is not None:
            rows.append(closure_weight * self.closure)
        return ca.vertcat(*rows)


_CACHE: PerMechanism[dict[tuple, IKProblem]] = PerMechanism()


def build_ik_problem(
    m: Mechanism,
    task: Tasks | None = None,
    frame: Frames = None,
    secondary: tuple[str, ...] = (),
) -> IKProblem:
    """The IK problem of a mechanism for a task space and frame (built once, then cached).

    Args:
        m: the mechanism.
        task: task space (default ``m.task``); with several frames, one per frame or one for all.
        frame: task frame (default: the end effector), or a tuple of frames: one problem for
            several targets at once.
        secondary: extra objectives from ``("manipulability", "limits")``; posture
            regularization is always part of the objective (its weight is a parameter).

    Raises:
        InvalidArgumentError: unknown task or secondary objective.
        UnknownFrameError: unknown frame.
    """
    pairs = frame_tasks(frame, task)
    tasks = tuple(m._task(t) for _, t in pairs)  # raises on an unknown task
    for f, _ in pairs:
        m._frame(f)
    tk = tasks if isinstance(frame, tuple) else tasks[0]
    extra = tuple(sorted(set(secondary) - {"posture"}))
    for s in extra:
        if s not in SECONDARY_OBJECTIVES:
            raise InvalidArgumentError(
                "secondary", f"unknown secondary objective {s!r}; use some of {SECONDARY_OBJECTIVES}"
            )
    key = (tk, frame, extra)
    per_mechanism = _CACHE.setdefault(m, {})
    if key not in per_mechanism:
        per_mechanism[key] = _build(m, tk, frame, extra)
    return per_mechanism[key]


def _build(m: Mechanism, task: Tasks, frame: Frames, secondary: tuple[str, ...]) -> IKProblem:
    q = m.q_sym
    pairs = frame_tasks(frame, task)
    target = ca.SX.sym("target", 12 * len(pairs))
    weights = ca.SX.sym("weights", 2)
    q_ref = ca.SX.sym("q_ref", m.n_q)
    sec = ca.SX.sym("secondary_weights", 3)
    blocks = [task_blocks(t, m.frame_expr(f), target[12 * i : 12 * i + 12]) for i, (f, t) in enumerate(pairs)]
    r_p, r_o = ca.vertcat(*(b[0] for b in blocks)), ca.vertcat(*(b[1] for b in blocks))
    f = 0.5 * (weights[0] ** 2 * ca.sumsqr(r_p) + weights[1] ** 2 * ca.sumsqr(r_o))
    f += 0.5 * sec[0] * ca.sumsqr(q - q_ref)
    f_sec = ca.SX(0)
    if "manipulability" in secondary:
        jt = ca.vertcat(*(m.jacobian_expr(f)[list(TASK_ROWS[t]), :] for f, t in pairs))
        f_sec -= sec[1] * ca.log(ca.det(ca.mtimes(jt, jt.T)) + _MANIP_EPS)
    if "limits" in secondary:
        span = np.maximum(m.upper - m.lower, 1e-12)
        f_sec += 0.5 * sec[2] * ca.sumsqr((q - m.mid_q()) / span)
    return IKProblem(
        mechanism=m,
        task=task,
        frame=frame,
        secondary=secondary,
        q=q,
        target=target,
        weights=weights,
        q_ref=q_ref,
        secondary_weights=sec,
        position_residual=r_p,
        orientation_residual=r_o,
        closure=m.closure_expr,
        secondary_objective=f_sec,
        objective=f + f_sec,
        lower=m.lower.copy(),
        upper=m.upper.copy(),
    )
