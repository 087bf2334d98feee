"""Figures of a planned path: joint trajectories against their limits, the tool's error along
the path, the branch changes (one matplotlib `Figure`, no ``pyplot`` state)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from optik.batch import fk_batch
from optik.mechanism import Mechanism
from optik.path.result import JointPath


def path_figure(m: Mechanism, path: JointPath, frame: str | None = None, title: str = "") -> Figure:
    """Three panels over the samples' times: every joint with its limits (dashed), the tool's
    position error against each pose (recomputed by FK) and the deviation between samples, and
    the branch-change count."""
    fig = Figure(figsize=(9.0, 8.0), layout="constrained")
    top, mid, low = fig.subplots(3, 1, sharex=True, height_ratios=(3, 1.4, 1))
    t = path.t
    for j, name in enumerate(m.coordinate_names):
        (line,) = top.plot(t, path.q[:, j], label=name)
        for bound in (m.lower[j], m.upper[j]):
            if np.isfinite(bound) and abs(bound) < 2.5 * np.pi:
                top.axhline(bound, color=line.get_color(), ls="--", lw=0.7, alpha=0.6)
    top.set_ylabel("joint (rad / m)")
    top.legend(ncols=min(m.n_q, 7), fontsize="small", loc="upper right")
    if len(path.q):
        err = np.linalg.norm(fk_batch(m, path.q, frame)[:, :3, 3] - path.poses[:, :3, 3], axis=1)
        mid.semilogy(t, np.maximum(err, 1e-17), label="position error at the samples")
        if len(path.deviation):
            mid.semilogy(
                0.5 * (t[1:] + t[:-1]), np.maximum(path.deviation, 1e-17), label="deviation between samples"
            )
        mid.legend(fontsize="small")
    mid.set_ylabel("tool error (m)")
    low.step(t, path.branch, where="post")
    low.set_ylabel("branch changes")
    low.set_xlabel("time (s)")
    fig.suptitle(title or path.message[:110])
    return fig
