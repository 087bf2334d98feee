"""The step's QP written in cvxpy, for cross-checking the other backends.

The problem is built once per task structure with cvxpy parameters (disciplined parametrized
programming), then re-solved with new values:

```text
minimise    1/2 ||W J dq - t||^2 + mu/2 ||dq||^2
subject to  lb <= dq <= ub,  J_c dq = b,  G dq <= h
```

which has the same minimiser as ``1/2 dq^T H dq + c^T dq`` of [`optik.diffik.build_qp`][optik.diffik.build_qp]
(``H = (WJ)^T WJ + mu I``, ``c = -(WJ)^T t``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optik.diffik.problem import DiffIKProblem
from optik.diffik.qp_outcome import QPOutcome, require_backend


class CvxpyStepProblem:
    """The parametrised cvxpy problem of one task structure."""

    def __init__(self, problem: DiffIKProblem) -> None:
        cp = require_backend("cvxpy", "cvxpy")
        n, rows, m_eq = problem.n, problem.jacobian.shape[0], problem.A.shape[0]
        self.dq = cp.Variable(n)
        self.jac = cp.Parameter((rows, n))
        self.target = cp.Parameter(rows)
        self.mu = cp.Parameter(nonneg=True)
        self.lb = cp.Parameter(n)
        self.ub = cp.Parameter(n)
        objective = 0.5 * cp.sum_squares(self.jac @ self.dq - self.target) + 0.5 * self.mu * cp.sum_squares(
            self.dq
        )
        cons = [self.lb <= self.dq, self.dq <= self.ub]
        self.a = self.b = None
        if m_eq:
            self.a = cp.Parameter((m_eq, n))
            self.b = cp.Parameter(m_eq)
            cons.append(self.a @ self.dq == self.b)
        self.g = self.h = None
        if problem.G.shape[0]:
            self.g = cp.Parameter(problem.G.shape)
            self.h = cp.Parameter(problem.G.shape[0])
            cons.append(self.g @ self.dq <= self.h)
        self.problem = cp.Problem(cp.Minimize(objective), cons)

    def solve(self, problem: DiffIKProblem, **settings: Any) -> QPOutcome:
        self.jac.value = problem.jacobian
        self.target.value = problem.target
        self.mu.value = problem.mu
        self.lb.value = problem.lb
        self.ub.value = problem.ub
        if self.a is not None:
            self.a.value = problem.A
            self.b.value = problem.b
        if self.g is not None:
            self.g.value = problem.G
            self.h.value = problem.h
        try:
            self.problem.solve(**settings)
        except Exception as exc:  # solver errors become a status
            return QPOutcome(None, "failed", f"cvxpy: {exc}")
        status = str(self.problem.status)
        if status in ("optimal", "optimal_inaccurate") and self.dq.value is not None:
            return QPOutcome(np.asarray(self.dq.value, dtype=float), "optimal", f"cvxpy {status}")
        return QPOutcome(None, "infeasible" if "infeasible" in status else "failed", f"cvxpy {status}")


def solve_cvxpy(problem: DiffIKProblem, **settings: Any) -> QPOutcome:
    """Solve with the cached cvxpy problem of this task structure (``settings``: ``Problem.solve``
    keyword arguments, e.g. ``solver="CLARABEL"``)."""
    key = f"cvxpy {problem.G.shape[0]}"  # the inequality rows' count is part of the problem
    cached = problem.cache.backends.get(key) if problem.cache is not None else None
    if cached is None:
        cached = CvxpyStepProblem(problem)
        if problem.cache is not None:
            problem.cache.backends[key] = cached
    return cached.solve(problem, **settings)
