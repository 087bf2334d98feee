"""Topology of a joint graph: spanning tree, cut joints, mobility.

Bodies are nodes, joints are edges. A spanning tree rooted at the base body is chosen with
Kruskal's rule over the joints in the order given, taking first the joints that cannot be cut
(prismatic, fixed and free joints: a cut free joint would close nothing) and never taking
joints marked ``cut=True``; every joint left over
closes a loop and becomes a *cut joint* (cut-joint method). The number of independent loops is
``g - n`` for ``g`` joints and ``n`` moving bodies.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from optik.errors import ModelError
from optik.mechanism.joint import Joint

UNCUTTABLE = ("prismatic", "fixed", "free")


@dataclass(frozen=True)
class TreeEdge:
    """A spanning-tree joint as traversed from the base.

    Attributes:
        joint: index of the joint in the mechanism's joint list.
        reversed: True when the traversal goes from the joint's child to its parent.
    """

    joint: int
    reversed: bool


@dataclass(frozen=True)
class Topology:
    """Result of [`analyse`][optik.mechanism.topology.analyse].

    Attributes:
        bodies: body names, base first, then in order of first appearance.
        order: tree edges in an order where every edge's upstream body is already placed.
        tree: indices of the joints in the spanning tree, in the given order.
        cuts: indices of the cut joints, in the given order.
    """

    bodies: tuple[str, ...]
    order: tuple[TreeEdge, ...]
    tree: tuple[int, ...]
    cuts: tuple[int, ...]


def _find(parent: dict[str, str], b: str) -> str:
    while parent[b] != b:
        parent[b] = parent[parent[b]]
        b = parent[b]
    return b


def analyse(joints: Sequence[Joint], base: str) -> Topology:
    """Spanning tree, traversal order and cut joints of a joint graph.

    Raises:
        ModelError: duplicate joint names, a joint from a body to itself, bodies not connected
            to the base, or a loop that could only be closed by cutting a prismatic, fixed or free joint.
    """
    names = [j.name for j in joints]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ModelError(f"duplicate joint names: {sorted(dup)}")
    bodies = [base]
    for j in joints:
        if j.parent == j.child:
            raise ModelError(f"joint {j.name!r} connects body {j.parent!r} to itself")
        for b in (j.parent, j.child):
            if b not in bodies:
                bodies.append(b)
    uf = {b: b for b in bodies}
    in_tree: set[int] = set()
    ranked = [i for i, j in enumerate(joints) if j.type in UNCUTTABLE and not j.cut]
    ranked += [i for i, j in enumerate(joints) if j.type not in UNCUTTABLE and not j.cut]
    for i in ranked:
        a, b = _find(uf, joints[i].parent), _find(uf, joints[i].child)
        if a != b:
            uf[a] = b
            in_tree.add(i)
    cuts = [i for i in range(len(joints)) if i not in in_tree]
    for i in cuts:
        # an explicit cut fixed joint is a weld (MJCF <equality weld>): its closure holds the pose
        if joints[i].type in UNCUTTABLE and not (joints[i].type == "fixed" and joints[i].cut):
            raise ModelError(
                f"joint {joints[i].name!r} ({joints[i].type}) would have to close a loop; "
                "only revolute, universal and spherical joints (and fixed ones marked cut=True) can be cut"
            )
    root = _find(uf, base)
    loose = [b for b in bodies if _find(uf, b) != root]
    if loose:
        raise ModelError(f"bodies not connected to the base {base!r}: {loose}")
    placed = {base}
    order: list[TreeEdge] = []
    pending = sorted(in_tree)
    while pending:
        rest = []
        for i in pending:
            j = joints[i]
            if j.parent in placed:
                order.append(TreeEdge(i, False))
                placed.add(j.child)
            elif j.child in placed:
                order.append(TreeEdge(i, True))
                placed.add(j.parent)
            else:
                rest.append(i)
        pending = rest
    return Topology(tuple(bodies), tuple(order), tuple(sorted(in_tree)), tuple(cuts))


def gruebler_kutzbach(n_moving_bodies: int, joints: Sequence[Joint], planar: bool) -> int:
    """Mobility ``M = lambda (n - g) + sum f_i`` (``lambda`` = 3 planar, 6 spatial).

    ``n`` counts the moving bodies, ``g`` the joints (cut joints included) and ``f_i`` the
    connectivity of joint ``i`` (seed 004, equations (2) and (3)).
    """
    lam = 3 if planar else 6
    return lam * (n_moving_bodies - len(joints)) + sum(j.dof for j in joints)
