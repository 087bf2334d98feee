"""`fk_batch`: forward kinematics of many configurations in compiled code, on every core."""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_batch
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.native import CCall, library

CHUNK = 256
"""Configurations per compiled call (the FK function mapped over a chunk)."""


class _MappedFK:
    """``T_frame(q)`` mapped over `CHUNK` configurations, compiled; one call object per thread
    (their work buffers are not shared)."""

    def __init__(self, m: Mechanism, frame: str | None) -> None:
        self.n_q = m.n_q
        self.name = f"optik_fk_chunk_{CHUNK}"
        one = ca.Function("optik_fk_one", [m.q_sym], [m.frame_expr(frame)])
        self.lib = library([one.map(self.name, "serial", CHUNK, [], [])], "auto")
        self._local = threading.local()

    def _call(self) -> tuple[CCall, np.ndarray, np.ndarray]:
        if not hasattr(self._local, "call"):
            q = np.zeros((CHUNK, self.n_q))  # C order = n_q x CHUNK column-major
            out = np.zeros((CHUNK, 4, 4))  # C order of the 4 x 4 CHUNK output: each T transposed
            self._local.call = (CCall(self.lib.get(), self.name, [q], [out]), q, out)
        return self._local.call

    def chunk(self, q: np.ndarray) -> np.ndarray:
        """Poses of up to `CHUNK` configurations ``(k, n_q)`` -> ``(k, 4, 4)``."""
        call, buf, out = self._call()
        k = len(q)
        buf[:k] = q
        buf[k:] = q[-1] if k else 0.0
        call()
        return out[:k].transpose(0, 2, 1).copy()


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


_MAPPED: PerMechanism[dict[str | None, _MappedFK]] = PerMechanism()


def _mapped(m: Mechanism, frame: str | None) -> _MappedFK:
    """The mapped FK of a frame (built once; it lives as long as the mechanism)."""
    per = _MAPPED.setdefault(m, {})
    found = per.get(frame)
    if found is None:
        found = per.setdefault(frame, _MappedFK(m, frame))
    return found


def fk_batch(m: Mechanism, q: Any, frame: str | None = None, workers: int | None = None) -> np.ndarray:
    """Poses ``(N, 4, 4)`` of a frame for ``N`` configurations ``(N, n_q)``.

    The same expressions as `optik.Mechanism.fk`, generated as C for chunks of `CHUNK`
    configurations and run on a thread pool (a ``ctypes`` call releases the GIL); without a C
    compiler, and while the library is built in the background, it is ``m.fk(q, frame)``.

    Raises:
        ShapeError, NonFiniteError: bad ``q``.
        UnknownFrameError: unknown frame.
    """
    qb, _ = as_batch(q, "q", m.n_q)
    m._frame(frame)
    fk = _mapped(m, frame)
    if fk.lib is None or fk.lib.get() is None or len(qb) < CHUNK:  # no compiler, or still building
        return m.fk(qb, frame).reshape(len(qb), 4, 4)
    starts = range(0, len(qb), CHUNK)
    used = workers or default_workers()
    if used == 1:
        return np.concatenate([fk.chunk(qb[a : a + CHUNK]) for a in starts])
    with ThreadPoolExecutor(max_workers=used) as pool:
        return np.concatenate(list(pool.map(lambda a: fk.chunk(qb[a : a + CHUNK]), starts)))
