"""URDF builder: the joints, frames and visuals of a URDF robot, for `Mechanism.from_urdf`.

`parse_urdf` reads a URDF file or text (safely and as ROS tools do: see
`optik.mechanism.urdf_xml`) and loads

* the **whole tree** when neither ``base_link`` nor ``tip_link`` is given: the root link (the
  one link that is no joint's child) is the base and every link is a named frame;
* the **subtree** below ``base_link`` when only that is given;
* the **chain** from ``base_link`` (default: the root link) down to ``tip_link``, which becomes
  the end effector. The links hanging off the path (a tool flange, a camera, the Panda's hand
  and fingers when the tip is the flange) stay as named frames, rigidly attached: a fixed joint
  keeps its origin, a moving joint off the path is *held* at 0 clipped into its limits (its
  value is in ``params["held_joints"]``), so the chain keeps the geometry of every link it
  carries and no coordinate is added.

It imports only the joint layer, so that `optik.mechanism.mechanism` builds on it without an
import cycle.

Joints (coordinates in depth-first order from the base, children in document order, so a chain
has them from base to tip):

* ``revolute``: rotation about ``axis``, limits from ``<limit lower upper>`` (required);
* ``continuous``: a revolute joint with infinite limits: its angle wraps (results are reported in
  ``(-pi, pi]``) and no solver puts a wall at +-pi;
* ``prismatic``: translation along ``axis``, limits required;
* ``fixed``: no coordinate; its transform is folded into the origin of the next moving joint
  and the links it passes become named frames, so the model has one coordinate per moving joint
  and no needless bodies;
* ``<mimic joint multiplier offset>`` on a revolute, continuous or prismatic joint: no coordinate
  of its own, ``q = multiplier * q_source + offset`` (`Mimic`; defaults 1 and 0; a mimic of a
  mimic is composed down to a joint with a coordinate). Its own ``<limit>`` is not enforced (as
  in urdfdom-based solvers); the source joint must be part of what is loaded. A ``<mimic>``
  naming no joint of the file is ignored, as MoveIt does, with a warning and a line in
  ``params["notes"]``.
* ``floating`` and ``planar`` joints are rejected (load the part below one with
  ``base_link=<its child>``).

``<origin xyz rpy>`` places the joint frame in the parent link: ``T = Trans(xyz) R`` with
URDF's ``R = Rot(z, yaw) Rot(y, pitch) Rot(x, roll)`` = `optik.spatial.rpy_to_rot`.
``<axis xyz>`` (default ``1 0 0``) is normalized. ``<limit velocity>`` values, when every
joint with a coordinate has a positive one, are kept in ``params["velocity_limits"]``. The
``<visual>`` elements of the loaded links (meshes with ``package://`` or relative names, boxes,
cylinders, spheres) are kept in ``params["visuals"]`` for drawing, their ``<collision>``
elements in ``params["collisions"]`` for `optik.collision` (`optik.mechanism.urdf_visuals`).
Each loaded link's ``<inertial>`` gives its mass (``<mass value>``) and centre of mass
(``<origin xyz>``, in the link frame) for the centre of mass of the robot (`Mechanism.com`).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass

import numpy as np
from lxml import etree

from optik import spatial
from optik.checks import as_name
from optik.errors import ModelError, UnknownFrameError
from optik.mechanism.joint import Joint, Mimic, axis_rotation
from optik.mechanism.parsed import ParsedModel
from optik.mechanism.urdf_visuals import read_visuals
from optik.mechanism.urdf_xml import UrdfXml, read_urdf_xml

__all__ = ["parse_urdf"]

_MOVING = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
_REJECTED = ("floating", "planar")


def _inertials(src: UrdfXml, links: list[etree._Element]) -> dict[str, tuple[float, np.ndarray]]:
    """``{link: (mass, com)}`` from the links' ``<inertial>`` (``<mass value>``, ``<origin xyz>``)."""
    out: dict[str, tuple[float, np.ndarray]] = {}
    for link in links:
        el = link.find("inertial")
        mass = None if el is None else el.find("mass")
        if mass is None:
            continue
        where = f"link {link.get('name')!r} <inertial>"
        value = float(_floats(src, f"{where} <mass value>", mass.get("value"), 1, (0.0,))[0])
        if value < 0:
            raise ModelError(f"{src.label}: {where}: negative mass {value}")
        out[link.get("name")] = (value, _origin(src, el, where)[:3, 3])
    return out


def _floats(src: UrdfXml, where: str, text: str | None, n: int, default: tuple[float, ...]) -> np.ndarray:
    """``n`` finite floats from a whitespace-separated attribute (``default`` when absent)."""
    if text is None:
        return np.array(default, dtype=float)
    try:
        values = [float(p) for p in text.split()]
    except ValueError as exc:
        raise ModelError(f"{src.label}: {where}: expected {n} numbers, got {text!r}") from exc
    if len(values) != n:
        raise ModelError(f"{src.label}: {where}: expected {n} numbers, got {text!r}")
    if not all(map(math.isfinite, values)):  # on the floats: a few numbers, no array reductions
        raise ModelError(f"{src.label}: {where}: values must be finite, got {text!r}")
    return np.array(values)


def _origin(src: UrdfXml, element: etree._Element, where: str) -> np.ndarray:
    """``Trans(xyz) Rot(z, yaw) Rot(y, pitch) Rot(x, roll)`` of an element's ``<origin>``."""
    el = element.find("origin")
    if el is None:
        return np.eye(4)
    xyz = _floats(src, f"{where} <origin xyz>", el.get("xyz"), 3, (0.0, 0.0, 0.0))
    rpy = _floats(src, f"{where} <origin rpy>", el.get("rpy"), 3, (0.0, 0.0, 0.0))
    return spatial.transform(spatial.rpy_to_rot(*rpy), xyz)


def _axis(src: UrdfXml, joint: etree._Element, where: str) -> np.ndarray:
    """The unit joint axis (URDF default ``1 0 0``)."""
    el = joint.find("axis")
    a = _floats(src, f"{where} <axis xyz>", None if el is None else el.get("xyz"), 3, (1.0, 0.0, 0.0))
    norm = float(np.linalg.norm(a))
    if norm < 1e-12:
        raise ModelError(f"{src.label}: {where}: <axis xyz> must be non-zero")
    return a / norm


def _limits(src: UrdfXml, joint: etree._Element, kind: str, where: str) -> tuple[float, float]:
    """``(lower, upper)``: unbounded for continuous joints, else from ``<limit>``, which is
    required; a missing ``lower`` or ``upper`` attribute is 0, as in urdfdom."""
    if kind == "continuous":
        return -np.inf, np.inf
    el = joint.find("limit")
    if el is None:
        raise ModelError(f"{src.label}: {where}: a {kind} joint needs <limit lower=... upper=...>")
    lo = _floats(src, f"{where} <limit lower>", el.get("lower"), 1, (0.0,))[0]
    hi = _floats(src, f"{where} <limit upper>", el.get("upper"), 1, (0.0,))[0]
    if lo > hi:
        raise ModelError(f"{src.label}: {where}: <limit> lower {lo} > upper {hi}")
    return float(lo), float(hi)


def _velocity(src: UrdfXml, joint: etree._Element, where: str) -> float | None:
    """``<limit velocity>`` when given and positive, else None (zero often means "unspecified")."""
    el = joint.find("limit")
    text = None if el is None else el.get("velocity")
    if text is None:
        return None
    v = float(_floats(src, f"{where} <limit velocity>", text, 1, (0.0,))[0])
    return v if v > 0 else None


def _link_of(src: UrdfXml, joint: etree._Element, tag: str, where: str) -> str:
    el = joint.find(tag)
    name = None if el is None else el.get("link")
    if not name:
        raise ModelError(f"{src.label}: {where} has no <{tag} link=...>")
    return name


@dataclass(frozen=True)
class _Tree:
    """The link tree of a document: links in document order, the joint above each child link
    ``{child: (joint element, parent)}`` and the joints below each link, in document order."""

    links: dict[str, etree._Element]
    parent_joint: dict[str, tuple[etree._Element, str]]
    children: dict[str, list[tuple[etree._Element, str]]]


def _tree(src: UrdfXml) -> _Tree:
    links: dict[str, etree._Element] = {}
    for el in src.root.findall("link"):
        name = el.get("name")
        if not name:
            raise ModelError(f"{src.label}: a <link> has no name")
        links[name] = el
    parent_joint: dict[str, tuple[etree._Element, str]] = {}
    children: dict[str, list[tuple[etree._Element, str]]] = {name: [] for name in links}
    seen: set[str] = set()
    for el in src.root.findall("joint"):
        name = el.get("name")
        if not name:
            raise ModelError(f"{src.label}: a <joint> has no name")
        if name in seen:
            raise ModelError(f"{src.label}: duplicate joint name {name!r}")
        seen.add(name)
        where = f"joint {name!r}"
        parent, child = _link_of(src, el, "parent", where), _link_of(src, el, "child", where)
        for link in (parent, child):
            if link not in links:
                raise ModelError(f"{src.label}: {where} refers to unknown link {link!r}")
        if child in parent_joint:
            raise ModelError(
                f"{src.label}: link {child!r} is the child of two joints "
                f"({parent_joint[child][0].get('name')!r} and {name!r}); URDF needs a tree"
            )
        parent_joint[child] = (el, parent)
        children[parent].append((el, child))
    return _Tree(links, parent_joint, children)


def _link(src: UrdfXml, tree: _Tree, link: object, argument: str) -> str:
    name = as_name(link, argument)
    if name not in tree.links:
        raise UnknownFrameError(argument, f"{src.label}: no link {name!r}; links: {sorted(tree.links)}")
    return name


def _root(src: UrdfXml, tree: _Tree) -> str:
    roots = [link for link in tree.links if link not in tree.parent_joint]
    if len(roots) != 1:
        what = f"several root links {roots}" if roots else "no root link (the joints form a cycle)"
        if not tree.links:
            what = "no <link>"
        raise ModelError(f"{src.label}: {what}; pass base_link")
    return roots[0]


def _path(src: UrdfXml, tree: _Tree, base: str, tip: str) -> list[tuple[etree._Element, str]]:
    """Joints from ``base`` down to ``tip`` as ``(element, child link)``."""
    path: list[tuple[etree._Element, str]] = []
    link = tip
    while link != base:
        if link not in tree.parent_joint or len(path) > len(tree.parent_joint):
            raise ModelError(f"{src.label}: tip_link {tip!r} is not downstream of base_link {base!r}")
        el, parent = tree.parent_joint[link]
        path.append((el, link))
        link = parent
    path.reverse()
    return path


def _subtree(tree: _Tree, base: str) -> list[tuple[etree._Element, str]]:
    """Every joint below ``base`` as ``(element, child link)``, depth first, children in
    document order (an explicit stack: no recursion limit on deep trees)."""
    out: list[tuple[etree._Element, str]] = []
    stack = list(reversed(tree.children[base]))
    while stack:
        el, child = stack.pop()
        out.append((el, child))
        stack.extend(reversed(tree.children[child]))
    return out


def _mimic(src: UrdfXml, el: etree._Element, where: str) -> Mimic | None:
    m = el.find("mimic")
    if m is None:
        return None
    source = m.get("joint")
    if not source:
        raise ModelError(f"{src.label}: {where} <mimic> has no joint=...")
    mult = _floats(src, f"{where} <mimic multiplier>", m.get("multiplier"), 1, (1.0,))[0]
    off = _floats(src, f"{where} <mimic offset>", m.get("offset"), 1, (0.0,))[0]
    return Mimic(source, float(mult), float(off))


def _resolve_mimics(src: UrdfXml, mimics: dict[str, Mimic | None]) -> dict[str, Mimic]:
    """Each mimic composed down to a joint with a coordinate (``q_b = a q_c + b`` and
    ``q_a = a' q_b + b'`` give ``q_a = a' a q_c + a' b + b'``)."""
    out: dict[str, Mimic] = {}
    for name, mimic in mimics.items():
        if mimic is None:
            continue
        mult, off, source, seen = mimic.multiplier, mimic.offset, mimic.joint, {name}
        while (nxt := mimics.get(source)) is not None:
            if source in seen:
                raise ModelError(
                    f"{src.label}: joint {name!r}: the <mimic> joints form a cycle through {source!r}"
                )
            seen.add(source)
            mult, off, source = mult * nxt.multiplier, mult * nxt.offset + off, nxt.joint
        if source not in mimics:
            raise ModelError(
                f"{src.label}: joint {name!r} mimics {source!r}, which is not a moving joint of the loaded "
                "part; load the whole tree or a part that holds both"
            )
        out[name] = Mimic(source, mult, off)
    return out


FLOATING_WORLD, FLOATING_JOINT = "world", "root_joint"
"""The fixed body and the free joint that ``floating_base=True`` adds (Pinocchio's names)."""


def _float_base(
    src: UrdfXml, tree: _Tree, base: str, specs: list[dict[str, object]], velocities: list[float | None]
) -> None:
    """Prepend the free joint ``world -> base`` (six coordinates, unbounded speeds)."""
    if FLOATING_WORLD in tree.links:
        raise ModelError(
            f"{src.label}: floating_base=True adds a body {FLOATING_WORLD!r}, but the robot has a link of "
            "that name; load the part below it with base_link=..."
        )
    if FLOATING_JOINT in {el.get("name") for el, _ in tree.parent_joint.values()}:
        what = f"floating_base=True adds a joint {FLOATING_JOINT!r}, which the robot has"
        raise ModelError(f"{src.label}: {what}")
    specs.insert(0, {"name": FLOATING_JOINT, "type": "free", "parent": FLOATING_WORLD, "child": base})
    velocities[:0] = [np.inf] * 6


TOOL_NAME = re.compile(r"(?:^|[^a-z])(?:tool\d*|tcp|ee|eef|end_?effector)(?:[^a-z]|$)", re.IGNORECASE)
"""A link name that says it is a tool frame: a word ``tool`` (``tool0``...), ``tcp``, ``ee``,
``eef`` or ``end_effector`` between non-letters (``left_tool``, ``panda_hand_tcp``,
``iiwa_link_ee``; not ``wheel``)."""


def _default_ee(tree: _Tree, selected: list[tuple[etree._Element, str]], base: str) -> str:
    """The end effector of a whole tree (or subtree): one of its leaves (links no joint leaves).

    A leaf named as a tool frame (`TOOL_NAME`) wins over one that is not; then the leaf with the
    most moving joints from ``base``; then a leaf without ``<visual>`` or ``<collision>`` (a
    frame rather than a body such as a finger); then the first in document order. So fingers or
    other bodies listed after a tool frame, or deeper than it (the Panda's prismatic fingers
    below its ``panda_hand_tcp``), do not become the end effector.
    """
    depth = {base: 0}
    parents = set()
    for el, child in selected:
        parent = el.find("parent").get("link")
        parents.add(parent)
        depth[child] = depth[parent] + (el.get("type") != "fixed")
    leaves = [child for _, child in selected if child not in parents]

    def rank(link: str) -> tuple[bool, int, bool]:
        el = tree.links[link]
        bare = el.find("visual") is None and el.find("collision") is None
        return TOOL_NAME.search(link) is not None, depth[link], bare

    return max(leaves, key=rank)  # max keeps the first of equal rank


def _held_value(src: UrdfXml, el: etree._Element, kind: str, where: str) -> float:
    """The value a moving joint off the chain is held at: 0 clipped into its limits (0 for a
    mimic or continuous joint, whose own limits are not enforced)."""
    if kind == "continuous" or el.find("mimic") is not None or el.find("limit") is None:
        return 0.0
    lo, hi = _limits(src, el, kind, where)
    return float(min(max(0.0, lo), hi))


def _off_path(
    src: UrdfXml, tree: _Tree, place: dict[str, tuple[str, np.ndarray]]
) -> tuple[dict[str, tuple[str, np.ndarray]], dict[str, float]]:
    """The links below the loaded ones that the chain does not pass, rigidly attached:
    ``({link: (body, offset)}, {held joint: value})``, depth first."""
    frames: dict[str, tuple[str, np.ndarray]] = {}
    held: dict[str, float] = {}
    stack = [(el, c, link) for link in place for el, c in reversed(tree.children[link]) if c not in place]
    known = dict(place)
    while stack:
        el, child, parent = stack.pop()
        name = el.get("name")
        where = f"joint {name!r}"
        kind = el.get("type")
        body, pending = known[parent]
        offset = pending @ _origin(src, el, where)
        if kind in _MOVING:
            held[name] = _held_value(src, el, kind, where)
            if held[name] != 0.0:
                axis = _axis(src, el, where)
                if kind == "prismatic":
                    motion = spatial.transform(position=held[name] * axis)
                else:
                    motion = spatial.transform(axis_rotation(axis, held[name]))
                offset = offset @ motion
        elif kind != "fixed":
            continue  # a floating or planar joint off the chain: its links are not carried
        known[child] = frames[child] = (body, offset)
        stack.extend((e, c, child) for e, c in reversed(tree.children[child]))
    return frames, held


def parse_urdf(
    source: str | os.PathLike[str],
    base_link: str | None = None,
    tip_link: str | None = None,
    floating_base: bool = False,
) -> ParsedModel:
    """A URDF robot's whole tree, the subtree below ``base_link``, or the chain to ``tip_link``.

    Every moving joint becomes a `Joint` named after the URDF joint; its pose is
    ``T_child = T_parent @ F @ origin @ motion(q)`` where ``F`` is the product of the origins
    of the fixed joints just before it (identity if none). Links reached through fixed joints
    become named frames on the last moving body, so ``m.fk(q, frame=link)`` works for every
    loaded link.

    Args:
        source: path of a URDF file, or the URDF XML text itself (any string containing ``<``).
        base_link: the fixed link, the mechanism's base body (default: the root link).
        tip_link: the end-effector link (default: load the whole tree below ``base_link``).
        floating_base: add a free joint ``"root_joint"`` (six coordinates: the base link's
            position and rotation vector in a new fixed body ``"world"``, the first coordinates
            of the model) above ``base_link``, as Pinocchio's ``JointModelFreeFlyer``.

    Returns:
        The model (a [`ParsedModel`][optik.mechanism.parsed.ParsedModel]) named after the
        ``<robot name>``; ``params``: ``"urdf"`` (source label), ``"base_link"``,
        ``"tip_link"`` (None for a tree), ``"visuals"`` and ``"collisions"`` (tuples of
        `Visual`), ``"held_joints"`` (``{joint: value}`` of the moving joints off a chain, see
        the module docstring; only for a chain that carries some), ``"notes"`` (what was ignored
        and why, when anything was) and, when every joint with a coordinate has a positive
        ``<limit velocity>``, ``"velocity_limits"`` (rad/s or m/s per coordinate);
        ``inertials``: the loaded links that have an ``<inertial>`` with a ``<mass>``.

    Raises:
        InvalidArgumentError: ``source`` is neither an existing file nor XML text (or not valid
            text); ``base_link`` or ``tip_link`` is not a string.
        UnknownFrameError: ``base_link`` or ``tip_link`` is not a link of the robot.
        ModelError: what `optik.mechanism.urdf_xml.read_urdf_xml` rejects, malformed numbers,
            several root links (pass ``base_link``), a tip that is not downstream of the base, a
            missing ``<limit>``, an unsupported (floating, planar, unknown) joint in the loaded
            part, a mimic of a joint outside it, or no moving joint at all. The message names
            the file and the joint.
    """
    src = read_urdf_xml(source)
    tree = _tree(src)
    base = _root(src, tree) if base_link is None else _link(src, tree, base_link, "base_link")
    tip = None if tip_link is None else _link(src, tree, tip_link, "tip_link")
    selected = _subtree(tree, base) if tip is None else _path(src, tree, base, tip)
    place: dict[str, tuple[str, np.ndarray]] = {base: (base, np.eye(4))}
    specs: list[dict[str, object]] = []
    mimics: dict[str, Mimic | None] = {}
    velocities: list[float | None] = []
    frames: dict[str, tuple[str, np.ndarray]] = {}
    notes: list[str] = []
    joint_names = {el.get("name") for el, _ in tree.parent_joint.values()}
    for el, child in selected:
        name = el.get("name")
        where = f"joint {name!r}"
        kind = el.get("type")
        body, pending = place[el.find("parent").get("link")]
        origin = pending @ _origin(src, el, where)
        if kind == "fixed":
            place[child] = frames[child] = (body, origin)
            continue
        if kind not in _MOVING:
            why = (
                f"is not supported; load the part below it with base_link={child!r}"
                if kind in _REJECTED
                else "is unknown; use revolute, continuous, prismatic, fixed"
            )
            raise ModelError(f"{src.label}: {where}: joint type {kind!r} {why}")
        mimics[name] = _mimic(src, el, where)
        if mimics[name] is not None and mimics[name].joint not in joint_names:
            notes.append(
                f"joint {name!r}: <mimic joint={mimics[name].joint!r}> names no joint of the file; the "
                "mimic is ignored and the joint has its own coordinate"
            )
            warnings.warn(f"{src.label}: {notes[-1]}", stacklevel=3)
            mimics[name] = None
        lo, hi = (None, None) if mimics[name] is not None else _limits(src, el, kind, where)
        if mimics[name] is None:
            velocities.append(_velocity(src, el, where))
        specs.append(
            {
                "name": name,
                "type": _MOVING[kind],
                "parent": body,
                "child": child,
                "origin": origin,
                "axis": _axis(src, el, where),
                "lower": lo,
                "upper": hi,
            }
        )
        place[child] = (child, np.eye(4))
    if floating_base:
        _float_base(src, tree, base, specs, velocities)
    if not specs:
        where = f"between {base!r} and {tip!r}" if tip is not None else f"below {base!r}"
        raise ModelError(f"{src.label}: no moving joint {where}")
    resolved = _resolve_mimics(src, mimics)
    joints = tuple(Joint(**spec, mimic=resolved.get(str(spec["name"]))) for spec in specs)
    ee = tip if tip is not None else _default_ee(tree, selected, base)
    held: dict[str, float] = {}
    if tip is not None:
        extra, held = _off_path(src, tree, place)
        place.update(extra)
        frames.update(extra)
    links = [tree.links[link] for link in place]

    def pose(el: etree._Element, where: str) -> np.ndarray:
        return _origin(src, el, where)

    def numbers(where: str, text: str | None, n: int, default: tuple[float, ...]) -> np.ndarray:
        return _floats(src, where, text, n, default)

    params: dict[str, object] = {
        "urdf": src.label,
        "base_link": base,
        "tip_link": tip,
        "visuals": read_visuals(links, pose, numbers, src.folder),
        "collisions": read_visuals(links, pose, numbers, src.folder, "collision"),
    }
    if held:
        params["held_joints"] = held
    if notes:
        params["notes"] = tuple(notes)
    if velocities and all(v is not None for v in velocities):
        params["velocity_limits"] = np.array(velocities, dtype=float)
    inertials = _inertials(src, links)
    name = src.root.get("name") or "urdf"
    return ParsedModel(name, FLOATING_WORLD if floating_base else base, joints, frames, ee, params, inertials)
