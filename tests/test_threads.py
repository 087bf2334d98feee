"""Thread safety of every compiled entry point: 4 threads calling the same entry point on one
shared mechanism give bit-identical answers to one thread.

Each entry point is warmed up (its C library built and loaded) before the single-thread
reference, so both runs go through the same compiled code. Each thread makes the reference's
calls in its own order (rotated), so that threads are at different targets at the same time.
Calls per thread: 1,000 for the fast entry points; fewer for the slow ones, so that the file
stays under 20 s on a shared 2-core machine: ``nlp`` (about 4 ms a solve: 20), the general 6R
solver (about 12 ms: 20), ``solve_ik_all_batch`` (64 targets a call: 100), batch solving (one
call is a thread pool over 32 targets: 20),
``fk_batch`` (512 configurations a call: 100), differential IK by QP (300) and by DLS (200;
0.2 to 1 ms a step), ``solve_fk`` of the five-bar (about 10 ms: 40) and the 3-RPR's assembly
modes (about 10 ms: 40).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
import pytest

import optik
from optik import diffik, native

M = optik.catalog.puma560()
Q = M.random_q(64, seed=11)
TARGETS = [M.fk(q) for q in Q]
MANY_Q = M.random_q(512, seed=12)
THREADS = 4
GENERAL = optik.dh_chain(
    [(0.3, 0.2, 1.1), (0.1, 0.5, -0.7), (0.2, 0.4, 0.9), (0.15, 0.3, 1.3), (0.1, 0.2, -1.2), (0.05, 0.3, 0.8)]
)
GENERAL_TARGETS = [GENERAL.fk(q) for q in GENERAL.random_q(8, seed=13)]


def _ik(method: str, **options: object) -> Callable[[int], bytes]:
    def call(i: int) -> bytes:
        r = optik.solve_ik(M, TARGETS[i % len(TARGETS)], method=method, seed=i, time_limit=30.0, **options)
        return r.q.tobytes() + repr((r.success, r.status, r.iterations, r.position_error)).encode()

    return call


def _all(i: int) -> bytes:
    s = optik.solve_ik_all(M, TARGETS[i % len(TARGETS)])
    return np.asarray(s.q).tobytes() + repr((s.method, s.certified)).encode()


def _all_batch(i: int) -> bytes:
    b = optik.solve_ik_all_batch(M, np.roll(np.array(TARGETS), i, axis=0))  # the interpreter lock released
    return b.q.tobytes() + b.counts.tobytes() + b.outside_limits.tobytes()


def _general_6r(i: int) -> bytes:
    s = optik.solve_ik_all(GENERAL, GENERAL_TARGETS[i % len(GENERAL_TARGETS)])
    return np.asarray(s.q).tobytes() + repr((s.method, s.certified)).encode()


def _closed_form(i: int) -> bytes:
    return b"".join(q.tobytes() for q in optik.closed_form.ik(M, TARGETS[i % len(TARGETS)]))


def _diffik(method: str) -> Callable[[int], bytes]:
    def call(i: int) -> bytes:
        task = diffik.FrameTask(target=TARGETS[(i + 1) % len(TARGETS)])
        r = diffik.step(M, Q[i % len(Q)], [task], 0.01, method=method)
        return r.v.tobytes() + r.status.encode()

    return call


def _batch(i: int) -> bytes:
    k = 32 * (i % 2)
    r = optik.solve_ik_batch(M, np.array(TARGETS[k : k + 32]), seed=i, workers=2, time_limit=30.0)
    return r.q.tobytes() + r.success.tobytes()


FIVE_BAR = optik.catalog.five_bar()
FIVE_BAR_INPUTS = [FIVE_BAR.mid_q()[FIVE_BAR.actuated_indices] + [d, -d] for d in np.linspace(-0.1, 0.1, 8)]
RPR = optik.catalog.planar_3rpr()
RPR_INPUTS = [RPR.mid_q()[RPR.actuated_indices] * s for s in (1.0, 1.05, 0.95, 1.1)]


def _solve_fk(i: int) -> bytes:
    r = optik.solve_fk(FIVE_BAR, FIVE_BAR_INPUTS[i % len(FIVE_BAR_INPUTS)], time_limit=30.0)
    assert r.success  # assembled (a failure would run to the time limit: not what is tested)
    return r.q.tobytes()


def _solve_fk_all(i: int) -> bytes:
    modes = optik.solve_fk_all(RPR, RPR_INPUTS[i % len(RPR_INPUTS)])
    return b"".join(r.q.tobytes() for r in modes) + repr(len(modes.dropped)).encode()


def _fk(i: int) -> bytes:
    q = Q[i % len(Q)]
    return M.fk(q).tobytes() + M.jacobian(q).tobytes()


def _fk_batch(i: int) -> bytes:
    return optik.fk_batch(M, np.roll(MANY_Q, i, axis=0), workers=2).tobytes()


ENTRY_POINTS = {
    "lm": (_ik("lm"), 1000),
    "nlp": (_ik("nlp"), 20),
    "closed_form method": (_ik("closed_form"), 1000),
    "closed_form.ik": (_closed_form, 1000),
    "solve_ik_all": (_all, 1000),
    "solve_ik_all_batch": (_all_batch, 100),
    "solve_ik_all general 6R": (_general_6r, 20),
    "diffik qp": (_diffik("qp"), 300),
    "diffik dls": (_diffik("dls"), 200),
    "solve_ik_batch": (_batch, 20),
    "fk and jacobian": (_fk, 1000),
    "solve_fk": (_solve_fk, 40),
    "solve_fk_all (3-RPR closed form)": (_solve_fk_all, 40),
    "fk_batch": (_fk_batch, 100),
}


@pytest.mark.parametrize("name", list(ENTRY_POINTS))
def test_four_threads_give_the_single_thread_answers(name):
    call, n = ENTRY_POINTS[name]
    call(0)
    native.wait()
    reference = [call(i) for i in range(n)]
    got: dict[int, list[bytes]] = {}
    errors: list[BaseException] = []
    start = threading.Barrier(THREADS)

    def work(t: int) -> None:
        order = [(i + t * n // THREADS) % n for i in range(n)]
        start.wait()
        try:
            answers = {i: call(i) for i in order}
            got[t] = [answers[i] for i in range(n)]
        except BaseException as exc:  # reported below, in the main thread
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(t,)) for t in range(THREADS)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not errors, errors[0]
    for t in range(THREADS):
        wrong = [i for i in range(n) if got[t][i] != reference[i]]
        assert not wrong, (
            f"thread {t}: {len(wrong)} of {n} answers differ from one thread's (first: call {wrong[0]})"
        )
