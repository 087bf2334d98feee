"""The collision geometry of a mechanism and its allowed-collision matrix, built once per model.

`robot_geometry` reads ``m.params["collisions"]`` (the URDF ``<collision>`` elements of every
loaded link, the links a chain carries off its path included: see `optik.mechanism.urdf`) into
`Part` objects, each a `Shape` at a fixed offset in a link frame, so that at ``q`` a part is at
``m.fk(q, frame=part.link) @ part.offset``. One compiled CasADi function gives every link's pose
at once (`RobotGeometry.link_poses`).

**Self-collision pairs.** Two links are never checked against each other when

* they are on the same rigid body (frames of one body never move relative to each other),
* they are the two bodies of one joint (adjacent: their meshes touch at the joint by design;
  a link fixed to a body, such as a tool, is still checked against the next body),
* the SRDF given to `Mechanism.from_urdf(..., srdf=...)` lists them in ``disable_collisions``,
* without an SRDF, they collide in every one of ``samples`` configurations drawn uniformly within
  the limits (seeded): a pair always in contact is part of the design, as in MoveIt's setup
  assistant.

Unlike the setup assistant, pairs that *never* collided in the samples are still checked: a
rare collision missed costs more than a check. The result is cached with the model (a weak
reference: it goes when the mechanism goes), and the sampled pairs on disk too
(`optik.native.cache_dir` ``/acm/<key>.json``, the key a digest of the pickled mechanism, its
mesh files' sizes and times and the sampling settings; written through a temporary file and
``os.replace``). A cache file that cannot be read, is not valid or names other links is logged
on the ``optik.collision.robot`` logger and replaced by a new sampling.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import logging
import os
import pickle
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from optik.collision.distance import pair_distances
from optik.collision.parts import Part, parts_of
from optik.collision.shapes import Shape
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.native import cache_dir

__all__ = ["RobotGeometry", "robot_geometry"]

ACM_SAMPLES = 500
"""Configurations sampled for the allowed-collision matrix of a model without an SRDF."""


@dataclass(frozen=True, eq=False)
class RobotGeometry:
    """The collision parts of a mechanism and the link pairs checked for self-collision.

    Attributes:
        links: the links that carry geometry, in document order.
        parts: the parts; ``parts[i].offset`` is in the frame of ``links[part_link[i]]``.
        part_link: index into ``links`` of each part.
        self_pairs: ``(k, 2)`` part indices checked against each other.
        disabled: the link pairs never checked, each sorted, with the reason
            (``"same body"``, ``"adjacent"``, ``"srdf"``, ``"always"``).
        notes: geometry that could not be used (a mesh file not found), with the reason.
    """

    mechanism: Any = field(repr=False)
    links: tuple[str, ...]
    parts: tuple[Part, ...]
    part_link: np.ndarray
    self_pairs: np.ndarray
    disabled: dict[tuple[str, str], str]
    notes: tuple[str, ...]
    _poses: ca.Function = field(repr=False)

    @functools.cached_property
    def fixed_parts(self) -> frozenset[int]:
        """The parts whose pose does not depend on the coordinates (their link is fixed to the
        base): their distance to a world object is the same at every ``q``."""
        m = self.mechanism
        q = m.q_sym
        fixed = [not ca.depends_on(ca.vec(m.frame_expr(link)), q) for link in self.links]
        return frozenset(k for k, link in enumerate(self.part_link.tolist()) if fixed[link])

    @functools.cached_property
    def pair_list(self) -> list[tuple[int, int]]:
        """`self_pairs` as a list of int pairs (what a search indexes per pair)."""
        return [(int(a), int(b)) for a, b in self.self_pairs]

    def link_poses(self, q: np.ndarray) -> np.ndarray:
        """Poses of `links` at ``q``: ``(L, 4, 4)``."""
        out = np.asarray(self._poses(q))
        return out.reshape(4, len(self.links), 4).transpose(1, 0, 2)

    def part_poses(self, q: np.ndarray, links: np.ndarray | None = None) -> np.ndarray:
        """Poses of `parts` at ``q`` in the base frame: ``(P, 4, 4)`` (``links``: the
        `link_poses` at ``q`` when already known)."""
        links = self.link_poses(q) if links is None else links
        offsets = np.stack([p.offset for p in self.parts])
        return links[self.part_link] @ offsets


def _link_parts(m: Mechanism) -> tuple[list[str], list[Part], list[int], list[str]]:
    links: list[str] = []
    parts: list[Part] = []
    owner: list[int] = []
    notes: list[str] = []
    for c in m.params.get("collisions", ()):
        if c.link not in m.frames:
            continue
        if c.geometry == "mesh":
            if c.path is None:
                notes.append(f"link {c.link!r}: collision mesh {c.filename!r} not found; not checked")
                continue
            shape = Shape("mesh", c.scale, path=c.path)
        else:
            shape = Shape(c.geometry, c.size)
        if c.link not in links:
            links.append(c.link)
        for part in parts_of(c.link, shape, np.asarray(c.origin, dtype=float)):
            parts.append(part)
            owner.append(links.index(c.link))
    return links, parts, owner, notes


def _structural(m: Mechanism, links: list[str]) -> dict[tuple[str, str], str]:
    """Link pairs on one body or on two bodies joined by a joint."""
    body = {link: m.frames[link][0] for link in links}
    joined = {frozenset((j.parent, j.child)) for j in m.joints}
    out: dict[tuple[str, str], str] = {}
    for i, a in enumerate(links):
        for b in links[i + 1 :]:
            key = (a, b) if a <= b else (b, a)
            if body[a] == body[b]:
                out[key] = "same body"
            elif frozenset((a, b)) in joined:
                out[key] = "adjacent"
    return out


def _pair_indices(links: list[str], owner: list[int], skip: dict[tuple[str, str], str]) -> np.ndarray:
    pairs = []
    for i in range(len(owner)):
        for j in range(i + 1, len(owner)):
            a, b = links[owner[i]], links[owner[j]]
            if a == b:
                continue
            if ((a, b) if a <= b else (b, a)) in skip:
                continue
            pairs.append((i, j))
    return np.array(pairs, dtype=int).reshape(-1, 2)


def _always_colliding(geo: RobotGeometry, samples: int, seed: int) -> dict[tuple[str, str], str]:
    """Link pairs of ``geo.self_pairs`` in contact in every sampled configuration."""
    if not len(geo.self_pairs):
        return {}
    m = geo.mechanism
    touching = np.ones(len(geo.self_pairs), dtype=bool)
    for q in m.random_q(samples, seed=seed):
        poses = geo.part_poses(q)
        todo = np.flatnonzero(touching)
        d = pair_distances(geo.parts, poses, geo.parts, poses, geo.self_pairs[todo])
        touching[todo] = d <= 0
        if not touching.any():
            return {}
    out: dict[tuple[str, str], str] = {}
    for i, j in geo.self_pairs[touching]:
        a, b = geo.links[geo.part_link[i]], geo.links[geo.part_link[j]]
        out[(a, b) if a <= b else (b, a)] = "always"
    return out


_LOG = logging.getLogger(__name__)
ACM_FORMAT = 1
"""Version of the on-disk allowed-collision files."""


def _acm_path(geo: RobotGeometry, samples: int, seed: int) -> Path | None:
    """The cache file of the sampled pairs of ``geo`` (None: the mechanism cannot be pickled)."""
    try:
        h = hashlib.sha256(pickle.dumps(geo.mechanism))
    except (pickle.PicklingError, TypeError, AttributeError):
        return None
    for part in geo.parts:
        if part.shape.path is not None:
            with contextlib.suppress(OSError):
                st = os.stat(part.shape.path)
                h.update(f"{part.shape.path}:{st.st_size}:{st.st_mtime_ns}".encode())
    h.update(f"{ACM_FORMAT}:{samples}:{seed}".encode())
    return cache_dir() / "acm" / f"{h.hexdigest()[:24]}.json"


def _read_acm(path: Path, links: tuple[str, ...]) -> dict[tuple[str, str], str] | None:
    """The pairs of a cache file, or None (missing; damaged: logged)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    except OSError as exc:
        _LOG.warning("allowed-collision cache %s unreadable (%s): sampling again", path, exc)
        return None
    try:
        data = json.loads(text)
        pairs = [tuple(p) for p in data["always"]]
        ok = data["format"] == ACM_FORMAT and all(
            len(p) == 2 and p[0] in links and p[1] in links and p[0] <= p[1] for p in pairs
        )
    except (ValueError, KeyError, TypeError):
        ok = False
    if not ok:
        _LOG.warning("allowed-collision cache %s is damaged: sampling again", path)
        return None
    return {(str(a), str(b)): "always" for a, b in pairs}


def _write_acm(path: Path, pairs: dict[tuple[str, str], str]) -> None:
    """Write the pairs atomically (a failure is logged: the cache is an optimization)."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".acm-")
        with os.fdopen(fd, "w") as f:
            json.dump({"format": ACM_FORMAT, "always": sorted(pairs)}, f)
        os.replace(tmp, path)
        tmp = None
    except OSError as exc:
        _LOG.warning("allowed-collision cache %s not written (%s)", path, exc)
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def _sampled_pairs(geo: RobotGeometry, samples: int, seed: int) -> dict[tuple[str, str], str]:
    """`_always_colliding`, through the on-disk cache."""
    path = _acm_path(geo, samples, seed)
    if path is not None:
        hit = _read_acm(path, geo.links)
        if hit is not None:
            return hit
    pairs = _always_colliding(geo, samples, seed)
    if path is not None:
        _write_acm(path, pairs)
    return pairs


_CACHE: PerMechanism[RobotGeometry] = PerMechanism()  # the geometry holds its mechanism: not a weak dict
_LOCK = threading.Lock()


def robot_geometry(m: Mechanism) -> RobotGeometry:
    """The collision geometry of ``m`` (built on first use, then cached with the model).

    Raises:
        InvalidArgumentError: ``m`` has no collision geometry (named ``m``): load it from a URDF
            whose links have ``<collision>`` elements.
    """
    with _LOCK:
        hit = _CACHE.get(m)
    if hit is not None:
        return hit
    links, parts, owner, notes = _link_parts(m)
    if not parts:
        raise InvalidArgumentError(
            "m", f"{m.name!r} has no collision geometry: load it from a URDF whose links have <collision>"
        )
    disabled = _structural(m, links)
    srdf = m.params.get("disabled_collisions")
    if srdf is not None:
        disabled.update({pair: "srdf" for pair in srdf if pair not in disabled})
    q = m.q_sym
    poses = ca.Function("collision_link_poses", [q], [ca.horzcat(*(m.frame_expr(link) for link in links))])
    geo = RobotGeometry(
        m,
        tuple(links),
        tuple(parts),
        np.array(owner, dtype=int),
        _pair_indices(links, owner, disabled),
        disabled,
        tuple(notes),
        poses,
    )
    if srdf is None:
        always = _sampled_pairs(geo, ACM_SAMPLES, seed=0)
        if always:
            disabled.update(always)
            geo = RobotGeometry(
                m,
                geo.links,
                geo.parts,
                geo.part_link,
                _pair_indices(links, owner, disabled),
                disabled,
                geo.notes,
                poses,
            )
    with _LOCK:
        return _CACHE.setdefault(m, geo)
