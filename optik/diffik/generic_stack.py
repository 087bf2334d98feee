"""A robot-independent compiled QP stack: the first differential-IK steps on a robot never compiled.

The [`StackFunction`][optik.diffik.problem.StackFunction] of a mechanism and task structure is
built from the mechanism's symbolic model and compiled for it: tens of milliseconds of CasADi
work before the first step, then the evaluator until gcc is done. For a serial chain
(`optik.solvers.generic_chain.chain_parameters`: revolute and prismatic joints, no loops) and
frame tasks (`optik.diffik.tasks.frame_rows.FrameRowsTask`: `FrameTask`, `PositionTask`,
`OrientationTask`, ...) under the configuration, velocity and acceleration limits, this module
compiles the same function (`optik.diffik.problem.stack_casadi`) once per machine for *any* chain
of ``n`` joints and that task structure, each frame's chain ``T(q) = A_0 M_0(q_0) ... A_n``
(`optik.solvers.generic_chain.chain_pose`) being an input appended to the parameters: same
formulas, the numbers of the per-robot stack to rounding.

`stack_for` returns it while the per-robot stack is not compiled (and starts building that one
in the background); `optik.diffik.problem.stack_function` then uses the per-robot stack. The
library is keyed by a digest of the sources it is generated from, the task structure (kinds,
which tasks share a frame, rows) and ``n``; when it is missing it is built in the background
and the per-robot path answers meanwhile, as without a compiler.
"""

from __future__ import annotations

import copy
import logging
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from optik.diffik._codegen import flatten, output_bounds, split_outputs
from optik.diffik.base import Limit, Task
from optik.diffik.limits import AccelerationLimit, ConfigurationLimit, VelocityLimit
from optik.diffik.problem import StackFunction, register_first_stack, stack_casadi, task_slices
from optik.diffik.tasks.frame_rows import FrameRowsTask
from optik.mechanism import Mechanism
from optik.mechanism.mechanism import geometric_jacobian
from optik.mechanism.memo import PerMechanism
from optik.native import CCall, Library, c_source, keyed_library, source_digest
from optik.solvers.generic_chain import chain_parameters, chain_pose, n_chain_parameters

_LOG = logging.getLogger(__name__)
_SOURCES = ("diffik/generic_stack.py", "diffik/problem.py", "diffik/base.py", "diffik/_codegen.py")
_SOURCES += ("diffik/tasks/frame_rows.py", "diffik/limits/configuration.py", "diffik/limits/velocity.py")
_SOURCES += ("diffik/limits/acceleration.py", "solvers/generic_chain.py", "spatial.py", "native.py")
_LIMITS = (ConfigurationLimit, VelocityLimit, AccelerationLimit)


class ChainModel:
    """The model the generic stack is generated from: ``n`` coordinates and one symbolic chain per
    task frame (what `optik.diffik.problem.stack_casadi` and the frame tasks read of a mechanism).

    Args:
        n: number of joints.
        n_frames: number of distinct task frames (frame ``k`` is named ``k``).
    """

    def __init__(self, n: int, n_frames: int) -> None:
        self.n_q = n
        self.q_sym = ca.SX.sym("q", n)
        self.is_closed = False
        self.lower = self.upper = np.zeros(n)  # sizes of the limits' parameters only
        self.params: dict[str, Any] = {}
        self._memo: dict[object, Any] = {}
        self.chains = [ca.SX.sym(f"chain{k}", n_chain_parameters(n)) for k in range(n_frames)]

    def frame_expr(self, frame: int) -> ca.SX:
        """``T(q)`` of frame ``frame``'s chain."""
        return chain_pose(self.q_sym, self.chains[frame])

    def jacobian_expr(self, frame: int) -> ca.SX:
        """Geometric Jacobian of frame ``frame``."""
        return geometric_jacobian(self.frame_expr(frame), self.q_sym)


class _Template(FrameRowsTask):
    """A frame task of the structure (kind, frame index, rows) only, for the code generation."""

    def __init__(self, kind: str, frame: int, rows: tuple[int, ...]) -> None:
        self.rows = rows
        self.kind = kind  # type: ignore[misc]
        super().__init__()
        self.frame = frame  # type: ignore[assignment]


def _structure(tasks: Sequence[Task], limits: Sequence[Limit]) -> tuple[tuple, list] | None:
    """``(key, frames)``: the task structure with frames numbered by first use, and the frames;
    None when a task or limit is not one the generic stack models."""
    if not all(type(lim) in _LIMITS for lim in limits):
        return None
    frames: list[str | None] = []
    shape = []
    for t in tasks:
        if not isinstance(t, FrameRowsTask):
            return None
        if t.frame not in frames:
            frames.append(t.frame)
        shape.append((t.kind, frames.index(t.frame), tuple(t.rows)))
    return (tuple(shape), tuple(lim.key() for lim in limits)), frames


def _source(n: int, key: tuple, limits: Sequence[Limit]) -> str:
    shape, _ = key
    model = ChainModel(n, 1 + max(f for _, f, _ in shape))
    tasks = [_Template(kind, f, rows) for kind, f, rows in shape]
    f = stack_casadi(model, tasks, limits, None, ca.vertcat(*model.chains))  # type: ignore[arg-type]
    return c_source([flatten(f)])


class ChainStack(StackFunction):
    """The generic stack of one chain mechanism and task structure (the interface of
    `optik.diffik.problem.StackFunction`; thread-safe: buffers per thread)."""

    def __init__(self, chains: list[np.ndarray], n: int, key: tuple, lib: Library) -> None:
        self.chains = chains
        rows = sum(len(r) for _, _, r in key[0])
        self.library = lib
        self.n_closure = 0
        self.dims = [len(r) for _, _, r in key[0]]
        self.slices, self.starts = task_slices(self.dims)
        shapes = [
            (n, n),
            (n, 1),
            (n, 1),
            (n, 1),
            (0, n),
            (0, 1),
            (rows, n),
            (rows, 1),
            (rows, 1),
            (0, 1),
            (1, 1),
        ]
        self._bounds = output_bounds(shapes)
        self._local = threading.local()

    def __call__(
        self, q: np.ndarray, p: list[np.ndarray], dt: float, v_prev: np.ndarray
    ) -> tuple[np.ndarray, ...]:
        """As `optik.diffik.problem.StackFunction.__call__` (the chains appended to ``p``)."""
        x = np.concatenate([q, *p, *self.chains, np.array([dt]), v_prev])
        call = getattr(self._local, "call", None)
        if call is None:
            self._local.x, self._local.out = np.zeros(x.shape[0]), np.zeros(self._bounds[-1][1])
            call = self._local.call = CCall(
                self.library.get(), "diffik_stack", [self._local.x], [self._local.out]
            )  # type: ignore[arg-type]
        self._local.x[:] = x
        call()
        return split_outputs(self._local.out.copy(), self._bounds)


_LIBRARIES: dict[tuple, Library | None] = {}
_LIBRARIES_LOCK = threading.Lock()
_STACKS: PerMechanism[dict[tuple, ChainStack | None]] = PerMechanism()


def _structure_only(limit: Limit) -> Limit:
    """A copy of ``limit`` for the code generation: its own parameter cache (which the call's
    mechanism keeps alive and other threads read), empty."""
    out = copy.copy(limit)
    out._cached = None
    return out


def _library(n: int, key: tuple, limits: Sequence[Limit]) -> Library | None:
    """The generic library of ``n`` joints and a task structure (one per process)."""
    found = _LIBRARIES.get((n, key), False)
    if found is False:
        with _LIBRARIES_LOCK:
            found = _LIBRARIES.get((n, key), False)
            if found is False:
                lims = [_structure_only(lim) for lim in limits]
                try:
                    digest = source_digest(_SOURCES, n, key)
                except OSError as exc:  # a partial install: the robot's own stack answers
                    _LOG.warning("optik: no generic QP stack, its sources cannot be read: %s", exc)
                    digest = None
                found = _LIBRARIES[(n, key)] = (
                    None
                    if digest is None
                    else keyed_library(f"optik_diffik_chain{n}", digest, lambda: _source(n, key, lims))
                )
    return found  # type: ignore[return-value]


def stack_for(m: Mechanism, tasks: Sequence[Task], limits: Sequence[Limit]) -> ChainStack | None:
    """The generic stack of ``m`` and the task structure when it applies and its library is
    loaded, else None (see the module docstring)."""
    found = _structure(tasks, limits)
    if found is None or m.is_closed:
        return None
    key, frames = found
    per = _STACKS.setdefault(m, {})
    if key not in per:
        chains = [chain_parameters(m, f) for f in frames]
        lib = _library(m.n_q, key, limits) if all(c is not None for c in chains) else None
        per[key] = None if lib is None else ChainStack(chains, m.n_q, key, lib)  # type: ignore[arg-type]
    stack = per[key]
    if stack is None or stack.library.state != "ready":
        return None
    return stack


def machine_files(
    m: Mechanism, tasks: Sequence[Task], limits: Sequence[Limit], timeout: float | None = None
) -> list[Path]:
    """Build (or load) the generic stack of ``m``'s joint count and the task structure, wait for
    it (at most ``timeout`` seconds) and return its cache files (`optik.native.Library.files`;
    none when it does not apply or is not built)."""
    found = _structure(tasks, limits)
    if found is None:
        return []
    lib = _library(m.n_q, found[0], limits)
    if lib is None or lib.wait(timeout) is None:
        return []
    return lib.files()


register_first_stack(stack_for)
