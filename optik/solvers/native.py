"""CasADi functions with dense vector inputs/outputs, called on preallocated buffers.

The IK methods that iterate in compiled code (``lm``, the error checks of ``nlp``) call their
CasADi functions through [`NativeFunction`][optik.solvers.native.NativeFunction]: generated C code compiled
and loaded by `optik.native` (about 1 us of overhead per call instead of about 100 us through CasADi's Python
interface), or the same interface over CasADi's own evaluator: while the library is still being built in
the background, without a compiler, or with ``compile=False``.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from optik.errors import InvalidArgumentError
from optik.native import Binding, Library, library


def native_functions(functions: list[ca.Function], compile: bool | str = "auto") -> list[NativeFunction]:
    """[`NativeFunction`][optik.solvers.native.NativeFunction] wrappers of several functions compiled into one
    library.

    Args:
        functions: functions with dense column inputs and outputs.
        compile: ``True`` compile now (raise when impossible), ``False`` use CasADi's evaluator,
            ``"auto"`` use the cached library, or CasADi's evaluator while it is built in the
            background (and for good when there is no working C compiler).

    Raises:
        InvalidArgumentError: bad ``compile`` value or non-dense inputs/outputs.
        SolverUnavailableError: ``compile=True`` without a working compiler.
    """
    for f in functions:
        _check_dense(f)  # before compiling
    lib = library(functions, compile)
    return [NativeFunction(f, lib) for f in functions]


def _check_dense(f: ca.Function) -> None:
    for i in range(f.n_in()):
        if f.size2_in(i) != 1 or not f.sparsity_in(i).is_dense():
            raise InvalidArgumentError("f", f"input {i} of {f.name()} must be a dense column")
    for i in range(f.n_out()):
        if f.size2_out(i) != 1 or not f.sparsity_out(i).is_dense():
            raise InvalidArgumentError("f", f"output {i} of {f.name()} must be a dense column")


class NativeFunction:
    """A CasADi function with dense vector inputs/outputs, callable on preallocated buffers.

    Write the inputs into `inputs` (numpy arrays), call, read `outputs` (views of
    preallocated buffers: copy them to keep them across calls). Not thread-safe.

    Args:
        f: the function; every input and output must be a dense column or scalar.
        library: library holding ``f`` (`optik.native.library`; None: CasADi's evaluator).
            Until it is ready the calls go to CasADi's evaluator, then to the C code.
    """

    def __init__(self, f: ca.Function, library: Library | None = None) -> None:
        _check_dense(f)
        self.function = f
        self.inputs = [np.zeros(f.size1_in(i)) for i in range(f.n_in())]
        self.outputs = [np.zeros(f.size1_out(i)) for i in range(f.n_out())]
        self.library = library
        self._native = Binding(library, f.name(), self.inputs, self.outputs)
        self._buffer: Any = None  # CasADi's evaluator on the same buffers, made at its first use

    @property
    def compiled(self) -> bool:
        """True when calls go to generated, compiled C code (False while it is being built)."""
        return self._native.compiled

    def __call__(self) -> list[np.ndarray]:
        """Evaluate on the current contents of `inputs`; returns `outputs`."""
        self._native(self._evaluate)
        return self.outputs

    def _evaluate(self) -> None:
        """CasADi's evaluator, into `outputs`: ``Function.buffer`` bound to `inputs` and
        `outputs` (about a microsecond of overhead per call instead of the hundred or so of a
        call through ``DM`` conversions, which would dominate the first solves while the library
        builds)."""
        if self._buffer is None:
            buffer, call = self.function.buffer()
            for i, a in enumerate(self.inputs):
                buffer.set_arg(i, memoryview(a))
            for i, a in enumerate(self.outputs):
                buffer.set_res(i, memoryview(a))
            self._buffer = (buffer, call)
        self._buffer[1]()
