"""`PerMechanism`: caches with one entry per mechanism that die with the mechanism.

A ``weakref.WeakKeyDictionary`` keyed on mechanisms does not free an entry whose value refers
back to its key (an `IKProblem`, a compiled kernel, a solver: each holds its mechanism): the
dictionary holds the value strongly, the value holds the key, so the key never dies. An
``lru_cache`` keyed on a mechanism keeps up to ``maxsize`` mechanisms alive for good.
`PerMechanism` stores the entry in the mechanism's own ``_memo`` dictionary instead: the entry
lives exactly as long as the mechanism, and the cycle mechanism -> entry -> mechanism is
reclaimed with it by the garbage collector. Every cache of optik keyed on a mechanism is a
`PerMechanism`. A cache that can gain entries without end (one per option combination, one
per shipped mechanism) is an `LRU` with a documented size.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable
from typing import TYPE_CHECKING, Generic, TypeVar

if TYPE_CHECKING:
    from optik.mechanism.mechanism import Mechanism

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

__all__ = ["LRU", "PerMechanism"]


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


class LRU(Generic[K, V]):
    """A mapping of at most ``size`` entries: reading or adding an entry makes it the most
    recently used, and adding one past ``size`` drops the least recently used. Thread-safe (one
    lock per instance)."""

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"an LRU holds at least one entry, got size {size}")
        self.size = size
        self._entries: OrderedDict[K, V] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: K, default: V | None = None) -> V | None:
        """The entry of ``key`` (now the most recent), or ``default``."""
        with self._lock:
            if key not in self._entries:
                return default
            self._entries.move_to_end(key)
            return self._entries[key]

    def setdefault(self, key: K, value: V) -> V:
        """The entry of ``key`` (now the most recent), set to ``value`` first when there is none
        (dropping the least recently used entry past ``size``)."""
        with self._lock:
            found = self._entries.setdefault(key, value)
            self._entries.move_to_end(key)
            while len(self._entries) > self.size:
                self._entries.popitem(last=False)
            return found

    def values(self) -> list[V]:
        """The entries, least recently used first (a copy)."""
        with self._lock:
            return list(self._entries.values())

    def __contains__(self, key: object) -> bool:
        with self._lock:
            return key in self._entries

    def __len__(self) -> int:
        return len(self._entries)
