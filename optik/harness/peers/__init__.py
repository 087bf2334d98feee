"""Thin adapters for the peer IK libraries the benchmark compares optik against.

[`load_peer`][optik.harness.peers.load_peer] returns a ready [`Peer`][optik.harness.peers.base.Peer] for a
problem, or raises [`PeerUnavailable`][optik.harness.peers.base.PeerUnavailable] with the reason (package
missing, no URDF, different joint count), which the benchmark reports as a note instead of crashing.
The rules every solver is held to (tolerance, clipping, warm-up, the independent check) are in
[`optik.harness.peers.rules`][optik.harness.peers.rules].
"""

from __future__ import annotations

from optik.harness.peers.base import Peer, PeerUnavailable
from optik.harness.peers.ikpy_peer import IKPy
from optik.harness.peers.pink_peer import Pink
from optik.harness.peers.rtb_peer import RoboticsToolbox
from optik.harness.peers.tracik_peer import TracIK
from optik.problem_files import PEERS, Problem

ADAPTERS: dict[str, type[Peer]] = {"trac_ik": TracIK, "rtb_lm": RoboticsToolbox, "pink": Pink, "ikpy": IKPy}
"""Adapter class per peer name (the names of [`optik.problem_files.PEERS`][optik.problem_files.PEERS])."""

__all__ = ["ADAPTERS", "IKPy", "Peer", "PeerUnavailable", "Pink", "RoboticsToolbox", "TracIK", "load_peer"]


def load_peer(name: str, problem: Problem) -> Peer:
    """The peer ``name`` bound to the problem's URDF chain.

    Raises:
        PeerUnavailable: unknown peer, package not installed, no shipped URDF, a task other than
            the full pose, or a URDF chain whose FK differs from the mechanism's.
    """
    if name not in ADAPTERS:
        raise PeerUnavailable(f"unknown peer {name!r}; known peers: {list(PEERS)}")
    chain = problem.urdf_chain()
    if chain is None:
        raise PeerUnavailable(f"{name}: problem {problem.name!r} has no shipped URDF for the peers")
    if problem.mechanism_task != "pose":
        raise PeerUnavailable(
            f"{name}: peers solve full poses, the problem's task is {problem.mechanism_task!r}"
        )
    urdf, base, tip = chain
    peer = ADAPTERS[name](problem.mechanism(), urdf, base, tip)
    peer.check_fk()
    return peer
