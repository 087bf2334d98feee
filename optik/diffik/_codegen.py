"""Compiled CasADi functions for the differential-IK hot path.

A CasADi ``Function`` called from Python costs tens of microseconds per call (argument
conversion to ``DM`` and back), more than a whole QP step should take. `CompiledFunction`
flattens a function to one input and one output vector, compiles it through `optik.native`
(generated C, cached on disk, called through ``ctypes`` on preallocated numpy buffers) and calls
the CasADi function itself while the C library is being built in the background and without a
C compiler (same numbers, slower).

Every input and output is dense and column-major (CasADi's storage), so a ``p x q`` output is
returned as a numpy array of shape ``(p, q)``; vectors are returned 1-D.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optik.native import Binding, library


class CompiledFunction:
    """A CasADi function callable on numpy arrays with little overhead.

    The function is flattened to one input vector (all inputs, column-major, concatenated) and
    one output vector, so a call is one copy in, one C call and one copy out; the outputs are
    returned as views into that copy (shape ``(rows, cols)``, transposed views of the column-major
    data; 1-D for vectors).

    Args:
        f: a CasADi ``SX`` function whose inputs and outputs are dense.
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
        self._in = np.zeros(x.shape[0])
        self._out = np.zeros(start)
        self.library = library([self._flat])
        self._native = Binding(self.library, f.name(), [self._in], [self._out])

    @property
    def compiled(self) -> bool:
        """True when the compiled C code is used; False for CasADi's evaluator (while it builds,
        or without a compiler)."""
        return self._native.compiled

    def _evaluate(self) -> None:
        """CasADi's evaluator, into the output buffer."""
        self._out[:] = np.asarray(self._flat(self._in), dtype=float).reshape(-1)

    def call_flat(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """Evaluate on the concatenated (column-major) inputs."""
        self._in[:] = x
        self._native(self._evaluate)
        out = self._out.copy()
        return tuple([out[a:b] if c == 1 else out[a:b].reshape(c, r).T for a, b, r, c in self._bounds])

    def __call__(self, *inputs: np.ndarray) -> tuple[np.ndarray, ...]:
        """Evaluate on numpy inputs (vectors or matrices of the declared shapes)."""
        return self.call_flat(
            np.concatenate([np.asarray(v, dtype=float).reshape(-1, order="F") for v in inputs])
        )
