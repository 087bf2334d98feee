"""``solve_ik_all``: the method asked for is the method used, the closed form answers alone and
completely, solutions outside the limits are reported, numerical answers are polished and distinct."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import closed_form
from optik.cli import main
from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.solvers.base import joint_distance


def _seed_target(seed: int = 1) -> tuple[optik.Mechanism, np.ndarray]:
    m = optik.catalog.seed_6r_arm()
    return m, m.fk(m.random_q(seed=seed))


def test_closed_form_method_returns_every_branch_alone() -> None:
    """Regression: method="closed_form" raised 'max_restarts: unknown option'."""
    m, target = _seed_target()
    sols = optik.solve_ik_all(m, target, method="closed_form")
    branches = closed_form.ik(m, target)
    assert len(sols) == len(branches) == 8
    assert {s.method for s in sols} == {"closed_form"}
    for b in branches:
        assert min(joint_distance(m, b, s.q) for s in sols) < 1e-12
    for s in sols:  # independent FK check
        np.testing.assert_allclose(m.fk(s.q), target, atol=1e-9)
    default = optik.solve_ik_all(m, target)
    assert {s.method for s in default} == {"closed_form"} and len(default) == 8


def test_closed_form_method_takes_no_options_and_must_apply() -> None:
    m, target = _seed_target()
    with pytest.raises(InvalidArgumentError, match=r"^patience_x"):
        optik.solve_ik_all(m, target, method="closed_form", patience_x=3)
    panda = optik.catalog.panda()
    with pytest.raises(SolverUnavailableError, match="closed_form"):
        optik.solve_ik_all(panda, panda.fk(panda.mid_q()), method="closed_form")


def test_numeric_method_is_the_method_used() -> None:
    """Regression: ``method="lm"`` on the five-bar returned the closed-form branches."""
    m = optik.catalog.five_bar()
    target = optik.Position(0.5, 1.4)
    sols = optik.solve_ik_all(m, target, method="lm", seed=0, time_limit=3.0)
    assert sols and {s.method for s in sols} == {"lm"}
    exact = closed_form.ik(m, target)
    for s in sols:  # polished onto an exact branch
        assert min(joint_distance(m, s.q, q) for q in exact) < 1e-9
    pairs = [(a, b) for i, a in enumerate(sols) for b in sols[i + 1 :]]
    assert all(joint_distance(m, a.q, b.q) >= 1e-4 for a, b in pairs)


def test_methods_without_restarts_run_in_the_multistart() -> None:
    m = optik.catalog.planar_2r()
    sols = optik.solve_ik_all(m, optik.Position(1.2, 0.6), method="dls", seed=0, time_limit=2.0, patience=10)
    assert sols and {s.method for s in sols} == {"dls"}


def test_solutions_outside_limits_are_reported() -> None:
    m, target = _seed_target(3)
    every = closed_form.ik(m, target, respect_limits=False)
    q_true = m.random_q(seed=3)
    tight = m.with_limits(lower=q_true - 0.5, upper=q_true + 0.5)
    sols = optik.solve_ik_all(tight, target)
    assert len(sols) + len(sols.outside_limits) == len(every)
    assert len(sols) >= 1 and all(tight.within_limits(s.q) for s in sols)
    assert f"{len(sols.outside_limits)} outside the joint limits" in sols.message


SEED_POSE = ["0.8", "0.3", "0.9", "0.2", "0.1", "0.3"]


@pytest.mark.parametrize(
    ("argv", "method"),
    [
        (["solve", "seed_6r_arm", "--target", *SEED_POSE, "--method", "closed_form"], "closed_form"),
        (["solve", "five_bar", "--target", "0.5", "1.4", "--method", "lm"], "lm"),
    ],
)
def test_cli_all_uses_the_method_asked_for(argv: list[str], method: str, capsys) -> None:
    assert main([*argv, "--all"]) in (0, 1)
    out = capsys.readouterr()
    assert "error" not in out.err
    lines = [line for line in out.out.splitlines() if line.startswith("[")]
    assert lines and all(f"] {method}:" in line for line in lines)
    assert f"by {method}" in out.out
