"""Closed forms of the closed-chain catalog, one module per mechanism: five-bar, doggy,
slider-crank, 3-RPR, Stewart-Gough.

Every solver returns **full** coordinate vectors (passive coordinates included, in the model's
coordinate order, found by coordinate name), one per branch, so that each answer can be checked
against ``m.fk`` and ``m.closure``. Geometry comes from ``m.params`` (see
`optik.catalog.closed_chains`). Importing this package registers every solver with
`optik.closed_form.register`.

Branch counts: five-bar IK 4 working modes, FK 2 assembly modes; doggy IK 4 leg combinations,
FK 1; slider-crank IK 2, FK 2; 3-RPR IK 1, FK every real root of a degree-6 polynomial;
Stewart-Gough IK 1, FK every real posture (at most 40) by homotopy continuation.
"""

from optik.closed_form.parallel.common import CIRCLE_TOL, QUADRATIC_STOP, circle_intersections, two_link_ik
from optik.closed_form.parallel.doggy import doggy_fk, doggy_ik
from optik.closed_form.parallel.five_bar import five_bar_fk, five_bar_ik
from optik.closed_form.parallel.planar_3rpr import (
    CONTINUUM_SAMPLES,
    planar_3rpr_fk,
    planar_3rpr_ik,
    planar_3rpr_poses,
    polish_planar_3rpr,
    rpr_polynomial,
)
from optik.closed_form.parallel.slider_crank import slider_crank_fk, slider_crank_ik
from optik.closed_form.parallel.stewart_gough import (
    DEGENERATE_E,
    GENERAL_STEWART_SOLUTIONS,
    StewartFK,
    polish_stewart,
    stewart_gough_fk,
    stewart_gough_ik,
    stewart_jacobian,
    stewart_poses,
)
from optik.closed_form.parallel.study import (
    quat_left,
    quat_right,
    quat_to_rot,
    stewart_quadrics,
    study_matrices,
)

__all__ = [
    "CIRCLE_TOL",
    "CONTINUUM_SAMPLES",
    "DEGENERATE_E",
    "GENERAL_STEWART_SOLUTIONS",
    "QUADRATIC_STOP",
    "StewartFK",
    "circle_intersections",
    "doggy_fk",
    "doggy_ik",
    "five_bar_fk",
    "five_bar_ik",
    "planar_3rpr_fk",
    "planar_3rpr_ik",
    "planar_3rpr_poses",
    "polish_planar_3rpr",
    "polish_stewart",
    "quat_left",
    "quat_right",
    "quat_to_rot",
    "rpr_polynomial",
    "slider_crank_fk",
    "slider_crank_ik",
    "stewart_gough_fk",
    "stewart_gough_ik",
    "stewart_jacobian",
    "stewart_poses",
    "stewart_quadrics",
    "study_matrices",
    "two_link_ik",
]
