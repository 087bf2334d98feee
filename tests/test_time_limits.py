"""Time limits (issue 18, item 6): no call waits for a C compile past its own time limit, and
the fuzzer holds every call to its limit plus `OVERTIME_SLACK` (the promise of
``docs/reliability.md``, measured by ``optik benchmark time_limits``)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

import optik
from fuzz.harness import OVERTIME_SLACK, Call, classify, spin
from optik import native
from optik.solvers import lm_kernel

PANDA = Path(optik.__file__).parent / "data" / "urdf" / "panda.urdf"


@pytest.mark.skipif(native.compiler() is None, reason="needs a C compiler (a build to wait for)")
def test_no_call_waits_for_a_compile_past_its_time_limit(monkeypatch, tmp_path, cpu_clock):
    """Once the evaluator's budget is spent, a call waits for the build, but only within its
    own limit: every wait it starts on the build is bounded by what is left of its 0.05 s (a
    busy machine may wake it late, which is no wait of its own: no wall-clock bound here) and
    the build is still running when it returns with the evaluator's answer."""
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))  # never compiled: the build starts now
    m = optik.Mechanism.from_urdf(PANDA, "panda_link0", "panda_link8")
    target = m.fk(m.random_q(seed=2))
    first = optik.solve_ik(m, target, method="lm", seed=0, time_limit=0.05)
    k = lm_kernel.kernel(m, "pose", None, 100.0, "auto")
    assert k.library.state == "building"
    k.library.evaluated(2 * native.EVALUATOR_BUDGET)  # the evaluator's budget is spent
    waits: list[float | None] = []  # the timeouts of the waits on the build (the real waits)
    real_wait = k.library._done.wait
    monkeypatch.setattr(
        k.library._done, "wait", lambda timeout=None: waits.append(timeout) or real_wait(timeout)
    )
    with cpu_clock() as cpu:
        late = optik.solve_ik(m, target, method="lm", seed=0, time_limit=0.05)
    building, during = k.library.state == "building", list(waits)
    native.wait()
    assert building, "the compiler finished before the call: nothing was tested"
    assert during, "the call did not wait for the build: the waiting path was not tested"
    assert all(t is not None and t <= 0.05 for t in during), f"waits of {during} s for a 0.05 s limit"
    assert cpu.seconds < 0.05 + OVERTIME_SLACK  # nor did it work past its limit
    assert first.status in ("solved", "time_limit") and late.status in ("solved", "time_limit")
    assert late.q.shape == (7,) and m.within_limits(late.q)  # an answer, from the evaluator


def test_the_fuzzer_holds_calls_to_their_limit_plus_the_slack():
    assert OVERTIME_SLACK == 0.25
    slow = Call("x", lambda: spin(0.05 + OVERTIME_SLACK + 0.1), limit=0.05)
    assert classify(slow).kind == "overtime"  # 0.4 s for a 0.05 s limit: within the old 3 x + 0.5 s
    assert classify(Call("x", lambda: spin(0.06), limit=0.05)).kind == "ok"


def test_the_fuzzer_times_work_not_a_busy_machine_and_still_catches_a_hang():
    """A call kept off the processor past its limit (here: asleep, as a loaded machine keeps it
    waiting) has not worked past it: ``ok``. One still running at the wall-clock ceiling is a
    hang, interrupted by the watchdog: ``overtime``, though it used no CPU time."""
    delayed = classify(Call("x", lambda: time.sleep(0.05 + OVERTIME_SLACK + 0.3), limit=0.05))
    assert delayed.kind == "ok" and delayed.seconds > 0.05 + OVERTIME_SLACK
    hang = classify(Call("x", lambda: time.sleep(60.0), limit=0.05), wall_ceiling=2.0)
    assert hang.kind == "overtime" and "watchdog" in hang.detail


def test_the_deadline_is_scoped_and_an_infinite_one_is_no_limit():
    assert native._DEADLINE.get() is None
    with native.deadline(12.5):
        assert native._DEADLINE.get() == 12.5
        with native.deadline(float("inf")):  # a wait without limit, not an overflow of the timeout
            assert native._DEADLINE.get() is None
        assert native._DEADLINE.get() == 12.5
    assert native._DEADLINE.get() is None
