"""Run a callback on the newest request only (gizmo drags and slider moves arrive faster than a
solve may finish)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Generic, TypeVar

__all__ = ["Latest"]

T = TypeVar("T")
_EMPTY: Any = object()


class Latest(Generic[T]):
    """Calls ``fn(arg)`` for the newest ``arg``: a call that arrives while ``fn`` runs replaces any
    waiting one and is run when the running call returns, by the thread that ran it; calls in
    between are dropped. At most one ``fn`` runs at a time.
    """

    def __init__(self, fn: Callable[[T], Any]) -> None:
        self._fn = fn
        self._pending: Any = _EMPTY
        self._running = threading.Lock()
        self._guard = threading.Lock()

    def __call__(self, arg: T) -> None:
        with self._guard:
            self._pending = arg
        while self._running.acquire(blocking=False):
            try:
                with self._guard:
                    job, self._pending = self._pending, _EMPTY
                if job is not _EMPTY:
                    self._fn(job)
            finally:
                self._running.release()
            with self._guard:
                if self._pending is _EMPTY:
                    return
