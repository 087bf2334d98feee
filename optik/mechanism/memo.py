"""`PerMechanism`: caches with one entry per mechanism that die with the mechanism.

A ``weakref.WeakKeyDictionary`` keyed on mechanisms does not free an entry whose value refers
back to its key (an `IKProblem`, a compiled kernel, a solver: each holds its mechanism): the
dictionary holds the value strongly, the value holds the key, so the key never dies. An
``lru_cache`` keyed on a mechanism keeps up to ``maxsize`` mechanisms alive for good.
`PerMechanism` stores the entry in the mechanism's own ``_memo`` dictionary instead: the entry
lives exactly as long as the mechanism, and the cycle mechanism -> entry -> mechanism is
reclaimed with it by the garbage collector. Every cache of optik keyed on a mechanism is a
`PerMechanism`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Generic, TypeVar

if TYPE_CHECKING:
    from optik.mechanism.mechanism import Mechanism

V = TypeVar("V")

__all__ = ["PerMechanism"]


class PerMechanism(Generic[V]):
    """A mapping ``mechanism -> value`` held by each mechanism (the subset of ``dict``'s
    interface that the caches use). Each instance is one cache: its entries are keyed by the
    instance in the mechanism's ``_memo``."""

    def get(self, m: Mechanism, default: V | None = None) -> V | None:
        """The entry of ``m``, or ``default``."""
        return m._memo.get(self, default)

    def setdefault(self, m: Mechanism, value: V) -> V:
        """The entry of ``m``, set to ``value`` first when there is none (atomic under the GIL:
        threads racing to fill it all get the same value)."""
        return m._memo.setdefault(self, value)

    def pop(self, m: Mechanism, default: V | None = None) -> V | None:
        """Remove the entry of ``m`` and return it (``default`` when there is none)."""
        return m._memo.pop(self, default)

    def __getitem__(self, m: Mechanism) -> V:
        return m._memo[self]

    def __setitem__(self, m: Mechanism, value: V) -> None:
        m._memo[self] = value

    def __contains__(self, m: object) -> bool:
        memo = getattr(m, "_memo", None)
        return memo is not None and self in memo
