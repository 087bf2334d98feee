"""Test-suite settings: reproducible property tests, a headless matplotlib, a CPU stopwatch."""

import os
import time

import matplotlib
import pytest
from hypothesis import HealthCheck, settings

matplotlib.use("Agg")

# Property tests draw their examples from a fixed seed, so a run is reproducible (conventions:
# seeded randomness); set OPTIK_HYPOTHESIS=explore to search with fresh randomness locally.
settings.register_profile("ci", derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("explore", deadline=None)
settings.load_profile(os.environ.get("OPTIK_HYPOTHESIS", "ci"))


class CPUClock:
    """The CPU seconds this process (all its threads) spends inside a ``with`` block.

    The upper bound a unit test may put on a call that honours a time limit: a busy machine
    delays the call on the wall clock (the scheduler runs other processes, the call's clock
    keeps running) but does not make it do more work, so ``seconds`` exceeds ``limit x threads
    + overhead`` only when the call itself works past its limit. A call that waits (sleeps,
    blocks) past its limit is not seen here: that is a wall-clock matter for the benchmarks
    (``optik benchmark time_limits``). Lower bounds (``solve_time >= limit``) stay on the wall
    clock, which a busy machine only lengthens.
    """

    seconds: float = 0.0

    def __enter__(self) -> "CPUClock":
        self._start = time.process_time()
        return self

    def __exit__(self, *exc: object) -> None:
        self.seconds = time.process_time() - self._start


@pytest.fixture
def cpu_clock() -> type[CPUClock]:
    """`CPUClock`, to time a call as ``with cpu_clock() as cpu: ...; cpu.seconds``."""
    return CPUClock


# A two-link arm: base cylinder, upper arm a box, forearm a capsule-like cylinder, a ball hand
# on a fixed joint, and a sensor hanging off the chain on a fixed joint.
TOY_ARM_URDF = """
<robot name="toy">
  <link name="base"><collision><origin xyz="0 0 0.05"/>
    <geometry><cylinder radius="0.1" length="0.1"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="0.25 0 0"/>
    <geometry><box size="0.5 0.06 0.06"/></geometry></collision></link>
  <link name="fore"><collision><origin xyz="0.2 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="0.03" length="0.4"/></geometry></collision></link>
  <link name="hand"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="tip"/>
  <link name="sensor"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="j2" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.5 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-2.9" upper="2.9"/></joint>
  <joint name="j3" type="fixed"><parent link="fore"/><child link="hand"/><origin xyz="0.45 0 0"/></joint>
  <joint name="j4" type="fixed"><parent link="hand"/><child link="tip"/><origin xyz="0.05 0 0"/></joint>
  <joint name="j5" type="fixed"><parent link="upper"/><child link="sensor"/><origin xyz="0.1 0 0.08"/></joint>
</robot>
"""


@pytest.fixture(scope="session")
def toy_arm_urdf() -> str:
    """A planar two-link arm with box, cylinder and sphere collision geometry (tests of optik.collision)."""
    return TOY_ARM_URDF
