"""Figures of the closed-chain catalog in every assembly / working mode: docs/img/parallel_*.png.

Run from the repository root: ``python docs/figures/parallel.py``. Each figure is
``optik.plot.draw_branches`` of the branches returned by the closed forms
(``optik.closed_form.parallel``) for one input:

* ``parallel_five_bar_fk.png``: the 2 assembly modes for ``theta = (1.2, 0.6)``;
* ``parallel_five_bar_ik.png``: the 4 working modes for the tool at ``(0.5, 1.4)``;
* ``parallel_five_bar_seed.png``: the seed's coaxial variant (tool on an extended link), 4 working modes;
* ``parallel_doggy_ik.png``: the 4 leg combinations for the body pose ``(0.1, 0.8, 0.2)``;
* ``parallel_slider_crank_fk.png``: the 2 assembly modes for ``theta = 1.0``;
* ``parallel_planar_3rpr_fk.png``: 6 real assembly modes of a 3-RPR (``RPR_SIX``);
* ``parallel_stewart_gough_fk.png``: every real posture of the catalog Stewart-Gough platform
  for the leg lengths of a tilted pose.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from _write import write_figures
from matplotlib.figure import Figure

import optik
from optik import closed_form
from optik.plot import draw_branches

RPR_SIX = {
    "platform": ((-0.14, -0.52), (-0.6, 0.41), (0.74, 0.11)),
    "rho": (1.08, 1.70, 1.79),
}
"""A 3-RPR (catalog base) with 6 real assembly modes (the catalog default has at most 4)."""


def _stewart_legs() -> tuple[optik.Mechanism, np.ndarray]:
    m = optik.catalog.stewart_gough()
    target = optik.spatial.transform(optik.spatial.rpy_to_rot(0.2, -0.1, 0.3), np.array([0.1, 0.05, 1.0]))
    q = closed_form.ik(m, target)[0]
    return m, q[m.actuated_indices]


def figures() -> dict[str, Figure]:
    """The figures by file stem."""
    out: dict[str, Figure] = {}
    m = optik.catalog.five_bar()
    out["five_bar_fk"] = draw_branches(m, closed_form.fk(m, [1.2, 0.6]), "five-bar FK: 2 assembly modes")
    out["five_bar_ik"] = draw_branches(
        m, closed_form.ik(m, optik.Position(0.5, 1.4)), "five-bar IK: 4 working modes, tool at (0.5, 1.4)"
    )
    seed = optik.catalog.five_bar(base=((0, 0), (0, 0)), lengths=(1.0, 1.0, 1.2, 1.2), tool=1.6)
    out["five_bar_seed"] = draw_branches(
        seed,
        closed_form.ik(seed, optik.Position(0.6, 1.6)),
        "seed five-bar (coaxial, tool 1.6): 4 working modes",
    )
    m = optik.catalog.doggy()
    out["doggy_ik"] = draw_branches(
        m, closed_form.ik(m, optik.Pose2D(0.1, 0.8, 0.2)), "doggy IK: 4 leg combinations for (0.1, 0.8, 0.2)"
    )
    m = optik.catalog.slider_crank()
    out["slider_crank_fk"] = draw_branches(m, closed_form.fk(m, [1.0]), "slider-crank FK: 2 assembly modes")
    m = optik.catalog.planar_3rpr(platform=RPR_SIX["platform"])
    out["planar_3rpr_fk"] = draw_branches(
        m, closed_form.fk(m, RPR_SIX["rho"]), f"3-RPR FK: 6 assembly modes, rho = {RPR_SIX['rho']}"
    )
    m, legs = _stewart_legs()
    qs = closed_form.fk(m, legs)
    out["stewart_gough_fk"] = draw_branches(m, qs, f"Stewart-Gough FK: {len(qs)} real postures")
    return out


def main(argv: list[str] | None = None) -> list[Path]:
    """Write every figure into ``--out`` (default ``docs/img``) and return the paths."""
    return write_figures("parallel", figures, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
