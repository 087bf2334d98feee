"""Compiled CasADi functions for the differential-IK hot path.

A CasADi ``Function`` called from Python costs tens of microseconds per call (argument
conversion to ``DM`` and back), more than a whole QP step should take. `CompiledFunction`
flattens a function to one input and one output vector, compiles it through `optik.native`
(generated C, cached on disk, called through ``ctypes`` on preallocated numpy buffers) and calls
the CasADi function itself while the C library is being built in the background and without a
C compiler (same numbers, slower).

Every input and output is dense and column-major (CasADi's storage), so a ``p x q`` output is
returned as a numpy array of shape ``(p, q)``; vectors are returned 1-D.

*Threads.* The ``ctypes`` call releases the GIL, so each thread has its own input and output
buffers and its own bound call (the generated code's work memory): threads calling one
`CompiledFunction` at once run in parallel and never see each other's numbers.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import casadi as ca
import numpy as np

from optik.native import Binding, library


def flatten(f: ca.Function) -> ca.Function:
    """``f`` with one input vector (every input, column-major, concatenated) and one output vector
    (every output, densified and column-major, concatenated), under the same name."""
    shapes = [f.size_in(i) for i in range(f.n_in())]
    x = ca.SX.sym("x", sum(r * c for r, c in shapes))
    args, start = [], 0
    for r, c in shapes:
        args.append(ca.reshape(x[start : start + r * c], r, c))
        start += r * c
    outs = f(*args)
    outs = outs if isinstance(outs, (list, tuple)) else [outs]
    return ca.Function(f.name(), [x], [ca.vertcat(*[ca.vec(ca.densify(o)) for o in outs])])


def output_bounds(shapes: list[tuple[int, int]]) -> list[tuple[int, int, int, int]]:
    """``(start, stop, rows, cols)`` of each output of shape ``(rows, cols)`` in the flattened output."""
    bounds, start = [], 0
    for r, c in shapes:
        bounds.append((start, start + r * c, r, c))
        start += r * c
    return bounds


def split_outputs(out: np.ndarray, bounds: list[tuple[int, int, int, int]]) -> tuple[np.ndarray, ...]:
    """The outputs in the flattened ``out`` (vectors 1-D, matrices ``(rows, cols)``)."""
    return tuple([out[a:b] if c == 1 else out[a:b].reshape(c, r).T for a, b, r, c in bounds])


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
        self._out_shapes = [f.size_out(i) for i in range(f.n_out())]
        self._flat = flatten(f)
        self._bounds = output_bounds(self._out_shapes)
        self._sizes = (int(self._flat.size1_in(0)), self._bounds[-1][1] if self._bounds else 0)
        self.library = library([self._flat])
        self._local = threading.local()

    def _thread_state(self) -> tuple[np.ndarray, np.ndarray, Binding, Callable[[], None]]:
        """This thread's ``(input buffer, output buffer, bound call, CasADi evaluation)``."""
        state = getattr(self._local, "state", None)
        if state is None:
            x, out = np.zeros(self._sizes[0]), np.zeros(self._sizes[1])

            def evaluate() -> None:  # CasADi's evaluator, into this thread's output buffer
                out[:] = np.asarray(self._flat(x), dtype=float).reshape(-1)

            state = self._local.state = (
                x,
                out,
                Binding(self.library, self._flat.name(), [x], [out]),
                evaluate,
            )
        return state

    @property
    def compiled(self) -> bool:
        """True when the compiled C code is used; False for CasADi's evaluator (while it builds,
        or without a compiler)."""
        return self._thread_state()[2].compiled

    def call_flat(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """Evaluate on the concatenated (column-major) inputs."""
        buf, out, native, evaluate = self._thread_state()
        buf[:] = x
        native(evaluate)
        return split_outputs(out.copy(), self._bounds)

    def __call__(self, *inputs: np.ndarray) -> tuple[np.ndarray, ...]:
        """Evaluate on numpy inputs (vectors or matrices of the declared shapes)."""
        return self.call_flat(
            np.concatenate([np.asarray(v, dtype=float).reshape(-1, order="F") for v in inputs])
        )
