"""QP backends for one differential-IK step.

* ``"daqp"``: DAQP's dual active-set solver called directly on the dense ``H`` (``n`` is small,
  so dense is fastest); bounds as simple bounds, closures as equality rows.
* ``"osqp"``: OSQP with the sparsity pattern set up once per task structure and updated in place
  (``update(Px, q, l, u, Ax)``), warm-started from the previous step's solution.
* ``"cvxpy"``: the same QP written with cvxpy parameters (built once, DPP), for cross-checks.
* any other name: the backend of that name through ``qpsolvers.solve_problem``.

Every backend returns a [`QPOutcome`][optik.diffik.qp_outcome.QPOutcome]; none raises on an infeasible or
failed solve. Unknown settings raise [`InvalidArgumentError`][optik.errors.InvalidArgumentError]
(``"options"``) for DAQP and OSQP; cvxpy and the qpsolvers backends report them as a failed solve (status and
message).
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import Any

import numpy as np

from optik.diffik.cvx import solve_cvxpy
from optik.diffik.problem import DiffIKProblem
from optik.diffik.qp_outcome import QPOutcome, require_backend
from optik.errors import InvalidArgumentError, SolverUnavailableError


def default_solver() -> str:
    """The default backend: ``"daqp"`` when installed (fastest in ``optik benchmark diffik``),
    else ``"osqp"``."""
    return "daqp" if importlib.util.find_spec("daqp") is not None else "osqp"


_SENSE: dict[tuple[int, int, int], np.ndarray] = {}
"""DAQP's constraint types (0 bound or inequality, 5 equality) per ``(n, equalities, inequalities)``
(DAQP only reads them)."""


_FREE = 1e30
"""DAQP's stand-in for an absent lower bound of an inequality row."""

_FREE_ROWS: dict[int, np.ndarray] = {}
"""``-_FREE`` repeated, per count of inequality rows (only read)."""


def _rows(problem: DiffIKProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The general constraint rows ``l <= C dq <= u``: the equalities ``A dq = b``, then the
    inequalities ``G dq <= h``."""
    k = problem.G.shape[0]
    if not k:
        return problem.A, problem.b, problem.b
    c = np.vstack([problem.A, problem.G])
    return c, np.concatenate([problem.b, np.full(k, -_FREE)]), np.concatenate([problem.b, problem.h])


def solve_daqp(problem: DiffIKProblem, **settings: Any) -> QPOutcome:
    """DAQP on the dense problem (``settings`` are DAQP settings, e.g. ``primal_tol``)."""
    daqp = require_backend("daqp", "daqp")
    n, m_eq, k = problem.n, problem.A.shape[0], problem.G.shape[0]
    sense = _SENSE.get((n, m_eq, k))
    if sense is None:
        sense = np.zeros(n + m_eq + k, dtype=np.int32)
        sense[n : n + m_eq] = 5
        sense = _SENSE.setdefault((n, m_eq, k), sense)
    if k or m_eq:  # equalities, then inequalities (no lower bound): each array made in one call
        rows = problem.A if not k else problem.G if not m_eq else np.vstack([problem.A, problem.G])
        free = _FREE_ROWS.get(k)
        if free is None:
            free = _FREE_ROWS.setdefault(k, np.full(k, -_FREE))
        upper = np.concatenate([problem.ub, problem.b, problem.h])
        lower = np.concatenate([problem.lb, problem.b, free])
    else:
        rows = problem.A
        upper, lower = problem.ub, problem.lb
    try:
        x, _, flag, _ = daqp.solve(problem.H, problem.c, rows, upper, lower, sense, **settings)
    except TypeError as exc:
        raise InvalidArgumentError("options", f"daqp: {exc}") from exc
    if flag in (1, 2):
        return QPOutcome(np.asarray(x, dtype=float), "optimal", f"daqp exitflag {flag}")
    return QPOutcome(None, "infeasible" if flag == -1 else "failed", f"daqp exitflag {flag}")


class OsqpWorkspace:
    """An OSQP workspace for one problem structure, set up once and updated in place."""

    def __init__(self, problem: DiffIKProblem, settings: dict[str, Any]) -> None:
        osqp = require_backend("osqp", "osqp")
        sp = importlib.import_module("scipy.sparse")  # imported on first use: it is slow to import
        n, m_eq = problem.n, problem.A.shape[0] + problem.G.shape[0]
        self._triu = np.triu_indices(n)
        order = np.lexsort((self._triu[0], self._triu[1]))  # CSC order: by column, then row
        self._p_rows, self._p_cols = self._triu[0][order], self._triu[1][order]
        p = sp.csc_matrix((np.ones(len(order)), (self._p_rows, self._p_cols)), shape=(n, n))
        a_dense = np.vstack([np.eye(n), np.ones((m_eq, n))])
        a = sp.csc_matrix(a_dense)
        rows, cols = np.nonzero(a_dense.T)  # CSC order of the pattern (column-major)
        self._a_rows, self._a_cols = cols, rows
        opts = {"verbose": False, "warm_starting": True, "eps_abs": 1e-7, "eps_rel": 1e-7, "polishing": False}
        opts.update(settings)
        self.solver = osqp.OSQP()
        try:
            self.solver.setup(p, np.zeros(n), a, -np.ones(n + m_eq), np.ones(n + m_eq), **opts)
        except ValueError as exc:
            raise InvalidArgumentError("options", f"osqp: {exc}") from exc
        self.n = n

    def solve(self, problem: DiffIKProblem) -> QPOutcome:
        n = self.n
        rows, lo_rows, up_rows = _rows(problem)
        a_full = np.vstack([np.eye(n), rows])
        self.solver.update(
            Px=problem.H[self._p_rows, self._p_cols],
            Ax=a_full[self._a_rows, self._a_cols],
            q=problem.c,
            l=np.concatenate([problem.lb, lo_rows]),
            u=np.concatenate([problem.ub, up_rows]),
        )
        res = self.solver.solve(raise_error=False)
        status = str(res.info.status)
        if status in ("solved", "solved inaccurate"):
            return QPOutcome(np.asarray(res.x, dtype=float), "optimal", f"osqp {status}")
        return QPOutcome(None, "infeasible" if "infeasible" in status else "failed", f"osqp {status}")


def solve_osqp(problem: DiffIKProblem, **settings: Any) -> QPOutcome:
    """OSQP with a persistent workspace per task structure (``settings``: OSQP settings)."""
    # repr: settings values may be unhashable; the rows' count is part of the workspace's pattern
    key = ("osqp", problem.G.shape[0], repr(sorted(settings.items())))
    ws = problem.cache.backends.get(key) if problem.cache is not None else None
    if ws is None:
        ws = OsqpWorkspace(problem, settings)
        if problem.cache is not None:
            problem.cache.backends[key] = ws
    return ws.solve(problem)


def solve_qpsolvers(problem: DiffIKProblem, solver: str, **settings: Any) -> QPOutcome:
    """Any backend of ``qpsolvers`` by name."""
    qpsolvers = require_backend("qpsolvers", solver)
    if solver not in qpsolvers.available_solvers:
        raise SolverUnavailableError(
            f"QP solver {solver!r} is not installed; available: {sorted(qpsolvers.available_solvers)} "
            f"(pip install qpsolvers[{solver}])"
        )
    has_eq, has_ineq = problem.A.shape[0] > 0, problem.G.shape[0] > 0
    qp = qpsolvers.Problem(
        problem.H,
        problem.c,
        G=problem.G if has_ineq else None,
        h=problem.h if has_ineq else None,
        A=problem.A if has_eq else None,
        b=problem.b if has_eq else None,
        lb=problem.lb,
        ub=problem.ub,
    )
    try:
        sol = qpsolvers.solve_problem(qp, solver=solver, **settings)
    except Exception as exc:  # backend-specific failures become a status, not a crash
        return QPOutcome(None, "failed", f"{solver}: {exc}")
    if sol.found and sol.x is not None:
        return QPOutcome(np.asarray(sol.x, dtype=float), "optimal", f"{solver} found")
    return QPOutcome(None, "infeasible", f"{solver} found no solution")


def solve_qp(problem: DiffIKProblem, solver: str | None = None, **settings: Any) -> QPOutcome:
    """Solve the step's QP with a backend by name (None:
    [`default_solver`][optik.diffik.qp.default_solver])."""
    name = default_solver() if solver is None else solver
    if name == "daqp":
        return solve_daqp(problem, **settings)
    if name == "osqp":
        return solve_osqp(problem, **settings)
    if name == "cvxpy":
        return solve_cvxpy(problem, **settings)
    return solve_qpsolvers(problem, name, **settings)
