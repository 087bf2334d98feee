"""Compiled CasADi functions for the differential-IK hot path.

A CasADi ``Function`` called from Python costs tens of microseconds per call (argument
conversion to ``DM`` and back), more than a whole QP step should take. :func:`compile_function`
generates C code for a function (``Function.generate``), compiles it once with the system C
compiler into a shared library cached on disk (keyed by a hash of the source) and calls it through
``ctypes`` on preallocated numpy buffers. Without a C compiler it falls back to calling the CasADi
function itself (same numbers, slower).

Every input and output is dense and column-major (CasADi's storage), so a ``p x q`` output is
returned as a numpy array of shape ``(p, q)``; vectors are returned 1-D.
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

_LIBS: dict[str, ctypes.CDLL] = {}


def cache_dir() -> Path:
    """Directory of the compiled libraries: ``$OPTIK_CACHE_DIR`` or ``~/.cache/optik/codegen``.

    Set ``OPTIK_NO_CODEGEN=1`` to skip compilation (CasADi's own evaluation is used)."""
    root = os.environ.get("OPTIK_CACHE_DIR")
    return Path(root) if root else Path.home() / ".cache" / "optik" / "codegen"


def _compile(source: str, name: str) -> ctypes.CDLL | None:
    """Compile C ``source`` into a cached shared library; None when no compiler works."""
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if os.environ.get("OPTIK_NO_CODEGEN") or cc is None:
        return None
    digest = hashlib.sha1(source.encode()).hexdigest()[:16]
    if digest in _LIBS:
        return _LIBS[digest]
    folder = cache_dir()
    lib_path = folder / f"{name}_{digest}.so"
    try:
        if not lib_path.exists():
            _build(cc, source, name, folder, lib_path)
        lib = ctypes.CDLL(str(lib_path))
    except (OSError, subprocess.SubprocessError):  # unwritable cache, broken compiler: fall back
        return None
    _LIBS[digest] = lib
    return lib


def _build(cc: str, source: str, name: str, folder: Path, lib_path: Path) -> None:
    """Compile ``source`` into ``lib_path`` (atomically: parallel processes may race here)."""
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        src = Path(tmp) / f"{name}.c"
        src.write_text(source)
        out = Path(tmp) / f"{name}.so"
        subprocess.run(
            [cc, "-O1", "-fPIC", "-shared", "-o", str(out), str(src), "-lm"],
            capture_output=True,
            text=True,
            check=True,
        )
        os.replace(out, lib_path)


class CompiledFunction:
    """A CasADi function callable on numpy arrays with little overhead.

    The function is flattened to one input vector (all inputs, column-major, concatenated) and
    one output vector, so a call is one copy in, one C call and one copy out; the outputs are
    returned as views into that copy (shape ``(rows, cols)``, transposed views of the column-major
    data; 1-D for vectors).

    Args:
        f: a CasADi ``SX`` function whose inputs and outputs are dense.

    Attributes:
        compiled: True when the C code was compiled and is used; False for the CasADi fallback.
    """

    def __init__(self, f: ca.Function) -> None:
        self.function = f
        self._in_shapes = [f.size_in(i) for i in range(f.n_in())]
        self._out_shapes = [f.size_out(i) for i in range(f.n_out())]
        x = ca.SX.sym("x", sum(r * c for r, c in self._in_shapes))
        args, start = [], 0
        for r, c in self._in_shapes:
            args.append(ca.reshape(x[start : start + r * c], r, c))
            start += r * c
        outs = f(*args)
        outs = outs if isinstance(outs, (list, tuple)) else [outs]
        flat = ca.vertcat(*[ca.vec(ca.densify(o)) for o in outs])
        self._flat = ca.Function(f.name(), [x], [flat])
        self._bounds = []
        start = 0
        for r, c in self._out_shapes:
            self._bounds.append((start, start + r * c, r, c))
            start += r * c
        lib = _compile(self._source(self._flat), f.name())
        self.compiled = lib is not None
        self._in = np.zeros(x.shape[0])
        self._out = np.zeros(start)
        if lib is None:
            return
        self._fun = getattr(lib, f.name())
        self._fun.restype = ctypes.c_int
        n_arg, n_res = self._flat.sz_arg(), self._flat.sz_res()
        self._arg = (ctypes.c_void_p * n_arg)(self._in.ctypes.data, *[None] * (n_arg - 1))
        self._res = (ctypes.c_void_p * n_res)(self._out.ctypes.data, *[None] * (n_res - 1))
        self._iw = np.zeros(max(self._flat.sz_iw(), 1), dtype=np.int64)
        self._w = np.zeros(max(self._flat.sz_w(), 1))
        self._args = (
            self._arg,
            self._res,
            ctypes.c_void_p(self._iw.ctypes.data),
            ctypes.c_void_p(self._w.ctypes.data),
            ctypes.c_int(0),
        )

    @staticmethod
    def _source(f: ca.Function) -> str:
        gen = ca.CodeGenerator(f"{f.name()}.c", {"with_header": False, "casadi_int": "long long int"})
        gen.add(f)
        return gen.dump()

    def call_flat(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """Evaluate on the concatenated (column-major) inputs."""
        if self.compiled:
            self._in[:] = x
            self._fun(*self._args)
            out = self._out.copy()
        else:
            out = np.asarray(self._flat(x), dtype=float).reshape(-1)
        return tuple([out[a:b] if c == 1 else out[a:b].reshape(c, r).T for a, b, r, c in self._bounds])

    def __call__(self, *inputs: np.ndarray) -> tuple[np.ndarray, ...]:
        """Evaluate on numpy inputs (vectors or matrices of the declared shapes)."""
        return self.call_flat(
            np.concatenate([np.asarray(v, dtype=float).reshape(-1, order="F") for v in inputs])
        )
