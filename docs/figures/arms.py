"""Figures of the 7-DOF catalog arms in a few postures: docs/img/arms_panda.png, arms_iiwa14.png.

Run from the repository root: ``python docs/figures/arms.py``. Each posture is drawn from the
catalog model (``optik.catalog.panda()`` / ``iiwa14()``) with ``optik.plot.draw``, on
common axis limits, with the pedestal from the base origin to the first joint in grey.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from _write import write_figures
from matplotlib.figure import Figure

from optik import catalog
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.plot import draw

PI = np.pi
POSTURES = {
    "panda": {
        "ready": (0.0, -PI / 4, 0.0, -3 * PI / 4, 0.0, PI / 2, PI / 4),
        "reach forward": (0.0, 0.6, 0.0, -1.2, 0.0, 1.8, 0.0),
        "elbow aside": (0.8, 0.3, -1.2, -1.8, 0.9, 2.2, -0.5),
    },
    "iiwa14": {
        "stretched": (0.0,) * 7,
        "bent": (0.0, PI / 4, 0.0, -PI / 2, 0.0, PI / 4, 0.0),
        "elbow aside": (0.6, 0.7, 1.2, -1.4, -0.8, 1.0, 0.3),
    },
}
"""Named joint vectors (rad) drawn for each arm; all are within the catalog limits."""


def _points(m: Mechanism, q: np.ndarray) -> np.ndarray:
    """Base origin, every body origin and the end effector at ``q`` (for the axis limits)."""
    frames = [*m.topology.bodies, m.ee]
    return np.array([np.zeros(3)] + [m.fk(q, frame=f)[:3, 3] for f in frames])


def figure(m: Mechanism, postures: dict[str, tuple[float, ...]]) -> Figure:
    """One 3-D subplot per named posture, all on the same cube of axis limits."""
    fig = Figure(figsize=(4.3 * len(postures), 4.8), layout="constrained")
    pts = np.vstack([_points(m, np.array(q)) for q in postures.values()])
    c = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    half = 0.55 * float(np.max(pts.max(axis=0) - pts.min(axis=0)))
    for i, (label, q) in enumerate(postures.items()):
        qq = np.array(q)
        if not m.within_limits(qq):
            raise InvalidArgumentError("POSTURES", f"posture {label!r} of {m.name} is outside the limits")
        ax = fig.add_subplot(1, len(postures), i + 1, projection="3d")
        first = m.fk(qq, frame=m.joints[0].child)[:3, 3]
        ax.plot([0.0, first[0]], [0.0, first[1]], [0.0, first[2]], color="0.5", lw=4)
        draw(m, qq, ax=ax)
        ax.set_xlim(c[0] - half, c[0] + half)
        ax.set_ylim(c[1] - half, c[1] + half)
        ax.set_zlim(max(c[2] - half, -0.05), max(c[2] - half, -0.05) + 2 * half)
        ax.set_box_aspect((1, 1, 1))
        ax.set_title(f"{m.name}: {label}")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
    return fig


def figures() -> dict[str, Figure]:
    """One figure per arm of ``POSTURES``."""
    return {name: figure(getattr(catalog, name)(), postures) for name, postures in POSTURES.items()}


def main(argv: list[str] | None = None) -> list[Path]:
    """Write one PNG per arm into ``--out`` (default ``docs/img``) and return the paths."""
    return write_figures("arms", figures, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
