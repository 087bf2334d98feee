"""Condition numbers of stacks of small matrices (the passive Jacobians of the FK modes).

``kappa(A) = sigma_max(A) / sigma_min(A)`` over the ``min(m, n)`` singular values (infinite when
the smallest is 0). In C (``conditions.c``: one-sided Jacobi, compiled once per machine in the
background by `optik.native.CFunction`), one call for the whole stack; until the library is
loaded, without a C compiler, and for matrices larger than the C code takes, one stacked
``numpy.linalg.svd``. The two agree to rounding (relative ``1e-12`` well away from singular
matrices, where both carry the error of the smallest singular value).
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from optik import native

SOURCE = Path(__file__).with_name("conditions.c")
"""The C kernel (`optik_conditions`)."""

_KERNEL = native.CFunction(
    SOURCE,
    "optik_conditions",
    "optik_conditions",
    [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_void_p],
)


def condition_numbers(a: np.ndarray) -> list[float]:
    """The condition number of each matrix of the stack ``a (K, m, n)`` (``m, n >= 1``).

    Raises:
        numpy.linalg.LinAlgError: a stack with a non-finite entry (from ``numpy.linalg.svd``).
    """
    count, rows, cols = a.shape
    fn = _KERNEL.get()
    if fn is not None and count:
        data = np.ascontiguousarray(a, dtype=float)
        out = np.empty(count)
        if fn(data.ctypes.data, count, rows, cols, out.ctypes.data) == 0:
            return out.tolist()
    s = np.linalg.svd(a, compute_uv=False)
    return [float(hi / lo) if lo > 0 else float("inf") for hi, lo in s[:, [0, -1]].tolist()]
