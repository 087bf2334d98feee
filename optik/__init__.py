"""optik: kinematics by constrained optimization.

Every mechanism becomes one CasADi model ([`Mechanism`][optik.Mechanism]) with joint limits and
loop-closure constraints; optik solves IK with limits, FK of parallel mechanisms in every
assembly mode and differential IK, and compares every solver against closed forms.
"""

from optik import catalog, closed_form, collision, diffik, spatial  # diffik registers "dls" and "qp"
from optik.batch import BatchResult, fk_batch, solve_ik_batch
from optik.collision import World
from optik.errors import (
    InvalidArgumentError,
    LimitsError,
    MissingExtraError,
    ModelError,
    NonFiniteError,
    OptikError,
    ProblemFileError,
    ReadOnlyError,
    ShapeError,
    SolverUnavailableError,
    UnknownFrameError,
)
from optik.mechanism import Joint, Mechanism, dh_chain, planar_chain
from optik.path import JointPath, plan_path
from optik.problem import IKProblem, build_ik_problem
from optik.reach import ReachMap, reach
from optik.results import FKModes, FKResult, IKResult, IKSolutions, IKSolutionsBatch
from optik.solvers import AllSolutions, Tolerances, self_motion, solve_ik, solve_ik_all, solve_ik_all_batch
from optik.solvers.fk import solve_fk, solve_fk_all
from optik.targets import Pose2D, Position
from optik.view import view

__version__ = "0.1.0"

__all__ = [
    "AllSolutions",
    "BatchResult",
    "FKModes",
    "FKResult",
    "IKProblem",
    "IKResult",
    "IKSolutions",
    "IKSolutionsBatch",
    "InvalidArgumentError",
    "Joint",
    "JointPath",
    "LimitsError",
    "Mechanism",
    "MissingExtraError",
    "ModelError",
    "NonFiniteError",
    "OptikError",
    "Pose2D",
    "Position",
    "ProblemFileError",
    "ReachMap",
    "ReadOnlyError",
    "ShapeError",
    "SolverUnavailableError",
    "Tolerances",
    "UnknownFrameError",
    "World",
    "build_ik_problem",
    "catalog",
    "closed_form",
    "collision",
    "dh_chain",
    "diffik",
    "fk_batch",
    "plan_path",
    "planar_chain",
    "reach",
    "self_motion",
    "solve_fk",
    "solve_fk_all",
    "solve_ik",
    "solve_ik_all",
    "solve_ik_all_batch",
    "solve_ik_batch",
    "spatial",
    "view",
]
