"""optik.catalog.robot: every example-robot-data arm loads, its FK equals pinocchio's, IK works.

Needs the extras ``robots`` (example-robot-data) and ``peers`` (pinocchio); skipped, with the
reason shown, without them. The IK test solves a few FK targets per arm here (method ``lm``
through CasADi's evaluator, ``compile=False``, so the suite does not start dozens of C builds);
``optik benchmark robots`` runs 200 targets per arm with the compiled code, against TRAC-IK.
"""

from __future__ import annotations

import importlib.metadata

import numpy as np
import pytest

import optik
from optik.catalog import robots
from optik.errors import InvalidArgumentError, MissingExtraError

try:
    robots.robots_dir()
except MissingExtraError as exc:
    pytest.skip(f"example-robot-data is not installed ({exc})", allow_module_level=True)
pytest.importorskip("pinocchio")

from optik.harness.peers.rules import Referee

NAMES = robots.robot_names()
IK_TARGETS = 8


def _reference(name: str) -> tuple[optik.Mechanism, Referee]:
    arm = robots.ARMS[name]
    m = optik.catalog.robot(name)
    ref = Referee(m, robots.robot_urdf(name), arm.base_link, arm.tip_link)
    assert ref.source == "pinocchio"
    return m, ref


def test_the_table_covers_the_arms_the_issue_names() -> None:
    for name in ("ur3", "ur5", "ur10", "panda", "kinova", "xarm7", "baxter_left_arm", "talos_right_arm"):
        assert name in NAMES
    assert len(NAMES) >= 30


@pytest.mark.parametrize("name", NAMES)
def test_arm_loads_and_its_fk_equals_pinocchio(name: str) -> None:
    m, ref = _reference(name)
    arm = robots.ARMS[name]
    assert m.kind == f"robot:{name}" and m.n_q >= 5 and m.params["tip_link"] == arm.tip_link
    for q in m.random_q(20, seed=1):
        np.testing.assert_allclose(m.fk(q), ref.fk(q), rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_ik_reaches_fk_targets_checked_by_pinocchio(name: str) -> None:
    m, ref = _reference(name)
    for q in m.random_q(IK_TARGETS, seed=2):
        target = ref.fk(q)
        res = optik.solve_ik(m, target, method="lm", time_limit=3.0, seed=0, compile=False)
        assert res.success, (name, res.message)
        verdict = ref.judge(res.q, target, optik.Tolerances(position=1e-6, orientation=1e-6))
        assert verdict.success and verdict.overshoot == 0.0, verdict  # recomputed by pinocchio


def test_unknown_names_are_listed() -> None:
    with pytest.raises(InvalidArgumentError, match="name") as info:
        optik.catalog.robot("ur55")
    assert "ur5" in str(info.value) and "panda" in str(info.value)
    with pytest.raises(InvalidArgumentError, match="name"):
        optik.catalog.robot(5)


def test_a_missing_extra_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    def not_installed(name: str):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.delenv("EXAMPLE_ROBOT_DATA_MODEL_DIR", raising=False)
    monkeypatch.setattr(importlib.metadata, "distribution", not_installed)
    robots._installed_dir.cache_clear()
    try:
        with pytest.raises(MissingExtraError, match=r"optik\[robots\]"):
            optik.catalog.robot("ur5")
    finally:
        monkeypatch.undo()
        robots._installed_dir.cache_clear()
    monkeypatch.setenv("EXAMPLE_ROBOT_DATA_MODEL_DIR", str(tmp_path / "nowhere"))
    with pytest.raises(MissingExtraError, match="EXAMPLE_ROBOT_DATA_MODEL_DIR"):
        robots.robots_dir()
    monkeypatch.setenv("EXAMPLE_ROBOT_DATA_MODEL_DIR", str(tmp_path))  # a folder without the file
    with pytest.raises(MissingExtraError, match=r"ur5_robot\.urdf"):
        optik.catalog.robot("ur5")
