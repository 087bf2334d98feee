"""What every peer adapter shares: the interface, the unavailability error, the URDF chain check.

A peer is a third-party IK library run on the same targets as optik's methods. An adapter loads
the problem's URDF once, then answers ``attempt(q0, target, time_limit, tol)`` with the raw
configuration it returned and its own success flag; the benchmark times the call, and the rules of
[`optik.harness.peers.rules`][optik.harness.peers.rules] (the same for every solver) settle and judge the
answer.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from pathlib import Path
from types import ModuleType

import numpy as np

from optik.errors import SolverUnavailableError
from optik.mechanism import Mechanism
from optik.solvers import Tolerances


class PeerUnavailable(SolverUnavailableError):
    """A peer cannot run here: its package is missing, or the problem has no usable URDF."""


class Peer(ABC):
    """One peer IK library bound to one URDF chain. The constructor imports the package
    (`import_package`), lets the adapter read the chain (`load`) and checks its joint count.

    Args:
        mechanism: optik's model of the same chain (joint order and limits are checked
            against the URDF's).
        urdf: path of the URDF file.
        base_link, tip_link: the chain's ends in the URDF.

    Raises:
        PeerUnavailable: the package is missing, the chain cannot be read, or its joint count
            differs from the mechanism's.
    """

    name: str = "peer"
    package: str = ""
    """Import name of the library (the pip name is in the class docstring)."""

    def __init__(self, mechanism: Mechanism, urdf: Path, base_link: str, tip_link: str) -> None:
        self.mechanism = mechanism
        self.urdf = Path(urdf)
        self.base_link = base_link
        self.tip_link = tip_link
        self.lib = self.import_package()
        self.check_joints(self.load())

    @abstractmethod
    def load(self) -> int:
        """Read the URDF chain into the peer's own model (``self.lib`` is the imported
        package) and return its number of joints (checked against ``mechanism.n_q``).

        Raises:
            PeerUnavailable: the peer cannot read the chain or lacks a dependency.
        """

    @classmethod
    def import_package(cls) -> ModuleType:
        """The peer's module.

        Raises:
            PeerUnavailable: it is not installed (the message says how to install it).
        """
        try:
            return importlib.import_module(cls.package)
        except ImportError as exc:
            raise PeerUnavailable(
                f"{cls.name}: package {cls.package!r} is not installed ({exc}); "
                'install the peers with: pip install "optik[peers]"'
            ) from None

    def check_joints(self, n: int) -> None:
        """Raise [`PeerUnavailable`][optik.harness.peers.base.PeerUnavailable] when the peer's chain
        has ``n != mechanism.n_q`` joints."""
        if n != self.mechanism.n_q:
            raise PeerUnavailable(
                f"{self.name}: the URDF chain {self.base_link} -> {self.tip_link} has {n} joints, "
                f"the mechanism {self.mechanism.name!r} has {self.mechanism.n_q}"
            )

    def check_fk(self, samples: int = 3, tol: float = 1e-6) -> None:
        """Compare the peer's FK with the mechanism's at random joint vectors (seeded).

        Raises:
            PeerUnavailable: the poses differ by more than ``tol`` (wrong chain or joint order).
        """
        m = self.mechanism
        for q in m.random_q(samples, seed=0):
            gap = float(np.max(np.abs(self.fk(q) - m.fk(q))))
            if gap > tol:
                raise PeerUnavailable(
                    f"{self.name}: FK of the URDF chain {self.base_link} -> {self.tip_link} differs from "
                    f"{m.name!r} by {gap:.2g}; not the same chain"
                )

    @abstractmethod
    def fk(self, q: np.ndarray) -> np.ndarray:
        """4x4 pose of the tip link according to the peer."""

    @abstractmethod
    def attempt(
        self, q0: np.ndarray, target: np.ndarray, time_limit: float, tol: Tolerances
    ) -> tuple[np.ndarray, bool]:
        """``(q, found)``: the raw joint vector the library returned for the 4x4 ``target`` of the
        tip link from ``q0`` (``q0`` itself when it returned none), and its own success flag."""

    def solve(self, q0: np.ndarray, target: np.ndarray, time_limit: float, tol: Tolerances) -> np.ndarray:
        """The raw joint vector of [`attempt`][optik.harness.peers.base.Peer.attempt]."""
        return self.attempt(q0, target, time_limit, tol)[0]
