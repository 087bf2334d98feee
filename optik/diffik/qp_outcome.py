"""What a QP backend of the differential-IK step returns, shared by the dispatcher
([`optik.diffik.qp`][optik.diffik.qp]) and every backend below it (e.g.
[`optik.diffik.cvx`][optik.diffik.cvx]), so that backends never import the dispatcher that picks them.
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass
from typing import Any

import numpy as np

from optik.errors import SolverUnavailableError


@dataclass
class QPOutcome:
    """What a backend returns.

    Attributes:
        dq: the solution (None when the backend found none).
        status: ``"optimal"``, ``"infeasible"`` or ``"failed"``.
        detail: backend status text.
    """

    dq: np.ndarray | None
    status: str
    detail: str


def require_backend(module: str, solver: str) -> Any:
    """The backend's module, imported on first use.

    Raises:
        SolverUnavailableError: ``module`` is not installed (the message says what to install).
    """
    if importlib.util.find_spec(module) is None:
        raise SolverUnavailableError(
            f"QP solver {solver!r} needs the {module!r} package: pip install {module}"
        )
    return importlib.import_module(module)
