"""Closed-form (analytic) kinematics returning every branch.

``ik(m, target)`` and ``fk(m, actuated)`` dispatch on ``m.kind``, or for IK on the solver
[`derive`][optik.closed_form.derive] finds from the joint axes of a 6R arm; the vectorized functions
(e.g. [`ik_planar_3r`][optik.closed_form.ik_planar_3r]) work on arrays of targets at once and return all
branches with a reachability mask.
"""

from optik.closed_form import parallel
from optik.closed_form.derived import DerivedIK, derive
from optik.closed_form.general_6r import General6R, ik_general_6r, solve_general_6r
from optik.closed_form.registry import fk, has_fk, has_ik, ik, register
from optik.closed_form.search_1d import Search1D, solve_search_1d
from optik.closed_form.serial import ik_planar_2r, ik_planar_3r, ik_pp, ik_rp, ik_seed_6r
from optik.spatial import rot_to_rpy_all as rpy_all
from optik.spatial import rot_to_zyz_all as zyz_all

__all__ = [
    "DerivedIK",
    "General6R",
    "Search1D",
    "derive",
    "fk",
    "has_fk",
    "has_ik",
    "ik",
    "ik_general_6r",
    "ik_planar_2r",
    "ik_planar_3r",
    "ik_pp",
    "ik_rp",
    "ik_seed_6r",
    "parallel",
    "register",
    "rpy_all",
    "solve_general_6r",
    "solve_search_1d",
    "zyz_all",
]
