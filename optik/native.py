"""Compiled CasADi functions: C code generation, the system C compiler, ``ctypes``.

Calling a CasADi ``Function`` from Python costs tens to a hundred microseconds per call
(argument conversion to ``DM`` and back), more than a whole IK iteration or QP step should take.
`library` generates C code for a list of functions (``casadi.CodeGenerator``), compiles it
once with the system C compiler into a shared library cached on disk (keyed by a hash of the
source and the compiler, so each machine compiles a given model once) and loads it;
`CCall` then calls one generated entry point through ``ctypes`` on preallocated numpy
buffers, about 1 us of overhead per call. Both the IK solvers ([`optik.solvers.native`][optik.solvers.native])
and differential IK (`optik.diffik._codegen`) use it.

Without a C compiler, with ``$OPTIK_NO_CODEGEN`` set, or with ``compile=False``, `library`
returns None and the callers evaluate with CasADi's own evaluator (same numbers, slower).

The cache directory is ``$OPTIK_CACHE_DIR`` or ``~/.cache/optik``. A library is written under a
temporary name and renamed into place (``os.replace``), so processes compiling the same source
at once never load a half-written file.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import casadi as ca
import numpy as np

from optik.errors import InvalidArgumentError, SolverUnavailableError

_INT = ctypes.c_longlong  # casadi_int of the generated code (see c_source)
_LIBS: dict[str, ctypes.CDLL] = {}  # loaded libraries by path


def compiler() -> str | None:
    """The C compiler: ``$CC`` or ``gcc``/``cc`` on the PATH; None when there is none or
    ``$OPTIK_NO_CODEGEN`` is set (then everything runs in CasADi's evaluator)."""
    if os.environ.get("OPTIK_NO_CODEGEN"):
        return None
    for cand in (os.environ.get("CC"), "gcc", "cc"):
        if cand and shutil.which(cand):
            return cand
    return None


def cache_dir() -> Path:
    """Directory of compiled libraries, ``$OPTIK_CACHE_DIR`` or ``~/.cache/optik`` (created on demand)."""
    d = Path(os.environ.get("OPTIK_CACHE_DIR") or Path.home() / ".cache" / "optik")
    d.mkdir(parents=True, exist_ok=True)
    return d


def c_source(functions: Sequence[ca.Function], extra_source: str = "") -> str:
    """C code of ``functions`` in one file (no header, ``casadi_int`` = ``long long int``),
    followed by ``extra_source`` (optik's own C calling the generated functions)."""
    gen = ca.CodeGenerator(f"{functions[0].name()}.c", {"with_header": False, "casadi_int": "long long int"})
    for f in functions:
        gen.add(f)
    return gen.dump() + extra_source


def compile_library(functions: Sequence[ca.Function], extra_source: str = "") -> Path:
    """Compile ``functions`` (and ``extra_source``, see `c_source`) into one shared
    library (once per source hash); its path.

    Raises:
        SolverUnavailableError: no C compiler, or the compilation failed.
        OSError: the cache directory is not writable.
    """
    return compile_source(c_source(functions, extra_source), functions[0].name())


def compile_source(source: str, stem: str, flags: Sequence[str] = ()) -> Path:
    """Compile C ``source`` into a shared library ``<stem>_<hash>.so`` in `cache_dir` (once per
    source, flags and compiler); its path. ``flags`` are extra compiler options (after ``-O2``).

    Raises:
        SolverUnavailableError: no C compiler, or the compilation failed.
        OSError: the cache directory is not writable.
    """
    cc = compiler()
    if cc is None:
        raise SolverUnavailableError("no C compiler found (set $CC or install gcc; unset $OPTIK_NO_CODEGEN)")
    digest = hashlib.sha256((source + cc + " ".join(flags)).encode()).hexdigest()[:20]
    folder = cache_dir()
    lib = folder / f"{stem}_{digest}.so"
    if lib.exists():
        return lib
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        src = Path(tmp, "f.c")
        src.write_text(source)
        out = Path(tmp, "f.so")
        proc = subprocess.run(
            [cc, "-O2", *flags, "-fPIC", "-shared", "-o", str(out), str(src), "-lm"],
            capture_output=True,
            text=True,
            check=False,
        )
        if proc.returncode != 0:
            raise SolverUnavailableError(f"compiling {stem} failed: {proc.stderr[-2000:]}")
        os.replace(out, lib)  # atomic: concurrent processes may compile the same source
    return lib


def library(
    functions: Sequence[ca.Function], compile: bool | str = "auto", extra_source: str = ""
) -> ctypes.CDLL | None:
    """The loaded library of ``functions``, or None: evaluate them with CasADi instead.

    Args:
        functions: the functions to compile into one library.
        compile: ``True`` compile (raise when impossible), ``False`` never compile (None),
            ``"auto"`` compile when a C compiler exists and works, else None.
        extra_source: C code appended to the generated code (see :func:`c_source`).

    Raises:
        InvalidArgumentError: bad ``compile`` value.
        SolverUnavailableError: ``compile=True`` without a working compiler.
    """
    return _load(lambda: compile_library(functions, extra_source), compile)


def source_library(
    source: str, stem: str, compile: bool | str = "auto", flags: Sequence[str] = ()
) -> ctypes.CDLL | None:
    """The loaded library of hand-written C ``source`` (see `compile_source`), or None.

    Args:
        source: C source text.
        stem: file name stem of the library.
        compile: as for `library`.
        flags: extra compiler options.

    Raises:
        InvalidArgumentError: bad ``compile`` value.
        SolverUnavailableError: ``compile=True`` without a working compiler.
    """
    return _load(lambda: compile_source(source, stem, flags), compile)


def _load(build: Callable[[], Path], compile: bool | str) -> ctypes.CDLL | None:
    if compile not in (True, False, "auto"):
        raise InvalidArgumentError("compile", f"expected True, False or 'auto', got {compile!r}")
    if compile is False or (compile == "auto" and compiler() is None):
        return None
    try:
        path = str(build())
        if path not in _LIBS:
            _LIBS[path] = ctypes.CDLL(path)
        return _LIBS[path]
    except (SolverUnavailableError, OSError):  # broken toolchain, unwritable cache, bad library
        if compile is True:
            raise
        return None


class CCall:
    """One generated function of a loaded library, bound to preallocated numpy buffers.

    Args:
        lib: the library (from `library`) that holds ``name``.
        name: the CasADi function's name.
        inputs: one contiguous float64 array per input (dense, column-major).
        outputs: one contiguous float64 array per output.

    The arrays are bound by address: write into ``inputs``, call, read ``outputs``. Keep them
    alive (and never reallocate them) while the call object is in use.
    """

    def __init__(
        self, lib: ctypes.CDLL, name: str, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray]
    ) -> None:
        self.name = name
        self._buffers = (list(inputs), list(outputs))  # keep the bound memory alive
        sizes = [_INT() for _ in range(4)]
        getattr(lib, f"{name}_work")(*[ctypes.byref(s) for s in sizes])
        n_arg, n_res, n_iw, n_w = (max(int(s.value), 1) for s in sizes)
        self._argv = (ctypes.c_void_p * n_arg)(*[b.ctypes.data for b in inputs])
        self._resv = (ctypes.c_void_p * n_res)(*[b.ctypes.data for b in outputs])
        self._iw = (_INT * n_iw)()
        self._w = (ctypes.c_double * n_w)()
        self._fn = getattr(lib, name)
        self._fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int]
        self._fn.restype = ctypes.c_int

    def __call__(self) -> None:
        """Evaluate on the current contents of the input buffers.

        Raises:
            SolverUnavailableError: the generated code reported an error.
        """
        if self._fn(self._argv, self._resv, self._iw, self._w, 0) != 0:
            raise SolverUnavailableError(f"{self.name}: evaluation failed")
