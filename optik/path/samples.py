"""Tool-pose freedom: the poses a path sample may take, and their IK solutions.

A torch or a spindle is symmetric about its axis: with ``free_axis="z"`` a sample's pose is any
``T R_z(phi)``, sampled at ``phi = psi_k + s * axis_step`` (``s = 0 .. S - 1``, a full turn).
The offset ``psi_k`` carries the samples along the path without twist (`transported`): the
tool's ``x`` axis of sample ``s`` at pose ``k + 1`` is that of pose ``k`` projected onto the
plane normal to the new tool axis, so a sample index held along the path is a tool that does
not turn about its axis, whatever the poses' own angles about it. A position
tolerance ``r_k`` lets the tool point move within ``r_k`` of its position: the samples are the
position itself and the six points ``+-r_k`` along the base axes. Each combination is one
*group* of the sample's nodes (its solutions); `optik.path.graph.branch_changes` compares a
step only with the nodes of its own group.

When the free axis is the axis of the arm's last joint through the tool point (a UR's ``tool0``
``z``, a PUMA's flange), the solutions of ``T R(phi)`` are those of ``T`` with that joint
turned by ``+-phi`` (`axis_joint` finds it and checks it by FK at random configurations): one IK
per pose instead of ``S``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.path.graph import Layered
from optik.path.nodes import closed_form_solutions, into_limits
from optik.path.redundant import self_motion_solutions
from optik.spatial import rot_x, rot_y, rot_z

AXES = {"x": rot_x, "y": rot_y, "z": rot_z}
"""The tool axes a path may leave free."""
OFFSETS = np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])
"""Unit offsets of the position-tolerance samples (the centre first)."""
SHORTCUT_TOL = 1e-9
"""FK agreement (m, rad) required of `axis_joint` at each test configuration."""


@dataclass(frozen=True)
class Samples:
    """The sampled poses of a path: per pose and group its angle about the free axis
    ``angle (N, S)``, per group its position offset direction ``offset (S, 3)`` (times the
    pose's tolerance ``radius (N,)``), from the ``targets (N, 4, 4)``; the poses themselves
    ``(N, S, 4, 4)`` are built on demand (`poses`, `columns`)."""

    targets: np.ndarray
    free_axis: str | None
    angle: np.ndarray
    offset: np.ndarray
    radius: np.ndarray

    def columns(self, count: int) -> np.ndarray:
        """The sampled poses of the first ``count`` groups of every pose ``(N, count, 4, 4)``."""
        n = len(self.targets)
        total = self.angle[:, :count]
        poses = np.repeat(self.targets[:, None], count, axis=1)  # (N, count, 4, 4)
        if self.free_axis is not None:
            rot = np.asarray(AXES[self.free_axis](total.reshape(-1)), dtype=float).reshape(n, count, 3, 3)
            poses[..., :3, :3] = np.einsum("nij,ncjk->ncik", self.targets[:, :3, :3], rot)
        poses[..., :3, 3] += self.radius[:, None, None] * self.offset[None, :count]
        return poses

    @cached_property
    def poses(self) -> np.ndarray:
        """Every sampled pose ``(N, S, 4, 4)``."""
        return self.columns(self.angle.shape[1])


def transported(targets: np.ndarray, free_axis: str) -> np.ndarray:
    """Per pose, the angle ``psi_k`` about its free axis that carries the first pose's
    perpendicular axis along the path without twist (module docstring).

    A sequential recursion (each step projects the carried axis), run on plain floats: numpy's
    per-call overhead on 3-vectors would dominate it."""
    a = "xyz".index(free_axis)
    b, c = (a + 1) % 3, (a + 2) % 3
    rot = targets[:, :3, :3]
    if np.all(rot[:, :, a] == rot[0, :, a]):  # one tool axis throughout: the first x is carried as is
        x = rot[0, :, b]
        out = np.arctan2(rot[:, :, c] @ x, rot[:, :, b] @ x)
        out[0] = 0.0
        return out
    axes, bs, cs = rot[:, :, a].tolist(), rot[:, :, b].tolist(), rot[:, :, c].tolist()
    out = [0.0] * len(targets)
    x0, x1, x2 = bs[0]
    for k in range(1, len(targets)):
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = axes[k], bs[k], cs[k]
        dot = x0 * a0 + x1 * a1 + x2 * a2
        y0, y1, y2 = x0 - dot * a0, x1 - dot * a1, x2 - dot * a2
        norm = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
        if norm < 1e-9:
            y0, y1, y2 = b0, b1, b2
        else:
            y0, y1, y2 = y0 / norm, y1 / norm, y2 / norm
        out[k] = math.atan2(y0 * c0 + y1 * c1 + y2 * c2, y0 * b0 + y1 * b1 + y2 * b2)
        x0, x1, x2 = y0, y1, y2
    return np.array(out)


def sample_poses(
    targets: np.ndarray, free_axis: str | None, axis_step: float, tolerance: np.ndarray | None
) -> Samples:
    """Every sampled pose of every target (module docstring)."""
    if free_axis is None:
        angles, psi = np.zeros(1), np.zeros(len(targets))
    else:
        count = max(1, round(2.0 * np.pi / axis_step))
        angles, psi = np.arange(count) * (2.0 * np.pi / count), transported(targets, free_axis)
    units = OFFSETS if tolerance is not None else OFFSETS[:1]
    total = psi[:, None] + angles[None]  # (N, A)
    radius = np.zeros(len(targets)) if tolerance is None else tolerance
    return Samples(
        targets, free_axis, np.repeat(total, len(units), axis=1), np.tile(units, (len(angles), 1)), radius
    )


_AXIS_JOINT: PerMechanism[dict[tuple[str, str | None, int], tuple[int, float] | None]] = PerMechanism()


def axis_joint(m: Mechanism, free_axis: str, frame: str | None, seed: int = 0) -> tuple[int, float] | None:
    """``(j, sign)`` when turning joint ``j`` by ``sign * phi`` turns the tool by ``R(phi)``
    about its free axis at every configuration (checked by FK at three random configurations and
    two angles), else None; found once per mechanism, axis and frame (cached on ``m``)."""
    per = _AXIS_JOINT.setdefault(m, {})
    key = (free_axis, frame, seed)
    if key not in per:
        per[key] = _find_axis_joint(m, free_axis, frame, seed)
    return per[key]


def _find_axis_joint(m: Mechanism, free_axis: str, frame: str | None, seed: int) -> tuple[int, float] | None:
    revolute = np.flatnonzero(np.asarray(m.revolute_mask, dtype=bool))
    if not revolute.size:
        return None
    j = int(revolute[-1])
    rng = np.random.default_rng(seed)
    lo, hi = np.maximum(m.lower, -np.pi), np.minimum(m.upper, np.pi)
    for sign in (1.0, -1.0):
        ok = True
        for q in rng.uniform(lo, hi, (3, m.n_q)):
            base = m.fk(q, frame)
            for phi in (0.7, -1.9):
                qt = q.copy()
                qt[j] += sign * phi
                turned = m.fk(qt, frame)
                want = base.copy()
                want[:3, :3] = base[:3, :3] @ np.asarray(AXES[free_axis](phi), dtype=float)
                if np.abs(turned - want).max() > SHORTCUT_TOL:
                    ok = False
        if ok:
            return j, sign
    return None


def _turned(m: Mechanism, q: np.ndarray, turn: np.ndarray, j: int) -> np.ndarray:
    """Angle ``j`` of ``q`` turned by ``turn`` (arrays of broadcastable shapes), shifted by whole
    turns into its limits (NaN where it does not fit).

    ``q`` lies within the limits and ``|turn| < 2 pi``, so one step of ``2 pi`` brings most sums
    ``v = q + turn`` into ``(-pi, pi]``: that value is kept where it lies within the limits (rule
    1 of `optik.spatial.wrap_to_limits`, ``wrap_angle(v)`` to a rounding), and only the others go
    through `optik.path.nodes.into_limits` (a few passes over the values instead of its dozens,
    on every free-axis sample of every pose)."""
    lo, hi = m.lower[j], m.upper[j]
    v = q + turn
    v -= _TURN * (v > np.pi)
    v += _TURN * (v <= -np.pi)
    ok = (v > -np.pi) & (v <= np.pi) & (v >= lo) & (v <= hi)
    if not ok.all():
        bad = ~ok
        raw = np.broadcast_to(q + turn, v.shape)[bad][:, None]
        v[bad] = into_limits(raw, m.lower[j : j + 1], m.upper[j : j + 1], np.ones(1, dtype=bool))[:, 0]
    return v


_TURN = 2.0 * np.pi


def sample_solutions(
    m: Mechanism,
    samples: Samples,
    frame: str | None,
    shortcut: tuple[int, float] | None,
    self_motion: tuple[int, np.ndarray] | None = None,
) -> tuple[Layered, Layered]:
    """Per path sample, every solution of every sampled pose ``(K, n)`` and its group ``(K,)``
    (with ``self_motion = (j, values)``: the solutions with coordinate ``j`` at each value, the
    group numbering pose sample and value, `optik.path.redundant`), as layers of one array.

    Without the shortcut every sampled pose is solved (``units = S`` per path sample); with it,
    only the ``units`` poses of the first axis angle (one per position offset), and the other
    ``S / units`` angles copy their solutions with the axis joint turned. A layer is then the
    block of its solved rows repeated once per angle, ordered angle by angle: group
    ``a * units + u`` of the block's row of unit ``u``.
    """
    n, s = samples.angle.shape
    if self_motion is not None:
        j, values = self_motion
        q, pose, tag = self_motion_solutions(m, samples.poses.reshape(-1, 4, 4), j, values)
        layer, unit = np.divmod(pose, s)
        return Layered.by_owner(q, layer, n), Layered.by_owner(unit * len(values) + tag, layer, n)
    units = s if shortcut is None else len(np.unique(samples.offset, axis=0))
    copies = s // units
    solved, counts = closed_form_solutions(m, samples.columns(units).reshape(-1, 4, 4), frame)
    unit = np.repeat(np.arange(n * units) % units, counts)  # the offset unit of each solved row
    block = counts.reshape(n, units).sum(axis=1)  # solved rows per path sample
    turn = samples.angle[0, ::units] - samples.angle[0, 0]  # the same turns at every pose
    if n and np.all(block == block[0]):  # as many rows per sample: blocks of one shape, no gather
        return _uniform(m, solved, unit, n, int(block[0]), copies, units, shortcut, turn)
    return _gathered(m, solved, unit, block, copies, units, shortcut, turn)


def _gathered(
    m: Mechanism,
    solved: np.ndarray,
    unit: np.ndarray,
    block: np.ndarray,
    copies: int,
    units: int,
    shortcut: tuple[int, float] | None,
    turn: np.ndarray,
) -> tuple[Layered, Layered]:
    """`sample_solutions` for any solved rows per path sample ``block (N,)``: one gather."""
    n = len(block)
    start = np.concatenate([[0], np.cumsum(block)[:-1]])
    size = copies * block  # rows per layer
    ramp = np.arange(size.sum()) - np.repeat(np.cumsum(size) - size, size)
    width = np.repeat(block, size)
    angle, row = np.divmod(ramp, np.maximum(width, 1))
    source = np.repeat(start, size) + row
    q = solved[source]
    group = angle * units + unit[source]
    pose = np.repeat(np.arange(n), size)
    if shortcut is not None:
        j, sign = shortcut
        turned = _turned(m, solved[:, j, None], sign * turn, j)
        q[:, j] = turned[source, angle]
        fits = np.isfinite(q[:, j])
        if not fits.all():
            q, group, pose = q[fits], group[fits], pose[fits]
    return Layered.by_owner(q, pose, n), Layered.by_owner(group, pose, n)


def _uniform(
    m: Mechanism,
    solved: np.ndarray,
    unit: np.ndarray,
    n: int,
    width: int,
    copies: int,
    units: int,
    shortcut: tuple[int, float] | None,
    turn: np.ndarray,
) -> tuple[Layered, Layered]:
    """`sample_solutions` when every path sample has ``width`` solved rows: each layer is its
    block ``(width, dof)`` repeated ``copies`` times, built by broadcasting."""
    q = np.empty((n, copies, width, m.n_q))
    q[...] = solved.reshape(n, 1, width, m.n_q)
    group = np.arange(copies)[None, :, None] * units + unit.reshape(n, 1, width)
    group = np.broadcast_to(group, (n, copies, width)).reshape(-1)
    full = True
    if shortcut is not None:
        j, sign = shortcut
        turned = _turned(m, solved[:, j].reshape(n, 1, width), (sign * turn)[None, :, None], j)
        q[..., j] = turned
        full = bool(np.isfinite(turned).all())
    q = q.reshape(-1, m.n_q)
    if full:  # every layer full: no count
        offset = np.arange(n + 1) * (copies * width)
        return Layered(q, offset), Layered(group, offset)
    fits = np.isfinite(q[:, shortcut[0]])
    pose = np.repeat(np.arange(n), copies * width)[fits]
    return Layered.by_owner(q[fits], pose, n), Layered.by_owner(group[fits], pose, n)


def chosen_angle(
    samples: Samples, groups: Sequence[np.ndarray], index: np.ndarray, per_sample: int = 1
) -> np.ndarray:
    """The angle about the free axis of each sample's chosen node ``(N,)``, in ``(-pi, pi]``
    (``per_sample`` groups per sampled pose: the self-motion values)."""
    g = Layered.of(groups).rows(index).astype(int) // per_sample
    a = samples.angle[np.arange(len(g)), g]
    return np.pi - np.remainder(np.pi - a, 2.0 * np.pi)
