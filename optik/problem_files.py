"""Benchmark problem files: one TOML file per mechanism, validated, then built and sampled.

A problem file names a catalog constructor and its parameters, optional joint-limit overrides,
how to draw targets, the success tolerances and which solvers and peers apply. Files are parsed
with `tomllib` (``tomli`` on Python 3.10): data only, no code is executed. Every error
names the file, the key and what is wrong, e.g.
``.../problems/five_bar.toml: targets.n: expected an integer >= 1, got 0``.

The shipped files live in the top-level folder ``problems/`` of the repository (the one copy),
installed as the package ``optik.problems`` (a ``package_dir`` mapping in ``setup.py``) and found
through `importlib.resources` as `PROBLEM_DIR`, so that a wheel install,
an editable install and a source tree on ``PYTHONPATH`` all see them; any other directory can
be given instead (``optik --problems-dir DIR``), and any file by path. Schema (every table but
``[mechanism]`` optional):

```toml
[problem]
description = "..."          # required, one line
name = "five_bar"            # default: the file name without .toml
default = true               # part of the default set of `optik bench`

[mechanism]
constructor = "five_bar"     # a function of optik.catalog; or instead of it:
# mjcf = "models/ant.xml"    # a MuJoCo model (relative to this file), Mechanism.from_mjcf
task = "position2d"          # default: the mechanism's own task
urdf = "panda"               # shipped URDF (optik.catalog.URDF_CHAINS) for the peers
[mechanism.params]           # keyword arguments of the constructor
lengths = [1.0, 1.0, 1.2, 1.2]

[limits]                     # radians / metres, one value per coordinate
lower = [...]
upper = [...]

[targets]
n = 200                      # targets of a full run
quick_n = 25                 # targets of `optik bench --quick`
seed = 0
sampling = "auto"            # "joint", "actuated", "pose" or "auto"
pose_center = [...]          # "pose": (x, y, phi) planar, (x, y, z, roll, pitch, yaw) spatial
pose_half_range = [...]

[tolerances]                 # the default success tolerances
position = 1e-6
orientation = 1e-6
closure = 1e-9

[solvers]
methods = ["closed_form", "lm", "nlp", "dls", "qp"]   # default: every registered method
peers = ["trac_ik", "pink", "ikpy"]                    # default: none
time_limit = 0.1             # seconds per IK call
quick_time_limit = 0.05

[world.table]                # obstacles, one sub-table per object (World.from_table): shown by
box = [1.0, 1.2, 0.04]       # `optik view`, avoided by its gizmo's IK
xyz = [0.5, 0.0, -0.03]

[path]                       # a tool path for `optik path` (Problem.path_poses, optik.path.shapes)
kind = "line"                # "line", "arc", "polyline" or "waypoints"
start_q = [...]              # first pose = FK(start_q) (line, arc, polyline)
end = [0.0, 0.2, 0.0]        # line: offset of the end; arc: center, axis, angle (deg), turn_tool;
n = 200                      # polyline: points (offsets); waypoints: [x, y, z, roll, pitch, yaw] rows
dt = 0.02                    # s between samples; and plan_path's free_axis, axis_step (deg),
                             # position_tolerance, max_deviation, self_motion_joint,
                             # self_motion_samples, smooth
```

Target sampling (the benchmark method): the reference configuration ``q`` is drawn so
that it satisfies the limits and the loop closures, and the target is ``T = FK(q)``:

* ``joint`` (open chains): ``q ~ U(lower, upper)``.
* ``actuated`` (closed chains): actuated coordinates ``a ~ U(lower_a, upper_a)``, assembled by
  the closed-form FK (one of its assembly modes within limits, drawn at random) or by
  [`optik.solve_fk`][optik.solve_fk]; draws that do not assemble are discarded.
* ``pose`` (closed chains with a closed-form IK): a pose drawn uniformly in the box
  ``center +- half_range``, solved by the closed-form IK (one branch within limits, at random);
  unreachable draws are discarded.
* ``auto``: ``joint`` for open chains; for closed chains ``pose`` when the file gives a pose
  box and a closed-form IK exists (the choice for mechanisms with more actuators than degrees
  of freedom, like the doggy, or with an expensive FK, like the 6-6 Stewart-Gough platform),
  else ``actuated``.
"""

from __future__ import annotations

import argparse
import inspect
import os
import sys
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from optik import catalog, closed_form, spatial
from optik.checks import as_name, as_rng
from optik.collision.world import World
from optik.errors import InvalidArgumentError, OptikError, ProblemFileError, SolverUnavailableError
from optik.mechanism import TASK_ROWS, Mechanism
from optik.solvers import Tolerances

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = [
    "PEERS",
    "PROBLEM_DIR",
    "SAMPLING",
    "Problem",
    "TargetSet",
    "add_source_arguments",
    "assemble",
    "constructors",
    "default_problems",
    "find_problem",
    "list_problems",
    "load_problem",
    "load_source",
    "problem_summary",
]

PROBLEM_DIR = Path(str(resources.files("optik.problems")))
"""The shipped problem files: the package ``optik.problems`` (the folder ``problems/`` of the repository)."""

PEERS = ("trac_ik", "rtb_lm", "pink", "ikpy")
"""Peer libraries a problem may ask for (adapters in [`optik.harness.peers`][optik.harness.peers])."""

SAMPLING = ("auto", "joint", "actuated", "pose")
"""Target sampling modes."""

PATH_KINDS = ("line", "arc", "polyline", "waypoints")
"""Tool paths of the ``[path]`` table (`optik.path.shapes`)."""

DEFAULT_TIME_LIMIT = 0.1
"""Seconds per IK call of a full run when the file does not say."""

DEFAULT_QUICK_TIME_LIMIT = 0.05
"""Seconds per IK call of ``--quick`` when the file does not say."""

MAX_DRAWS_PER_TARGET = 50
"""Draws allowed per requested target before sampling gives up (closed chains)."""

MAX_TARGETS = 1_000_000
"""Most targets one problem samples (``targets.n``, ``quick_n`` and the ``n`` of
[`Problem.sample_targets`][optik.problem_files.Problem.sample_targets]): memory stays bounded."""

MAX_FILE_BYTES = 1 << 20
"""Largest problem file read (1 MiB; the shipped ones are under 2 kB)."""


# ---------------------------------------------------------------------------- schema
@dataclass(frozen=True)
class _Key:
    """One key of the schema: a parser ``value -> value`` raising ``ValueError(what is wrong)``."""

    parse: Callable[[Any], Any]
    required: bool = False


def _number(v: Any) -> float:
    # TOML integers are unbounded: one beyond the float range is not a finite number either
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not abs(v) <= sys.float_info.max:
        raise ValueError(f"expected a finite number, got {v!r:.40}")
    return float(v)


def _positive(v: Any) -> float:
    x = _number(v)
    if x <= 0:
        raise ValueError(f"expected a number > 0, got {v!r}")
    return x


def _count(minimum: int, maximum: int | None = None) -> Callable[[Any], int]:
    def parse(v: Any) -> int:
        too_big = maximum is not None and isinstance(v, int) and v > maximum
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum or too_big:
            bound = f"an integer >= {minimum}" + ("" if maximum is None else f" and <= {maximum}")
            raise ValueError(f"expected {bound}, got {v!r}")
        return v

    return parse


def _string(v: Any) -> str:
    if not isinstance(v, str) or not v.strip():
        raise ValueError(f"expected a non-empty string, got {v!r}")
    return v


def _boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise ValueError(f"expected true or false, got {v!r}")
    return v


def _numbers(v: Any) -> tuple[float, ...]:
    if not isinstance(v, list) or not v:
        raise ValueError(f"expected a non-empty array of numbers, got {v!r}")
    return tuple(_number(x) for x in v)


def _strings(v: Any) -> tuple[str, ...]:
    if not isinstance(v, list):
        raise ValueError(f"expected an array of strings, got {v!r}")
    return tuple(_string(x) for x in v)


def _one_of(options: tuple[str, ...]) -> Callable[[Any], str]:
    def parse(v: Any) -> str:
        if v not in options:
            raise ValueError(f"expected one of {list(options)}, got {v!r}")
        return v

    return parse


def _subset(options: tuple[str, ...]) -> Callable[[Any], tuple[str, ...]]:
    def parse(v: Any) -> tuple[str, ...]:
        items = _strings(v)
        bad = [x for x in items if x not in options]
        if bad:
            raise ValueError(f"unknown {bad}; expected names among {list(options)}")
        return items

    return parse


def _rows(width: int) -> Callable[[Any], tuple[tuple[float, ...], ...]]:
    def parse(v: Any) -> tuple[tuple[float, ...], ...]:
        if not isinstance(v, list) or not v:
            raise ValueError(f"expected a non-empty array of {width}-number arrays, got {v!r}")
        rows = tuple(_numbers(r) for r in v)
        if any(len(r) != width for r in rows):
            raise ValueError(f"expected arrays of {width} numbers each, got {v!r}")
        return rows

    return parse


def _table(v: Any) -> dict[str, Any]:
    if not isinstance(v, dict):
        raise ValueError(f"expected a table, got {v!r}")
    return v


SCHEMA: dict[str, dict[str, _Key]] = {
    "problem": {
        "description": _Key(_string, required=True),
        "name": _Key(_string),
        "default": _Key(_boolean),
    },
    "mechanism": {
        "constructor": _Key(_string),
        "mjcf": _Key(_string),
        "params": _Key(_table),
        "task": _Key(_one_of(tuple(TASK_ROWS))),
        "urdf": _Key(_string),
    },
    "limits": {"lower": _Key(_numbers), "upper": _Key(_numbers)},
    "targets": {
        "n": _Key(_count(1, MAX_TARGETS)),
        "quick_n": _Key(_count(1, MAX_TARGETS)),
        "seed": _Key(_count(0)),
        "sampling": _Key(_one_of(SAMPLING)),
        "pose_center": _Key(_numbers),
        "pose_half_range": _Key(_numbers),
    },
    "tolerances": {"position": _Key(_positive), "orientation": _Key(_positive), "closure": _Key(_positive)},
    "solvers": {
        "methods": _Key(_strings),
        "peers": _Key(_subset(PEERS)),
        "time_limit": _Key(_positive),
        "quick_time_limit": _Key(_positive),
    },
    "path": {
        "kind": _Key(_one_of(PATH_KINDS), required=True),
        "start_q": _Key(_numbers),
        "n": _Key(_count(2, MAX_TARGETS)),
        "end": _Key(_numbers),
        "center": _Key(_numbers),
        "axis": _Key(_numbers),
        "angle": _Key(_number),
        "turn_tool": _Key(_boolean),
        "points": _Key(_rows(3)),
        "waypoints": _Key(_rows(6)),
        "dt": _Key(_positive),
        "free_axis": _Key(_one_of(("x", "y", "z"))),
        "axis_step": _Key(_positive),
        "position_tolerance": _Key(_positive),
        "max_deviation": _Key(_positive),
        "self_motion_joint": _Key(_string),
        "self_motion_samples": _Key(_count(2, 10_000)),
        "smooth": _Key(_boolean),
    },
}
"""Tables, their keys and parsers; ``[problem]`` and ``[mechanism]`` are required tables."""

REQUIRED_TABLES = ("problem", "mechanism")


def _validate(path: Path, data: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Check every table and key against [`SCHEMA`][optik.problem_files.SCHEMA]; return the parsed values."""
    out: dict[str, dict[str, Any]] = {}
    for table in data:
        if table not in SCHEMA and table != "world":  # [world] is read by World.from_table
            raise ProblemFileError(
                f"{path}: [{table}]: unknown table; known tables: {sorted([*SCHEMA, 'world'])}"
            )
    for table, keys in SCHEMA.items():
        if table not in data:
            if table in REQUIRED_TABLES:
                raise ProblemFileError(f"{path}: [{table}]: missing required table")
            out[table] = {}
            continue
        body = data[table]
        if not isinstance(body, dict):
            raise ProblemFileError(f"{path}: {table}: expected a table [{table}], got {body!r}")
        parsed: dict[str, Any] = {}
        for key, value in body.items():
            if key not in keys:
                raise ProblemFileError(f"{path}: {table}.{key}: unknown key; known keys: {sorted(keys)}")
            try:
                parsed[key] = keys[key].parse(value)
            except ValueError as exc:
                raise ProblemFileError(f"{path}: {table}.{key}: {exc}") from None
        for key, spec in keys.items():
            if spec.required and key not in parsed:
                raise ProblemFileError(f"{path}: {table}.{key}: missing required key")
        out[table] = parsed
    return out


# ---------------------------------------------------------------------------- problem
@dataclass(frozen=True)
class TargetSet:
    """Targets of one benchmark run.

    Attributes:
        q: ``(n, n_q)`` reference configurations (within limits, closures satisfied).
        poses: ``(n, 4, 4)`` targets ``FK(q)`` of the end-effector frame.
        task: task space the targets are meant for.
        sampling: the sampling mode used.
        draws: random draws made (``> n`` when some draws did not assemble / were unreachable).
    """

    q: np.ndarray
    poses: np.ndarray
    task: str
    sampling: str
    draws: int

    def __len__(self) -> int:
        return len(self.q)


def assemble(
    m: Mechanism, actuated: np.ndarray, numerical: bool = False, time_limit: float = 0.1
) -> list[np.ndarray]:
    """Configurations of a closed chain for given actuated values, within limits.

    Every assembly mode of the closed-form FK when one is registered (and ``numerical`` is
    False), else the one mode [`optik.solve_fk`][optik.solve_fk] finds from the mid-limit configuration
    (``[]`` when the inputs do not assemble; ``time_limit`` seconds bound that search).

    Raises:
        SolverUnavailableError: neither a closed-form FK nor ``optik.solve_fk`` exists.
    """
    if closed_form.has_fk(m) and not numerical:
        return closed_form.fk(m, actuated)
    import optik

    solve_fk = getattr(optik, "solve_fk", None)
    if solve_fk is None:
        if closed_form.has_fk(m):
            return closed_form.fk(m, actuated)
        raise SolverUnavailableError(
            f"{m.name!r} is a closed chain without a closed-form FK and optik.solve_fk is not available"
        )
    res = solve_fk(m, actuated, time_limit=time_limit)
    return [np.asarray(res.q, dtype=float)] if res.success and m.within_limits(res.q) else []


@dataclass(frozen=True)
class Problem:
    """A validated problem file (see the module docstring for the schema).

    Attributes:
        name: problem name (file name without ``.toml`` unless given).
        path: the file.
        description: one line.
        default: part of the default set of ``optik bench``.
        constructor: name of the [`optik.catalog`][optik.catalog] function (``"mjcf"`` for an
            MJCF model).
        params: its keyword arguments.
        task: task space override (None: the mechanism's task).
        urdf: shipped URDF robot name for the peers (None: no peers can run).
        lower, upper: joint-limit overrides (None: the constructor's limits).
        n, quick_n: numbers of targets (full run, ``--quick``).
        seed: target seed.
        sampling: sampling mode (see [`SAMPLING`][optik.problem_files.SAMPLING]).
        pose_center, pose_half_range: the pose box of ``sampling = "pose"``.
        tolerances: success tolerances.
        methods: IK methods to run (None: every registered method that applies).
        peers: peer libraries to run.
        time_limit, quick_time_limit: seconds per IK call.
        path_table: the parsed ``[path]`` table ({} without one; `path_poses`).
        mjcf: the MuJoCo model file of ``mechanism.mjcf`` (None: a catalog constructor).
        world: the obstacles of the ``[world]`` table ([`World.from_table`][optik.World.from_table],
            mesh paths relative to the file; None without one).
    """

    name: str
    path: Path
    description: str
    default: bool
    constructor: str
    params: dict[str, Any]
    task: str | None
    urdf: str | None
    lower: tuple[float, ...] | None
    upper: tuple[float, ...] | None
    n: int
    quick_n: int
    seed: int
    sampling: str
    pose_center: tuple[float, ...] | None
    pose_half_range: tuple[float, ...] | None
    tolerances: Tolerances
    methods: tuple[str, ...] | None
    peers: tuple[str, ...]
    time_limit: float
    quick_time_limit: float
    path_table: dict[str, Any] = field(default_factory=dict)
    mjcf: Path | None = None
    world: World | None = None

    def _error(self, key: str, what: str) -> ProblemFileError:
        return ProblemFileError(f"{self.path}: {key}: {what}")

    @cached_property
    def _mechanism(self) -> Mechanism:
        if self.mjcf is not None:
            try:
                m = Mechanism.from_mjcf(self.mjcf)
            except OptikError as exc:  # MuJoCo's own refusal, a model without joints, no MuJoCo
                raise self._error("mechanism.mjcf", str(exc)) from None
            return self._limited(m)
        fn = getattr(catalog, self.constructor)
        try:
            m = fn(**self.params)
        except InvalidArgumentError as exc:
            raise self._error(f"mechanism.params.{exc.argument}", str(exc)) from None
        except OptikError as exc:  # e.g. a ModelError of parameters that do not make a mechanism
            raise self._error("mechanism.params", str(exc)) from None
        return self._limited(m)

    def _limited(self, m: Mechanism) -> Mechanism:
        """``m`` with the file's limit overrides."""
        if self.lower is not None or self.upper is not None:
            for key, value in (("lower", self.lower), ("upper", self.upper)):
                if value is not None and len(value) != m.n_q:
                    raise self._error(
                        f"limits.{key}", f"expected {m.n_q} values ({', '.join(m.coordinate_names)})"
                    )
            try:
                m = m.with_limits(self.lower, self.upper)
            except InvalidArgumentError as exc:
                raise self._error("limits", str(exc)) from None
        return m

    def path_poses(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The tool poses ``(n, 4, 4)`` of the ``[path]`` table and their times (None without
        ``dt``); the start pose is ``FK(start_q)``, every offset in metres in the base frame,
        ``angle`` and ``axis_step`` in degrees, waypoints as ``(x, y, z, roll, pitch, yaw)``.

        Raises:
            ProblemFileError: no ``[path]`` table, or a key its kind needs is missing or wrong.
        """
        from optik.path import shapes

        p = self.path_table
        if not p:
            raise self._error("[path]", "the problem has no [path] table")
        kind, n = p["kind"], p.get("n", 200)
        need = {"line": ("start_q", "end"), "arc": ("start_q", "center", "angle"),
                "polyline": ("start_q", "points"), "waypoints": ("waypoints",)}[kind]  # fmt: skip
        for key in need:
            if key not in p:
                raise self._error(f"path.{key}", f"missing: a {kind} needs {', '.join(need)}")
        m = self.mechanism()
        try:
            start = m.fk(p["start_q"]) if "start_q" in p else None
            if kind == "line":
                poses = shapes.line(start, p["end"], n)
            elif kind == "arc":
                axis = p.get("axis", (0.0, 0.0, 1.0))
                poses = shapes.arc(
                    start, p["center"], axis, np.radians(p["angle"]), n, p.get("turn_tool", True)
                )
            elif kind == "polyline":
                poses = shapes.polyline(start, p["points"], n)
            else:
                rows = [spatial.transform(spatial.rpy_to_rot(*w[3:]), w[:3]) for w in p["waypoints"]]
                poses = shapes.waypoints(np.array([np.asarray(r, dtype=float) for r in rows]), n)
        except InvalidArgumentError as exc:
            raise self._error(f"path.{exc.argument}", str(exc)) from None
        times = None if "dt" not in p else np.arange(n) * p["dt"]
        return poses, times

    def path_options(self) -> dict[str, Any]:
        """The keyword arguments of `optik.plan_path` the ``[path]`` table sets."""
        p, out = self.path_table, {}
        for key in ("free_axis", "position_tolerance", "max_deviation", "smooth"):
            if key in p:
                out[key] = p[key]
        if "axis_step" in p:
            out["axis_step"] = float(np.radians(p["axis_step"]))
        if "self_motion_joint" in p:
            m = self.mechanism()
            name = p["self_motion_joint"]
            if name not in m.coordinate_names:
                raise self._error(
                    "path.self_motion_joint", f"unknown coordinate; known: {list(m.coordinate_names)}"
                )
            j = m.coordinate_names.index(name)
            out["self_motion"] = (name, np.linspace(m.lower[j], m.upper[j], p.get("self_motion_samples", 29)))
        out["tol"] = self.tolerances
        return out

    def mechanism(self) -> Mechanism:
        """The catalog mechanism with its parameters and limits (built once per problem).

        Raises:
            ProblemFileError: the parameters or limits are rejected by the constructor.
        """
        return self._mechanism

    @property
    def mechanism_task(self) -> str:
        """The task space of the benchmark (the override or the mechanism's own)."""
        return self.task or self.mechanism().task

    def target_count(self, quick: bool = False) -> int:
        """Number of targets of a full or a quick run."""
        return self.quick_n if quick else self.n

    def call_time_limit(self, quick: bool = False) -> float:
        """Seconds allowed per IK call in a full or a quick run."""
        return self.quick_time_limit if quick else self.time_limit

    def urdf_chain(self) -> tuple[Path, str, str] | None:
        """``(urdf file, base link, tip link)`` for the peers, or None when the file has no URDF
        or the catalog does not ship it."""
        if self.urdf is None:
            return None
        chains = getattr(catalog, "URDF_CHAINS", {})
        if self.urdf not in chains:
            return None
        path = Path(catalog.urdf_path(self.urdf))
        if not path.is_file():
            return None
        base, tip = chains[self.urdf]
        return path, base, tip

    def sampling_mode(self) -> str:
        """The sampling mode after resolving ``auto`` (see the module docstring).

        Raises:
            ProblemFileError: ``joint`` for a closed chain, ``actuated``/``pose`` for an open
                chain, or ``pose`` without a pose box or a closed-form IK.
        """
        m = self.mechanism()
        mode = self.sampling
        has_box = self.pose_center is not None and self.pose_half_range is not None
        if mode == "auto":
            if not m.is_closed:
                return "joint"
            return "pose" if has_box and closed_form.has_ik(m) else "actuated"
        if (mode == "joint") == m.is_closed:
            kind = "closed" if m.is_closed else "open"
            raise self._error("targets.sampling", f"{mode!r} does not apply to the {kind} chain {m.name!r}")
        if mode == "pose" and not has_box:
            raise self._error("targets.pose_center", "sampling 'pose' needs pose_center and pose_half_range")
        return mode

    def sample_targets(
        self, n: int | None = None, seed: int | np.random.Generator | None = None
    ) -> TargetSet:
        """Draw ``n`` reference configurations and their targets (the benchmark method).

        Args:
            n: number of targets (default: the file's ``n``).
            seed: seed or Generator (default: the file's ``seed``).

        Returns:
            A [`TargetSet`][optik.problem_files.TargetSet]; for closed chains possibly fewer than ``n``
            targets when fewer than ``n`` of ``MAX_DRAWS_PER_TARGET * n`` draws assemble (``draws`` says how
            many).

        Raises:
            ProblemFileError: the sampling mode does not apply, or no draw succeeded.
            SolverUnavailableError: the sampling needs a closed form or ``optik.solve_fk`` that
                is not available.
        """
        count = self.n if n is None else n
        integer = isinstance(count, (int, np.integer)) and not isinstance(count, bool)
        if not integer or not 1 <= count <= MAX_TARGETS:
            raise InvalidArgumentError("n", f"expected an integer in [1, {MAX_TARGETS}], got {count!r}")
        rng = as_rng(self.seed if seed is None else seed)
        m = self.mechanism()
        mode = self.sampling_mode()
        if mode == "joint":
            qs = m.random_q(int(count), rng)
            draws = int(count)
        else:
            draw = self._draw_actuated if mode == "actuated" else self._draw_pose
            found: list[np.ndarray] = []
            draws = 0
            while len(found) < count and draws < MAX_DRAWS_PER_TARGET * count:
                draws += 1
                options = draw(m, rng)
                if options:
                    found.append(options[int(rng.integers(len(options)))])
            if not found:
                what = f"none of {draws} '{mode}' draws gave a configuration within limits"
                raise self._error("targets", what)
            qs = np.array(found)
        poses = np.asarray(m.fk(qs)).reshape(len(qs), 4, 4)
        return TargetSet(qs, poses, self.mechanism_task, mode, draws)

    def _draw_actuated(self, m: Mechanism, rng: np.random.Generator) -> list[np.ndarray]:
        idx = m.actuated_indices
        lo, hi = m.sampling_bounds
        return assemble(m, rng.uniform(lo[idx], hi[idx]))

    def _draw_pose(self, m: Mechanism, rng: np.random.Generator) -> list[np.ndarray]:
        if not closed_form.has_ik(m):
            raise SolverUnavailableError(f"sampling 'pose' needs a closed-form IK for {m.name!r}")
        center = np.asarray(self.pose_center)
        half = np.asarray(self.pose_half_range)
        size = 3 if m.planar else 6
        if center.shape != (size,) or half.shape != (size,):
            raise self._error(
                "targets.pose_center", f"pose_center and pose_half_range need {size} values for {m.name!r}"
            )
        v = center + rng.uniform(-1.0, 1.0, size) * half
        if m.planar:
            t = spatial.planar_pose(*v)
        else:
            t = spatial.transform(spatial.rpy_to_rot(v[3], v[4], v[5]), v[:3])
        return closed_form.ik(m, t)


def constructors() -> list[str]:
    """The mechanism constructors of [`optik.catalog`][optik.catalog]: its public functions that
    return a [`Mechanism`][optik.Mechanism] (not helpers such as ``urdf_path``, nor attributes
    such as ``__class__``), sorted."""
    names = []
    for name in getattr(catalog, "__all__", ()):
        fn = getattr(catalog, name, None)
        if inspect.isfunction(fn) and typing.get_type_hints(fn).get("return") is Mechanism:
            names.append(name)
    return sorted(names)


def _from_data(path: Path, data: dict[str, Any]) -> Problem:
    v = _validate(path, data)
    prob, mech, lim, tg, tol, sol, path_table = (v[k] for k in SCHEMA)
    if ("constructor" in mech) == ("mjcf" in mech):
        raise ProblemFileError(
            f"{path}: [mechanism]: give one of constructor (a catalog function) or mjcf (a file)"
        )
    mjcf = None
    if "mjcf" in mech:
        mjcf = (path.parent / mech["mjcf"]).resolve()
        if not mjcf.is_file():
            raise ProblemFileError(f"{path}: mechanism.mjcf: no such file {mjcf}")
        if mech.get("params"):
            raise ProblemFileError(f"{path}: mechanism.params: an MJCF model takes no parameters")
    constructor = mech.get("constructor", "mjcf")
    names = constructors()
    fn = getattr(catalog, constructor) if constructor in names else None
    if fn is None and mjcf is None:
        raise ProblemFileError(
            f"{path}: mechanism.constructor: {constructor!r} is not available in this version of "
            f"optik.catalog; available: {names}"
        )
    params = dict(mech.get("params", {}))
    signature = inspect.signature(fn) if fn is not None else None
    for key in params if signature is not None else ():
        if key not in signature.parameters:
            raise ProblemFileError(
                f"{path}: mechanism.params.{key}: not a parameter of optik.catalog.{constructor}; "
                f"parameters: {list(signature.parameters)}"
            )
    world = None
    if "world" in data:
        if not isinstance(data["world"], dict):
            raise ProblemFileError(f"{path}: world: expected a table [world], got {data['world']!r}")
        try:
            world = World.from_table(data["world"], folder=path.parent)
        except InvalidArgumentError as exc:
            raise ProblemFileError(f"{path}: {exc}") from None
    return Problem(
        name=prob.get("name", path.stem),
        path=path,
        description=prob["description"],
        default=prob.get("default", True),
        constructor=constructor,
        params=params,
        task=mech.get("task"),
        urdf=mech.get("urdf"),
        lower=lim.get("lower"),
        upper=lim.get("upper"),
        n=tg.get("n", 200),
        quick_n=tg.get("quick_n", 25),
        seed=tg.get("seed", 0),
        sampling=tg.get("sampling", "auto"),
        pose_center=tg.get("pose_center"),
        pose_half_range=tg.get("pose_half_range"),
        tolerances=Tolerances(
            position=tol.get("position", Tolerances.position),
            orientation=tol.get("orientation", Tolerances.orientation),
            closure=tol.get("closure", Tolerances.closure),
        ),
        methods=sol.get("methods"),
        peers=sol.get("peers", ()),
        time_limit=sol.get("time_limit", DEFAULT_TIME_LIMIT),
        quick_time_limit=sol.get("quick_time_limit", DEFAULT_QUICK_TIME_LIMIT),
        path_table=path_table,
        mjcf=mjcf,
        world=world,
    )


def load_problem(path: str | Path) -> Problem:
    """Read and validate one problem file.

    Raises:
        ProblemFileError: unreadable file, invalid TOML, or a schema violation (the message
            names the file and the key).
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidArgumentError("path", f"expected a file path, got {path!r}")
    p = Path(path)
    if "\0" in str(p):
        raise ProblemFileError(f"{str(p)!r}: cannot read the problem file: the path contains a NUL character")
    try:
        with p.open("rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ProblemFileError(f"{p}: cannot read the problem file: {exc.strerror or exc}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise ProblemFileError(f"{p}: larger than {MAX_FILE_BYTES} bytes; not a problem file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ProblemFileError(f"{p}: not UTF-8 text (byte {exc.start}): {exc.reason}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProblemFileError(f"{p}: invalid TOML: {exc}") from None
    except RecursionError:  # tomllib recurses per nesting level of arrays and inline tables
        raise ProblemFileError(f"{p}: invalid TOML: arrays or tables nested too deeply") from None
    return _from_data(p, data)


def _directory(directory: str | Path | None) -> Path:
    d = PROBLEM_DIR if directory is None else Path(directory)
    if not d.is_dir():
        raise InvalidArgumentError(
            "problems", f"no problem directory at {d}; pass a folder of .toml problem files or a .toml file"
        )
    return d


def list_problems(directory: str | Path | None = None) -> list[Problem]:
    """Every problem file of a directory (default [`PROBLEM_DIR`][optik.problem_files.PROBLEM_DIR]), sorted by
    name."""
    return sorted((load_problem(p) for p in _directory(directory).glob("*.toml")), key=lambda pr: pr.name)


def default_problems(directory: str | Path | None = None) -> list[Problem]:
    """The problems marked ``default = true`` (the set ``optik bench`` runs without arguments)."""
    return [p for p in list_problems(directory) if p.default]


def default_constructors(directory: str | Path | None = None) -> list[str]:
    """The [`optik.catalog`][optik.catalog] constructors of the default problems (`default_problems`),
    sorted, each once: the mechanisms ``optik bench`` covers (the twelve of the shipped set)."""
    return sorted({p.constructor for p in default_problems(directory)})


def find_problem(name: str, directory: str | Path | None = None) -> Problem:
    """A problem by name (``five_bar``) or by path (``my/problem.toml``).

    Raises:
        InvalidArgumentError: no such problem (the message lists the known names).
        ProblemFileError: the file is invalid.
    """
    as_path = Path(as_name(name, "problem"))
    if "\0" in name:
        raise InvalidArgumentError("problem", f"no such problem file: {name!r} (contains a NUL character)")
    if as_path.suffix == ".toml" or as_path.is_file():
        if not as_path.is_file():
            raise InvalidArgumentError("problem", f"no such problem file: {name}")
        return load_problem(as_path)
    d = _directory(directory)
    candidate = d / f"{name}.toml"
    if candidate.is_file():
        return load_problem(candidate)
    for problem in list_problems(d):
        if problem.name == name:
            return problem
    known = sorted(p.stem for p in d.glob("*.toml"))
    raise InvalidArgumentError("problem", f"unknown problem {name!r}; known problems: {known}")


def add_source_arguments(parser: Any) -> None:
    """The arguments of a command that loads one mechanism (``optik view``, ``optik reach``):
    ``PROBLEM|ROBOT|URDF``, ``--base`` / ``--tip`` (a URDF chain) and ``--problems-dir``; read
    back by [`load_source`][optik.problem_files.load_source]."""
    parser.add_argument(
        "source",
        metavar="PROBLEM|ROBOT|URDF",
        help=(
            "a problem name (e.g. panda, five_bar; see --problems-dir) or .toml file; a robot of "
            "optik.catalog.robot (needs the robots extra): "
            f"{', '.join(catalog.robot_names())}; a .urdf file with --base and --tip; or an MJCF "
            "(.xml) file, loaded whole (needs the mjcf extra)"
        ),
    )
    parser.add_argument("--base", help="base link of a URDF chain (required with a .urdf file)")
    parser.add_argument("--tip", help="tip link of a URDF chain (required with a .urdf file)")
    add_problems_dir(parser, argparse.SUPPRESS)


def add_problems_dir(parser: Any, default: Any) -> None:
    """The ``--problems-dir DIR`` option: on the ``optik`` parser with ``default=None``, and on
    each subcommand with ``argparse.SUPPRESS``, so that ``optik --problems-dir D solve ...`` and
    ``optik solve --problems-dir D ...`` both set it (the subcommand's value wins)."""
    parser.add_argument(
        "--problems-dir",
        metavar="DIR",
        default=default,
        help="directory of problem files (default: the problem files shipped with optik)",
    )


def load_source(
    source: str, base: str | None, tip: str | None, problems_dir: str | Path | None = None
) -> tuple[Mechanism, Problem | None]:
    """The mechanism of a command's ``PROBLEM|ROBOT|URDF`` argument, and its problem (None for
    a robot, a URDF or an MJCF file). A name is a problem first, else a robot of
    `optik.catalog.robot`; a ``.xml`` or ``.mjcf`` file is a MuJoCo model, loaded whole
    (`Mechanism.from_mjcf`).

    Raises:
        InvalidArgumentError: no such URDF or MJCF file, a URDF without both ``--base`` and
            ``--tip``, an MJCF file with one of them;
            a name that is neither a problem nor a robot (the message lists both).
        ProblemFileError: the problem file is invalid.
        MissingExtraError: a robot name without the ``robots`` extra.
    """
    if Path(source).suffix.lower() in (".xml", ".mjcf"):
        if not Path(source).is_file():
            raise InvalidArgumentError("PROBLEM|ROBOT|URDF", f"no such file: {source}")
        if base is not None or tip is not None:
            raise InvalidArgumentError("--base", "an MJCF model loads whole: no --base or --tip")
        return Mechanism.from_mjcf(source), None
    if Path(source).suffix.lower() == ".urdf":
        if not Path(source).is_file():
            raise InvalidArgumentError("PROBLEM|ROBOT|URDF", f"no such file: {source}")
        if base is None or tip is None:
            raise InvalidArgumentError("--base", "a URDF file needs --base and --tip (the chain's end links)")
        return Mechanism.from_urdf(source, base, tip), None
    try:
        problem = find_problem(source, problems_dir)
    except InvalidArgumentError as exc:
        if source in catalog.robot_names():
            return catalog.robot(source), None
        if str(exc).startswith("problem: unknown problem"):
            raise InvalidArgumentError(
                "PROBLEM|ROBOT|URDF", f"{str(exc).partition(': ')[2]}; robots: {list(catalog.robot_names())}"
            ) from None
        raise
    return problem.mechanism(), problem


def problem_summary(problem: Problem) -> dict[str, Any]:
    """A JSON-friendly description of a problem (for reports)."""
    try:
        m = problem.mechanism()
        mech = {"name": m.name, "n_q": m.n_q, "closed": m.is_closed, "planar": m.planar}
    except OptikError as exc:
        mech = {"error": str(exc)}
    return {
        "name": problem.name,
        "file": str(problem.path),
        "description": problem.description,
        "constructor": problem.constructor,
        "params": problem.params,
        "mechanism": mech,
        "tolerances": {
            "position": problem.tolerances.position,
            "orientation": problem.tolerances.orientation,
            "closure": problem.tolerances.closure,
        },
    }
