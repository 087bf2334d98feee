"""The rules every solver of a benchmark is held to, optik's methods and the peers alike, in one place.

Every benchmark script and `optik bench` take these from here, so that no solver gets a rule of its own:

* **Tolerance.** Success is position error ``<= tol.position`` (Euclidean, m) and geodesic
  orientation error ``<= tol.orientation`` (rad). optik's methods stop once their errors are
  below half the tolerances (`optik.solvers.lm`), and every peer is asked for the same half:

    * TRAC-IK bounds each of the six components of its twist error by ``eps``, so its Euclidean
      position (or rotation) error can reach ``sqrt(3) eps``. It gets ``eps = min(tol.position,
      tol.orientation) / 2`` ([`twist_epsilon`][optik.harness.peers.rules.twist_epsilon]):
      ``sqrt(3) / 2 = 0.87 < 1``, so every success TRAC-IK claims meets the Euclidean tolerance, with
      13 % room for the clipping below (a float32 limit overshoot of 1e-7 rad moves the tip by about
      1e-7 m). ``eps = tol / sqrt(3)`` would imply the bound with no room left; ``tol / (2 sqrt(3))``
      would ask more of TRAC-IK than its success is judged by.
    * The Robotics Toolbox stops when ``E = |e|^2 / 2 <= tol_E`` for the 6-vector error ``e``
      (position, rotation vector); ``tol_E = (tol / 2)^2 / 2``
      ([`residual_bound`][optik.harness.peers.rules.residual_bound]) gives ``|e| <= tol / 2``, which
      bounds both parts by half the tolerance, as optik's stop does.

* **Clipping, for everybody.** optik's `solve_ik` returns its answer wrapped and clipped into the
  limits; every peer's answer goes through the same wrap and clip
  ([`settle`][optik.harness.peers.rules.settle]) before it is judged. The *overshoot* of the raw
  answer (how far it was outside the limits, 0 for optik whose public answer is already clipped) is
  reported for every solver.

* **Warm-up, for everybody.** One untimed call per solver before the timed ones
  ([`warm_up`][optik.harness.peers.rules.warm_up]): optik builds and loads its compiled code, the peers
  load their URDF and allocate their solvers.

* **One independent check.** Every answer, whoever produced it, is judged by one
  [`Referee`][optik.harness.peers.rules.Referee]: the FK of the settled answer computed by Pinocchio
  from the same URDF where Pinocchio is installed (else optik's own FK, and the referee says so), the
  tolerances above, and the limits satisfied exactly (no margin).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optik import spatial
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.solvers import Tolerances

__all__ = [
    "HALF",
    "Referee",
    "Verdict",
    "overshoot",
    "residual_bound",
    "settle",
    "twist_epsilon",
    "warm_up",
]

HALF = 0.5
"""Fraction of the tolerances every solver is asked to reach (optik's own stopping margin)."""


def twist_epsilon(tol: Tolerances) -> float:
    """TRAC-IK's per-component twist bound: ``eps = HALF * min(tol.position, tol.orientation)``.

    With every component of the position (rotation) error within ``eps``, its Euclidean norm is at
    most ``sqrt(3) eps = 0.87 min(tol)``, inside the tolerance.
    """
    return HALF * min(tol.position, tol.orientation)


def residual_bound(tol: Tolerances) -> float:
    """The Robotics Toolbox's residual bound ``tol_E = (HALF min(tol))^2 / 2``.

    Its solvers stop when ``E = e^T e / 2 <= tol_E`` for the 6-vector ``e = (position error,
    rotation vector)``; then

    ```
    |e_position|, |e_rotation| <= |e| = sqrt(2 E) <= HALF min(tol.position, tol.orientation)
    ```
    """
    e = HALF * min(tol.position, tol.orientation)
    return 0.5 * e * e


def overshoot(m: Mechanism, q: np.ndarray) -> float:
    """How far ``q`` lies outside the limits: ``max(0, max(lower - q), max(q - upper))``; ``inf`` for
    a non-finite ``q``."""
    q = np.asarray(q, dtype=float)
    if q.shape != m.lower.shape or not np.all(np.isfinite(q)):
        return math.inf
    return float(max(0.0, np.max(m.lower - q), np.max(q - m.upper)))


def settle(m: Mechanism, q: np.ndarray) -> np.ndarray:
    """``q`` wrapped and clipped into the limits, ``clip(m.wrap(q))``: the treatment optik's
    `solve_ik` gives its own answers (`optik.solvers.base.make_result`). A value a rounding past a
    limit stays on that side ([`Mechanism.wrap`][optik.Mechanism.wrap] takes the shift nearest the
    limits) and is clipped onto it; a non-finite ``q`` is returned as it is (it fails)."""
    q = np.asarray(q, dtype=float)
    if q.shape != m.lower.shape or not np.all(np.isfinite(q)):
        return q
    return np.clip(m.wrap(q), m.lower, m.upper)


def warm_up(calls: Iterable[Callable[[], object]]) -> None:
    """Call each solver once, untimed, before any timed call (the same for every solver)."""
    for call in calls:
        call()


@dataclass(frozen=True)
class Verdict:
    """The referee's judgement of one answer.

    Attributes:
        success: pose within the tolerances and the settled answer within the limits exactly.
        position, orientation: errors of the settled answer (m, rad) by the referee's FK.
        overshoot: limit overshoot of the raw answer (before [`settle`][optik.harness.peers.rules.settle]).
    """

    success: bool
    position: float
    orientation: float
    overshoot: float


Pose = Callable[[np.ndarray], np.ndarray]


def _pinocchio_fk(m: Mechanism, urdf: Path, base: str, tip: str) -> Pose:
    """The tip pose in the base link by Pinocchio from the same URDF, as a function of optik's
    coordinates: the joints on the path from the base link to the tip link, in order (continuous
    joints set through ``cos, sin``)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    base_id, tip_id = (model.getFrameId(link, pin.FrameType.BODY) for link in (base, tip))
    if max(base_id, tip_id) >= len(model.frames):
        raise InvalidArgumentError("urdf", f"{urdf} has no link {base!r} or {tip!r}")
    stop = model.frames[base_id].parentJoint
    path, j = [], model.frames[tip_id].parentJoint
    while j not in (0, stop):
        if model.joints[j].nq > 0:
            path.append(j)
        j = model.parents[j]
    slots = [(model.joints[j].idx_q, model.joints[j].nq) for j in reversed(path)]
    if len(slots) != m.n_q:
        raise InvalidArgumentError("urdf", f"{base} -> {tip} has {len(slots)} joints, {m.name!r} has {m.n_q}")
    q_pin = pin.neutral(model)

    def pose(q: np.ndarray) -> np.ndarray:
        for (i, nq), v in zip(slots, q, strict=True):
            if nq == 1:
                q_pin[i] = v
            else:  # continuous joint: (cos, sin)
                q_pin[i], q_pin[i + 1] = np.cos(v), np.sin(v)
        pin.framesForwardKinematics(model, data, q_pin)
        return (data.oMf[base_id].inverse() * data.oMf[tip_id]).homogeneous

    return pose


class Referee:
    """The one check every answer of a benchmark goes through.

    Args:
        m: the mechanism (its limits are the URDF's).
        urdf, base, tip: the URDF chain; with Pinocchio installed its FK is the referee's.

    Raises:
        InvalidArgumentError: ``urdf``: the chain has other links or joints than the mechanism, or
            Pinocchio's FK of it differs from the mechanism's (by more than 1e-9 at seeded samples).

    Attributes:
        source: ``"pinocchio"`` or ``"optik"`` (whose FK judges).
    """

    def __init__(self, m: Mechanism, urdf: Path | str | None = None, base: str = "", tip: str = "") -> None:
        self.mechanism = m
        self._fk: Pose = m.fk
        self.source = "optik"
        if urdf is not None:
            try:
                self._fk = _pinocchio_fk(m, Path(urdf), base, tip)
                self.source = "pinocchio"
            except ImportError:
                return
            gap = max(float(np.max(np.abs(self.fk(q) - m.fk(q)))) for q in m.random_q(3, seed=0))
            if gap > 1e-9:
                raise InvalidArgumentError(
                    "urdf", f"Pinocchio's FK of {base} -> {tip} differs from {m.name!r} by {gap:.1e}"
                )

    def fk(self, q: np.ndarray) -> np.ndarray:
        """4x4 tip pose of ``q`` by the referee's FK."""
        return np.asarray(self._fk(np.asarray(q, dtype=float)))

    def judge(self, q: np.ndarray | None, target: np.ndarray, tol: Tolerances) -> Verdict:
        """Settle the raw answer ``q`` (``None``: nothing returned, a failure), then check its pose
        against ``target`` and its limits exactly."""
        m = self.mechanism
        if q is None:
            return Verdict(False, math.inf, math.inf, 0.0)
        raw = np.asarray(q, dtype=float)
        over = overshoot(m, raw)
        qq = settle(m, raw)
        if not math.isfinite(over):
            return Verdict(False, math.inf, math.inf, over)
        pose = self.fk(qq)
        pos = float(np.linalg.norm(pose[:3, 3] - target[:3, 3]))
        ori = float(spatial.angle_between(pose[:3, :3], target[:3, :3]))
        inside = bool(np.all(qq >= m.lower) and np.all(qq <= m.upper))
        return Verdict(inside and pos <= tol.position and ori <= tol.orientation, pos, ori, over)
