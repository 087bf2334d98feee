"""Figures of the differential-IK pages (``docs/img/diffik_*.png``).

Run from the repository root: ``python docs/figures/diffik.py``. Every figure is computed here
from optik (no stored data):

* ``diffik_welding.png``: the Panda welds a seam at constant tool orientation and speed (QP):
  joint trajectories, tracking error, manipulability and distance to the joint limits;
* ``diffik_singularity.png``: a planar 2R arm stretched through its elbow singularity and back:
  joint speeds of the pseudo-inverse against damped least squares, and the manipulability;
* ``diffik_self_motion.png``: the Panda's self-motion with the flange fixed (strict priority):
  joint 3 turned by a secondary task, the flange error, and the other joints following.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import optik
from optik import diffik
from optik.diffik import scenarios
from optik.plot import save_figure

OUT = Path(__file__).resolve().parents[1] / "img"
TOOL_DOWN = np.diag([1.0, -1.0, -1.0])


def welding() -> Path:
    """Panda welding seam: joints, tracking error, manipulability, limit margin."""
    m = optik.catalog.panda()
    path = diffik.polyline_path(
        [[0.45, -0.2, 0.25], [0.6, -0.2, 0.25], [0.6, 0.15, 0.3]], 0.25, 0.01, TOOL_DOWN
    )
    q0 = optik.solve_ik(m, path[0], method="qp", time_limit=2.0).q
    res = diffik.track(m, q0, path, 0.01, "qp", tasks=[diffik.PostureTask(q0, cost=1e-3)])
    fig, axes = plt.subplots(2, 2, figsize=(10, 6.5), sharex=True)
    for k in range(m.n_q):
        axes[0, 0].plot(res.t, res.q[:, k], label=m.coordinate_names[k])
    axes[0, 0].set_ylabel("joint angle (rad)")
    axes[0, 0].legend(ncol=4, fontsize=7)
    axes[0, 1].semilogy(res.t[1:], np.maximum(res.position_error, 1e-12), label="position (m)")
    axes[0, 1].semilogy(res.t[1:], np.maximum(res.orientation_error, 1e-12), label="orientation (rad)")
    axes[0, 1].set_ylabel("tracking error")
    axes[0, 1].legend(fontsize=8)
    axes[1, 0].plot(res.t, res.manipulability)
    axes[1, 0].set_ylabel("manipulability sqrt(det J J^T)")
    axes[1, 1].plot(res.t, res.limit_margin)
    axes[1, 1].axhline(0.0, color="k", lw=0.8)
    axes[1, 1].set_ylabel("min distance to a joint limit (rad)")
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle("Panda welding a seam at 0.25 m/s, tool pointing down (QP step, dt = 10 ms)")
    fig.tight_layout()
    return save_figure(fig, OUT / "diffik_welding.png")


def singularity() -> Path:
    """2R arm through its elbow singularity: pinv vs DLS joint speeds."""
    sc = scenarios.elbow_singularity()
    m, path = sc.m, sc.path
    q0 = optik.solve_ik(m, optik.Position(1.0, 0.0), q0=sc.q0, method="qp").q
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for method, style in (("pinv", "-"), ("dls", "-"), ("qp", "--")):
        res = diffik.track(m, q0, path, sc.dt, method)
        speed = np.max(np.abs(res.v), axis=1)
        axes[0].plot(res.t[1:], speed, style, label=method)
        axes[1].semilogy(res.t[1:], np.maximum(res.position_error, 1e-12), style, label=method)
        axes[2].plot(res.t, res.manipulability, style, label=method)
    axes[0].set_ylabel("max joint speed (rad/s)")
    axes[1].set_ylabel("position error (m)")
    axes[2].set_ylabel("manipulability")
    for ax in axes:
        ax.set_xlabel("time (s)")
        ax.legend(fontsize=8)
    fig.suptitle("Planar 2R driven 5 cm beyond its reach and back (elbow singularity)")
    fig.tight_layout()
    return save_figure(fig, OUT / "diffik_singularity.png")


def self_motion() -> Path:
    """Panda self-motion: flange fixed, joint 3 turned by a secondary task."""
    sc = scenarios.self_motion()
    m, q0 = sc.m, sc.q0
    res = diffik.track(m, q0, sc.path, sc.dt, "priority", tasks=sc.tasks)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for k in range(m.n_q):
        axes[0].plot(res.t, res.q[:, k] - q0[k], label=m.coordinate_names[k])
    axes[0].set_ylabel("q - q0 (rad)")
    axes[0].legend(ncol=4, fontsize=7)
    axes[1].semilogy(res.t[1:], np.maximum(res.position_error, 1e-16), label="position (m)")
    axes[1].semilogy(res.t[1:], np.maximum(res.orientation_error, 1e-16), label="orientation (rad)")
    axes[1].set_ylabel("flange error")
    axes[1].legend(fontsize=8)
    for ax in axes:
        ax.set_xlabel("time (s)")
    fig.suptitle("Panda self-motion: flange fixed (priority 0), joint 3 turned by 1 rad (priority 1)")
    fig.tight_layout()
    return save_figure(fig, OUT / "diffik_self_motion.png")


def main() -> None:
    """Write every figure and print the paths."""
    for make in (welding, singularity, self_motion):
        print(make())


if __name__ == "__main__":
    main()
