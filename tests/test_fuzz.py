"""The fuzz suite, short budget: every public entry point of the harness `tests/fuzz/harness.py` with
derandomized hypothesis calls (valid and corrupted arguments mixed), each outcome classified; no
call may leak another exception, claim a false success or run past its time limit. The long run
is ``python tests/fuzz/long_run.py --calls 100000`` (docs/reliability.md)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings

import optik
from fuzz import harness as fuzzing
from fuzz.harness import ENTRIES, Call, Tally, classify, spin

EXAMPLES = {
    "cli (subprocess)": 3,
    "solve_fk_all": 10,
    "diffik.track": 10,
    "Mechanism": 30,
    "closed_form.ik": 30,
}
"""Calls per entry point (default 15)."""


@pytest.fixture(scope="module", autouse=True)
def _pool() -> None:
    fuzzing.warm_up()


def _run(entry: str, n: int) -> Tally:
    tally = Tally()

    @settings(
        derandomize=True,
        max_examples=n,
        database=None,
        deadline=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(call=ENTRIES[entry]())
    def run(call: Call) -> None:
        tally.add(classify(call))

    run()
    return tally


@pytest.mark.parametrize("entry", sorted(ENTRIES))
def test_fuzz_entry_point(entry: str) -> None:
    tally = _run(entry, EXAMPLES.get(entry, 15))
    assert tally.n_failures == 0, tally.report()
    assert tally.calls >= min(3, EXAMPLES.get(entry, 15))


def test_classifier_finds_each_kind_of_failure() -> None:
    """The suite can fail: a leaked exception, a false success and a call past its limit are each
    classified as such (and an OptikError is the expected answer)."""
    m = fuzzing.pool("planar_2r")
    target = m.fk([0.3, 0.2])

    def raise_value_error() -> None:
        raise ValueError("boom")

    def raise_optik_error() -> None:
        raise optik.InvalidArgumentError("q", "bad")

    def fake_success() -> optik.IKResult:
        res = optik.solve_ik(m, target)
        res.q = np.array([1.0, 1.0])  # not a solution, still claiming success
        return res

    check = fuzzing.check_ik(m, target, None, None, None)
    assert classify(Call("x", raise_value_error)).kind == "leak"
    assert classify(Call("x", raise_optik_error)).kind == "optik_error"
    assert classify(Call("x", fake_success, check)).kind == "false_success"
    assert classify(Call("x", lambda: optik.solve_ik(m, target), check)).kind == "ok"
    assert classify(Call("x", lambda: spin(0.6), limit=0.01)).kind == "overtime"
