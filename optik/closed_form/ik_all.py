"""Every solution of one IK target of a derived closed form in one compiled call.

CasADi generates the functions of a derived closed form (`optik.closed_form.derived`): its ``B``
candidate branches for a target (16 entries of the 4x4 transform, row-major, -> 6 angles per
candidate), split into groups, one function each (the regular candidates, and each run of
stand-ins for a singularity), and the FK check of one candidate (``q``, target -> position
error ``|p(q) - p*|`` and orientation error, the geodesic angle of ``R(q) R*^T``, on the
product-of-exponentials model). optik's driver ``ik_all.c``, compiled with them, does for one
target:

1. validate the target as ``optik.checks.as_transform`` does, and ``q0``
   (finite); when either fails it answers *status 1* and the caller's validating path raises
   the named error;
2. go through the candidates in their order, a group's function evaluated when the first
   candidate of it is needed: skip the stand-ins for a singularity whose regular candidate
   passed ([`DerivedIK.stand_ins`][optik.closed_form.derived.DerivedIK.stand_ins]; a group of
   stand-ins whose regular candidates all passed is never evaluated: the usual target away
   from the singularity pays for the regular candidates only) and the non-finite candidates (a
   subproblem without a real solution); FK-check the others: kept when both errors are within
   the check tolerances; a candidate failing the check but within the polish range answers
   *status 2* (the caller's numpy path polishes it, `DerivedIK.finish`);
3. wrap the kept ones to ``(-pi, pi]``; two closer than ``same`` (max-norm, angles modulo
   ``2 pi``) answer *status 2* (the numpy path merges them by their accuracy);
4. shift each angle outside the limits by the whole turns that land within them, or nearest
   them ([`spatial.wrap_to_limits`][optik.spatial.wrap_to_limits], the same rules and
   arithmetic), and split the solutions into those within every limit and the others;
5. with ``sort``, order the ones within the limits by their max-norm distance to ``q0``
   (angles modulo ``2 pi``), stable.

The FK check takes the cosines and sines of a candidate's angles, which the driver evaluates
from those angles once per distinct value (candidates share angles). One call costs about 1 us of
``ctypes`` and buffer copies besides the arithmetic, well under 1 us through the Python binding
(`AllSolutionsKernel.fast`); `AllSolutionsKernel.many` runs the driver over many targets in one
call, and `AllSolutionsKernel.rows` hands back the solutions within the limits alone (one array, for
`optik.AllSolutions`). The driver is reentrant (stack memory only); the Python buffers of one kernel are
guarded by a lock.
"""

from __future__ import annotations

import ctypes
import logging
import sys
import sysconfig
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from optik import native
from optik.checks import ORTHO_DIAG, ORTHO_OFF
from optik.closed_form import registry
from optik.errors import SolverUnavailableError

DRIVER = Path(__file__).with_name("ik_all.c")
"""optik's C driver."""

_IN = 16 + 6 + 6 + 6 + 8  # target, q0, lower, upper, conf (the layout of ik_all.c)
_LOG = logging.getLogger(__name__)


def python_flags() -> tuple[str, ...]:
    """Compiler options for the driver's Python binding (``-DOPTIK_PYTHON`` and the include
    directories of Python and numpy), or none when the headers are not installed (the driver
    is then called through ``ctypes`` alone)."""
    include = sysconfig.get_paths().get("include") or ""
    if not (Path(include) / "Python.h").exists():
        return ()
    # the versions are part of the cache key: a library built against other headers is not reused
    abi = f"-DOPTIK_ABI={sys.implementation.cache_tag}_numpy{np.__version__.replace('.', '_')}"
    return ("-DOPTIK_PYTHON", abi, f"-I{include}", f"-I{np.get_include()}")


class AllSolutionsKernel:
    """The compiled driver of one derived closed form (thread-safe).

    Args:
        branches: the candidate functions, each with the indices (among the ``B`` candidates)
            of what it computes: ``t (16) -> candidates (6 per index)``, one column; every
            index once. The first one's candidates are evaluated for every target, each other
            one only when one of its candidates is needed (a stand-in whose regular candidate
            failed the check).
        check: ``(cs (12), t (16)) -> (position error, orientation error)``, one output of 2:
            the FK check of one candidate given the cosines and then the sines of its angles.
        stand_ins: per candidate, the earlier candidate it stands in for (-1: none): it is not
            checked, and not kept, when that one passes the check.
        check_tol: ``(position, orientation)`` tolerances of the FK check.
        polish_tol: ``(position, orientation)``: failing candidates within these are polished
            by the caller (status 2).
        same: distance under which two kept candidates must be merged by the caller (status 2).
        compile: as in ``optik.native.library`` (``"auto"``: built in the background; `ready`
            tells when it is loaded).

    With the Python and numpy headers the library also holds a Python binding of the driver
    (a builtin function taking the arrays themselves): a call then costs well under a
    microsecond besides the arithmetic. Without them the driver is called through ``ctypes`` on
    buffers guarded by a lock.
    """

    def __init__(
        self,
        branches: Sequence[tuple[ca.Function, Sequence[int]]],
        check: ca.Function,
        stand_ins: tuple[int, ...],
        check_tol: tuple[float, float],
        polish_tol: tuple[float, float],
        same: float,
        compile: bool | str = "auto",
    ) -> None:
        order = [k for _, indices in branches for k in indices]
        self.size = len(order)
        functions = [f for f, _ in branches]
        group = [0] * self.size  # the function computing candidate b, and its row in raw
        for g, (_, indices) in enumerate(branches):
            for k in indices:
                group[k] = g
        row = [order.index(k) for k in range(self.size)]
        starts = np.cumsum([0] + [len(indices) for _, indices in branches[:-1]]).tolist()
        conf = (*check_tol, *polish_tol, same, ORTHO_DIAG, ORTHO_OFF)
        every = (*functions, check)
        work = [max(f.sz_iw() for f in every), max(f.sz_w() for f in every)]
        signature = "const casadi_real**, casadi_real**, casadi_int*, casadi_real*, int"
        defines = (
            f"\n#define OPTIK_B {self.size}\n#define OPTIK_G {len(functions)}\n"
            f"#define OPTIK_IW {work[0]}\n#define OPTIK_W {work[1]}\n"
            f"#define OPTIK_CHECK {check.name()}\n"
            f"#define OPTIK_LIMIT_TOL {float(registry.LIMIT_TOL).hex()}\n"
            f"static int (*const optik_group_fn[{len(functions)}])({signature}) = "
            f"{{{', '.join(f.name() for f in functions)}}};\n"
            f"static const int optik_group_at[{len(functions)}] = {{{', '.join(map(str, starts))}}};\n"
            f"static const int optik_group[{self.size}] = {{{', '.join(map(str, group))}}};\n"
            f"static const int optik_row[{self.size}] = {{{', '.join(map(str, row))}}};\n"
            f"static const int optik_stand_in[{self.size}] = {{{', '.join(map(str, stand_ins))}}};\n"
            f"static const double optik_conf[7] = {{{', '.join(float(v).hex() for v in conf)}}};\n"
        )
        # errno is never read: sqrt becomes one instruction, sin and cos of one angle one sincos
        # (every library is built without semantic interposition: the generated functions are
        # inlined into the driver, about 0.6 us of 3.4 per target)
        driver = native.driver_source(DRIVER, compile)
        flags = ("-fno-math-errno", *python_flags())
        source = None if driver is None else defines + driver
        self.library = None if source is None else native.library([*functions, check], compile, source, flags)
        self._in = np.zeros(_IN)
        self._in[34:41] = conf
        self._out = np.zeros(3 + 14 * self.size)
        self._limits = b""
        self._fn: Any = None
        self.fast: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray] | bool | None] | None = None
        """The Python binding ``fast(t, q0, lower, upper, sort)`` once loaded, when the library
        has one: the answer of `__call__`, False for status 1 or 2, None for arrays of another
        type or layout than float64 of the right shape."""
        self.many: Callable[..., tuple[np.ndarray, ...] | None] | None = None
        """The Python binding over many targets ``many(t (M, 4, 4), q0, lower, upper, sort)``
        once loaded, when the library has one (``q0``: None, ``(6,)`` or ``(M, 6)``; arrays
        C-contiguous float64): ``(q within (K, 6), errors (K, 2), counts within (M,), q outside
        (L, 6), counts outside (M,), status (M,))``, the targets one after the other (those of
        status 1 or 2 have no rows: the caller decides them), with the interpreter lock released
        during the loop; None for arrays of another type or layout."""
        self.rows: Callable[..., np.ndarray | tuple[np.ndarray, np.ndarray] | bool | None] | None = None
        """The Python binding of the solutions within the limits alone, ``rows(t, q0, lower,
        upper, outside)`` once loaded, when the library has one: ``q within (K, 6)`` sorted as
        by `fast` (``outside`` true: the pair ``(q within, q outside (L, 6))``); False and None
        as `fast`'s. One array per call, no other Python object."""
        self._args = (ctypes.c_void_p(self._in.ctypes.data), ctypes.c_void_p(self._out.ctypes.data))
        self.lock = threading.Lock()

    @property
    def ready(self) -> bool:
        """True once the compiled library is loaded (False while it builds or when it failed)."""
        if self._fn is None and self.library is not None:
            lib = self.library.get()
            if lib is not None:
                fn = lib.optik_ik_all
                fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
                fn.restype = ctypes.c_int
                if hasattr(lib, "optik_ik_all_function"):  # called with the GIL held: PyDLL
                    make = ctypes.PyDLL(str(self.library.path)).optik_ik_all_function
                    make.argtypes = []
                    make.restype = ctypes.py_object
                    try:
                        self.fast, self.many, self.rows = make()
                    except Exception as exc:  # e.g. numpy's C API refused: the ctypes path stays
                        _LOG.warning("optik: no Python binding for %s: %s", self.library.path.name, exc)
                self._fn = fn
        return self._fn is not None

    def __call__(
        self, t: np.ndarray, q0: np.ndarray | None, lower: np.ndarray, upper: np.ndarray, sort: bool = True
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The solutions of target ``t (4, 4)`` (call only when `ready`).

        Args:
            t: the target.
            q0: with ``sort``, the solutions within the limits are ordered by their distance to
                it (None: to the middle of the limits, as ``Mechanism.mid_q``).
            lower, upper: the joint limits (infinite: no shift, every solution within).
            sort: False keeps the candidate order.

        Returns:
            ``(q within (K, 6), their (position, orientation) errors (K, 2), q outside (L, 6))``,
            or None for status 1 or 2 (module docstring: the caller's general path decides).

        Raises:
            SolverUnavailableError: the generated code reported an error.
        """
        if self.fast is not None:
            try:
                got = self.fast(t, q0, lower, upper, sort)
            except RuntimeError as exc:
                raise SolverUnavailableError(str(exc)) from None
            if got is not None:
                return got or None  # False: status 1 or 2
            # None: arrays of another type or layout, converted into the buffers below
        with self.lock:
            buf, out = self._in, self._out
            buf[:16] = np.reshape(t, 16)
            if q0 is not None:
                buf[16:22] = q0
            buf[41] = (1.0 if q0 is not None else 2.0) if sort else 0.0
            limits = lower.tobytes() + upper.tobytes()
            if limits != self._limits:  # limits rarely change: written when they do
                buf[22:28] = lower
                buf[28:34] = upper
                self._limits = limits
            if self._fn(*self._args) != 0:
                raise SolverUnavailableError("optik_ik_all: evaluation of the generated code failed")
            status, n_in, n_out = out[:3].tolist()
            if status != 0.0:
                return None
            i, o = 6 * int(n_in), 6 * int(n_out)
            block = out[3 : 3 + i + o + i // 3].copy()  # q within, q outside, errors within
        return block[:i].reshape(-1, 6), block[i + o :].reshape(-1, 2), block[i : i + o].reshape(-1, 6)
