"""MJCF builder: the joints, frames and visuals of a MuJoCo model, for `Mechanism.from_mjcf`.

The model is compiled by MuJoCo itself (``mujoco.MjModel``, the optional extra ``mjcf``), so
includes, defaults, ``<compiler angle=... eulerseq=...>``, ``autolimits`` and frames behave as
they do in MuJoCo; `parse_mjcf` then reads the compiled arrays (``body_pos``, ``body_quat``,
``jnt_pos``, ``jnt_axis``, ``jnt_range``, ``qpos0``, ...). Names: MuJoCo's world body is the base
``"world"``; unnamed bodies, joints and sites are called ``body<id>``, ``joint<id>``, ``site<id>``.

Bodies and joints. A MuJoCo body with joints ``j_1 ... j_k`` moves, relative to its parent, by

```
T_body = T_parent Trans(body_pos) R(body_quat) M_1(q_1) ... M_k(q_k)
```

where each joint acts about its anchor ``a = jnt_pos`` in the body frame:

* ``hinge``: ``M = Trans(a) Rot(axis, q - qpos0) Trans(-a)``: an optik ``revolute`` joint with
  ``origin = Trans(a) Rot(axis, -qpos0)`` and ``child_offset = Trans(a)``, so its coordinate is
  MuJoCo's ``qpos`` itself (``qpos0`` is the joint's ``ref``);
* ``slide``: ``M = Trans((q - qpos0) axis)``: ``prismatic``, ``origin = Trans(-qpos0 axis)``;
* ``ball``: ``M = Trans(a) R(quat) Trans(-a)``: ``spherical``, whose three coordinates are the
  rotation vector of the joint's quaternion;
* ``free``: the body's pose in the world is ``Trans(p) R(quat)`` whatever its parent: an optik
  ``free`` joint from the world, coordinates ``p`` and the rotation vector of ``quat``.

A body with several joints gets an intermediate body per joint but the last, named
``<body>/<joint>`` (the pose after that joint). A body without joints is *fixed*: a frame on the
nearest moving ancestor, like a URDF fixed joint; so is a mocap body (at its compiled pose, as
``mj_kinematics`` places it before any ``mocap_pos`` is set). `to_qpos` and `from_qpos`
convert between optik's coordinates and MuJoCo's ``qpos``.

Limits: a joint with ``jnt_limited`` has ``jnt_range`` as its limits; one without is unbounded
(its angle wraps). A limited ball joint bounds the rotation angle, ``|w| <= range[1]``, which
is not a box: its rotation vector gets the box ``[-range[1], range[1]]^3``, which holds that
ball but is larger (said in ``params["notes"]``).

Frames: every body (fixed ones included) is a frame named after it; every site is a frame
named after it, unless a body already has that name, then ``site:<name>``
(``params["site_frames"]`` maps each site to its frame). Geoms are kept in ``params["visuals"]``
(`optik.mechanism.urdf_visuals.Visual`, drawn by `optik.view`): spheres, boxes, cylinders,
capsules, ellipsoids (unit spheres with ``scale``) and meshes (the asset file, placed so that
MuJoCo's re-centring of the mesh is undone); planes, height fields and SDFs are not kept.

Actuation: when the model has actuators, the joints an actuator drives directly (joint
transmission) are actuated and the others passive (inputs and unknowns of `optik.solve_fk`);
without actuators every joint is actuated.

Equality constraints (active at start): ``connect`` becomes a cut spherical joint between the two
bodies (or sites) at the anchors, so its loop-closure residual is MuJoCo's constraint residual
(``efc_pos``, opposite sign); ``weld`` a cut fixed joint (the frame ``relpose`` on body 1 held on
the frame at ``anchor`` on body 2, or the two sites' frames): MuJoCo's position residual (opposite
sign) and rotation rows of norm ``2 sin(theta / 2)`` where MuJoCo's have ``sin(theta / 2)``;
``tendon`` on one fixed tendon (length ``sum_k c_k q_k`` held at its qpos0 value plus
``polycoef[0]``) of two joints makes the second joint follow the first (a `Mimic`), of three or
more joints (or of a coupled one) is one loop-closure row ``sum_k c_k q_k - L`` (a
`LinearClosure`: MuJoCo's residual ``efc_pos`` of the equality, same sign); ``joint`` with a
linear polynomial, ``q1 - qpos0_1 = c0 + c1 (q2 - qpos0_2)``, makes joint 1 follow joint 2 (a
`Mimic`; joint 1 has no coordinate and its own range is not enforced, as for URDF mimic joints).
Not modelled, and listed in ``params["notes"]``: ``tendon`` equalities on spatial tendons or on
two tendons, all ``flex`` equalities, nonlinear joint polynomials, inactive equalities, and the
tendons not made couplings or rows (their length ranges, and actuators on them).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from optik import spatial
from optik.checks import as_vector
from optik.errors import InvalidArgumentError, MissingExtraError, ModelError
from optik.mechanism.joint import Joint, LinearClosure, Mimic
from optik.mechanism.parsed import ParsedModel
from optik.mechanism.urdf_visuals import Visual

__all__ = ["from_qpos", "load_mjmodel", "parse_mjcf", "to_qpos"]

_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3
_GEOM_PLANE, _GEOM_HFIELD, _GEOM_SPHERE, _GEOM_CAPSULE = 0, 1, 2, 3
_GEOM_ELLIPSOID, _GEOM_CYLINDER, _GEOM_BOX, _GEOM_MESH = 4, 5, 6, 7
_EQ_CONNECT, _EQ_WELD, _EQ_JOINT, _EQ_TENDON, _OBJ_SITE, _WRAP_JOINT, _TRN_TENDON = 0, 1, 2, 3, 6, 1, 3


def load_mjmodel(source: Any) -> tuple[Any, str]:
    """``(mujoco.MjModel, label)`` of a file path, MJCF text or an ``MjModel``.

    Raises:
        MissingExtraError: the ``mujoco`` package is not installed.
        InvalidArgumentError: ``source`` is neither an existing file, MJCF text nor an ``MjModel``.
        ModelError: MuJoCo's compiler rejects the model (its message is kept).
    """
    try:
        import mujoco
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingExtraError('from_mjcf needs MuJoCo: pip install "optik[mjcf]"') from exc
    if isinstance(source, mujoco.MjModel):
        return source, "<MjModel>"
    if isinstance(source, str) and "<" in source:
        loader, label = mujoco.MjModel.from_xml_string, "<string>"
    elif isinstance(source, str | os.PathLike) and Path(source).is_file():
        loader, label = mujoco.MjModel.from_xml_path, str(source)
    else:
        what = f"expected an MJCF file, MJCF text or an MjModel, got {source!r}"
        raise InvalidArgumentError("source", what)
    try:
        return loader(str(source)), label
    except ValueError as exc:
        raise ModelError(f"{label}: MuJoCo cannot compile the model: {exc}") from exc


def _quat_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrix of a MuJoCo quaternion ``(w, x, y, z)`` (normalized first, as MuJoCo does)."""
    w, x, y, z = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _pose(pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
    return spatial.transform(_quat_matrix(quat), np.asarray(pos, dtype=float))


def _quat_to_rotvec(quat: np.ndarray) -> np.ndarray:
    """Rotation vector ``w`` (``|w| <= pi``) of a quaternion ``(w, x, y, z)``."""
    q = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    if q[0] < 0:
        q = -q
    s = np.linalg.norm(q[1:])
    if s < 1e-12:
        return 2.0 * q[1:]  # first order; exact to rounding for these magnitudes
    return 2.0 * np.arctan2(s, q[0]) * q[1:] / s


def _rotvec_to_quat(w: np.ndarray) -> np.ndarray:
    t = float(np.linalg.norm(w))
    if t < 1e-12:
        return np.concatenate([[1.0], 0.5 * w])
    return np.concatenate([[np.cos(t / 2)], np.sin(t / 2) * w / t])


def _names(model: Any, kind: str, count: int, adr: np.ndarray) -> list[str]:
    """Names of ``count`` objects from MuJoCo's name buffer (``<kind><id>`` when unnamed)."""
    raw = bytes(model.names)
    out = []
    for i in range(count):
        start = int(adr[i])
        name = raw[start : raw.index(b"\0", start)].decode()
        out.append(name or f"{kind}{i}")
    return out


def _claim(taken: set[str], name: str, label: str, what: str) -> str:
    if name in taken:
        raise ModelError(f"{label}: {what} {name!r} clashes with another frame name")
    taken.add(name)
    return name


def _mesh_path(model: Any, mesh: int) -> Path | None:
    adr = int(model.mesh_pathadr[mesh])
    if adr < 0:
        return None
    raw = bytes(model.paths)
    path = Path(raw[adr : raw.index(b"\0", adr)].decode())
    return path if path.is_file() else None


def _visual(model: Any, g: int, frame: str) -> Visual | None:
    """The geom ``g`` as a `Visual` of its body's frame (None for planes, height fields, SDFs)."""
    kind, size = int(model.geom_type[g]), model.geom_size[g]
    origin = _pose(model.geom_pos[g], model.geom_quat[g])
    if kind == _GEOM_SPHERE:
        return Visual(frame, origin, "sphere", size=(float(size[0]),))
    if kind == _GEOM_CAPSULE:
        return Visual(frame, origin, "capsule", size=(float(size[0]), 2.0 * float(size[1])))
    if kind == _GEOM_CYLINDER:
        return Visual(frame, origin, "cylinder", size=(float(size[0]), 2.0 * float(size[1])))
    if kind == _GEOM_BOX:
        return Visual(frame, origin, "box", size=tuple(2.0 * float(s) for s in size))
    if kind == _GEOM_ELLIPSOID:
        scale = (float(size[0]), float(size[1]), float(size[2]))
        return Visual(frame, origin, "sphere", scale=scale, size=(1.0,))
    if kind == _GEOM_MESH:
        mesh = int(model.geom_dataid[g])
        path = _mesh_path(model, mesh)
        # MuJoCo stores the vertices as R^T (scale v_file - pos): undo that placement
        recentre = _pose(model.mesh_pos[mesh], model.mesh_quat[mesh])
        scale = tuple(float(s) for s in model.mesh_scale[mesh])
        filename = None if path is None else str(path)
        return Visual(frame, origin @ np.linalg.inv(recentre), "mesh", filename, path, scale)  # type: ignore[arg-type]
    return None


def _joint(
    model: Any, j: int, name: str, parent: str, child: str, pending: np.ndarray, notes: list[str]
) -> Joint:
    """The optik joint of MuJoCo joint ``j`` (see the module docstring for the placement)."""
    kind = int(model.jnt_type[j])
    anchor = spatial.transform(position=np.asarray(model.jnt_pos[j], dtype=float))
    axis = np.asarray(model.jnt_axis[j], dtype=float)
    limited = bool(model.jnt_limited[j])
    lo, hi = (float(v) for v in model.jnt_range[j])
    ref = float(model.qpos0[model.jnt_qposadr[j]])
    if kind == _FREE:
        return Joint(name, "free", parent, child)
    if kind == _BALL:
        bound = (-hi,) * 3 if limited else (-np.inf,) * 3
        if limited:
            notes.append(
                f"ball joint {name!r}: the angle limit {hi:g} rad is kept as the box [-{hi:g}, {hi:g}]^3 "
                "of its rotation vector, which is larger than the ball |w| <= limit"
            )
        return Joint(
            name,
            "spherical",
            parent,
            child,
            pending @ anchor,
            child_offset=anchor,
            lower=bound,
            upper=tuple(-b for b in bound),
        )
    lower, upper = ((lo,), (hi,)) if limited else ((-np.inf,), (np.inf,))
    if kind == _SLIDE:
        origin = pending @ spatial.transform(position=-ref * axis)
        return Joint(name, "prismatic", parent, child, origin, axis, lower=lower, upper=upper)
    origin = pending @ anchor @ spatial.transform(_axis_rotation(axis, -ref))
    return Joint(name, "revolute", parent, child, origin, axis, lower=lower, upper=upper, child_offset=anchor)


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    k = spatial.hat(axis / np.linalg.norm(axis))
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def parse_mjcf(source: Any) -> ParsedModel:
    """A MuJoCo model's whole body tree as optik joints and frames.

    Args:
        source: an MJCF file path, MJCF text (any string containing ``<``) or a
            ``mujoco.MjModel``.

    Returns:
        The model (a [`ParsedModel`][optik.mechanism.parsed.ParsedModel]); coordinates in
        MuJoCo's joint order; ``params``: ``"mjcf"`` (source label), ``"qpos_map"`` (per joint
        with a coordinate: MuJoCo type, optik coordinate index, ``qpos`` address; used by
        `to_qpos` and `from_qpos`), ``"qpos_mimics"`` (per coupled joint: ``qpos`` address,
        source coordinate, multiplier, offset), ``"nq"`` (MuJoCo's ``nq``), ``"site_frames"``,
        ``"visuals"`` and ``"notes"`` (what was not read and why, when anything was not);
        ``inertials``: the bodies with a mass (fixed bodies included; MuJoCo's compiler has
        already derived masses from geoms where asked).

    Raises:
        MissingExtraError: MuJoCo is not installed (``pip install "optik[mjcf]"``).
        InvalidArgumentError: ``source`` is none of the above.
        ModelError: MuJoCo rejects the model, the model has no joint, or two frames would have
            one name (a generated name such as ``body3`` taken by a named object).
    """
    model, label = load_mjmodel(source)
    if model.njnt == 0:
        raise ModelError(f"{label}: the model has no joint")
    bodies = _names(model, "body", model.nbody, model.name_bodyadr)
    joints_named = _names(model, "joint", model.njnt, model.name_jntadr)
    sites = _names(model, "site", model.nsite, model.name_siteadr)
    bodies[0] = "world"
    taken: set[str] = set()
    for b in bodies:
        _claim(taken, b, label, "body")
    notes: list[str] = []
    place: dict[int, tuple[str, np.ndarray]] = {0: ("world", np.eye(4))}
    frames: dict[str, tuple[str, np.ndarray]] = {}
    joints: list[Joint] = []
    depth = {0: 0}
    for b in range(1, model.nbody):
        parent = int(model.body_parentid[b])
        body, offset = place[parent]
        pending = offset @ _pose(model.body_pos[b], model.body_quat[b])
        first, count = int(model.body_jntadr[b]), int(model.body_jntnum[b])
        depth[b] = depth[parent] + count
        if count == 0:
            place[b] = frames[bodies[b]] = (body, pending)
            if model.body_mocapid[b] >= 0:
                notes.append(f"mocap body {bodies[b]!r} is fixed at its compiled pose")
            continue
        for k, j in enumerate(range(first, first + count)):
            last = k == count - 1
            child = bodies[b] if last else _claim(taken, f"{bodies[b]}/{joints_named[j]}", label, "body")
            if int(model.jnt_type[j]) == _FREE:
                body, pending = "world", np.eye(4)
            joints.append(_joint(model, j, joints_named[j], body, child, pending, notes))
            body, pending = child, np.eye(4)
        place[b] = (bodies[b], np.eye(4))
    site_frames: dict[str, str] = {}
    for s, name in enumerate(sites):
        frame = name if name not in taken else f"site:{name}"
        _claim(taken, frame, label, "site")
        body, offset = place[int(model.site_bodyid[s])]
        frames[frame] = (body, offset @ _pose(model.site_pos[s], model.site_quat[s]))
        site_frames[name] = frame
    visuals = [v for g in range(model.ngeom) if (v := _visual(model, g, bodies[model.geom_bodyid[g]]))]
    ee = bodies[max(range(model.nbody), key=lambda b: (depth[b], -b))]
    if model.nu:  # with actuators, the joints they drive are the actuated ones
        driven = {int(model.actuator_trnid[u, 0]) for u in range(model.nu) if model.actuator_trntype[u] == 0}
        joints[:] = [jt if j in driven else replace(jt, actuated=False) for j, jt in enumerate(joints)]
    cuts, rows, coupled = _equalities(model, joints, joints_named, place, site_frames, frames, notes)
    coords, qpos_map, first = 0, [], {}
    for j, joint in enumerate(joints):
        first[joint.name] = coords
        if joint.mimic is None:
            qpos_map.append((int(model.jnt_type[j]), coords, int(model.jnt_qposadr[j])))
        coords += joint.dof
    mimics = tuple(
        (int(model.jnt_qposadr[j]), first[jt.mimic.joint], jt.mimic.multiplier, jt.mimic.offset)
        for j, jt in enumerate(joints)
        if jt.mimic is not None
    )
    joints.extend(cuts)
    notes.extend(_tendon_notes(model, coupled))
    params: dict[str, object] = {
        "mjcf": label,
        "nq": int(model.nq),
        "qpos_map": tuple(qpos_map),
        "qpos_mimics": mimics,
        "site_frames": site_frames,
        "visuals": tuple(visuals),
    }
    if notes:
        params["notes"] = tuple(notes)
    raw = bytes(model.names)
    name = raw[: raw.index(b"\0")].decode() or "mjcf"
    inertials = {
        bodies[b]: (float(model.body_mass[b]), np.array(model.body_ipos[b], dtype=float))
        for b in range(1, model.nbody)
        if model.body_mass[b] > 0
    }
    return ParsedModel(name, "world", tuple(joints), frames, ee, params, inertials, tuple(rows))


def _equalities(
    model: Any,
    joints: list[Joint],
    joint_names: list[str],
    place: dict[int, tuple[str, np.ndarray]],
    site_frames: dict[str, str],
    frames: dict[str, tuple[str, np.ndarray]],
    notes: list[str],
) -> tuple[list[Joint], list[LinearClosure], set[int]]:
    """The active ``<equality>`` constraints: ``connect`` and ``weld`` as cut joints (loop
    closures), ``joint`` with a linear polynomial and ``tendon`` on a two-joint fixed tendon as
    mimic couplings (``joints`` is updated in place), ``tendon`` on a fixed tendon of three or
    more joints as a `LinearClosure` row; the cut joints, the rows and the ids of the tendons
    made couplings or rows are returned. What is not modelled goes to ``notes``."""
    eq_names = _names(model, "equality", model.neq, model.name_eqadr)
    sites = _names(model, "site", model.nsite, model.name_siteadr)
    kinds = {0: "connect", 1: "weld", 2: "joint", 3: "tendon", 4: "flex"}
    cuts: list[Joint] = []
    rows: list[LinearClosure] = []
    coupled_tendons: set[int] = set()
    for e in range(model.neq):
        kind, name = int(model.eq_type[e]), eq_names[e]
        what = f"equality {kinds.get(kind, kind)} {name!r}"
        if not model.eq_active0[e]:
            notes.append(f"{what} is inactive at start and is not modelled")
            continue
        a, b, data = (
            int(model.eq_obj1id[e]),
            int(model.eq_obj2id[e]),
            np.asarray(model.eq_data[e], dtype=float),
        )
        if kind == _EQ_CONNECT:
            if int(model.eq_objtype[e]) == _OBJ_SITE:
                (pa, oa), (pb, ob) = frames[site_frames[sites[a]]], frames[site_frames[sites[b]]]
            else:
                (pa, oa), (pb, ob) = place[a], place[b]
                oa = oa @ spatial.transform(position=data[0:3])
                ob = ob @ spatial.transform(position=data[3:6])
            if pa == pb:
                notes.append(f"{what} joins two points of one rigid body and is not modelled")
                continue
            cuts.append(Joint(f"equality:{name}", "spherical", pa, pb, oa, child_offset=ob, cut=True))
        elif kind == _EQ_WELD:
            # MuJoCo: p1 + R1 relpos = p2 + R2 anchor and R1 relquat = R2 (body semantic; sites: the
            # two site frames coincide)
            if int(model.eq_objtype[e]) == _OBJ_SITE:
                (pa, oa), (pb, ob) = frames[site_frames[sites[a]]], frames[site_frames[sites[b]]]
            else:
                (pa, oa), (pb, ob) = place[a], place[b]
                oa = oa @ _pose(data[3:6], data[6:10])
                ob = ob @ spatial.transform(position=data[0:3])
            if pa == pb:
                notes.append(f"{what} welds a rigid body to itself and is not modelled")
                continue
            cuts.append(Joint(f"equality:{name}", "fixed", pa, pb, oa, child_offset=ob, cut=True))
        elif kind == _EQ_JOINT and b >= 0 and not np.any(data[2:5]):
            follower, source = joints[a], joints[b]
            if follower.type not in ("revolute", "prismatic") or source.type not in ("revolute", "prismatic"):
                notes.append(f"{what} couples a ball or free joint and is not modelled")
                continue
            if follower.mimic is not None or source.mimic is not None:
                notes.append(f"{what} couples a coupled joint and is not modelled")
                continue
            # q_a - qpos0_a = c0 + c1 (q_b - qpos0_b)
            q0a, q0b = float(model.qpos0[model.jnt_qposadr[a]]), float(model.qpos0[model.jnt_qposadr[b]])
            coupling = Mimic(joint_names[b], float(data[1]), q0a + float(data[0]) - float(data[1]) * q0b)
            joints[a] = replace(follower, mimic=coupling, lower=None, upper=None)
            notes.append(
                f"{what}: joint {joint_names[a]!r} follows {joint_names[b]!r}; its own range is not enforced"
            )
        elif kind == _EQ_TENDON and b < 0:
            coupled = _tendon_coupling(model, a, float(data[0]), joints, joint_names, f"equality:{name}")
            if isinstance(coupled, str):
                notes.append(f"{what} {coupled}")
                continue
            coupled_tendons.add(a)
            if isinstance(coupled, LinearClosure):
                rows.append(coupled)
                notes.append(
                    f"{what}: a loop-closure row, its fixed tendon of {len(coupled.coefficients)} joints "
                    "held at constant length"
                )
                continue
            follower, coupling = coupled
            joints[follower] = replace(joints[follower], mimic=coupling, lower=None, upper=None)
            notes.append(
                f"{what}: joint {joint_names[follower]!r} follows {coupling.joint!r} (fixed tendon of "
                "constant length); its own range is not enforced"
            )
        else:
            notes.append(
                f"{what} is not modelled (only connect, weld, linear joint and fixed-tendon equalities are)"
            )
    return cuts, rows, coupled_tendons


def _tendon_notes(model: Any, coupled: set[int]) -> list[str]:
    """What is not modelled of the tendons not made couplings or closure rows (``coupled``):
    their lengths constrain no configuration here, so a length range (``limited``) is not
    enforced and an actuator on one drives no coordinate. Empty when every tendon is one."""
    rest = [t for t in range(model.ntendon) if t not in coupled]
    if not rest:
        return []
    names = _names(model, "tendon", model.ntendon, model.name_tendonadr)
    listed = ", ".join(repr(names[t]) for t in rest)
    note = (
        f"{len(rest)} of {model.ntendon} tendon(s) are not modelled ({listed}): no coupling, constraint or "
        "limit comes from their lengths"
    )
    if limited := [repr(names[t]) for t in rest if model.tendon_limited[t]]:
        note += f"; the length range of {', '.join(limited)} is not enforced"
    on = {
        int(model.actuator_trnid[u, 0]) for u in range(model.nu) if model.actuator_trntype[u] == _TRN_TENDON
    }
    if driven := [repr(names[t]) for t in rest if t in on]:
        note += f"; the actuators on {', '.join(driven)} drive no coordinate"
    return [note]


def _tendon_coupling(
    model: Any, tendon: int, shift: float, joints: list[Joint], joint_names: list[str], label: str
) -> tuple[int, Mimic] | LinearClosure | str:
    """What a tendon equality on one fixed tendon makes: MuJoCo holds its length
    ``L = sum_k c_k q_k`` at ``L0 + shift`` (``L0``: the length at qpos0). Of two free joints,
    joint ``b`` follows ``a``: ``q_b = -(c_a / c_b) q_a + (L0 + shift) / c_b`` (a coupling);
    otherwise (three or more joints, or a coupled one) the row ``sum_k c_k q_k - (L0 + shift)``
    named ``label``, MuJoCo's residual of the equality. Why not, for a spatial tendon or a ball
    or free joint (a str)."""
    first, count = int(model.tendon_adr[tendon]), int(model.tendon_num[tendon])
    wraps = [
        (int(model.wrap_type[w]), int(model.wrap_objid[w]), float(model.wrap_prm[w]))
        for w in range(first, first + count)
    ]
    if any(kind != _WRAP_JOINT for kind, _, _ in wraps):
        return "is on a spatial tendon, and is not modelled"
    if any(joints[j].type not in ("revolute", "prismatic") for _, j, _ in wraps):
        return "couples a ball or free joint and is not modelled"
    length = float(model.tendon_length0[tendon]) + shift
    if count == 2:
        (_, ja, ca_), (_, jb, cb) = wraps
        if joints[ja].mimic is None and joints[jb].mimic is None and cb != 0.0:
            return jb, Mimic(joint_names[ja], -ca_ / cb, length / cb)
    return LinearClosure(label, tuple((joint_names[j], c) for _, j, c in wraps), length)


def _qpos_map(m: Any) -> tuple[tuple[int, int, int], ...]:
    qmap = getattr(m, "params", {}).get("qpos_map")
    if qmap is None:
        raise InvalidArgumentError("m", "expected a mechanism loaded by Mechanism.from_mjcf")
    return qmap


def to_qpos(m: Any, q: Any) -> np.ndarray:
    """MuJoCo's ``qpos`` (length ``nq``) of optik coordinates ``q`` of a `Mechanism.from_mjcf` model.

    Hinge and slide coordinates are copied; a ball joint's rotation vector ``w`` and a free
    joint's ``(p, w)`` become ``exp(w)`` as a unit quaternion ``(cos(|w|/2), sin(|w|/2) w/|w|)``.

    Raises:
        InvalidArgumentError: ``m`` was not loaded from MJCF, or ``q`` has the wrong size.
    """
    qmap = _qpos_map(m)
    qq = as_vector(q, "q", m.n_q)
    qpos = np.zeros(int(m.params["nq"]))
    for a, i, multiplier, offset in m.params.get("qpos_mimics", ()):
        qpos[a] = multiplier * qq[i] + offset
    for kind, i, a in qmap:
        if kind == _FREE:
            qpos[a : a + 3] = qq[i : i + 3]
            qpos[a + 3 : a + 7] = _rotvec_to_quat(qq[i + 3 : i + 6])
        elif kind == _BALL:
            qpos[a : a + 4] = _rotvec_to_quat(qq[i : i + 3])
        else:
            qpos[a] = qq[i]
    return qpos


def from_qpos(m: Any, qpos: Any) -> np.ndarray:
    """optik coordinates of MuJoCo's ``qpos`` (the inverse of `to_qpos`; rotation vectors with
    ``|w| <= pi``; quaternions need not be normalized).

    Raises:
        InvalidArgumentError: ``m`` was not loaded from MJCF, or ``qpos`` has the wrong size.
    """
    qmap = _qpos_map(m)
    qp = as_vector(qpos, "qpos", int(m.params["nq"]))
    q = np.zeros(m.n_q)
    for kind, i, a in qmap:
        if kind == _FREE:
            q[i : i + 3] = qp[a : a + 3]
            q[i + 3 : i + 6] = _quat_to_rotvec(qp[a + 3 : a + 7])
        elif kind == _BALL:
            q[i : i + 3] = _quat_to_rotvec(qp[a : a + 4])
        else:
            q[i] = qp[a]
    return q
