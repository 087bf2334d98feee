"""The self-collision benchmark (benchmarks/bench_collision_self.py) and the TRAC-IK peer's quiet
construction: KDL's root-inertia message never reaches the output, anything else printed does."""

from __future__ import annotations

import ctypes
from pathlib import Path

import pytest

pytest.importorskip("coal", reason="collision checks need coal (extra 'collision')")
pytest.importorskip("pinocchio", reason="the judge is Pinocchio + coal (extra 'peers')")

PAGE = Path(__file__).resolve().parents[1] / "docs" / "measured" / "collision_self.md"


def test_kdl_quiet_drops_only_the_root_inertia_line(capfd):
    from optik.harness.peers.tracik_peer import kdl_quiet

    libc = ctypes.CDLL(None)
    with kdl_quiet():
        libc.printf(
            b"The root link %%s has an inertia specified in the URDF, but KDL does not support it.base\n"
        )
        libc.printf(b"a line of its own\n")
    out = capfd.readouterr().out
    assert "a line of its own" in out and "has an inertia" not in out


def test_tracik_construction_prints_no_kdl_line(capfd):
    pytest.importorskip("pytracik", reason="TRAC-IK is the peer (extra 'peers')")
    import optik
    from optik.catalog.robots import robots_dir
    from optik.harness.peers.tracik_peer import TracIK

    urdf = robots_dir() / "panda_description" / "urdf" / "panda.urdf"  # its root link has an inertia
    m = optik.Mechanism.from_urdf(urdf, "panda_link0", "panda_hand_tcp")
    TracIK(m, urdf, "panda_link0", "panda_hand_tcp").load()
    assert "KDL" not in capfd.readouterr().out


@pytest.mark.peers
def test_benchmark_runs_both_robots_and_judges_every_answer(capfd):
    from optik.benchmarks import bench_collision_self

    assert bench_collision_self.main(["--n", "2", "--time-limit", "0.05", "--compile-wait", "120"]) == 0
    out = capfd.readouterr().out
    assert out.count("| optik lm + collisions |") == 2 and out.count("| TRAC-IK + coal rejection |") == 2
    assert "dual_panda (15 joints" in out and "talos (9 joints" in out and "KDL" not in out


def test_the_generated_page_has_no_kdl_line():
    text = PAGE.read_text(encoding="utf-8")
    assert "| optik lm + collisions |" in text and "KDL" not in text
