"""optik.native: one compile path and cache for the IK solvers and differential IK; the CasADi
evaluator while a library builds in the background, and for good without a compiler."""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import stat
import threading
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import optik
from optik import native
from optik.diffik._codegen import CompiledFunction
from optik.native import NativeFunction, native_functions
from optik.solvers import lm_kernel

X = ca.SX.sym("x", 3)
PANDA = Path(optik.__file__).parent / "data" / "urdf" / "panda.urdf"


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


def test_interpreted_calls_follow_the_buffers() -> None:
    """The evaluator path reads `inputs` and writes `outputs` in place at every call (CasADi's
    ``Function.buffer`` bound to them): the same numbers as a call through ``DM``, input after
    input, with scalar and vector inputs and outputs."""
    y = ca.SX.sym("y")
    f = ca.Function("optik_test_buffers", [X, y], [ca.sin(X) * y, ca.sumsqr(X) + y])
    fn = native_functions([f], False)[0]
    out = fn.outputs
    for value, scale in (([0.3, -1.2, 2.0], 2.0), ([1.0, 0.0, -0.5], -3.0), ([0.0, 0.0, 0.0], 0.5)):
        fn.inputs[0][:] = value
        fn.inputs[1][0] = scale
        got = fn()
        assert got[0] is out[0] and got[1] is out[1]
        want = f(np.array(value), scale)
        np.testing.assert_array_equal(got[0], np.asarray(want[0]).ravel())
        np.testing.assert_array_equal(got[1], np.asarray(want[1]).ravel())


def test_compiled_and_casadi_evaluation_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    f = ca.Function("diffik_test_fun", [X], [ca.vertcat(ca.sin(X[0]) * X[1], X[2] ** 2), ca.mtimes(X, X.T)])
    compiled = CompiledFunction(f)
    compiled.library.wait()
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
    lib = native.library([f], True)
    assert lib.state == "ready" and lib.path.parent == tmp_path
    manifest = lib.path.with_name(lib.path.name + ".json")  # its size and hash (see test_cache_faults)
    assert sorted(tmp_path.iterdir()) == [lib.path, manifest]  # the temporary build folder is gone
    assert native.library([f]) is lib  # loaded once per process

    def no_compiler(*args, **kwargs):
        raise AssertionError("recompiled a cached library")

    monkeypatch.setattr(native.subprocess, "Popen", no_compiler)
    native._BUILDS.pop(lib.path)  # as in a new process: the cached file is loaded, not compiled
    again = native.library([f], True)
    assert again.path == lib.path and again.state == "ready"
    g = ca.Function("optik_test_cache", [X], [ca.sin(X)])  # same name, other source: other library
    with pytest.raises(AssertionError, match="recompiled"):
        native.library([g], True)
    # a library built with other flags (before -fno-semantic-interposition joined them) is another
    # file: never loaded in place of this one
    before = tuple(x for x in native._FLAGS if x != "-fno-semantic-interposition")
    monkeypatch.setattr(native, "_FLAGS", before)
    native._BUILDS.pop(lib.path)
    with pytest.raises(AssertionError, match="recompiled"):
        native.library([f], True)


def test_first_calls_evaluate_while_the_library_builds_then_switch(
    monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path / "fresh"))  # not created yet
    f = ca.Function("optik_test_switch", [X], [ca.sin(X) * ca.cos(X[1]) + X[2] ** 3])
    fn = native_functions([f])[0]
    assert fn.library.state == "building" and not fn.compiled
    fn.inputs[0][:] = [0.3, -1.2, 2.0]
    before = fn()[0].copy()  # answered by CasADi's virtual machine meanwhile
    assert native.wait(timeout=60)
    assert fn.library.state == "ready" and fn.compiled
    np.testing.assert_array_equal(fn()[0], before)
    name = fn.library.path.name
    assert sorted(p.name for p in (tmp_path / "fresh").iterdir()) == [name, f"{name}.json"]  # no leftovers


def test_calls_wait_for_the_build_once_the_evaluator_budget_is_spent(
    monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    f = ca.Function("optik_test_budget", [X], [ca.exp(X) - X[0]])
    fn = native_functions([f])[0]
    fn.inputs[0][:] = [0.1, 0.2, 0.3]
    fn()
    assert fn.library.state == "building" and 0 < fn.library._evaluated < native.EVALUATOR_BUDGET
    fn.library.evaluated(native.EVALUATOR_BUDGET)  # as if long evaluations had been made meanwhile
    out = fn()[0].copy()
    assert fn.library.state == "ready" and fn.compiled  # that call waited for the compiler
    np.testing.assert_allclose(out, np.exp([0.1, 0.2, 0.3]) - 0.1, rtol=0, atol=1e-15)


def test_a_failed_background_build_is_logged_and_evaluation_goes_on(
    monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", "false")  # a "compiler" that always fails
    f = ca.Function("optik_test_failed", [X], [X * 3.0])
    records: list[logging.LogRecord] = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = records.append  # a handler of our own: other tests reconfigure logging
    previous = (native._LOG.level, native._LOG.disabled, logging.root.manager.disable)
    native._LOG.addHandler(handler)
    native._LOG.setLevel(logging.WARNING)
    native._LOG.disabled = False
    logging.disable(logging.NOTSET)
    try:
        fn = native_functions([f])[0]
        fn.inputs[0][:] = [1.0, 2.0, 3.0]
        np.testing.assert_array_equal(fn()[0], [3.0, 6.0, 9.0])
        fn.library.wait(timeout=60)
    finally:
        native._LOG.removeHandler(handler)
        native._LOG.setLevel(previous[0])
        native._LOG.disabled = previous[1]
        logging.disable(previous[2])
    assert fn.library.state == "failed" and not fn.compiled
    assert any("optik_test_failed" in r.getMessage() for r in records) and "failed" in fn.library.error
    np.testing.assert_array_equal(fn()[0], [3.0, 6.0, 9.0])
    with pytest.raises(optik.SolverUnavailableError):
        native.library([f], True)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("env", [{"OPTIK_NO_CODEGEN": "1"}, {"CC": "false"}])
def test_fallback_without_a_working_compiler(monkeypatch: pytest.MonkeyPatch, tmp_path, env) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    f = ca.Function("optik_test_fallback", [X], [X * 2.0])
    assert native.library([f], False) is None
    with pytest.raises(optik.SolverUnavailableError):
        native.library([f], True)
    fn = native_functions([f])[0]
    fn.inputs[0][:] = [1.0, 2.0, 3.0]
    assert not fn.compiled
    np.testing.assert_array_equal(fn()[0], [2.0, 4.0, 6.0])
    assert not CompiledFunction(f).compiled
    assert not list(tmp_path.glob("*.so"))


def _fresh_panda(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> optik.Mechanism:
    """A Panda never compiled: empty cache directory, and a new mechanism (its caches are its own)."""
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    return optik.Mechanism.from_urdf(PANDA, "panda_link0", "panda_link8")


def test_panda_ik_answers_the_same_before_and_after_the_switch(
    monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    m = _fresh_panda(monkeypatch, tmp_path)
    targets = [m.fk(q) for q in m.random_q(12, seed=7)]
    first = optik.solve_ik(m, targets[0], method="lm", seed=0)
    kernel = lm_kernel.kernel(m, "pose", None, 100.0, "auto")
    assert kernel.library.state == "building"  # answered without waiting for the C build
    # a long limit: the Python loop must finish its starts on a loaded machine too (same answers)
    interpreted = [optik.solve_ik(m, t, method="lm", seed=0, compile=False, time_limit=5.0) for t in targets]
    assert native.wait(timeout=120)
    compiled = [optik.solve_ik(m, t, method="lm", seed=0, time_limit=5.0) for t in targets]
    assert kernel.compiled and not lm_kernel.kernel(m, "pose", None, 100.0, False).compiled
    # the first answer came from the evaluator within the default 0.1 s: right, but on a loaded
    # machine from another number of restarts than the compiled run, so it is checked by its FK
    assert first.success and np.abs(m.fk(first.q) - targets[0]).max() < 1e-5
    for a, b in zip(interpreted, compiled, strict=True):
        assert a.success and b.success and a.iterations == b.iterations
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
    # a locked joint's value and limits are kernel inputs: locking it at 3 values builds nothing
    for v in (0.1, 0.2, 0.3):
        q_v = np.r_[v, m.random_q(seed=11)[1:]]
        locked = optik.solve_ik_all(m, m.fk(q_v), method="lm", fixed={m.coordinate_names[0]: v}, seed=0)
        assert len(locked.q) >= 1 and all(s[0] == v for s in locked.q)
    assert native.wait(timeout=120)
    # one LM kernel (the error check is compiled into it); beside it, the generic kernel of 7
    # joints when this process had not loaded one before (optik.solvers.generic_chain)
    assert len(list(tmp_path.glob("optik_lm_step_*.so"))) == 1
    assert {p.name.split("_")[1] for p in tmp_path.glob("*.so")} <= {"chain7", "lm"}


def test_diffik_step_answers_the_same_before_and_after_the_switch(
    monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    from optik import diffik
    from optik.diffik import generic_stack

    m = _fresh_panda(monkeypatch, tmp_path)
    goal = m.fk(m.random_q(seed=3))
    q0 = m.mid_q()
    task = diffik.FrameTask(target=goal)
    first = diffik.step(m, q0, [task], dt=0.01)
    own = diffik.problem._STACKS.get(m, {})
    if own:  # the robot's stack answered through CasADi: the first step did not wait for gcc
        assert next(iter(own.values())).function.library.state == "building"
    else:  # a generic stack was loaded before in this process (optik.diffik.generic_stack)
        assert isinstance(first.problem.cache, generic_stack.ChainStack)
    assert native.wait(timeout=120)
    stack = next(iter(diffik.problem._STACKS[m].values()))
    assert stack.function.compiled
    again = diffik.step(m, q0, [task], dt=0.01)
    np.testing.assert_allclose(again.q, first.q, rtol=0, atol=1e-12)


def test_compiler_version_is_kept_per_executable(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    """``cc --version`` runs once per compiler executable (its record in the cache directory is
    read by later processes) and again when the executable changes."""
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path / "cache"))
    cc = tmp_path / "fakecc"
    cc.write_text("#!/bin/sh\necho 'fakecc 1.0'\necho second line\n")
    cc.chmod(0o755)
    native.compiler_version.cache_clear()
    assert native.compiler_version(str(cc)) == "fakecc 1.0"
    (memo,) = (tmp_path / "cache" / "compilers").iterdir()
    assert memo.read_text() == "fakecc 1.0"
    memo.write_text("recorded")  # a later process reads the record instead of running cc
    native.compiler_version.cache_clear()
    assert native.compiler_version(str(cc)) == "recorded"
    cc.write_text("#!/bin/sh\necho 'fakecc 2.0 (upgraded)'\n")  # another size: another key
    native.compiler_version.cache_clear()
    assert native.compiler_version(str(cc)) == "fakecc 2.0 (upgraded)"
    native.compiler_version.cache_clear()


def test_source_digest_keys_generated_code_by_its_sources_and_parts() -> None:
    """One digest for the generic kernels' caches: SHA-256 of CasADi's version, the parts and
    the source files' bytes (the same keys the chain kernel and QP stack used before, so their
    cached libraries stay valid); another part or source is another key; a missing source raises."""
    package = Path(optik.__file__).resolve().parent
    want = hashlib.sha256(f"{ca.__version__}\0{7}\0{('a', 1)!r}".encode())
    for rel in ("spatial.py", "native.py"):
        want.update((package / rel).read_bytes())
    assert native.source_digest(("spatial.py", "native.py"), 7, ("a", 1)) == want.hexdigest()
    assert native.source_digest(("spatial.py",), 7) != native.source_digest(("spatial.py",), 8)
    assert native.source_digest(("spatial.py",), 7) != native.source_digest(("native.py",), 7)
    with pytest.raises(OSError):
        native.source_digest(("no_such_file.py",), 7)


def test_the_compiler_version_record_has_the_cache_files_mode(
    monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    """The record is ``0666`` less the umask, like the manifests beside it (readable by the other
    users of a shared cache), not mkstemp's private ``0600``."""
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path / "cache"))
    cc = tmp_path / "fakecc"
    cc.write_text("#!/bin/sh\necho 'fakecc 1.0'\n")
    cc.chmod(0o755)
    umask = os.umask(0o022)
    try:
        native.compiler_version.cache_clear()
        assert native.compiler_version(str(cc)) == "fakecc 1.0"
    finally:
        os.umask(umask)
        native.compiler_version.cache_clear()
    (memo,) = (tmp_path / "cache" / "compilers").iterdir()
    assert stat.S_IMODE(memo.stat().st_mode) == 0o644


def test_compiler_searches_the_path_once_and_again_when_its_answer_is_gone(
    monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    """``compiler()`` memoizes its PATH search per ``$CC``/``$PATH`` (no search on later calls, the
    same answer from many threads) and searches again when the executable it found is gone."""
    monkeypatch.delenv("OPTIK_NO_CODEGEN", raising=False)
    cc = tmp_path / "mycc"
    cc.write_text("#!/bin/sh\n")
    cc.chmod(0o755)
    monkeypatch.setenv("CC", str(cc))
    searched: list[str] = []
    real_which = shutil.which
    monkeypatch.setattr(
        native.shutil, "which", lambda name, *a, **k: searched.append(name) or real_which(name, *a, **k)
    )
    assert native.compiler() == str(cc) and searched == [str(cc)]
    answers: list[str | None] = []
    threads = [
        threading.Thread(target=lambda: answers.extend(native.compiler() for _ in range(50)))
        for _ in range(4)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert answers == [str(cc)] * 200 and searched == [str(cc)]  # no search after the first
    cc.unlink()  # the memo's executable is gone: searched again, another answer
    assert native.compiler() == next((c for c in ("gcc", "cc") if real_which(c)), None)
    assert searched[:2] == [str(cc), str(cc)]
