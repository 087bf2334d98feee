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
