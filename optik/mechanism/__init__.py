"""The model layer: joints, mechanisms, builders."""

from optik.mechanism.builders import dh_chain, planar_chain
from optik.mechanism.joint import JOINT_DOF, Joint
from optik.mechanism.mechanism import TASK_ROWS, Mechanism

__all__ = ["JOINT_DOF", "TASK_ROWS", "Joint", "Mechanism", "dh_chain", "planar_chain"]
