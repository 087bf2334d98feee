"""Bounded caches (issue 18, item 9): no cache keeps a mechanism alive. Every cache keyed on a
mechanism is an `optik.mechanism.memo.PerMechanism`, held by the mechanism itself, so what a
solver built for a mechanism is freed with it: dropping mechanisms leaves memory flat."""

from __future__ import annotations

import gc
import os
import weakref
from collections.abc import Callable

import numpy as np
import pytest

import optik
from optik import diffik, native


def _rss_mb() -> float:
    """Resident memory of this process (MB; CasADi's and the compiled code's too)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


@pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="resident memory read from /proc")
def test_a_thousand_mechanisms_built_and_dropped_leave_memory_flat():
    refs = []
    start = 0.0
    for i in range(1000):
        m = optik.catalog.planar_2r()
        optik.build_ik_problem(m, "position2d", None)  # cached per mechanism
        refs.append(weakref.ref(m))
        del m
        if i == 199:
            gc.collect()
            start = _rss_mb()
    gc.collect()
    alive = sum(r() is not None for r in refs)
    assert alive == 0, f"{alive} of 1000 dropped mechanisms are kept alive by a cache"
    assert _rss_mb() - start < 5.0  # 800 mechanisms of about 100 kB each would take 80 MB


P3 = optik.Position([0.3, 0.2, 0.4])
T6 = optik.catalog.puma560().fk(np.array([0.3, -0.5, 0.4, 0.2, 0.6, -0.3]))


def _arm() -> optik.Mechanism:
    return optik.dh_chain([(0.3, 0.2, 1.1), (0.1, 0.5, -0.7), (0.2, 0.4, 0.9)])


BOXED = (
    '<robot name="boxed"><link name="base"/><link name="l1"><collision><geometry>'
    '<box size="0.1 0.1 0.3"/></geometry></collision></link><joint name="j1" type="revolute">'
    '<parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>'
    '<limit lower="-2" upper="2" effort="1" velocity="1"/></joint></robot>'
)


def _self_motion(m: optik.Mechanism) -> object:
    from optik.path.redundant import self_motion_solutions

    return self_motion_solutions(m, m.fk(m.mid_q())[None], 2, np.array([0.3]))


def _geometry(m: optik.Mechanism) -> object:
    from optik.collision import robot_geometry

    return robot_geometry(m)


USES: dict[str, tuple[Callable[[], optik.Mechanism], Callable[[optik.Mechanism], object]]] = {
    "solve_ik lm": (_arm, lambda m: optik.solve_ik(m, P3, method="lm", time_limit=0.05)),
    "solve_ik nlp": (_arm, lambda m: optik.solve_ik(m, P3, method="nlp", time_limit=0.05)),
    "solve_ik_all": (_arm, lambda m: optik.solve_ik_all(m, P3, time_limit=0.05)),
    "solve_ik_batch": (_arm, lambda m: optik.solve_ik_batch(m, np.array([P3.xyz] * 3), task="position")),
    "fk_batch": (_arm, lambda m: optik.fk_batch(m, m.random_q(300, seed=1))),
    "diffik step": (_arm, lambda m: diffik.step(m, m.mid_q(), [diffik.PositionTask(target=P3.xyz)], 0.01)),
    "closed form (derived)": (optik.catalog.puma560, lambda m: optik.solve_ik(m, T6, method="closed_form")),
    "solve_ik_all (derived)": (optik.catalog.puma560, lambda m: optik.solve_ik_all(m, T6)),
    "self-motion (locked closed forms)": (optik.catalog.iiwa14, _self_motion),
    "collision geometry": (lambda: optik.Mechanism.from_urdf(BOXED), _geometry),
}


@pytest.mark.parametrize("name", list(USES))
def test_no_cache_keeps_a_mechanism_alive(name):
    if name == "collision geometry":
        pytest.importorskip("coal", reason="collision geometry needs coal (extra 'collision')")
    make, use = USES[name]
    m = make()
    use(m)
    native.wait()
    use(m)  # the compiled path as well
    ref = weakref.ref(m)
    del m
    gc.collect()
    assert ref() is None, f"{name}: a cache keeps the mechanism alive"


def test_lru_keeps_the_most_recently_used_entries():
    from optik.mechanism.memo import LRU

    cache: LRU[str, int] = LRU(2)
    assert cache.setdefault("a", 1) == 1 and cache.setdefault("b", 2) == 2
    assert cache.get("a") == 1  # now the most recent: "b" goes first
    assert cache.setdefault("a", 9) == 1  # an existing entry is kept
    cache.setdefault("c", 3)
    assert "b" not in cache and cache.values() == [1, 3] and len(cache) == 2
    assert cache.get("b", -1) == -1
    with pytest.raises(ValueError):
        LRU(0)


def test_prepared_requests_are_bounded_per_mechanism_and_unhashable_ones_not_kept():
    """The lm and balance caches of validated requests (solvers.base.PreparedCache)."""
    from types import SimpleNamespace

    from optik.solvers.base import PreparedCache

    cache: PreparedCache[str] = PreparedCache(size=2)
    a, b = optik.catalog.planar_2r(), optik.catalog.planar_3r()

    def request(**options):
        return SimpleNamespace(task="position", frame=None, tol=1e-6, options=options)

    keys = [cache.key(request(posture_gain=g, block=2)) for g in (0.1, 0.2, 0.3)]
    assert keys[0] == cache.key(request(block=2, posture_gain=0.1))  # options sorted
    assert cache.key(request(posture_gain=0.1), 7) != keys[0]  # the extra part counts
    for i, key in enumerate(keys):
        assert cache.put(a, key, f"a{i}") == f"a{i}"
    assert cache.get(a, keys[0]) is None and cache.get(a, keys[2]) == "a2"  # the oldest dropped
    assert cache.put(a, keys[2], "other") == "a2"  # the stored entry wins
    assert cache.get(b, keys[2]) is None  # per mechanism
    unhashable = cache.key(request(q_ref=np.zeros(2)))
    assert unhashable is None and cache.put(a, unhashable, "x") == "x" and cache.get(a, unhashable) is None


def test_nlp_solver_pools_are_bounded_per_mechanism(monkeypatch):
    """One pool of built solvers per argument combination (here: per ``solver_options``), at
    most POOLS_PER_MECHANISM of them, the least recently used dropped."""
    from optik.solvers import nlp

    monkeypatch.setattr(nlp, "POOLS_PER_MECHANISM", 2)
    m = optik.catalog.planar_2r()
    target = m.fk(np.array([0.3, 0.5]))
    for mu in (1e-1, 1e-2, 1e-3):
        res = optik.solve_ik(m, target, q0=[0.2, 0.4], method="nlp", solver_options={"ipopt.mu_init": mu})
        assert res.success
    kept = [key[6] for key in nlp._SOLVERS[m]._entries]  # the solver options' repr
    # each solve uses two combinations (its own and a warm-start variant): the last solve's stay
    assert len(kept) == 2 and all("('ipopt.mu_init', 0.001)" in k for k in kept)


def test_a_worker_keeps_a_bounded_number_of_shipped_mechanisms(monkeypatch):
    """`optik.batch.distributed.solve_shipped` keeps the first copy of each shipped mechanism,
    at most WORKER_MECHANISMS of them (here 2): the least recently used is dropped."""
    from optik.batch import chunk, distributed
    from optik.mechanism.memo import LRU
    from optik.solvers.base import Tolerances

    worker = distributed._ON_WORKER
    assert isinstance(worker, LRU) and worker.size == distributed.WORKER_MECHANISMS
    monkeypatch.setattr(distributed, "_ON_WORKER", LRU(2))
    spec = chunk.ChunkSpec("closed_form", "position2d", None, 1.0, Tolerances())
    shipped = [(f"key{i}", optik.catalog.planar_2r()) for i in range(3)]
    for key, m in shipped:
        targets = m.fk(np.array([[0.3, 0.5]]))
        out = distributed.solve_shipped(
            (key, m), spec, targets, np.zeros((1, 2)), np.zeros(1, dtype=np.uint64)
        )
        assert out.success.all()
    again = optik.catalog.planar_2r()  # another copy under a kept key: the kept copy serves
    distributed.solve_shipped(("key2", again), spec, targets, np.zeros((1, 2)), np.zeros(1, dtype=np.uint64))
    assert [m for m in distributed._ON_WORKER.values()] == [shipped[1][1], shipped[2][1]]
