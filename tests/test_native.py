"""optik.native: one compile path and cache for the IK solvers and differential IK; the fallback."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import optik
from optik import native
from optik.diffik._codegen import CompiledFunction
from optik.solvers.native import NativeFunction, native_functions

X = ca.SX.sym("x", 3)


def test_native_function_compiled_and_interpreted_agree() -> None:
    f = ca.Function("optik_test_native", [X], [ca.sin(X) * X[0], ca.sumsqr(X)])
    compiled = native_functions([f], True)[0]
    interpreted = native_functions([f], False)[0]
    assert compiled.compiled and not interpreted.compiled
    for fn in (compiled, interpreted):
        fn.inputs[0][:] = [0.3, -1.2, 2.0]
    for a, b in zip(compiled(), interpreted(), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-15)
    with pytest.raises(optik.InvalidArgumentError):
        NativeFunction(ca.Function("m", [X], [ca.mtimes(X, X.T)]))
    with pytest.raises(optik.InvalidArgumentError):
        native_functions([f], "sometimes")


def test_compiled_and_casadi_evaluation_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    f = ca.Function("diffik_test_fun", [X], [ca.vertcat(ca.sin(X[0]) * X[1], X[2] ** 2), ca.mtimes(X, X.T)])
    compiled = CompiledFunction(f)
    monkeypatch.setenv("OPTIK_NO_CODEGEN", "1")
    fallback = CompiledFunction(f)
    assert compiled.compiled and not fallback.compiled
    value = np.array([0.3, -1.2, 2.0])
    for a, b in zip(compiled(value), fallback(value), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-14)
    np.testing.assert_allclose(fallback(value)[1], np.outer(value, value))


def test_library_is_compiled_once_into_the_cache(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    f = ca.Function("optik_test_cache", [X], [ca.cos(X)])
    path = native.compile_library([f])
    assert path.parent == tmp_path and path.exists()
    assert list(tmp_path.iterdir()) == [path]  # the temporary build folder is gone

    def no_compiler(*args, **kwargs):
        raise AssertionError("recompiled a cached library")

    monkeypatch.setattr(native.subprocess, "run", no_compiler)
    assert native.compile_library([f]) == path
    assert native.library([f]) is native.library([f])  # loaded once per process
    g = ca.Function("optik_test_cache", [X], [ca.sin(X)])  # same name, other source: other library
    with pytest.raises(AssertionError, match="recompiled"):
        native.compile_library([g])


@pytest.mark.parametrize("env", [{"OPTIK_NO_CODEGEN": "1"}, {"CC": "false"}])
def test_fallback_without_a_working_compiler(monkeypatch: pytest.MonkeyPatch, tmp_path, env) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    f = ca.Function("optik_test_fallback", [X], [X * 2.0])
    assert native.library([f], "auto") is None
    assert native.library([f], False) is None
    with pytest.raises(optik.SolverUnavailableError):
        native.library([f], True)
    fn = native_functions([f])[0]
    fn.inputs[0][:] = [1.0, 2.0, 3.0]
    assert not fn.compiled
    np.testing.assert_array_equal(fn()[0], [2.0, 4.0, 6.0])
    assert not CompiledFunction(f).compiled
    assert not list(tmp_path.glob("*.so"))
