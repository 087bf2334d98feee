"""`BatchResult`: the outcomes of many IK solves as arrays, in input order."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from optik.errors import require_extra
from optik.results import IKResult

PER_TARGET = (
    "q",
    "success",
    "position_error",
    "orientation_error",
    "closure_error",
    "iterations",
    "restarts",
    "solve_time",
    "status",
    "seed",
)
"""The per-target array fields of `BatchResult`, in table order."""


@dataclass
class BatchResult:
    """Outcomes of `optik.solve_ik_batch`, one row per target, in input order.

    Attributes:
        q: answers ``(N, n)`` (the closest configuration found where ``success`` is False),
            wrapped and within the limits as `optik.solve_ik` returns them.
        success: every tolerance met and the limits satisfied.
        position_error: Euclidean position error (m).
        orientation_error: geodesic orientation error (rad).
        closure_error: max-norm of the loop-closure residual.
        iterations: solver iterations per target (summed over restarts).
        restarts: restarts per target.
        solve_time: seconds per target, measured where it was solved.
        status: ``"solved"``, ``"not_converged"``, ``"time_limit"``, ``"max_restarts"``...
        seed: the seed of each target's solve: ``solve_ik(m, targets[i], q0[i], seed=seed[i])``
            gives the same answer.
        method: the IK method.
        base_seed: the batch's seed (None was 0; None here when the seeds were given per target).
        wall_time: seconds of the whole batch call, `compile_time` included.
        compile_time: seconds of it spent building and compiling the code every chunk runs
            (the LM kernel, a closed form's driver) before the first chunk; about zero once it
            is in memory or in the disk cache, zero on a Dask cluster (the workers compile).
        workers: threads (local) or Dask workers that solved it.
        coordinate_names: the mechanism's coordinate names, one per column of ``q`` (the
            columns of `to_dataframe`).
    """

    q: np.ndarray
    success: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    closure_error: np.ndarray
    iterations: np.ndarray
    restarts: np.ndarray
    solve_time: np.ndarray
    status: np.ndarray
    seed: np.ndarray
    method: str = "lm"
    base_seed: int | None = 0
    wall_time: float = 0.0
    compile_time: float = 0.0
    workers: int = 1
    coordinate_names: tuple[str, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.success)

    @property
    def success_rate(self) -> float:
        """Fraction of targets solved (0 for an empty batch)."""
        return float(np.mean(self.success)) if len(self) else 0.0

    @property
    def throughput(self) -> float:
        """Targets per second of wall time, the compile excluded: ``len / (wall_time -
        compile_time)`` (the compile of a first call is reported apart, in `compile_time`)."""
        solving = self.wall_time - self.compile_time
        return len(self) / solving if solving > 0 else float("inf")

    def result(self, i: int) -> IKResult:
        """Row ``i`` as an `optik.IKResult`."""
        ok = bool(self.success[i])
        return IKResult(
            q=self.q[i].copy(),
            success=ok,
            position_error=float(self.position_error[i]),
            orientation_error=float(self.orientation_error[i]),
            closure_error=float(self.closure_error[i]),
            limits_ok=True,
            iterations=int(self.iterations[i]),
            solve_time=float(self.solve_time[i]),
            method=self.method,
            status=str(self.status[i]),
            message="" if ok else f"not solved: {self.status[i]}",
            restarts=int(self.restarts[i]),
        )

    def records(self) -> list[dict[str, Any]]:
        """One dict per target: the fields of `PER_TARGET` as plain Python values
        (``q`` as a list)."""
        columns = {name: getattr(self, name).tolist() for name in PER_TARGET}
        return [dict(zip(columns, row, strict=True)) for row in zip(*columns.values(), strict=True)]

    def to_dataframe(self) -> Any:
        """A pandas ``DataFrame``, one row per target, with ``q`` split into one column per
        coordinate, named after the mechanism's coordinates (`coordinate_names`; ``q[0]``,
        ``q[1]``, ... for a result built without them).

        Raises:
            MissingExtraError: pandas is not installed (``pip install "optik[pandas]"``).
        """
        pd = require_extra("pandas", "pandas", "BatchResult.to_dataframe")
        names = self.coordinate_names or tuple(f"q[{j}]" for j in range(self.q.shape[1]))
        data: dict[str, Any] = {name: self.q[:, j] for j, name in enumerate(names)}
        data.update({name: getattr(self, name) for name in PER_TARGET if name != "q"})
        return pd.DataFrame(data)

    @classmethod
    def concatenate(cls, parts: Sequence[BatchResult], **meta: Any) -> BatchResult:
        """The rows of ``parts`` one after another; ``meta`` sets the non-array fields."""
        if not parts:
            raise ValueError("concatenate needs at least one part")
        arrays = {name: np.concatenate([getattr(p, name) for p in parts]) for name in PER_TARGET}
        scalars = {f.name: getattr(parts[0], f.name) for f in fields(cls) if f.name not in PER_TARGET}
        return cls(**arrays, **{**scalars, **meta})
