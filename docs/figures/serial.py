"""Figures of the serial catalog arms in every IK branch for one target: docs/img/serial_*.png.

Run from the repository root: ``python docs/figures/serial.py``. Each figure is
``optik.plot.draw_branches`` of the branches that ``optik.closed_form.ik`` returns
(limits ignored, so that every branch of the closed form shows) for one target:

* ``serial_planar_2r.png``: 2 branches (``theta2 >= 0`` and ``<= 0``) for ``(x, y) = (1.2, 0.6)``;
* ``serial_planar_3r.png``: 2 branches for ``(x, y, phi) = (1.1, 0.9, 0.6)``;
* ``serial_rp_arm.png``: ``(theta, r)`` and ``(theta + pi, -r)`` for ``(x, y) = (0.8, 0.9)``;
* ``serial_pp_arm.png``: the single branch for ``(x, y) = (0.4, -0.3)``;
* ``serial_seed_6r_arm.png``: the 8 branches (shoulder x wrist x elbow) of ``SEED_6R_Q``'s pose.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from _write import write_figures
from matplotlib.figure import Figure

import optik
from optik import closed_form
from optik.plot import draw_branches

SEED_6R_Q = np.array([0.5, -0.8, -1.1, -1.0, 1.1, 0.8])
"""A posture of the default seed 6R arm whose pose has all 8 branches."""


def figures() -> dict[str, Figure]:
    """The figures by file stem."""
    cat = optik.catalog
    cases = [
        ("planar_2r", cat.planar_2r(), optik.Position(1.2, 0.6), "planar 2R: 2 branches for (1.2, 0.6)"),
        (
            "planar_3r",
            cat.planar_3r(),
            optik.Pose2D(1.1, 0.9, 0.6),
            "planar 3R: 2 branches for (x, y, phi) = (1.1, 0.9, 0.6)",
        ),
        ("rp_arm", cat.rp_arm(), optik.Position(0.8, 0.9), "R-P arm: (theta, r) and (theta + pi, -r)"),
        ("pp_arm", cat.pp_arm(), optik.Position(0.4, -0.3), "P-P arm: 1 branch for (0.4, -0.3)"),
    ]
    out = {
        stem: draw_branches(m, closed_form.ik(m, target, respect_limits=False), title)
        for stem, m, target, title in cases
    }
    m = cat.seed_6r_arm()
    qs = closed_form.ik(m, m.fk(SEED_6R_Q), respect_limits=False)
    out["seed_6r_arm"] = draw_branches(m, qs, f"seed 6R arm: {len(qs)} branches (shoulder x wrist x elbow)")
    return out


def main(argv: list[str] | None = None) -> list[Path]:
    """Write every figure into ``--out`` (default ``docs/img``) and return the paths."""
    return write_figures("serial", figures, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
