"""Fast calls of CasADi functions from Python: C code generation, gcc, ``ctypes``.

Calling a CasADi ``Function`` from Python costs about 100 us per call for small functions
(argument conversion dominates), more than the whole computation of an IK iteration. Where a
C compiler exists, :func:`native_functions` generates C code for the functions
(``casadi.CodeGenerator``), compiles it into a shared library (cached on disk, keyed by a hash
of the source, so each machine compiles a given model once) and calls the generated entry point
through ``ctypes`` with preallocated buffers: about 1 us of overhead per call. Without a
compiler (or with ``compile=False``) the same interface wraps CasADi's own evaluator.

The cache directory is ``$OPTIK_CACHE_DIR`` or ``~/.cache/optik``.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from optik.errors import InvalidArgumentError, SolverUnavailableError

_P = ctypes.POINTER(ctypes.c_double)
_INT = ctypes.c_longlong  # casadi_int of the generated code
_LIBS: dict[str, ctypes.CDLL] = {}


def compiler() -> str | None:
    """The C compiler used for code generation: ``$CC`` or ``gcc``/``cc`` on the PATH (None: none)."""
    for cand in (os.environ.get("CC"), "gcc", "cc"):
        if cand and shutil.which(cand):
            return cand
    return None


def cache_dir() -> Path:
    """Directory of compiled libraries (created on demand)."""
    d = Path(os.environ.get("OPTIK_CACHE_DIR", Path.home() / ".cache" / "optik"))
    d.mkdir(parents=True, exist_ok=True)
    return d


def _compile(functions: list[ca.Function]) -> Path:
    """Generate C for ``functions`` (one file), compile it once per source hash, return the library."""
    cc = compiler()
    if cc is None:
        raise SolverUnavailableError("no C compiler found (set $CC or install gcc)")
    stem = functions[0].name()
    with tempfile.TemporaryDirectory() as tmp:
        cg = ca.CodeGenerator(f"{stem}.c", {"with_header": False})
        for f in functions:
            cg.add(f)
        cg.generate(tmp + os.sep)
        source = Path(tmp, f"{stem}.c").read_text()
    digest = hashlib.sha256((source + cc).encode()).hexdigest()[:20]
    lib = cache_dir() / f"{stem}_{digest}.so"
    if lib.exists():
        return lib
    with tempfile.TemporaryDirectory(dir=cache_dir()) as tmp:
        src = Path(tmp, "f.c")
        src.write_text(source)
        out = Path(tmp, "f.so")
        proc = subprocess.run(
            [cc, "-O2", "-fPIC", "-shared", "-o", str(out), str(src), "-lm"],
            capture_output=True,
            text=True,
            check=False,
        )
        if proc.returncode != 0:
            raise SolverUnavailableError(f"compiling {stem} failed: {proc.stderr[-2000:]}")
        os.replace(out, lib)  # atomic: concurrent processes may compile the same source
    return lib


def native_functions(functions: list[ca.Function], compile: bool | str = "auto") -> list[NativeFunction]:
    """:class:`NativeFunction` wrappers of several functions compiled into one library.

    Args:
        functions: functions with dense column inputs and outputs.
        compile: ``True`` compile (raise when impossible), ``False`` use CasADi's evaluator,
            ``"auto"`` compile when a C compiler exists and works, else use the evaluator.

    Raises:
        InvalidArgumentError: bad ``compile`` value or non-dense inputs/outputs.
        SolverUnavailableError: ``compile=True`` without a working compiler.
    """
    if compile not in (True, False, "auto"):
        raise InvalidArgumentError("compile", f"expected True, False or 'auto', got {compile!r}")
    lib = None
    if compile is True:
        lib = _compile(functions)
    elif compile == "auto" and compiler() is not None:
        try:
            lib = _compile(functions)
        except (SolverUnavailableError, OSError):  # broken toolchain or unwritable cache: interpret
            lib = None
    return [NativeFunction(f, lib) for f in functions]


class NativeFunction:
    """A CasADi function with dense vector inputs/outputs, callable on preallocated buffers.

    Write the inputs into :attr:`inputs` (numpy arrays), call, read :attr:`outputs` (views of
    preallocated buffers: copy them to keep them across calls). Not thread-safe.

    Args:
        f: the function; every input and output must be a dense column or scalar.
        library: compiled library holding ``f`` (None: CasADi's evaluator).

    Attributes:
        compiled: True when calls go to generated, compiled C code.
    """

    def __init__(self, f: ca.Function, library: Path | None = None) -> None:
        self.function = f
        self.inputs = [np.zeros(f.size1_in(i)) for i in range(f.n_in())]
        self.outputs = [np.zeros(f.size1_out(i)) for i in range(f.n_out())]
        for i in range(f.n_in()):
            if f.size2_in(i) != 1 or not f.sparsity_in(i).is_dense():
                raise InvalidArgumentError("f", f"input {i} of {f.name()} must be a dense column")
        for i in range(f.n_out()):
            if f.size2_out(i) != 1 or not f.sparsity_out(i).is_dense():
                raise InvalidArgumentError("f", f"output {i} of {f.name()} must be a dense column")
        self.compiled = library is not None
        if library is not None:
            self._bind(library)

    def _bind(self, path: Path) -> None:
        key = str(path)
        if key not in _LIBS:
            _LIBS[key] = ctypes.CDLL(key)
        lib = _LIBS[key]
        name = self.function.name()
        sizes = [_INT() for _ in range(4)]
        getattr(lib, f"{name}_work")(*[ctypes.byref(s) for s in sizes])
        n_arg, n_res, n_iw, n_w = (max(int(s.value), 1) for s in sizes)
        self._argv = (_P * n_arg)(*[b.ctypes.data_as(_P) for b in self.inputs])
        self._resv = (_P * n_res)(*[b.ctypes.data_as(_P) for b in self.outputs])
        self._iw = (_INT * n_iw)()
        self._w = (ctypes.c_double * n_w)()
        self._fn = getattr(lib, name)
        self._fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int]
        self._fn.restype = ctypes.c_int

    def __call__(self) -> list[np.ndarray]:
        """Evaluate on the current contents of :attr:`inputs`; returns :attr:`outputs`."""
        if self.compiled:
            if self._fn(self._argv, self._resv, self._iw, self._w, 0) != 0:
                raise SolverUnavailableError(f"{self.function.name()}: evaluation failed")
            return self.outputs
        res = self.function(*self.inputs)
        res = res if isinstance(res, (list, tuple)) else [res]
        for buf, val in zip(self.outputs, res, strict=True):
            buf[:] = np.asarray(val, dtype=float).reshape(-1)
        return self.outputs
