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

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from optik.mechanism import Mechanism
from optik.path.nodes import closed_form_solutions
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
    """The sampled poses of a path: ``poses (N, S, 4, 4)``, per pose and group its angle about
    the free axis ``angle (N, S)``, per group its position offset direction ``offset (S, 3)``
    (times the pose's tolerance)."""

    poses: np.ndarray
    angle: np.ndarray
    offset: np.ndarray


def transported(targets: np.ndarray, free_axis: str) -> np.ndarray:
    """Per pose, the angle ``psi_k`` about its free axis that carries the first pose's
    perpendicular axis along the path without twist (module docstring)."""
    a = "xyz".index(free_axis)
    b, c = (a + 1) % 3, (a + 2) % 3
    out = np.zeros(len(targets))
    carried = targets[0, :3, b]
    for k in range(1, len(targets)):
        r = targets[k, :3, :3]
        x = carried - (carried @ r[:, a]) * r[:, a]
        norm = np.linalg.norm(x)
        x = r[:, b] if norm < 1e-9 else x / norm
        out[k] = np.arctan2(x @ r[:, c], x @ r[:, b])
        carried = x
    return out


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
    spin = np.tile(np.eye(4), (*total.shape, 1, 1))
    if free_axis is not None:
        rot = np.asarray(AXES[free_axis](total.reshape(-1)), dtype=float)
        spin[..., :3, :3] = rot.reshape(*total.shape, 3, 3)
    turned = targets[:, None] @ spin  # (N, A, 4, 4)
    radius = np.zeros(len(targets)) if tolerance is None else tolerance
    shift = radius[:, None, None] * units[None]  # (N, P, 3)
    poses = np.repeat(turned[:, :, None], len(units), axis=2)  # (N, A, P, 4, 4)
    poses[..., :3, 3] += shift[:, None]
    n = len(targets)
    return Samples(
        poses.reshape(n, -1, 4, 4), np.repeat(total, len(units), axis=1), np.tile(units, (len(angles), 1))
    )


def axis_joint(m: Mechanism, free_axis: str, frame: str | None, seed: int = 0) -> tuple[int, float] | None:
    """``(j, sign)`` when turning joint ``j`` by ``sign * phi`` turns the tool by ``R(phi)``
    about its free axis at every configuration (checked by FK at three random configurations and
    two angles), else None."""
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


def _into_limits(v: np.ndarray, lower: float, upper: float) -> np.ndarray:
    """Angles shifted by the first of ``0, 2 pi, -2 pi, 4 pi, -4 pi`` (after wrapping to
    ``[-pi, pi)``) that lands within ``[lower, upper]``; NaN where none does."""
    w = np.remainder(v + np.pi, 2.0 * np.pi) - np.pi
    out = np.full_like(w, np.nan)
    for shift in 2.0 * np.pi * np.array([0.0, 1.0, -1.0, 2.0, -2.0]):
        fits = np.isnan(out) & (w + shift >= lower) & (w + shift <= upper)
        out[fits] = w[fits] + shift
    return out


def sample_solutions(
    m: Mechanism,
    samples: Samples,
    frame: str | None,
    shortcut: tuple[int, float] | None,
    self_motion: tuple[int, np.ndarray] | None = None,
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per path sample, every solution of every sampled pose ``(K, n)`` and its group ``(K,)``
    (with ``self_motion = (j, values)``: the solutions with coordinate ``j`` at each value, the
    group numbering pose sample and value, `optik.path.redundant`)."""
    n, s = samples.poses.shape[:2]
    if self_motion is not None:
        j, values = self_motion
        rows, tags = self_motion_solutions(m, samples.poses.reshape(-1, 4, 4), j, values)
        layers, groups = [], []
        for k in range(n):
            part = range(k * s, (k + 1) * s)
            layers.append(np.concatenate([rows[i] for i in part]))
            groups.append(np.concatenate([(i - k * s) * len(values) + tags[i] for i in part]))
        return layers, groups
    units = s if shortcut is None else len(np.unique(samples.offset, axis=0))
    # one IK per sampled pose, or with the shortcut per offset (the groups of axis angle 0)
    flat = closed_form_solutions(m, samples.poses[:, :units].reshape(-1, 4, 4), frame)
    counts = np.array([len(f) for f in flat])
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    pose_of, group_of = np.divmod(np.arange(n * s), s)  # every (pose, group)
    source = pose_of * units + group_of % units  # the solved pose it copies
    size = counts[source]
    ramp = np.arange(size.sum()) - np.repeat(np.cumsum(size) - size, size)
    q = np.concatenate(flat)[np.repeat(first[source], size) + ramp] if size.sum() else np.zeros((0, m.n_q))
    pose, group = np.repeat(pose_of, size), np.repeat(group_of, size)
    if shortcut is not None:
        j, sign = shortcut
        turn = samples.angle[pose, group] - samples.angle[pose, 0]  # from the solved groups' angle
        q[:, j] = _into_limits(q[:, j] + sign * turn, m.lower[j], m.upper[j])
        fits = np.isfinite(q[:, j])
        q, pose, group = q[fits], pose[fits], group[fits]
    cuts = np.cumsum(np.bincount(pose, minlength=n))[:-1]
    return np.split(q, cuts), np.split(group, cuts)


def chosen_angle(
    samples: Samples, groups: Sequence[np.ndarray], index: np.ndarray, per_sample: int = 1
) -> np.ndarray:
    """The angle about the free axis of each sample's chosen node ``(N,)``, in ``(-pi, pi]``
    (``per_sample`` groups per sampled pose: the self-motion values)."""
    g = np.array([g[i] for g, i in zip(groups, index, strict=True)], dtype=int) // per_sample
    a = samples.angle[np.arange(len(g)), g]
    return np.pi - np.remainder(np.pi - a, 2.0 * np.pi)
