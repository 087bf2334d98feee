"""Named mechanisms with sensible default dimensions.

Every constructor returns an [`optik.Mechanism`][optik.Mechanism] whose ``kind`` names its entry here, so
that [`optik.closed_form`][optik.closed_form] can find the analytic solvers of that mechanism.
"""

from optik.catalog.arms import URDF_CHAINS, URDF_TREES, dual_panda, iiwa14, panda, urdf_path
from optik.catalog.closed_chains import doggy, five_bar, planar_3rpr, slider_crank, stewart_gough
from optik.catalog.industrial import puma560
from optik.catalog.legged import legged, legged_names
from optik.catalog.robots import robot, robot_names
from optik.catalog.serial import planar_2r, planar_3r, pp_arm, rp_arm, seed_6r_arm

__all__ = [
    "URDF_CHAINS",
    "URDF_TREES",
    "doggy",
    "dual_panda",
    "five_bar",
    "iiwa14",
    "legged",
    "legged_names",
    "panda",
    "planar_2r",
    "planar_3r",
    "planar_3rpr",
    "pp_arm",
    "puma560",
    "robot",
    "robot_names",
    "rp_arm",
    "seed_6r_arm",
    "slider_crank",
    "stewart_gough",
    "urdf_path",
]
