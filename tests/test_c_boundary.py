"""Buffers handed to C are checked at the boundary (issue 18, item 11): `optik.native.CCall`
checks its bound buffers against the generated function's signature once, when it is made, and
`LMKernel.run` checks the shapes and kinds of its arrays before the driver reads them; a wrong
call raises an error naming the argument instead of reading or writing out of bounds."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import optik
from optik import native
from optik.errors import InvalidArgumentError, ShapeError
from optik.solvers import lm_kernel
from optik.solvers.lm_kernel import kernel

pytestmark = pytest.mark.skipif(native.compiler() is None, reason="needs a C compiler")

X = ca.SX.sym("x", 3)
Y = ca.SX.sym("y", 2, 2)
F = ca.Function("optik_test_boundary", [X, Y], [X * 2, ca.mtimes(Y, Y), ca.SX(ca.Sparsity.lower(3))])


@pytest.fixture(scope="module")
def lib():
    return native.library([F], True).get()


def _buffers():
    return [np.zeros(3), np.zeros(4)], [np.zeros(3), np.zeros(4), np.zeros(6)]


def test_right_buffers_are_bound_and_evaluated(lib):
    ins, outs = _buffers()
    call = native.CCall(lib, F.name(), ins, outs)
    ins[0][:] = [1.0, 2.0, 3.0]
    ins[1][:] = [1.0, 2.0, 3.0, 4.0]  # column-major [[1, 3], [2, 4]]
    call()
    np.testing.assert_array_equal(outs[0], [2.0, 4.0, 6.0])
    np.testing.assert_array_equal(outs[1], [7.0, 10.0, 15.0, 22.0])


@pytest.mark.parametrize(
    ("change", "error", "match"),
    [
        (lambda i, o: (i[:1], o), InvalidArgumentError, r"^inputs: .* takes 2 inputs, got 1"),
        (lambda i, o: (i, [*o, np.zeros(1)]), InvalidArgumentError, r"^outputs: .* takes 3 outputs, got 4"),
        (
            lambda i, o: ([i[0], np.zeros(3)], o),
            ShapeError,
            r"^inputs: .*buffer 1 has 3 entries, its argument 4",
        ),
        (
            lambda i, o: (i, [o[0], o[1], np.zeros(9)]),
            ShapeError,
            r"^outputs: .*buffer 2 has 9 entries, its argument 6",
        ),
        (
            lambda i, o: ([i[0].astype(np.float32), i[1]], o),
            InvalidArgumentError,
            "contiguous float64.*float32",
        ),
        (lambda i, o: ([np.zeros(6)[::2], i[1]], o), InvalidArgumentError, "contiguous float64"),
        (
            lambda i, o: ([[0.0, 0.0, 0.0], i[1]], o),
            InvalidArgumentError,
            "contiguous float64 array, got list",
        ),
    ],
)
def test_wrong_buffers_are_rejected_when_bound(lib, change, error, match):
    ins, outs = change(*_buffers())
    with pytest.raises(error, match=match):
        native.CCall(lib, F.name(), ins, outs)


def test_a_read_only_output_is_rejected(lib):
    ins, outs = _buffers()
    outs[0].flags.writeable = False
    with pytest.raises(InvalidArgumentError, match=r"^outputs: .*output buffer 0 is read-only"):
        native.CCall(lib, F.name(), ins, outs)


M = optik.catalog.planar_2r()


@pytest.mark.parametrize("compile", [True, False])  # the C driver and the Python loop alike
def test_lm_kernel_run_checks_its_arrays(compile):
    k = kernel(M, "pose2d", None, 100.0, compile)
    settings = lm_kernel.Settings(10, 50, 2, 1.0, 1e-2, 0.9, (1e-6, 1e-6, 1e-9), 0.0, (1.0, 1.0), M.mid_q())
    conf = settings.conf(M)
    target = optik.problem.target_parameters(M.fk(np.array([0.4, 0.7])))[None]
    q0, seeds = M.mid_q()[None], np.array([3], dtype=np.uint64)
    out = k.run(target, q0, seeds, conf)
    assert out.status[0] == 0
    bad = [
        ((target[:, :11], q0, seeds, conf), ShapeError, r"^targets: expected shape \(N, 12\), got \(1, 11\)"),
        ((target[0], q0, seeds, conf), ShapeError, "^targets: "),
        ((target, np.zeros((2, 2)), seeds, conf), ShapeError, r"^q0: expected shape \(1, 2\)"),
        ((target, q0, np.array([1, 2], dtype=np.uint64), conf), ShapeError, "^seeds: "),
        ((target, q0, np.array([0.5]), conf), InvalidArgumentError, "^seeds: expected integers >= 0"),
        ((target, q0, np.array([-1]), conf), InvalidArgumentError, "^seeds: expected integers >= 0"),
        ((target, q0, seeds, conf[:-1]), ShapeError, rf"^conf: expected shape \({len(conf)},\)"),
        ((target.astype(str), q0, seeds, conf), InvalidArgumentError, "^targets: expected real numbers"),
    ]
    for args, error, match in bad:
        with pytest.raises(error, match=match):
            k.run(*args)
