"""Cartesian path planning over every IK solution (`plan_path`, `JointPath`).

The layered graph of every solution of every pose (`optik.path.nodes`), its path of least
weighted joint motion by dynamic programming (`optik.path.graph`), the path's times
(`optik.path.timing`) and the planner with its independent checks (`optik.path.plan`).
"""

from optik.path.plan import check_path, plan_path
from optik.path.result import JointPath

__all__ = ["JointPath", "check_path", "plan_path"]
