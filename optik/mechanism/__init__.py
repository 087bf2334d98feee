"""The model layer: joints, mechanisms, builders."""

from optik.mechanism.builders import dh_chain, planar_chain
from optik.mechanism.joint import JOINT_DOF, Joint, LinearClosure, Mimic
from optik.mechanism.mechanism import TASK_ROWS, Mechanism

__all__ = [
    "JOINT_DOF",
    "TASK_ROWS",
    "Joint",
    "LinearClosure",
    "Mechanism",
    "Mimic",
    "dh_chain",
    "planar_chain",
]
