"""IK solvers behind one ``solve_ik``; methods register themselves in
[`optik.solvers.base`][optik.solvers.base]."""

from optik.solvers import closed as _closed  # noqa: F401  (registers "closed_form")
from optik.solvers import lm as _lm  # noqa: F401  (registers "lm")
from optik.solvers import nlp as _nlp  # noqa: F401  (registers "nlp")
from optik.solvers.all import self_motion, solve_ik_all
from optik.solvers.all_batch import solve_ik_all_batch
from optik.solvers.all_solutions import AllSolutions
from optik.solvers.api import pick_method, solve_ik
from optik.solvers.base import IKRequest, Tolerances, methods, register_method

__all__ = [
    "AllSolutions",
    "IKRequest",
    "Tolerances",
    "methods",
    "pick_method",
    "register_method",
    "self_motion",
    "solve_ik",
    "solve_ik_all",
    "solve_ik_all_batch",
]
