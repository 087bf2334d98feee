"""The [`Mechanism`][optik.Mechanism]: one symbolic CasADi model of any linkage.

A mechanism is a set of bodies connected by [`Joint`][optik.mechanism.joint.Joint] objects. A
spanning tree (see [`optik.mechanism.topology`][optik.mechanism.topology]) gives every body a pose
``T_body(q)`` as a CasADi ``SX`` expression in the coordinates ``q`` of the tree joints; each cut joint gives
loop-closure equations ``c(q) = 0``. Named frames are fixed offsets on bodies. From these expressions the
mechanism compiles, once and lazily, CasADi functions for forward kinematics, the geometric Jacobian and the
closure residual.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import replace
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from optik import spatial
from optik.checks import as_batch, as_bool, as_limits, as_name, as_rng, as_vector, read_only, real_array
from optik.errors import InvalidArgumentError, ModelError, ReadOnlyError, UnknownFrameError
from optik.mechanism.inertia import check_inertials, com_expr
from optik.mechanism.joint import Joint, LinearClosure
from optik.mechanism.mjcf import parse_mjcf
from optik.mechanism.mobility import generic_closure_rank
from optik.mechanism.srdf import read_disabled_collisions
from optik.mechanism.topology import analyse, gruebler_kutzbach
from optik.mechanism.urdf import parse_urdf

_LOG = logging.getLogger(__name__)

TASK_ROWS: dict[str, tuple[int, ...]] = {
    "pose": (0, 1, 2, 3, 4, 5),
    "position": (0, 1, 2),
    "orientation": (3, 4, 5),
    "pose2d": (0, 1, 5),
    "position2d": (0, 1),
}
"""Rows of the 6-row geometric Jacobian ``[v; w]`` that each task space uses."""
_EYE = read_only(np.eye(4))


def _frozen(indices: np.ndarray) -> np.ndarray:
    """``indices`` made read-only: cached on the mechanism and shared by its callers."""
    indices.flags.writeable = False
    return indices


def _function_name(prefix: str, frame: str) -> str:
    """A valid CasADi function name for a frame (letters, digits, single underscores): link names
    such as ``flying_arm_5__gripper`` or ``link-1`` are not."""
    return "_".join([prefix, *(p for p in re.split(r"[^A-Za-z0-9]+", frame) if p)])


def _is_unit_z(v: np.ndarray) -> bool:
    """``np.allclose(v, [0, 0, 1])`` of a finite 3-vector, on its floats (``|v_i - z_i| <= 1e-8 +
    1e-5 |z_i|``): a fresh process's first ``np.allclose`` costs 0.2 ms, each from_urdf calls it."""
    return all(abs(x - z) <= 1e-8 + 1e-5 * z for x, z in zip(v.tolist(), (0.0, 0.0, 1.0), strict=True))


def _is_planar_transform(t: np.ndarray) -> bool:
    return bool(abs(t[2, 3]) < 1e-12 and _is_unit_z(t[2, :3]) and _is_unit_z(t[:3, 2]))


def _joint_is_planar(j: Joint) -> bool:
    if j.type == "fixed":
        ok_axis = True
    elif j.type == "revolute":
        ok_axis = _is_unit_z(np.abs(j.axis))
    elif j.type == "prismatic":
        ok_axis = abs(j.axis[2]) < 1e-12
    else:
        return False
    return ok_axis and _is_planar_transform(j.origin) and _is_planar_transform(j.child_offset)


def _perpendiculars(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    u1 = np.cross(a, helper)
    u1 /= np.linalg.norm(u1)
    return u1, np.cross(a, u1)


def geometric_jacobian(t: ca.SX, q: ca.SX) -> ca.SX:
    """Geometric Jacobian ``[dp/dq; w]`` (6 x n, base frame) of the pose expression ``t`` (4x4):
    column ``k`` has the linear part ``dp/dq_k`` and the angular part ``vee(dR/dq_k R^T)``."""
    r, p = t[:3, :3], t[:3, 3]
    jl = ca.jacobian(p, q)
    dr = ca.jacobian(ca.vec(r), q)
    cols = [spatial.vee(ca.mtimes(ca.reshape(dr[:, k], 3, 3), r.T)) for k in range(int(q.shape[0]))]
    return ca.vertcat(jl, ca.horzcat(*cols))


class Mechanism:
    """A kinematic model: joints, limits, loop closures and named frames.

    Args:
        joints: the joints; tree joints get coordinates in this order.
        base: name of the fixed body.
        frames: extra named frames ``{name: (body, 4x4 offset)}``; every body is a frame too,
            under its own name, which no extra frame may take.
        ee: name of the end-effector frame (default: child body of the last joint).
        name: a label for printing.
        task: default task space for Jacobian measures: ``"pose"``, ``"position"``,
            ``"pose2d"``, ``"position2d"`` (default: ``"pose2d"`` for planar mechanisms,
            ``"pose"`` otherwise).
        inertials: link masses ``{frame: (mass, com)}``: the mass (kg) and the centre of mass
            (3-vector) in that frame (a body or a named frame), for `com` and `com_jacobian`
            (see [`optik.mechanism.inertia`][optik.mechanism.inertia]).
        linear_closures: linear equations of joint values (`LinearClosure`), each one more row
            of `closure` after the cut joints' rows.

    Raises:
        ModelError: inconsistent topology (see
            [`optik.mechanism.topology.analyse`][optik.mechanism.topology.analyse]), or a linear
            closure names a joint that is not a revolute or prismatic tree or mimic joint.
        UnknownFrameError: ``ee`` or a frame's body does not exist.
        InvalidArgumentError: a frame has a body's name, an offset is not 4x4, or an inertial
            is malformed (a negative or non-finite mass, a centre that is not a 3-vector).
    """

    def __init__(
        self,
        joints: Sequence[Joint],
        base: str = "base",
        frames: Mapping[str, tuple[str, Any]] | None = None,
        ee: str | None = None,
        name: str = "mechanism",
        task: str | None = None,
        inertials: Mapping[str, tuple[Any, Any]] | None = None,
        linear_closures: Sequence[LinearClosure] = (),
    ) -> None:
        if not joints:
            raise ModelError("a mechanism needs at least one joint")
        self.joints: tuple[Joint, ...] = tuple(joints)
        self.base = base
        self.name = name
        self.topology = analyse(self.joints, base)
        self.planar = all(_joint_is_planar(j) for j in self.joints)
        self.frames: dict[str, tuple[str, np.ndarray]] = {b: (b, _EYE) for b in self.topology.bodies}
        for fname, (body, offset) in (frames or {}).items():
            if fname in self.topology.bodies:
                raise InvalidArgumentError(
                    "frames",
                    f"frame {fname!r} has the name of a body: it would hide the body's own frame; "
                    "give it another name",
                )
            if body not in self.frames:
                raise UnknownFrameError("frames", f"frame {fname!r} is on unknown body {body!r}")
            off = read_only(real_array(offset, "frames"))
            if off.shape != (4, 4):
                raise InvalidArgumentError("frames", f"frame {fname!r}: offset must be 4x4")
            self.frames[fname] = (body, off)
        self.ee = self.joints[-1].child if ee is None else ee
        if self.ee not in self.frames:
            raise UnknownFrameError(
                "ee", f"unknown end-effector frame {self.ee!r}; known: {sorted(self.frames)}"
            )
        if task is not None and task not in TASK_ROWS:
            raise InvalidArgumentError("task", f"unknown task {task!r}; use one of {sorted(TASK_ROWS)}")
        self.task = task or ("pose2d" if self.planar else "pose")
        self.inertials: dict[str, tuple[float, np.ndarray]] = check_inertials(inertials, self.frames)
        """Link masses ``{frame: (mass, com in that frame)}`` (empty when none were given)."""
        self._slices: dict[int, slice] = {}
        names: list[str] = []
        lower: list[float] = []
        upper: list[float] = []
        actuated: list[bool] = []
        for i in self.topology.tree:
            j = self.joints[i]
            self._slices[i] = slice(len(names), len(names) + j.dof)
            names += j.coordinate_names()
            lower += j.lower
            upper += j.upper
            actuated += [j.actuated] * j.dof
        self.coordinate_names: tuple[str, ...] = tuple(names)
        self._lower = read_only(lower)
        self._upper = read_only(upper)
        self._actuated: tuple[bool, ...] = tuple(actuated)
        self._mimic_sources = self._mimic_coordinates()
        self.linear_closures: tuple[LinearClosure, ...] = self._check_linear_closures(linear_closures)
        """Linear equations of joint values closing loops besides the cut joints (`closure` rows)."""
        self.params: dict[str, Any] = {}
        """Catalog parameters (link lengths, base points, ...) the mechanism was built from."""
        self._geometry_of: Mechanism | None = None  # set by with_limits
        self.kind: str | None = None
        """Catalog key (e.g. ``"planar_3r"``) under which [`optik.closed_form`][optik.closed_form] finds this
        mechanism's analytic solvers; None for mechanisms built by hand."""
        self._memo: dict[object, Any] = {}
        """Entries of the caches keyed on this mechanism (`optik.mechanism.memo.PerMechanism`)."""
        self._fk_funs: dict[str, ca.Function] = {}
        self._jac_funs: dict[str, ca.Function] = {}

    def _mimic_coordinates(self) -> dict[int, int]:
        """``{mimic joint index: coordinate index of its source}``, checking every coupling."""
        index = {j.name: i for i, j in enumerate(self.joints)}
        out: dict[int, int] = {}
        for i, j in enumerate(self.joints):
            if j.mimic is None:
                continue
            src = index.get(j.mimic.joint)
            if src is None:
                raise ModelError(f"joint {j.name!r} mimics {j.mimic.joint!r}, which is not a joint here")
            source = self.joints[src]
            if source.mimic is not None or source.dof != 1 or src not in self._slices:
                raise ModelError(
                    f"joint {j.name!r} mimics {source.name!r}, which has no coordinate of its own "
                    "(it must be a revolute or prismatic tree joint that mimics nothing)"
                )
            if i in self.topology.cuts:
                raise ModelError(f"mimic joint {j.name!r} would have to close a loop")
            out[i] = self._slices[src].start
        return out

    def _check_linear_closures(self, closures: Sequence[LinearClosure]) -> tuple[LinearClosure, ...]:
        index = {j.name: i for i, j in enumerate(self.joints)}
        out = tuple(closures)
        for c in out:
            if not isinstance(c, LinearClosure):
                raise InvalidArgumentError("linear_closures", f"expected LinearClosure objects, got {c!r}")
            for name, _ in c.coefficients:
                i = index.get(name)
                one_value = i is not None and self.joints[i].type in ("revolute", "prismatic")
                if not one_value or i in self.topology.cuts:
                    raise ModelError(
                        f"linear closure {c.name!r} names {name!r}, which is not a revolute or prismatic "
                        "tree or mimic joint here"
                    )
        return out

    def _joint_value(self, i: int, q: Any) -> Any:
        """The value of the one-coordinate joint ``i`` (its coordinate, or its mimic coupling's
        value) in the coordinates ``q``."""
        source = self._mimic_sources.get(i)
        return q[self._slices[i].start] if source is None else self.joints[i].mimic.value(q[source])

    @classmethod
    def from_urdf(
        cls,
        source: str | os.PathLike[str],
        base_link: str | None = None,
        tip_link: str | None = None,
        srdf: str | os.PathLike[str] | None = None,
        floating_base: bool = False,
    ) -> Mechanism:
        """A URDF robot: the whole tree, the tree below ``base_link``, or one chain.

        ``source`` is a URDF file path or the XML text. With neither link given the whole tree
        is loaded (its root link is the base, every link is a named frame); with ``base_link``
        only, the subtree below that link; with ``tip_link``, the chain from ``base_link`` (default
        the root link) to ``tip_link``, which is then ``ee``. Coordinates are named after the URDF
        joints; the task is ``"pose"``; ``params`` holds what `optik.mechanism.urdf.parse_urdf`
        read (source, links, velocity limits, visuals, collision geometry). See that function for
        what is supported and what is raised. ``srdf`` (a file or the XML text) gives the link
        pairs `optik.collision` never checks, its ``disable_collisions``, kept in
        ``params["disabled_collisions"]`` (`optik.mechanism.srdf.read_disabled_collisions`);
        without it `optik.collision` samples them. With ``floating_base=True`` the base link
        hangs from a new fixed body ``"world"`` by a free joint ``"root_joint"`` whose six
        coordinates (position, rotation vector) come first. Link masses (``<inertial>``) give
        `com`.
        """
        model = parse_urdf(source, base_link, tip_link, as_bool(floating_base, "floating_base"))
        m = cls(model.joints, model.base, model.frames, model.ee, model.name, "pose", model.inertials)
        m.params = dict(model.params)
        if srdf is not None:
            m.params["disabled_collisions"] = read_disabled_collisions(srdf)
        return m

    @classmethod
    def from_mjcf(cls, source: Any) -> Mechanism:
        """A MuJoCo model's whole body tree, compiled by MuJoCo (``pip install "optik[mjcf]"``).

        ``source`` is an MJCF file path, the XML text or a ``mujoco.MjModel``. The base is the
        world body ``"world"``; every body and site is a named frame; hinge, slide, ball and
        free joints become revolute, prismatic, spherical and free joints whose coordinates
        are MuJoCo's ``qpos`` (rotation vectors instead of quaternions:
        `optik.mechanism.mjcf.to_qpos` and `optik.mechanism.mjcf.from_qpos` convert). The task
        is ``"pose"``; ``params`` holds what `optik.mechanism.mjcf.parse_mjcf` read (source,
        site frames, visuals, notes). See that module for what is supported and what is raised.
        """
        model = parse_mjcf(source)
        m = cls(
            model.joints,
            model.base,
            model.frames,
            model.ee,
            model.name,
            "pose",
            model.inertials,
            model.linear_closures,
        )
        m.params = dict(model.params)
        return m

    # ------------------------------------------------------------------ limits
    @property
    def lower(self) -> np.ndarray:
        """Lower coordinate limits (read-only: the compiled solvers of a mechanism are built for its
        limits; [`with_limits`][optik.Mechanism.with_limits] makes a mechanism with other ones)."""
        return self._lower

    @lower.setter
    def lower(self, value: Any) -> None:
        raise ReadOnlyError("lower", "the limits are read-only; use m.with_limits(lower=..., upper=...)")

    @property
    def upper(self) -> np.ndarray:
        """Upper coordinate limits (read-only, as [`lower`][optik.Mechanism.lower])."""
        return self._upper

    @upper.setter
    def upper(self, value: Any) -> None:
        raise ReadOnlyError("upper", "the limits are read-only; use m.with_limits(lower=..., upper=...)")

    # ------------------------------------------------------------------ structure
    @property
    def n_q(self) -> int:
        """Number of coordinates (tree joints' coordinates)."""
        return len(self.coordinate_names)

    @property
    def n_closure(self) -> int:
        """Number of loop-closure equations."""
        return int(self.closure_expr.shape[0])

    @property
    def is_closed(self) -> bool:
        """True when the mechanism has at least one loop."""
        return bool(self.topology.cuts or self.linear_closures)

    @property
    def actuated(self) -> tuple[bool, ...]:
        """Per coordinate, True when its joint is actuated (read-only: the joints decide it)."""
        return self._actuated

    @actuated.setter
    def actuated(self, value: Any) -> None:
        raise ReadOnlyError("actuated", "the actuation is read-only; build a Mechanism with other joints")

    @cached_property
    def actuated_indices(self) -> np.ndarray:
        """Indices of the actuated coordinates (read-only; computed once: every FK call reads them)."""
        return _frozen(np.flatnonzero(self._actuated))

    @cached_property
    def passive_indices(self) -> np.ndarray:
        """Indices of the passive coordinates (read-only; computed once)."""
        return _frozen(np.flatnonzero(~np.asarray(self._actuated, dtype=bool)))

    @cached_property
    def revolute_mask(self) -> np.ndarray:
        """True for scalar angle coordinates (revolute and universal joints), which are equal
        modulo 2 pi. Spherical coordinates are rotation vectors, not angles (see `wrap`)."""
        mask: list[bool] = []
        for i in self.topology.tree:
            j = self.joints[i]
            mask += [j.type in ("revolute", "universal")] * j.dof
        out = np.array(mask, dtype=bool)
        out.flags.writeable = False  # cached and shared: read-only
        return out

    @cached_property
    def spherical_slices(self) -> tuple[slice, ...]:
        """Coordinate slices of the rotation vectors of the tree: each spherical joint's three
        coordinates and the last three of each free joint."""
        out = []
        for i in self.topology.tree:
            sl, kind = self._slices[i], self.joints[i].type
            if kind == "spherical":
                out.append(sl)
            elif kind == "free":
                out.append(slice(sl.start + 3, sl.stop))
        return tuple(out)

    def mobility(self) -> int:
        """Degrees of freedom: ``n_q - rank(dc/dq)`` at generic assembled configurations.

        An open chain has ``n_q``. For a closed chain the closure Jacobian's rank is taken at
        configurations assembled from seeded random starts
        ([`generic_closure_rank`][optik.mechanism.mobility.generic_closure_rank]), so planar loops
        built in 3-D count the 3 constraints per loop they impose, not Gruebler-Kutzbach's 6.
        When no start assembles, Gruebler-Kutzbach's count from the topology
        (`optik.mechanism.topology.gruebler_kutzbach`) is returned, with a logged warning.
        """
        return self._mobility

    @cached_property
    def _mobility(self) -> int:
        if not self.is_closed:
            return self.n_q
        rank = generic_closure_rank(lambda q: self.closure_function(q), self.random_q(8, seed=0))
        if rank is not None:
            return self.n_q - rank
        count = gruebler_kutzbach(len(self.topology.bodies) - 1, self.joints, self.planar)
        _LOG.warning("%s: no configuration assembled; mobility %d by Gruebler-Kutzbach", self.name, count)
        return count

    def __repr__(self) -> str:
        kind = "planar" if self.planar else "spatial"
        return (
            f"Mechanism({self.name!r}, {kind}, n_q={self.n_q}, closures={self.n_closure}, "
            f"mobility={self.mobility()}, ee={self.ee!r})"
        )

    # ------------------------------------------------------------------ symbolic model
    @cached_property
    def q_sym(self) -> ca.SX:
        """The coordinate vector as a CasADi ``SX`` symbol (``n_q`` x 1)."""
        return ca.SX.sym("q", self.n_q)

    @cached_property
    def body_transforms(self) -> dict[str, ca.SX]:
        """``{body: T_body(q)}`` as ``SX`` 4x4 expressions in `q_sym`."""
        q = self.q_sym
        poses: dict[str, Any] = {self.base: ca.SX.eye(4)}
        for edge in self.topology.order:
            j = self.joints[edge.joint]
            source = self._mimic_sources.get(edge.joint)
            m = j.motion(q[self._slices[edge.joint]] if source is None else [j.mimic.value(q[source])])
            if edge.reversed:
                poses[j.parent] = ca.mtimes(
                    [poses[j.child], j.child_offset, spatial.inv_transform(ca.SX(m)), np.linalg.inv(j.origin)]
                )
            else:
                poses[j.child] = ca.mtimes([poses[j.parent], j.origin, m, np.linalg.inv(j.child_offset)])
        return poses

    def frame_expr(self, frame: str | None = None) -> ca.SX:
        """``T_frame(q)`` as an ``SX`` expression.

        Raises:
            UnknownFrameError: the frame does not exist.
        """
        body, offset = self._frame(frame)
        return ca.mtimes(self.body_transforms[body], offset)

    @cached_property
    def closure_expr(self) -> ca.SX:
        """Loop-closure residual ``c(q)`` (cut-joint method) as an ``SX`` column.

        For a cut joint with parent-side frame ``A = T_parent origin`` and child-side frame
        ``B = T_child child_offset``: the origins coincide, ``p_B - p_A = 0`` (x and y only for
        planar mechanisms); a spatial revolute joint adds ``(R_A u_k) . (R_B a) = 0`` for the two
        unit vectors ``u_k`` normal to its axis ``a``; a universal joint adds
        ``(R_A a_1) . (R_B a_2) = 0``; a fixed cut joint (a weld) adds the 9 rows
        ``vec(R_B - R_A) / sqrt(2)``, of norm ``2 sin(theta / 2)`` for the relative rotation
        ``theta``: zero only where the frames agree (3 of the rows are independent; the 3 rows of
        ``vee(R_A^T R_B - R_B^T R_A)`` would also vanish at ``theta = pi``, with a rank-deficient
        Jacobian there), as the orientation rows of the IK residual (`optik.problem`). Each
        `LinearClosure` adds the row ``sum_k c_k q_k - value`` after them.
        """
        rows: list[Any] = []
        poses = self.body_transforms
        for i in self.topology.cuts:
            j = self.joints[i]
            a = ca.mtimes(poses[j.parent], j.origin)
            b = ca.mtimes(poses[j.child], j.child_offset)
            dp = b[:3, 3] - a[:3, 3]
            rows.append(dp[:2] if self.planar else dp)
            if self.planar or j.type == "spherical":
                continue
            ra, rb = a[:3, :3], b[:3, :3]
            if j.type == "revolute":
                for u in _perpendiculars(j.axis):
                    rows.append(ca.dot(ca.mtimes(ra, u), ca.mtimes(rb, j.axis)))
            elif j.type == "universal":
                rows.append(ca.dot(ca.mtimes(ra, j.axis), ca.mtimes(rb, j.axis2)))
            elif j.type == "fixed":
                rows.append(ca.vec(rb - ra) / np.sqrt(2.0))
        index = {j.name: i for i, j in enumerate(self.joints)}
        for c in self.linear_closures:
            terms = [k * self._joint_value(index[name], self.q_sym) for name, k in c.coefficients]
            rows.append(ca.sum1(ca.vertcat(*terms)) - c.value)
        return ca.vertcat(*rows) if rows else ca.SX(0, 1)

    def jacobian_expr(self, frame: str | None = None) -> ca.SX:
        """Geometric Jacobian ``[dp/dq; w]`` (6 x n, base frame) as an ``SX`` expression.

        Column ``k`` has the linear part ``dp/dq_k`` and the angular part
        ``vee(dR/dq_k R^T)``, valid for every joint type.
        """
        return geometric_jacobian(self.frame_expr(frame), self.q_sym)

    def _frame(self, frame: str | None) -> tuple[str, np.ndarray]:
        name = self.ee if frame is None else frame
        if not isinstance(name, str) or name not in self.frames:
            raise UnknownFrameError("frame", f"unknown frame {name!r}; known: {sorted(self.frames)}")
        return self.frames[name]

    # ------------------------------------------------------------------ compiled functions
    def fk_function(self, frame: str | None = None) -> ca.Function:
        """Compiled ``q -> T_frame(q)`` (built once per frame)."""
        key = self.ee if frame is None else frame
        try:
            return self._fk_funs[key]
        except (KeyError, TypeError):  # TypeError: an unhashable frame, rejected by _frame
            expr = self.frame_expr(key)  # raises for an unknown frame
            f = self._fk_funs[key] = ca.Function(_function_name("fk", key), [self.q_sym], [expr])
            return f

    def jacobian_function(self, frame: str | None = None) -> ca.Function:
        """Compiled ``q -> J(q)`` (6 x n geometric Jacobian, built once per frame)."""
        key = self.ee if frame is None else frame
        try:
            return self._jac_funs[key]
        except (KeyError, TypeError):  # TypeError: an unhashable frame, rejected by _frame
            expr = self.jacobian_expr(key)
            f = self._jac_funs[key] = ca.Function(_function_name("jac", key), [self.q_sym], [expr])
            return f

    @cached_property
    def com_function(self) -> ca.Function:
        """Compiled ``q -> (com(q), J_com(q))`` (3 x 1 and 3 x n).

        Raises:
            ModelError: the mechanism has no mass.
        """
        return ca.Function("com", [self.q_sym], [self._com_expr, self._com_jacobian_expr])

    @cached_property
    def _com_expr(self) -> ca.SX:
        """``com(q)`` (3 x 1, symbolic); raises `ModelError` without mass."""
        return com_expr(self.inertials, self.frames, self.body_transforms, self.name)

    @cached_property
    def _com_jacobian_expr(self) -> ca.SX:
        return ca.jacobian(self._com_expr, self.q_sym)

    @cached_property
    def _com_only_function(self) -> ca.Function:
        """``q -> com(q)``: what `com` evaluates (no Jacobian computed and dropped)."""
        return ca.Function("com_only", [self.q_sym], [self._com_expr])

    @cached_property
    def _com_jacobian_function(self) -> ca.Function:
        """``q -> J_com(q)``: what `com_jacobian` evaluates."""
        return ca.Function("com_jacobian", [self.q_sym], [self._com_jacobian_expr])

    @cached_property
    def closure_function(self) -> ca.Function:
        """Compiled ``q -> (c(q), dc/dq)``."""
        c = self.closure_expr
        return ca.Function("closure", [self.q_sym], [c, ca.jacobian(c, self.q_sym)])

    # ------------------------------------------------------------------ numerical API
    def check_q(self, q: Any, name: str = "q") -> np.ndarray:
        """``q`` as a finite float vector of length `n_q` (else [`OptikError`][optik.OptikError])."""
        return as_vector(q, name, self.n_q)

    def fk(self, q: Any, frame: str | None = None) -> np.ndarray:
        """Pose of a frame: 4x4 homogeneous transform (``(N, 4, 4)`` for ``q`` of shape ``(N, n)``).

        Args:
            q: coordinates, shape ``(n_q,)`` or ``(N, n_q)``.
            frame: frame name (default: the end effector).
        """
        qb, single = as_batch(q, "q", self.n_q)
        f = self.fk_function(frame)
        if not len(qb):
            return np.zeros((0, 4, 4))
        out = (
            np.asarray(f(qb.T)).reshape(4, len(qb), 4).transpose(1, 0, 2)
            if len(qb) > 1
            else (np.asarray(f(qb[0]))[None])
        )
        return out[0] if single else out

    def jacobian(self, q: Any, frame: str | None = None) -> np.ndarray:
        """Geometric Jacobian ``[v; w] = J(q) qdot`` (6 x n, base frame, at the frame origin)."""
        return np.asarray(self.jacobian_function(frame)(self.check_q(q)))

    @property
    def mass(self) -> float:
        """Total mass of the `inertials` (kg; 0 when none were given)."""
        return float(sum(m for m, _ in self.inertials.values()))

    def com(self, q: Any) -> np.ndarray:
        """Centre of mass in the base frame, ``sum_i m_i p_i(q) / M`` (``(3,)``, or ``(N, 3)``
        for ``q`` of shape ``(N, n_q)``).

        Raises:
            ModelError: the mechanism has no mass (no `inertials`).
        """
        qb, single = as_batch(q, "q", self.n_q)
        f = self._com_only_function
        if not len(qb):
            return np.zeros((0, 3))
        out = np.asarray(f(qb.T)).T if len(qb) > 1 else np.asarray(f(qb[0])).reshape(1, 3)
        return out[0] if single else out

    def com_jacobian(self, q: Any) -> np.ndarray:
        """``d com / d q`` (3 x n_q, base frame): the CoM velocity is ``J_com(q) qdot``.

        Raises:
            ModelError: the mechanism has no mass (no `inertials`).
        """
        return np.asarray(self._com_jacobian_function(self.check_q(q)))

    def closure(self, q: Any) -> np.ndarray:
        """Loop-closure residual vector (empty for open chains)."""
        if not self.is_closed:
            self.check_q(q)
            return np.zeros(0)
        return np.asarray(self.closure_function(self.check_q(q))[0]).reshape(-1)

    def closure_jacobian(self, q: Any) -> np.ndarray:
        """``dc/dq`` (``n_closure`` x ``n_q``)."""
        if not self.is_closed:
            return np.zeros((0, self.n_q))
        return np.asarray(self.closure_function(self.check_q(q))[1])

    def task_jacobian(self, q: Any, frame: str | None = None, task: str | None = None) -> np.ndarray:
        """Rows of the geometric Jacobian for a task space (default `task`)."""
        rows = TASK_ROWS[self._task(task)]
        return self.jacobian(q, frame)[list(rows)]

    def _task(self, task: str | None) -> str:
        return self.task if task is None else as_name(task, "task", TASK_ROWS)

    def manipulability(self, q: Any, frame: str | None = None, task: str | None = None) -> float:
        """Yoshikawa's measure ``sqrt(det(J J^T))`` = product of singular values of the task Jacobian."""
        s = np.linalg.svd(self.task_jacobian(q, frame, task), compute_uv=False)
        return float(np.prod(s))

    def condition_number(self, q: Any, frame: str | None = None, task: str | None = None) -> float:
        """``sigma_max / sigma_min`` of the task Jacobian (``inf`` at a singularity)."""
        s = np.linalg.svd(self.task_jacobian(q, frame, task), compute_uv=False)
        return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")

    def jacobian_determinant(self, q: Any, frame: str | None = None, task: str | None = None) -> float:
        """``det J`` of a square task Jacobian.

        Raises:
            InvalidArgumentError: the task Jacobian is not square.
        """
        j = self.task_jacobian(q, frame, task)
        if j.shape[0] != j.shape[1]:
            raise InvalidArgumentError("task", f"Jacobian is {j.shape[0]}x{j.shape[1]}, not square")
        return float(np.linalg.det(j))

    def joint_torques(
        self, q: Any, wrench: Any, frame: str | None = None, task: str | None = None
    ) -> np.ndarray:
        """Statics ``tau = J^T F``: joint efforts that balance a wrench at the frame.

        ``F`` is ``[force; moment]`` in the base frame restricted to the task rows (e.g.
        ``[f_x, f_y, m_z]`` for ``"pose2d"``). By virtual work ``tau . qdot = F . xdot``.
        """
        j = self.task_jacobian(q, frame, task)
        f = as_vector(wrench, "wrench", j.shape[0])
        return j.T @ f

    # ------------------------------------------------------------------ sampling and limits
    @cached_property
    def sampling_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Finite ``(lower, upper)`` for seeds and sampling: the limits where they are finite.

        An unbounded side is replaced so that the interval spans ``2 pi`` for angles and
        rotation vectors (one turn: ``[-pi, pi]`` when both sides are unbounded, ``[lo, lo + 2 pi]``
        or ``[hi - 2 pi, hi]`` when one is) and ``2`` m for prismatic coordinates and the positions
        of free joints. The limits themselves stay infinite: solvers never clip an unbounded
        coordinate.
        """
        span = np.full(self.n_q, 2.0 * np.pi)
        for i in self.topology.tree:
            sl = self._slices[i]
            if self.joints[i].type == "prismatic":
                span[sl] = 2.0
            elif self.joints[i].type == "free":
                span[sl.start : sl.start + 3] = 2.0
        lo, hi = self.lower.copy(), self.upper.copy()
        both = ~np.isfinite(lo) & ~np.isfinite(hi)
        lo[both], hi[both] = -0.5 * span[both], 0.5 * span[both]
        lo = np.where(np.isfinite(lo), lo, hi - span)
        hi = np.where(np.isfinite(hi), hi, lo + span)
        for a in (lo, hi):
            a.flags.writeable = False  # cached and shared: read-only
        return lo, hi

    @property
    def unbounded(self) -> np.ndarray:
        """True for coordinates with an infinite limit on either side (e.g. URDF continuous joints)."""
        return ~(np.isfinite(self.lower) & np.isfinite(self.upper))

    def mid_q(self) -> np.ndarray:
        """The mid-limit configuration ``(lower + upper) / 2`` of the
        [`sampling_bounds`][optik.Mechanism.sampling_bounds] (0 for a coordinate unbounded on both sides)."""
        lo, hi = self.sampling_bounds
        return 0.5 * (lo + hi)

    def random_q(self, n: int | None = None, seed: int | np.random.Generator | None = None) -> np.ndarray:
        """Coordinates drawn uniformly within the [`sampling_bounds`][optik.Mechanism.sampling_bounds]
        (the limits where finite; loop closures *not* enforced).

        Args:
            n: number of samples (None: one vector).
            seed: seed or Generator.
        """
        rng = as_rng(seed)
        shape = (self.n_q,) if n is None else (n, self.n_q)
        lo, hi = self.sampling_bounds
        return rng.uniform(lo, hi, size=shape)

    def within_limits(self, q: Any, tol: float = 0.0) -> bool:
        """True when ``lower - tol <= q <= upper + tol`` for every coordinate."""
        qq = self.check_q(q)
        return bool(np.all(qq >= self.lower - tol) and np.all(qq <= self.upper + tol))

    def clip(self, q: Any) -> np.ndarray:
        """``q`` clipped into the limits."""
        return np.clip(self.check_q(q), self.lower, self.upper)

    def wrap(self, q: Any) -> np.ndarray:
        """Canonical coordinates of the same configuration(s).

        Angles are shifted by multiples of 2 pi into ``(-pi, pi]``, or into the limits when the
        limits allow a shifted value there, or else as near the limits as a shift gets
        ([`spatial.wrap_to_limits`][optik.spatial.wrap_to_limits] gives the rules). A spherical
        joint's rotation vector ``w`` with ``|w| > pi`` is replaced by ``w (1 - 2 pi / |w|)``,
        the same rotation with angle ``2 pi - |w| < pi`` about the opposite axis, so that every
        rotation has one coordinate vector (up to the sign at exactly a half-turn).

        Args:
            q: coordinates, shape ``(n_q,)`` or ``(N, n_q)`` (rows wrapped independently).

        Returns:
            A new array of the shape of ``q``.
        """
        qb, single = as_batch(q, "q", self.n_q)
        w = spatial.wrap_to_limits(qb, self.lower, self.upper, self.revolute_mask)
        for sl in self.spherical_slices:
            w[:, sl] = spatial.wrap_rotation_vector(w[:, sl])
        return w[0] if single else w

    def with_limits(self, lower: Any = None, upper: Any = None) -> Mechanism:
        """A copy with new coordinate limits (same joints, frames and end effector).

        Raises:
            LimitsError: lower > upper or NaN.
        """
        lo = self.lower if lower is None else as_limits(lower, "lower", self.n_q)
        hi = self.upper if upper is None else as_limits(upper, "upper", self.n_q)
        joints = list(self.joints)
        for i, sl in self._slices.items():
            joints[i] = replace(joints[i], lower=tuple(lo[sl]), upper=tuple(hi[sl]))
        copy = self._rebuild(joints)
        copy._geometry_of = self.geometry
        return copy

    @property
    def geometry(self) -> Mechanism:
        """The mechanism this one was made from by `with_limits` (through any number of such
        copies), else itself: the same model but for the limits. Code compiled with the limits as
        inputs (the LM kernel of `optik.solvers.lm_kernel`) is shared through it, so that
        pinning a joint at many values (`optik.solve_ik_all` with ``fixed=``) compiles once."""
        return self._geometry_of or self

    def _rebuild(self, joints: Sequence[Joint]) -> Mechanism:
        extra = {k: v for k, v in self.frames.items() if k not in self.topology.bodies}
        return _restore(
            joints,
            self.base,
            extra,
            self.ee,
            self.name,
            self.task,
            self.kind,
            self.params,
            self.inertials,
            self.linear_closures,
        )

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickle the definition (joints, frames, names, catalog data) only: the symbolic model
        and the compiled functions are rebuilt on first use after unpickling (CasADi symbols do
        not pickle; e.g. Dask ships a mechanism to its workers this way)."""
        extra = {k: v for k, v in self.frames.items() if k not in self.topology.bodies}
        names = (self.ee, self.name, self.task, self.kind)
        closures = self.linear_closures
        definition = (self.joints, self.base, extra, *names, self.params, self.inertials, closures)
        return _restore, definition


def _restore(
    joints: Sequence[Joint],
    base: str,
    frames: Mapping[str, tuple[str, Any]],
    ee: str,
    name: str,
    task: str,
    kind: str | None,
    params: dict[str, Any],
    inertials: Mapping[str, tuple[float, Any]] | None = None,
    linear_closures: Sequence[LinearClosure] = (),
) -> Mechanism:
    """A mechanism from its definition, with its catalog kind and parameters."""
    m = Mechanism(joints, base, frames, ee, name, task, inertials, linear_closures)
    m.kind = kind
    m.params = dict(params)
    return m
