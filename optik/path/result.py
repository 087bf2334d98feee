"""`JointPath`: the answer of [`plan_path`][optik.plan_path]."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class JointPath:
    """A joint path through a sequence of tool poses.

    Attributes:
        q: configurations ``(N, n)``, one per sample (``(0, n)`` when no path was found).
        t: times of the samples ``(N,)`` (s), starting at 0.
        qd: joint velocities ``(N, n)``: the second-order finite difference of ``q`` over ``t``
            (a convex combination of the two adjacent segment velocities, so within any bound the
            segments meet).
        qdd: joint accelerations ``(N, n)``, the same difference of ``qd``.
        branch: per sample, how many branch changes the path made before it (0 everywhere for a
            path that never changes branch; see [`optik.path.plan`][optik.path.plan]).
        cost: weighted joint-space length, the sum over segments of ``|W (q[k+1] - q[k])|``.
        checks: each check run on the final path (recomputed from ``q`` and ``t``) and whether it
            passed: ``"fk"``, ``"limits"``, ``"velocity"``, ``"acceleration"``, ``"branch"``,
            ``"collision"``, ``"deviation"`` (the ones that apply).
        success: True when a path was found and every check passed.
        message: what was done, what was stretched or dropped, and why a path failed.
        stretched: number of segments whose time was stretched to meet the velocity limits
            (``times=None`` only).
        axis_angle: per sample, the rotation about the free tool axis that was chosen (rad; zeros
            without ``free_axis``).
        nodes: number of graph nodes (solutions) per pose.
        poses: the path's poses ``(N, 4, 4)``: the ones asked for, with the samples that
            densification inserted.
        deviation: per segment, the largest distance of the tool from the straight segment
            between its ends while the joints move linearly (m; `optik.path.densify`).
    """

    q: np.ndarray
    t: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    branch: np.ndarray
    cost: float
    checks: dict[str, bool] = field(default_factory=dict)
    success: bool = False
    message: str = ""
    stretched: int = 0
    axis_angle: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    poses: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    deviation: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def flips(self) -> int:
        """Number of branch changes along the path."""
        return int(self.branch[-1]) if len(self.branch) else 0

    def __len__(self) -> int:
        return len(self.q)
