"""URDF builder: the joints and frames of a URDF robot, for `Mechanism.from_urdf`.

`parse_urdf` reads a URDF file (or a URDF string), finds the path through the link tree
from ``base_link`` down to ``tip_link`` and turns the joints on that path into
`Joint` objects; branches off the path are ignored. It imports only the joint layer, so
that `optik.mechanism.mechanism` can build on it without an import cycle.

Supported, per joint on the path:

* ``revolute``: rotation about ``axis``, limits from ``<limit lower upper>`` (required);
* ``continuous``: an unlimited revolute joint, modelled with limits ``[-pi, pi]`` since optik
  reports angles wrapped to ``(-pi, pi]``, so that the whole circle is reachable;
* ``prismatic``: translation along ``axis``, limits required;
* ``fixed``: no coordinate; its transform is folded into the origin of the next moving joint
  and the links it passes become named frames, so the model has one coordinate per moving joint
  and no needless bodies.

``<origin xyz rpy>`` places the joint frame in the parent link: ``T = Trans(xyz) R`` with
URDF's ``R = Rot(z, yaw) Rot(y, pitch) Rot(x, roll)`` = `optik.spatial.rpy_to_rot`.
``<axis xyz>`` (default ``1 0 0``) is normalized. ``<limit velocity>`` values, when every moving
joint has a positive one, are kept in ``m.params["velocity_limits"]``. ``floating`` and ``planar`` joints and
``<mimic>`` joints on the path are rejected with `ModelError`.

Safety: the text is parsed with `xml.etree.ElementTree` only after a check that rejects any
``<!DOCTYPE`` or ``<!ENTITY`` declaration, so no entity is ever expanded and no external
resource is fetched (URDF never needs a DTD).
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from optik import spatial
from optik.errors import InvalidArgumentError, ModelError, UnknownFrameError
from optik.mechanism.joint import Joint

__all__ = ["UrdfModel", "parse_urdf"]

_DTD = re.compile(r"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)
_MOVING = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
_REJECTED = ("floating", "planar")


@dataclass(frozen=True)
class UrdfModel:
    """What `parse_urdf` read: the arguments of a `Mechanism` and its ``params``.

    Attributes:
        name: the ``<robot name>`` (``"urdf"`` when absent).
        base: the base link (the fixed body).
        joints: one `Joint` per moving joint, in coordinate order.
        frames: links reached through fixed joints, ``{link: (body, 4x4 offset)}``.
        ee: the end-effector link.
        params: ``"urdf"`` (source label), ``"base_link"``, ``"tip_link"`` and, when every
            moving joint has a positive ``<limit velocity>``, ``"velocity_limits"``.
    """

    name: str
    base: str
    joints: tuple[Joint, ...]
    frames: dict[str, tuple[str, np.ndarray]]
    ee: str
    params: dict[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class _Source:
    """URDF text and the label that error messages use for it (the file path or ``<string>``)."""

    text: str
    label: str


def _read(source: str | os.PathLike[str]) -> _Source:
    """The URDF text: ``source`` is XML text when it contains ``<``, else a file path."""
    if isinstance(source, str) and "<" in source:
        return _Source(source, "<string>")
    if not isinstance(source, (str, os.PathLike)):
        raise InvalidArgumentError(
            "source", f"expected a URDF path or XML string, got {type(source).__name__}"
        )
    path = Path(source)
    if not path.is_file():
        raise InvalidArgumentError("source", f"no URDF file {str(path)!r}")
    try:
        return _Source(path.read_text(encoding="utf-8"), str(path))
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidArgumentError("source", f"cannot read URDF file {str(path)!r}: {exc}") from exc


def _parse_xml(src: _Source) -> ET.Element:
    """Parse the text after rejecting DTDs (no entity expansion, no external entities)."""
    m = _DTD.search(src.text)
    if m:
        raise ModelError(
            f"{src.label}: URDF contains a <!{m.group(1).upper()} declaration; DTDs and entities are "
            "rejected (no entity expansion)"
        )
    try:
        root = ET.fromstring(src.text)
    except ET.ParseError as exc:
        raise ModelError(f"{src.label}: malformed XML: {exc}") from exc
    if root.tag != "robot":
        raise ModelError(f"{src.label}: root element is <{root.tag}>, expected <robot>")
    return root


def _floats(src: _Source, where: str, text: str | None, n: int, default: tuple[float, ...]) -> np.ndarray:
    """``n`` finite floats from a whitespace-separated attribute (``default`` when absent)."""
    if text is None:
        return np.array(default, dtype=float)
    parts = text.split()
    try:
        values = np.array([float(p) for p in parts], dtype=float)
    except ValueError as exc:
        raise ModelError(f"{src.label}: {where}: expected {n} numbers, got {text!r}") from exc
    if values.shape != (n,):
        raise ModelError(f"{src.label}: {where}: expected {n} numbers, got {text!r}")
    if not np.all(np.isfinite(values)):
        raise ModelError(f"{src.label}: {where}: values must be finite, got {text!r}")
    return values


def _origin(src: _Source, joint: ET.Element, where: str) -> np.ndarray:
    """``Trans(xyz) Rot(z, yaw) Rot(y, pitch) Rot(x, roll)`` of a joint's ``<origin>``."""
    el = joint.find("origin")
    if el is None:
        return np.eye(4)
    xyz = _floats(src, f"{where} <origin xyz>", el.get("xyz"), 3, (0.0, 0.0, 0.0))
    rpy = _floats(src, f"{where} <origin rpy>", el.get("rpy"), 3, (0.0, 0.0, 0.0))
    return spatial.transform(spatial.rpy_to_rot(*rpy), xyz)


def _axis(src: _Source, joint: ET.Element, where: str) -> np.ndarray:
    """The unit joint axis (URDF default ``1 0 0``)."""
    el = joint.find("axis")
    a = _floats(src, f"{where} <axis xyz>", None if el is None else el.get("xyz"), 3, (1.0, 0.0, 0.0))
    norm = float(np.linalg.norm(a))
    if norm < 1e-12:
        raise ModelError(f"{src.label}: {where}: <axis xyz> must be non-zero")
    return a / norm


def _limits(src: _Source, joint: ET.Element, kind: str, where: str) -> tuple[float, float]:
    """``(lower, upper)``: ``[-pi, pi]`` for continuous joints, else from ``<limit>`` (required)."""
    if kind == "continuous":
        return -np.pi, np.pi
    el = joint.find("limit")
    if el is None or el.get("lower") is None or el.get("upper") is None:
        raise ModelError(f"{src.label}: {where}: a {kind} joint needs <limit lower=... upper=...>")
    lo = _floats(src, f"{where} <limit lower>", el.get("lower"), 1, (0.0,))[0]
    hi = _floats(src, f"{where} <limit upper>", el.get("upper"), 1, (0.0,))[0]
    if lo > hi:
        raise ModelError(f"{src.label}: {where}: <limit> lower {lo} > upper {hi}")
    return float(lo), float(hi)


def _velocity(src: _Source, joint: ET.Element, where: str) -> float | None:
    """``<limit velocity>`` when given and positive, else None (zero often means "unspecified")."""
    el = joint.find("limit")
    text = None if el is None else el.get("velocity")
    if text is None:
        return None
    v = float(_floats(src, f"{where} <limit velocity>", text, 1, (0.0,))[0])
    return v if v > 0 else None


def _link_of(src: _Source, joint: ET.Element, tag: str, where: str) -> str:
    el = joint.find(tag)
    name = None if el is None else el.get("link")
    if not name:
        raise ModelError(f"{src.label}: {where} has no <{tag} link=...>")
    return name


def _chain(src: _Source, root: ET.Element, base_link: str, tip_link: str) -> list[tuple[ET.Element, str]]:
    """Joints on the path from ``base_link`` down to ``tip_link`` as ``(element, child link)``."""
    links = [el.get("name") for el in root.findall("link")]
    if None in links or "" in links:
        raise ModelError(f"{src.label}: a <link> has no name")
    link_set = set(links)
    for arg, link in (("base_link", base_link), ("tip_link", tip_link)):
        if link not in link_set:
            raise UnknownFrameError(arg, f"{src.label}: no link {link!r}; links: {sorted(link_set)}")
    parent_joint: dict[str, tuple[ET.Element, str]] = {}
    seen: set[str] = set()
    for el in root.findall("joint"):
        name = el.get("name")
        if not name:
            raise ModelError(f"{src.label}: a <joint> has no name")
        if name in seen:
            raise ModelError(f"{src.label}: duplicate joint name {name!r}")
        seen.add(name)
        where = f"joint {name!r}"
        parent, child = _link_of(src, el, "parent", where), _link_of(src, el, "child", where)
        for link in (parent, child):
            if link not in link_set:
                raise ModelError(f"{src.label}: {where} refers to unknown link {link!r}")
        if child in parent_joint:
            raise ModelError(
                f"{src.label}: link {child!r} is the child of two joints "
                f"({parent_joint[child][0].get('name')!r} and {name!r}); URDF needs a tree"
            )
        parent_joint[child] = (el, parent)
    path: list[tuple[ET.Element, str]] = []
    link = tip_link
    while link != base_link:
        if link not in parent_joint or len(path) > len(parent_joint):
            raise ModelError(
                f"{src.label}: tip_link {tip_link!r} is not downstream of base_link {base_link!r}"
            )
        el, parent = parent_joint[link]
        path.append((el, link))
        link = parent
    path.reverse()
    return path


def parse_urdf(source: str | os.PathLike[str], base_link: str, tip_link: str) -> UrdfModel:
    """The serial chain of a URDF robot from ``base_link`` to ``tip_link``.

    Every moving joint on the path becomes one coordinate named after the URDF joint; its pose
    is ``T_child = T_parent @ F @ origin @ motion(q)`` where ``F`` is the product of the origins
    of the fixed joints just before it (identity if none). Links reached through fixed joints
    become named frames on the last moving body, so ``m.fk(q, frame=link)`` works for every link
    on the path.

    Args:
        source: path of a URDF file, or the URDF XML text itself (any string containing ``<``).
        base_link: the fixed link; it becomes the mechanism's base body.
        tip_link: the end-effector link; it becomes the frame ``m.ee``.

    Returns:
        The model named after the ``<robot name>``, coordinates named after the URDF joints,
        limits from ``<limit>`` (``[-pi, pi]`` for continuous joints) and the parsed chain in
        ``params`` (``"urdf"``: source label, ``"base_link"``, ``"tip_link"``, and
        ``"velocity_limits"``, rad/s or m/s per coordinate, when every moving joint on the path
        has a positive ``<limit velocity>``).

    Raises:
        InvalidArgumentError: ``source`` is neither an existing file nor XML text.
        UnknownFrameError: ``base_link`` or ``tip_link`` is not a link of the robot.
        ModelError: a DOCTYPE/ENTITY declaration, malformed XML or numbers, a tip that is not
            downstream of the base, a missing ``<limit>``, an unsupported (floating, planar,
            mimic, unknown) joint on the path, or a path without any moving joint. The message
            names the file and the joint.
    """
    src = _read(source)
    root = _parse_xml(src)
    path = _chain(src, root, base_link, tip_link)
    joints: list[Joint] = []
    velocities: list[float | None] = []
    frames: dict[str, tuple[str, np.ndarray]] = {}
    body, pending = base_link, np.eye(4)
    for el, child in path:
        name = el.get("name", "")
        where = f"joint {name!r}"
        kind = el.get("type")
        origin = _origin(src, el, where)
        if kind == "fixed":
            pending = pending @ origin
            frames[child] = (body, pending)
            continue
        if kind not in _MOVING:
            why = "is not supported in a serial chain" if kind in _REJECTED else "is unknown"
            raise ModelError(
                f"{src.label}: {where}: joint type {kind!r} {why}; use revolute, continuous, prismatic, fixed"
            )
        if el.find("mimic") is not None:
            raise ModelError(f"{src.label}: {where} has <mimic>; coupled joints are not supported")
        lo, hi = _limits(src, el, kind, where)
        velocities.append(_velocity(src, el, where))
        joints.append(
            Joint(
                name,
                _MOVING[kind],
                body,
                child,
                origin=pending @ origin,
                axis=_axis(src, el, where),
                lower=lo,
                upper=hi,
            )
        )
        body, pending = child, np.eye(4)
    if not joints:
        raise ModelError(f"{src.label}: no moving joint between {base_link!r} and {tip_link!r}")
    params: dict[str, object] = {"urdf": src.label, "base_link": base_link, "tip_link": tip_link}
    if all(v is not None for v in velocities):
        params["velocity_limits"] = np.array(velocities, dtype=float)
    return UrdfModel(root.get("name") or "urdf", base_link, tuple(joints), frames, tip_link, params)
