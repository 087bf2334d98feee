"""The model layer: joints, mechanisms, builders."""

from optik.mechanism.builders import dh_chain, planar_chain
from optik.mechanism.joint import JOINT_DOF, Joint, Mimic
from optik.mechanism.mechanism import TASK_ROWS, Mechanism

__all__ = ["JOINT_DOF", "TASK_ROWS", "Joint", "Mechanism", "Mimic", "dh_chain", "planar_chain"]
