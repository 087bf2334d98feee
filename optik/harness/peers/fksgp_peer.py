"""fkSGP (github.com/martyushev/fkSGP, MIT; not on PyPI): Stewart-Gough FK by elimination templates.

Its Python solver ``solver66(X, x, L, realOnly)`` takes the base and platform attachment points
with the first point of each at the origin (``X = b - b_0``, ``x = p - p_0``), the squared leg
lengths ``L``, and returns every real posture as ``[R | t']`` with ``X_i = R x_i + t'``; for
optik's frames ``b_i = R p_i + t`` that is ``t = t' + b_0 - R p_0``. The checkout is used where it
lies: nothing of it is copied into optik. Its ``python/__init__.py`` imports a test script
(f-strings that need Python 3.12), so the solver module is loaded from its folder under a package
name of its own without running that ``__init__``.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable
from pathlib import Path

import numpy as np

from optik.harness.peers.base import PeerUnavailable

__all__ = ["load_fksgp"]

Postures = Callable[[np.ndarray, np.ndarray, np.ndarray], list[tuple[np.ndarray, np.ndarray]]]
"""``(base 6x3, platform 6x3, leg lengths 6) -> [(R, t), ...]`` every real posture."""

_PACKAGE = "_optik_fksgp"


def load_fksgp(directory: str | Path) -> Postures:
    """The general 6-6 solver of the fkSGP checkout ``directory`` as a postures function.

    Raises:
        PeerUnavailable: no ``python/solver66.py`` under ``directory``, or it does not import.
    """
    folder = Path(directory) / "python"
    if not (folder / "solver66.py").is_file():
        raise PeerUnavailable(
            f"fksgp: {folder / 'solver66.py'} not found (pass the folder of a fkSGP checkout)"
        )
    if _PACKAGE not in sys.modules:
        pkg = types.ModuleType(_PACKAGE)
        pkg.__path__ = [str(folder)]
        sys.modules[_PACKAGE] = pkg
    try:
        solver = importlib.import_module(f"{_PACKAGE}.solver66").solver66
    except Exception as exc:  # a checkout of another version, a missing scipy, ...
        raise PeerUnavailable(f"fksgp: cannot import {folder / 'solver66.py'}: {exc}") from None

    def postures(
        base: np.ndarray, platform: np.ndarray, rho: np.ndarray
    ) -> list[tuple[np.ndarray, np.ndarray]]:
        b, p = np.asarray(base, dtype=float), np.asarray(platform, dtype=float)
        rt, _ = solver(b - b[0], p - p[0], np.asarray(rho, dtype=float) ** 2, 1)
        return [(m[:, :3], m[:, 3] + b[0] - m[:, :3] @ p[0]) for m in np.asarray(rt, dtype=float)]

    return postures
