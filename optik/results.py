"""Result records of the solvers (kept in the problems layer so every solver shares them)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, overload

import numpy as np


@dataclass
class IKResult:
    """Outcome of one inverse-kinematics solve.

    Attributes:
        q: the best coordinates found (the closest solution when ``success`` is False).
        success: every tolerance met: position, orientation, closure, limits.
        position_error: Euclidean position error of the task frame (m).
        orientation_error: geodesic orientation error (rad); 0 for position-only tasks.
        closure_error: max-norm of the loop-closure residual (0 for open chains).
        limits_ok: ``lower <= q <= upper`` holds exactly.
        iterations: solver iterations (summed over restarts).
        solve_time: wall time of the call (s), failures included; for a collision-aware solve
            the exact check of the answer included (not the full search for the nearest pair
            that a clear answer's ``min_distance`` makes when first read).
        method: the method that produced ``q`` (``"lm"``, ``"nlp"``, ``"closed_form"``, ...).
        status: short machine-readable status (``"solved"``, ``"unreachable"``, ``"time_limit"``,
            ``"outside_limits"``, ``"not_found"``: a closed form not certified complete found no
            branch within the limits, so it does not say the target is out of reach...).
        message: human-readable explanation, in particular why a solve failed.
        restarts: number of restarts used.
        extra: method-specific details (e.g. ``"setup_time"``).
        frame_errors: ``{frame: (position error, orientation error)}`` of a several-target solve
            (`optik.solve_ik` with a ``{frame: target}`` dict), each from that frame's own FK;
            ``position_error`` and ``orientation_error`` are then the largest of them. Empty for
            one target.
        min_distance: for a collision-aware solve (``world=`` or ``self_collision=True``), the
            exact smallest signed distance of ``q`` to the world and to itself (m); None otherwise.
        collision_pair: the closest pair at ``q`` (link, link or world object) of such a solve.
    """

    q: np.ndarray
    success: bool
    position_error: float
    orientation_error: float
    closure_error: float
    limits_ok: bool
    iterations: int
    solve_time: float
    method: str
    status: str
    message: str = ""
    restarts: int = 0
    extra: dict = field(default_factory=dict)
    frame_errors: dict[str, tuple[float, float]] = field(default_factory=dict)
    min_distance: float | None = None
    collision_pair: tuple[str, str] | None = None


class LazyDistanceResult(IKResult):
    """An `IKResult` whose ``min_distance`` and ``collision_pair`` are computed on their first
    read (or before a first write), by ``nearest() -> (min_distance, collision_pair)``: a
    collision-aware solve that only decided its answer is clear (`optik.collision.check.search`
    with ``stop``) leaves the full search for the exact nearest pair to a caller that reads it.

    The two fields are settled once, under a lock: threads that read them at once see the same
    values, and none reads them before they are made. ``dataclasses.replace`` works as on an
    `IKResult` (the copy's fields are settled; it has no function left to call).

    Args:
        res: the result, every field but those two final (copied, not called again). ``None``
            when the fields come as keywords (``dataclasses.replace``).
        nearest: the function of the two fields, called at most once.
        **fields: every `IKResult` field, when ``res`` is ``None``.
    """

    def __init__(
        self,
        res: IKResult | None = None,
        nearest: Callable[[], tuple[float, tuple[str, str] | None]] | None = None,
        **fields: Any,
    ) -> None:
        self._nearest: Callable[[], tuple[float, tuple[str, str] | None]] | None = None
        if res is None:
            IKResult.__init__(self, **fields)
            return
        self.__dict__.update(vars(res))
        self._nearest = nearest

    def _settle(self) -> dict[str, Any]:
        """The instance dict, the two fields computed first if they are not yet."""
        if self._nearest is not None:
            with _SETTLE_LOCK:
                nearest = self._nearest
                if nearest is not None:  # another thread may have settled them meanwhile
                    self.__dict__["min_distance"], self.__dict__["collision_pair"] = nearest()
                    self._nearest = None
        return self.__dict__

    def __getstate__(self) -> dict[str, Any]:
        """The state of a copy or pickle: the two fields computed (the function is not kept)."""
        return {**self._settle(), "_nearest": None}

    def _set_distance(self, value: float | None) -> None:
        self._settle()["min_distance"] = value

    def _set_pair(self, value: tuple[str, str] | None) -> None:
        self._settle()["collision_pair"] = value

    min_distance = property(lambda self: self._settle()["min_distance"], _set_distance)  # type: ignore[assignment]
    collision_pair = property(lambda self: self._settle()["collision_pair"], _set_pair)  # type: ignore[assignment]


_SETTLE_LOCK = threading.RLock()
"""Held while a `LazyDistanceResult` computes its two fields (re-entrant: a ``nearest`` that
reads another result's fields does not wait on itself)."""


@dataclass
class FKResult:
    """Outcome of one forward-kinematics solve of a (possibly closed) mechanism.

    Attributes:
        pose: 4x4 pose of the end-effector frame.
        q: all coordinates, passive included.
        success: the closure residual is within tolerance and the limits hold.
        residual: max-norm of the loop-closure residual.
        solve_time: wall time (s).
        condition_number: condition number of the closure Jacobian with respect to the passive
            coordinates (large near a singularity of the assembly).
        message: explanation, in particular why a solve failed.
        limits_ok: ``lower <= q <= upper`` holds exactly (angles shifted by 2 pi into the limits
            first).
        limits_violated: names of the coordinates outside their limits (actuated ones included).
    """

    pose: np.ndarray
    q: np.ndarray
    success: bool
    residual: float
    solve_time: float
    condition_number: float = float("nan")
    message: str = ""
    extra: dict = field(default_factory=dict)
    limits_ok: bool = True
    limits_violated: tuple[str, ...] = ()


class FKModes(list):
    """The assembly modes returned by [`solve_fk_all`][optik.solve_fk_all]: a list of
    [`FKResult`][optik.FKResult], plus what was left out and why.

    Attributes:
        dropped: modes that close but were left out because they violate a joint limit
            (``within_limits=True``), each an [`FKResult`][optik.FKResult] with ``limits_ok=False``.
        message: why the list is what it is: empty inputs that cannot assemble, modes dropped
            (how many, which coordinates), actuated values outside their limits; ``""`` when
            every mode found is in the list.
    """

    def __init__(self, modes: list[FKResult] = (), dropped: list[FKResult] = (), message: str = "") -> None:
        super().__init__(modes)
        self.dropped = list(dropped)
        self.message = message

    def __repr__(self) -> str:
        return f"FKModes({list.__repr__(self)}, dropped={len(self.dropped)}, message={self.message!r})"


_new = object.__new__


class IKSolutions(Sequence[IKResult]):
    """The solutions that ``optik.solve_ik_all`` returns: a sequence of ``IKResult``, one per
    distinct solution (indexing, slicing, iteration, ``len``), with what was left out and why.

    The compiled closed forms return their solutions as arrays (`from_arrays`): `q` is then the
    ``(K, n)`` array itself and each ``IKResult`` is made when it is first read.

    Attributes:
        outside_limits: configurations that solve the target but lie outside the joint limits
            (not in the list).
        failed_check: candidates dropped because they did not pass the FK check, even after
            polishing (not in the list).
        in_collision: with ``world=`` or ``self_collision=True``, the solutions the exact check
            finds closer than the margin (not in the list), each an ``IKResult`` with
            ``success=False``, status ``"in_collision"``, its ``min_distance`` and ``collision_pair``.
        method: how the solutions were found (``"closed_form"`` or the numerical method).
        uncertified_reason: why the solutions are not certified to be every solution: the
            numerical multi-start (never certified), the 1-D search of
            `optik.closed_form.search_1d`, a failed count check of the general 6R solver; ""
            only for a closed form that proves completeness (`certified`).
        message: a sentence summarizing the counts.
    """

    __slots__ = (
        "_arrays", "_n_q", "_outside", "_results", "failed_check", "in_collision", "method",
        "uncertified_reason",
    )  # fmt: skip

    def __init__(
        self,
        results: Iterable[IKResult] = (),
        outside_limits: Iterable[np.ndarray] | None = None,
        failed_check: int = 0,
        method: str = "",
        uncertified_reason: str = "",
        n_q: int = 0,
    ) -> None:
        """Args: the attributes of the same names; ``results`` the solutions, ``n_q`` the
        mechanism's coordinate count (the width of `q` when there is no solution)."""
        self._results: list[IKResult] | None = list(results)
        self._n_q = n_q
        self._arrays: tuple[np.ndarray, np.ndarray, float] | None = None
        self._outside: Any = outside_limits if outside_limits is not None else ()
        self.failed_check = failed_check
        self.in_collision: list[IKResult] = []
        self.method = method
        self.uncertified_reason = uncertified_reason

    @classmethod
    def from_arrays(
        cls, q: np.ndarray, errors: np.ndarray, outside_limits: np.ndarray, method: str, solve_time: float
    ) -> IKSolutions:
        """Successful solutions given as arrays: ``q (K, n)``, their ``(position, orientation)``
        errors ``(K, 2)`` (no loop closure, every limit met: the results' ``closure_error`` is 0
        and ``limits_ok`` True), ``outside_limits (L, n)``, the method and the call's wall time."""
        out = _new(cls)
        out._results = None
        out._arrays = (q, errors, solve_time)
        out._n_q = q.shape[1]
        out._outside = outside_limits
        out.failed_check = 0
        out.in_collision = []
        out.method = method
        out.uncertified_reason = ""
        return out

    @property
    def q(self) -> np.ndarray:
        """The solutions' coordinates as one ``(K, n)`` array, in order (``(0, n)`` when there
        are none)."""
        if self._arrays is not None:
            return self._arrays[0]
        rows = [r.q for r in self._list()]
        return np.array(rows) if rows else np.zeros((0, self._n_q))

    @property
    def certified(self) -> bool:
        """True only when a closed form proves that these are every solution: ``method`` is
        ``"closed_form"`` and there is no `uncertified_reason`."""
        return self.method == "closed_form" and not self.uncertified_reason

    @property
    def outside_limits(self) -> list[np.ndarray]:
        """Solutions of the target outside the joint limits (not in the sequence)."""
        if not isinstance(self._outside, list):
            self._outside = list(self._outside)
        return self._outside

    def _list(self) -> list[IKResult]:
        if self._results is None:
            q, errors, elapsed = self._arrays  # type: ignore[misc]
            self._results = [
                IKResult(row, True, e[0], e[1], 0.0, True, 0, elapsed, self.method, "solved")
                for row, e in zip(q, errors.tolist(), strict=True)
            ]
        return self._results

    def __len__(self) -> int:
        return len(self._arrays[0]) if self._results is None else len(self._results)  # type: ignore[index]

    @overload
    def __getitem__(self, index: int) -> IKResult: ...

    @overload
    def __getitem__(self, index: slice) -> list[IKResult]: ...

    def __getitem__(self, index: int | slice) -> IKResult | list[IKResult]:
        return self._list()[index]

    def __iter__(self) -> Iterator[IKResult]:
        return iter(self._list())

    def __eq__(self, other: object) -> bool:
        """Equal to a sequence of the same results in the same order (a list, another
        ``IKSolutions``)."""
        if isinstance(other, (IKSolutions, list, tuple)):
            return self._list() == list(other)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]  # mutable, like a list

    def __repr__(self) -> str:
        outside = len(self.outside_limits)
        return f"IKSolutions({self._list()!r}, outside_limits={outside}, method={self.method!r})"

    @property
    def message(self) -> str:
        """E.g. ``"6 solutions by closed_form; 2 outside the joint limits left out"``."""
        text = f"{len(self)} solution(s) by {self.method or 'no method'}"
        if len(self.outside_limits):
            text += f"; {len(self.outside_limits)} outside the joint limits left out"
        if self.failed_check:
            text += f"; {self.failed_check} candidate(s) failing the FK check dropped"
        if self.in_collision:
            text += f"; {len(self.in_collision)} in collision left out"
        if not self.certified:
            text += f"; not certified complete ({self.uncertified_reason})"
        return text


@dataclass(eq=False)
class IKSolutionsBatch(Sequence[IKSolutions]):
    """Every solution of many targets (``optik.solve_ik_all_batch``) as arrays: no Python
    object per solution. Target ``i`` holds rows ``offsets[i]:offsets[i + 1]`` of `q` (nearest
    its start first); ``batch[i]`` is its `IKSolutions` (made when read).

    Attributes:
        q: ``(K, n)`` the solutions within the joint limits, target after target.
        errors: ``(K, 2)`` their position and orientation errors (every one within the
            tolerances: each passed the FK check).
        counts: ``(M,)`` the number of solutions of each target.
        outside_limits: ``(L, n)`` the solutions outside the joint limits, target after target.
        outside_counts: ``(M,)`` how many of those each target has.
        certified: ``(M,)`` True where a closed form proves the target's solutions complete.
        solve_time: wall time of the whole call (s).
        general: the targets answered one by one by ``optik.solve_ik_all`` (a candidate to
            polish, two close candidates, no compiled driver), ``{index: its IKSolutions}``;
            their rows are in the arrays too.
    """

    q: np.ndarray
    errors: np.ndarray
    counts: np.ndarray
    outside_limits: np.ndarray
    outside_counts: np.ndarray
    certified: np.ndarray
    solve_time: float
    general: dict[int, IKSolutions] = field(default_factory=dict)

    @cached_property
    def offsets(self) -> np.ndarray:
        """``(M + 1,)``: target ``i``'s solutions are rows ``offsets[i]:offsets[i + 1]`` of `q`."""
        return np.concatenate(([0], np.cumsum(self.counts)))

    @cached_property
    def outside_offsets(self) -> np.ndarray:
        """``(M + 1,)``: target ``i``'s solutions outside the limits are rows
        ``outside_offsets[i]:outside_offsets[i + 1]`` of `outside_limits`."""
        return np.concatenate(([0], np.cumsum(self.outside_counts)))

    @property
    def target(self) -> np.ndarray:
        """``(K,)``: the index of each solution's target."""
        return np.repeat(np.arange(len(self.counts)), self.counts)

    def __len__(self) -> int:
        return len(self.counts)

    @overload
    def __getitem__(self, index: int) -> IKSolutions: ...

    @overload
    def __getitem__(self, index: slice) -> list[IKSolutions]: ...

    def __getitem__(self, index: int | slice) -> IKSolutions | list[IKSolutions]:
        if isinstance(index, slice):
            return [self[i] for i in range(len(self))[index]]
        i = range(len(self))[index]  # negative indices; IndexError past the end
        if i in self.general:
            return self.general[i]
        a, b = self.offsets[i : i + 2].tolist()
        c, d = self.outside_offsets[i : i + 2].tolist()
        outside = self.outside_limits[c:d]
        return IKSolutions.from_arrays(self.q[a:b], self.errors[a:b], outside, "closed_form", self.solve_time)
