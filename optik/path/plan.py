"""`plan_path`: a Cartesian path of tool poses as a joint path, over every IK solution.

For an arm with a complete closed form (`optik.solve_ik_all` certified), every solution of
every pose becomes a node of a layered graph, and the path of least weighted joint motion
through it is found by dynamic programming (`optik.path.graph`): the exact optimum over all
solutions, so it never changes branch unless the poses force it. Joints that can turn past
``+-pi`` are compared modulo ``2 pi`` and their turns counted afterwards, or planned over every
turn when the limits bind (`optik.path.nodes`). With given times, the edges that break the
velocity limits are removed; without, the times are the shortest the velocity limits allow, or
those of a tool speed stretched where the limits need it (`optik.path.timing`).

The answer is checked from its configurations alone, independently of how it was found: the FK
of every sample against its pose, the joint limits, the velocity and acceleration limits on the
finite differences, the branch changes, collisions with a `World`.

A *branch change* is a step to a solution of the next pose other than the one nearest the
current configuration (`optik.path.graph.branch_changes`): on a densely sampled path the nearest
solution is the continuation of the branch, any other a jump.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optik.batch import fk_batch
from optik.checks import ORTHO_DIAG, ORTHO_OFF, as_float, as_int, as_name, as_transform, as_vector, real_array
from optik.collision import World, check_many
from optik.errors import InvalidArgumentError, ShapeError
from optik.mechanism import Mechanism
from optik.path.densify import midpoints, tool_deviation
from optik.path.edges import EDGE_STEP, colliding_segments
from optik.path.graph import Layered, branch_changes, least_motion
from optik.path.nodes import realize, turn_copies, wrapping
from optik.path.redundant import refine
from optik.path.result import JointPath
from optik.path.samples import AXES, axis_joint, chosen_angle, sample_poses, sample_solutions
from optik.path.timing import derivatives, segment_times, step_bounds
from optik.solvers import Tolerances
from optik.spatial import angle_between

MAX_CUT_ROUNDS = 100
"""Most rounds of removing the edges of the optimum that collide between samples."""
VELOCITY_SLACK = 1e-9
"""Relative rounding allowed on the velocity check (times equal to ``|dq| / v`` give ``v`` to
rounding)."""


def _poses(poses: Any) -> np.ndarray:
    """The poses ``(N, 4, 4)``, each a proper transform: checked at once to `as_transform`'s
    tolerances, and pose by pose (its error naming the first bad one) when that fails."""
    a = real_array(poses, "poses")
    if a.ndim != 3 or a.shape[1:] != (4, 4) or len(a) == 0:
        raise ShapeError("poses", f"expected N >= 1 transforms of shape (N, 4, 4), got {a.shape}")
    r = a[:, :3, :3]
    gram = np.einsum("nji,njk->nik", r, r) - np.eye(3)
    off = np.abs(gram - np.einsum("nii->ni", gram)[:, :, None] * np.eye(3))
    ok = (
        np.isfinite(a).all()
        and np.all(np.abs(a[:, 3, :3]) <= 1e-9)
        and np.all(np.abs(a[:, 3, 3] - 1.0) <= 1e-9 + 1e-5)
        and np.all(np.abs(np.einsum("nii->ni", gram)) <= ORTHO_DIAG)
        and np.all(off <= ORTHO_OFF)
        and np.all(np.linalg.det(r) >= 0.0)
    )
    if ok:
        return np.array(a)
    return np.stack([as_transform(t, f"poses[{k}]") for k, t in enumerate(a)])


def _times(times: Any, n: int) -> np.ndarray | None:
    if times is None:
        return None
    t = as_vector(times, "times", n)
    if np.any(np.diff(t) <= 0.0):
        raise InvalidArgumentError("times", "must be strictly increasing")
    return t - t[0]


def _positive(value: Any, name: str, n: int) -> np.ndarray:
    v = as_vector(value, name, n)
    if np.any(v <= 0.0):
        raise InvalidArgumentError(name, f"every entry must be > 0, got {v}")
    return v


def _velocity(m: Mechanism, velocity: Any) -> np.ndarray | None:
    if velocity is None:
        own = m.params.get("velocity_limits") if isinstance(m.params, dict) else None
        return None if own is None else np.asarray(own, dtype=float)
    return _positive(velocity, "velocity", m.n_q)


def _failed(m: Mechanism, nodes: np.ndarray, message: str, poses: np.ndarray) -> JointPath:
    empty = np.zeros((0, m.n_q))
    return JointPath(empty, np.zeros(0), empty, empty, np.zeros(0, dtype=int), float("inf"),
                     {}, False, message, 0, np.zeros(0), nodes, poses, np.zeros(0))  # fmt: skip


def _tolerance(value: Any, n: int) -> np.ndarray | None:
    if value is None:
        return None
    a = real_array(value, "position_tolerance")
    a = np.full(n, float(a)) if a.ndim == 0 else as_vector(a, "position_tolerance", n)
    if not np.all(np.isfinite(a)) or np.any(a < 0.0):
        raise InvalidArgumentError("position_tolerance", f"must be finite and >= 0, got {value!r}")
    return a


def _self_motion(m: Mechanism, value: Any) -> tuple[int, np.ndarray] | None:
    if value is None:
        return None
    if not isinstance(value, tuple | list) or len(value) != 2:
        raise InvalidArgumentError("self_motion", f"expected (joint name, values), got {value!r:.80}")
    name = as_name(value[0], "self_motion", m.coordinate_names)
    j = m.coordinate_names.index(name)
    vals = as_vector(value[1], "self_motion")
    if np.any(vals < m.lower[j]) or np.any(vals > m.upper[j]):
        raise InvalidArgumentError(
            "self_motion", f"values of {name!r} must lie within [{m.lower[j]:g}, {m.upper[j]:g}]"
        )
    return j, vals


def _free_of_collisions(
    m: Mechanism, solutions: Layered, world: World | None, margin: float
) -> tuple[np.ndarray | None, int]:
    """Which nodes are free of collisions with ``world`` and with the robot itself ``(M,)``
    (None without a world: all of them), and how many are not."""
    if world is None or not len(solutions.data):
        return None, 0
    free = ~check_many(m, solutions.data, world=world, margin=margin).in_collision
    return free, int(np.count_nonzero(~free))


def check_path(
    m: Mechanism,
    q: np.ndarray,
    t: np.ndarray,
    qdd: np.ndarray,
    targets: np.ndarray,
    frame: str | None,
    tol: Tolerances,
    velocity: np.ndarray | None,
    acceleration: np.ndarray | None,
    free_axis: str | None = None,
    position_tolerance: np.ndarray | None = None,
    fk: np.ndarray | None = None,
) -> dict[str, bool]:
    """The checks of a path recomputed from its samples alone: FK of every sample against its
    target pose (the position within ``position_tolerance`` more, only the direction of the free
    axis when there is one), joint limits, segment velocities ``|dq| / dt`` against ``velocity``
    and accelerations against ``acceleration`` (when given). ``fk``: the poses of ``q`` when
    already computed (`optik.path.densify.tool_deviation`)."""
    fk = fk_batch(m, q, frame) if fk is None else fk
    pos = np.linalg.norm(fk[:, :3, 3] - targets[:, :3, 3], axis=1)
    if position_tolerance is not None:
        pos = np.maximum(pos - position_tolerance, 0.0)
    if free_axis is None:
        ori = np.array([angle_between(a[:3, :3], b[:3, :3]) for a, b in zip(fk, targets, strict=True)])
    else:
        col = "xyz".index(free_axis)
        cos = np.einsum("ij,ij->i", fk[:, :3, col], targets[:, :3, col])
        ori = np.arccos(np.clip(cos, -1.0, 1.0))
    checks = {
        "fk": bool(np.all(pos <= tol.position) and np.all(ori <= tol.orientation)),
        "limits": bool(np.all(q >= m.lower) and np.all(q <= m.upper)),
    }
    if velocity is not None:
        seg = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None] if len(q) > 1 else np.zeros((0, m.n_q))
        checks["velocity"] = bool(np.all(seg <= velocity * (1.0 + VELOCITY_SLACK)))
    if acceleration is not None:
        checks["acceleration"] = bool(np.all(np.abs(qdd) <= acceleration))
    return checks


def plan_path(
    m: Mechanism,
    poses: Any,
    times: Any = None,
    *,
    free_axis: str | None = None,
    axis_step: float = np.pi / 18,
    position_tolerance: Any = None,
    max_deviation: float | None = None,
    max_rounds: int = 8,
    weights: Any = None,
    velocity: Any = None,
    acceleration: Any = None,
    speed: float | None = None,
    frame: str | None = None,
    tol: float | Tolerances | None = None,
    world: World | None = None,
    margin: float = 0.0,
    edge_step: float = EDGE_STEP,
    max_flips: int | None = 0,
    self_motion: tuple[str, Any] | None = None,
    smooth: bool = False,
) -> JointPath:
    """A joint path through ``poses`` of least weighted joint motion, over every IK solution.

    The graph has one layer per pose and one node per solution of each of its sampled poses; the
    answer minimizes the weighted joint-space length

    ```
    L = sum_k |W (q_{k+1} - q_k)|_2 ,   W = diag(weights)
    ```

    exactly over the graph (dynamic programming, `optik.path.graph`).

    Args:
        m: an arm with a complete closed form (`optik.solve_ik_all` certified).
        poses: tool poses ``(N, 4, 4)``, in order.
        times: sample times ``(N,)`` (s, strictly increasing): edges breaking the velocity limits
            at these times are removed. None: the shortest times the velocity limits allow, or
            those of ``speed`` stretched where the limits need it (`optik.path.timing`).
        free_axis: ``"x"``, ``"y"`` or ``"z"``: the tool is symmetric about this axis of its
            frame, each pose may turn about it (`optik.path.samples`); None: the full pose.
        axis_step: sampling step of the turn about the free axis (rad; a full turn is sampled).
        position_tolerance: how far (m) the tool point may lie from each pose's position, one
            value or one per pose: the position and the six points at that distance along the
            base axes are sampled.
        max_deviation: largest distance (m) of the tool from the straight segment between two
            samples while the joints move linearly; samples are inserted halfway where it is
            exceeded and the path planned again (`optik.path.densify`), at most ``max_rounds``
            times. None: measured, not enforced.
        max_rounds: most densification rounds.
        weights: per-joint weights of the joint motion ``(n,)`` (default ones).
        velocity: joint velocity limits ``(n,)`` (default: the model's ``<limit velocity>`` when
            it has them, else none).
        acceleration: joint acceleration limits ``(n,)``, checked on the answer (not planned).
        speed: tool speed (m/s) giving the nominal times when ``times`` is None.
        frame: the tool frame (default: the end effector).
        tol: FK tolerances of the check (default `optik.Tolerances()`).
        world: obstacles; configurations in collision with them or with the robot itself are
            no nodes (`optik.collision.check_many`).
        margin: clearance (m) of the collision check.
        edge_step: with a world, the largest joint step (rad) between the configurations checked
            along each segment of the path (the joints move linearly between samples): a graph
            edge whose segment collides is removed and the path planned again
            (`optik.path.edges`).
        max_flips: most branch changes the ``"branch"`` check accepts (None: any, for poses far
            apart, where the nearest solution says nothing about continuity).
        self_motion: ``(joint, values)`` for a redundant (7-DOF) arm: its self-motion sampled
            by locking the coordinate ``joint`` at each of ``values`` (within its limits), every
            solution of the 6R chain left by its derived closed form (`optik.path.redundant`).
        smooth: refine the graph's answer continuously (`optik.path.redundant.refine`: one NLP
            over the whole path, warm-started from it), kept when shorter and every check
            passes; with full poses only (no ``free_axis``, no ``position_tolerance``).

    Returns:
        A [`JointPath`][optik.path.JointPath]; ``success=False`` with a message when a pose has
        no solution (or none free of collisions), when no path meets the velocity limits at the
        given times, or when a check of the answer fails.

    Raises:
        OptikError: malformed input (named argument); `SolverUnavailableError` when ``m`` has no
            certified closed form.
    """
    targets = _poses(poses)
    n = len(targets)
    t_given = _times(times, n)
    if free_axis is not None:
        as_name(free_axis, "free_axis", AXES)
    step = as_float(axis_step, "axis_step", 0.0, strict=True)
    radius = _tolerance(position_tolerance, n)
    limit = None if max_deviation is None else as_float(max_deviation, "max_deviation", 0.0, strict=True)
    rounds = as_int(max_rounds, "max_rounds")
    w = np.ones(m.n_q) if weights is None else as_vector(weights, "weights", m.n_q)
    if np.any(w < 0.0):
        raise InvalidArgumentError("weights", f"must be >= 0, got {w}")
    v = _velocity(m, velocity)
    acc = None if acceleration is None else _positive(acceleration, "acceleration", m.n_q)
    spd = None if speed is None else as_float(speed, "speed", 0.0, strict=True)
    tols = Tolerances.from_arg(tol)
    edge = as_float(edge_step, "edge_step", 0.0, strict=True)
    flips_ok = None if max_flips is None else as_int(max_flips, "max_flips")
    motion = _self_motion(m, self_motion)
    smooth = bool(smooth)
    if smooth and (free_axis is not None or radius is not None):
        raise InvalidArgumentError("smooth", "needs full poses: no free_axis, no position_tolerance")
    shortcut = None if free_axis is None or motion is not None else axis_joint(m, free_axis, frame)
    plan = _Plan(m, frame, free_axis, step, shortcut, w, v, world, margin, motion, edge)
    inserted = 0
    for round_ in range(rounds + 1):
        found = plan.solve(targets, t_given, radius)
        if isinstance(found, str):
            return _failed(m, plan.sizes, found, targets)
        q, index, groups, layers, periods, cost, note = found
        tool, dev = tool_deviation(m, q, frame)
        far = np.flatnonzero(dev > limit) if limit is not None else np.zeros(0, dtype=int)
        if not far.size or round_ == rounds:
            break
        targets, (t_given, radius) = midpoints(targets, [t_given, radius], far)
        inserted += far.size
    n = len(targets)
    branch = branch_changes(layers, index, w, groups, periods)

    def finish(
        qq: np.ndarray, fk: np.ndarray, dq: np.ndarray
    ) -> tuple[np.ndarray, int, np.ndarray, np.ndarray, dict[str, bool]]:
        stretched = 0
        if t_given is None:
            travel = np.linalg.norm(np.diff(targets[:, :3, 3], axis=0), axis=1)
            tt, stretched = segment_times(qq, travel, v, spd)
        else:
            tt = t_given
        qd, qdd = derivatives(qq, tt)
        checks = check_path(m, qq, tt, qdd, targets, frame, tols, v, acc, free_axis, radius, fk)
        checks["branch"] = bool(flips_ok is None or branch[-1] <= flips_ok)
        if world is not None:
            checks["collision"] = not np.any(
                check_many(m, qq, world=world, margin=margin).in_collision
            ) and not len(colliding_segments(m, qq, world, margin, edge))
        if limit is not None:
            checks["deviation"] = bool(np.all(dq <= limit))
        return tt, stretched, qd, qdd, checks

    t, stretched, qd, qdd, checks = finish(q, tool, dev)
    refined = ""
    if smooth:
        q2 = refine(m, q, targets, frame, min(tols.position, tols.orientation))
        refined = "; the refinement did not converge"
        if q2 is not None:
            cost2 = float(np.linalg.norm(np.diff(q2, axis=0) * w, axis=1).sum())
            tool2, dev2 = tool_deviation(m, q2, frame)
            got = finish(q2, tool2, dev2)
            refined = "; the refinement was not kept (not shorter, or a check failed)"
            if cost2 < cost and all(got[4].values()):
                refined = f"; refined from {cost:.6g}"
                q, cost, dev = q2, cost2, dev2
                t, stretched, qd, qdd, checks = got
    sizes = plan.sizes
    parts = [
        f"{n} poses, {sizes.mean():.3g} nodes per pose on average{note}",
        f"joint-space length {cost:.6g}{refined}",
        f"{int(branch[-1])} branch changes",
    ]
    if inserted:
        parts.append(f"{inserted} samples inserted to keep the tool within {limit:g} m of the segments")
    if plan.dropped:
        parts.append(f"{plan.dropped} colliding configurations dropped")
    if plan.cut:
        parts.append(f"{plan.cut} edges colliding between their samples removed")
    if t_given is None:
        if v is None:
            parts.append(
                "no velocity limits: " + ("unit time steps" if spd is None else "times from the tool speed")
            )
        elif spd is None:
            parts.append("times: the shortest the velocity limits allow")
        else:
            parts.append(
                f"times from the tool speed, {stretched} segments stretched to meet the velocity limits"
            )
    failed = [name for name, ok in checks.items() if not ok]
    if failed:
        parts.append("failed checks: " + ", ".join(failed))
    angle = chosen_angle(plan.samples, groups, index, 1 if motion is None else len(motion[1]))
    return JointPath(q, t, qd, qdd, branch, cost, checks, not failed, "; ".join(parts), stretched, angle,
                     sizes, targets, dev)  # fmt: skip


class _Plan:
    """One planning round's graph and its optimum (the fixed settings of a `plan_path` call)."""

    def __init__(
        self,
        m: Mechanism,
        frame: str | None,
        free_axis: str | None,
        step: float,
        shortcut: tuple[int, float] | None,
        w: np.ndarray,
        v: np.ndarray | None,
        world: World | None,
        margin: float,
        motion: tuple[int, np.ndarray] | None,
        edge_step: float,
    ) -> None:
        self.m, self.frame, self.free_axis, self.step, self.shortcut = m, frame, free_axis, step, shortcut
        self.w, self.v, self.world, self.margin, self.motion = w, v, world, margin, motion
        self.sizes = np.zeros(0, dtype=int)
        self.dropped = self.cut = 0
        self.edge_step = edge_step
        self.samples = sample_poses(np.eye(4)[None], None, step, None)

    def solve(self, targets: np.ndarray, times: np.ndarray | None, radius: np.ndarray | None) -> Any:
        """The optimum over the graph of ``targets`` as ``(q, index, groups, layers, periods,
        cost, note)``, or the message of a failure. With a world, the segments of the optimum
        are checked between its samples (`optik.path.edges`); the edges that collide are
        removed from the graph and the optimum found again, until none collides."""
        m = self.m
        self.samples = sample_poses(targets, self.free_axis, self.step, radius)
        solutions, groups = sample_solutions(m, self.samples, self.frame, self.shortcut, self.motion)
        free, self.dropped = _free_of_collisions(m, solutions, self.world, self.margin)
        layers = solutions if free is None else solutions.keep(free)
        groups = groups if free is None else groups.keep(free)
        self.sizes = layers.sizes
        empty = np.flatnonzero(self.sizes == 0)
        if empty.size:
            why = (
                "every solution collides"
                if len(solutions[empty[0]])
                else "no solution within the joint limits"
            )
            return f"pose {empty[0]} has {why} ({empty.size} such poses)"
        bounds = None if times is None or self.v is None else step_bounds(times, self.v)
        removed: dict[bool, list[tuple[int, int, int]]] = {False: [], True: []}  # per graph: turns or not
        every_turn: list[Any] = []  # the graph of every turn, made when first needed
        self.cut = 0
        for _ in range(MAX_CUT_ROUNDS):
            got = self._optimum(layers, groups, bounds, times, removed, every_turn)
            if isinstance(got, str) or self.world is None:
                return got
            q, index, turns = got[0], got[1], bool(got[-1])
            hit = colliding_segments(m, q, self.world, self.margin, self.edge_step)
            if not hit.size:
                return got
            removed[turns] += [(int(k) + 1, int(index[k]), int(index[k + 1])) for k in hit]
            self.cut += hit.size
        return (
            f"no path free of collisions between its samples found: {self.cut} colliding edges removed "
            f"in {MAX_CUT_ROUNDS} rounds"
        )

    def _optimum(
        self,
        layers: Layered,
        groups: Layered,
        bounds: np.ndarray | None,
        times: np.ndarray | None,
        removed: dict[bool, list[tuple[int, int, int]]],
        every_turn: list[Any],
    ) -> Any:
        """The optimum over ``layers`` without the ``removed`` edges (module docstring of
        `optik.path.nodes`: the relaxed graph first, the graph of every turn when its turns do
        not fit the limits), or the message of a failure."""
        m = self.m
        periods = wrapping(m)
        best = least_motion(layers, self.w, bounds, periods, _edges(removed[False]))
        if best.blocked >= 0:
            k = best.blocked
            if removed[False] or times is None:
                return f"no joint path within the velocity limits and free of collisions reaches pose {k}"
            why = f"no solution of pose {k} is reachable from pose {k - 1} in {times[k] - times[k - 1]:g} s"
            return f"no joint path within the velocity limits at the given times: {why}"
        rows = layers.rows(best.index)
        q = realize(rows, periods, m.lower, m.upper)
        note = ""
        if q is None:  # the relaxed optimum turns a joint past its limits: plan over every turn
            if not every_turn:
                angles = np.asarray(m.revolute_mask, dtype=bool)
                copies = [turn_copies(layer, m.lower, m.upper, angles) for layer in layers]
                every_turn += [
                    Layered.of([c[0] for c in copies]),
                    Layered.of([g[c[1]] for g, c in zip(groups, copies, strict=True)]),
                ]
            layers, groups = every_turn
            periods = np.zeros(m.n_q)
            best = least_motion(layers, self.w, bounds, periods, _edges(removed[True]))
            if best.blocked >= 0:
                return (
                    f"no joint path within the joint limits and the velocity limits: pose {best.blocked} "
                    "is not reachable on any turn of the joints"
                )
            q = layers.rows(best.index)
            per_pose = layers.sizes.mean()
            note = f"; turns reach the joint limits: planned over every turn ({per_pose:.3g} nodes per pose)"
        return q, best.index, groups, layers, periods, best.cost, note


def _edges(removed: list[tuple[int, int, int]]) -> np.ndarray | None:
    return np.array(removed, dtype=np.int64).reshape(-1, 3) if removed else None
