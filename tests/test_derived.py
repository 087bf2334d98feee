"""Analytic IK derived from a model's structure (optik.closed_form.derived): family detection on
DH, catalog and URDF arms, every branch FK-checked, the generating configuration always found,
agreement with the hand-written seed 6R solver and (when installed) with EAIK's solution sets."""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import optik
from optik import closed_form
from optik.closed_form.structure import Axes, axes_of, detect
from optik.mechanism import dh_chain
from optik.solvers.base import joint_distance

P = np.pi / 2
ARMS = {
    # name: standard-DH rows (d, a, alpha)
    "sw_12_intersecting": [(0, 0, P), (0, 0.43, 0), (0.15, 0.02, -P), (0.43, 0, P), (0, 0, -P), (0, 0, 0)],
    "sw_23_parallel": [(0.35, 0.07, -P), (0, 0.36, 0), (0, 0, P), (0.38, 0, -P), (0, 0, P), (0.065, 0, 0)],
    "sw_23_intersecting": [(0.3, 0.1, P), (0.1, 0, P), (0.4, 0, -P), (0.38, 0, -P), (0, 0, P), (0.06, 0, 0)],
    "sw_12_parallel": [(0.3, 0.2, 0), (0.1, 0.3, P), (0.2, 0, -P), (0.38, 0, -P), (0, 0, P), (0.065, 0, 0)],
    "sw_general": [
        (0.3, 0.15, 1.0),
        (0.1, 0.3, 0.7),
        (0.2, 0.05, -1.2),
        (0.38, 0, -P),
        (0, 0, P),
        (0.06, 0, 0),
    ],
    "spherical_base": [
        (0.3, 0, P),
        (0, 0, -P),
        (0.4, 0.05, 1.0),
        (0.1, 0.25, -0.7),
        (0.15, 0.2, 0.4),
        (0.1, 0, 0),
    ],
    "tp_56_intersecting": [
        (0.09, 0, P),
        (0, -0.425, 0),
        (0, -0.39, 0),
        (0.11, 0, P),
        (0.09, 0, -P),
        (0.08, 0, 0),
    ],
    "tp_general": [(0.09, 0, P), (0, -0.425, 0), (0, -0.39, 0), (0.11, 0, P), (0.09, 0.05, -P), (0.08, 0, 0)],
    "tp_reversed": [(0.2, 0.1, 0.8), (0.1, 0.3, P), (0.05, 0.4, 0), (0.1, 0.35, 0), (0, 0.2, P), (0.1, 0, 0)],
}
FAMILY = {
    "sw_12_intersecting": "spherical_wrist (1-2 intersecting)",
    "sw_23_parallel": "spherical_wrist (2-3 parallel)",
    "sw_23_intersecting": "spherical_wrist (2-3 intersecting)",
    "sw_12_parallel": "spherical_wrist (1-2 parallel)",
    "sw_general": "spherical_wrist (general)",
    "spherical_base": "spherical_base (general)",
    "tp_56_intersecting": "three_parallel (5-6 intersecting)",
    "tp_general": "three_parallel (general)",
    "tp_reversed": "three_parallel_reversed (general)",
}

UR_DIR = "cmeel.prefix/share/example-robot-data/robots/ur_description/urdf"


def _ur(name: str) -> optik.Mechanism:
    """The joint-limited UR URDF of example-robot-data (skipped visibly when not installed)."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (extra 'robots')")
    path = Path(str(dist.locate_file(f"{UR_DIR}/{name}_joint_limited_robot.urdf")))
    if not path.exists():
        pytest.skip(f"{path} not found in example-robot-data")
    return optik.Mechanism.from_urdf(path, "base_link", "tool0")


def _check_all(m: optik.Mechanism, n: int = 60, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every kept branch reproduces the target (FK of the mechanism itself, not the derived
    model), the generating configuration is among them, and no two are the same solution."""
    solver = closed_form.derive(m)
    assert solver is not None
    qs = m.random_q(n, seed=seed)
    targets = m.fk(qs)
    q, ok = solver.solve(targets)
    assert q.shape[0] == n and q.shape[2] == 6 and ok.shape == q.shape[:2] and q.shape[1] in (8, 16)
    for i in range(n):
        sols = q[i][ok[i]]
        assert len(sols) >= 1
        np.testing.assert_allclose(m.fk(sols), np.broadcast_to(targets[i], (len(sols), 4, 4)), atol=1e-9)
        assert min(joint_distance(m, s, qs[i]) for s in sols) < 1e-7
        pairs = [(a, b) for j, a in enumerate(sols) for b in sols[j + 1 :]]
        assert all(joint_distance(m, a, b) >= 1e-6 for a, b in pairs)
    return qs, q, ok


@pytest.mark.parametrize("name", sorted(ARMS))
def test_each_family_is_detected_and_solved(name: str) -> None:
    m = dh_chain(ARMS[name], "standard", name=name, task="pose")
    solver = closed_form.derive(m)
    assert solver is not None and solver.structure.name == FAMILY[name]
    _check_all(m)
    assert closed_form.has_ik(m)


def test_seed_6r_derived_solver_agrees_with_the_hand_written_one() -> None:
    """The seed arm's registered closed form is the derived one; the hand-written vectorized
    kernel (ik_seed_6r) cross-checks it: the same solution sets on regular targets, and at the
    wrist singularity (q5 = 0) every returned branch reaches the target."""
    m = optik.catalog.seed_6r_arm()
    d = [m.params[k] for k in ("d2", "d3", "d4")]
    solver = closed_form.derive(m)
    assert solver.structure.name == "three_parallel (5-6 intersecting)"
    assert isinstance(closed_form.registry.ik_solver(m), closed_form.derived.DerivedRows)
    qs, _, ok = _check_all(m, n=40, seed=3)
    hand_q, hand_ok = closed_form.ik_seed_6r(*d, m.fk(qs))
    for i in range(len(qs)):
        registered = closed_form.ik(m, m.fk(qs[i]), respect_limits=False)
        hand = hand_q[i][hand_ok[i]]
        assert len(hand) == len(registered) == ok[i].sum()
        for a in hand:
            assert min(joint_distance(m, a, b) for b in registered) < 1e-9
    singular = m.random_q(20, seed=5)
    singular[:, 4] = 0.0
    for target in m.fk(singular):
        got = closed_form.ik(m, target, respect_limits=False)
        assert got
        np.testing.assert_allclose(m.fk(np.array(got)), np.broadcast_to(target, (len(got), 4, 4)), atol=1e-9)


def test_puma560_catalog_arm_has_a_derived_closed_form() -> None:
    m = optik.catalog.puma560()
    assert closed_form.derive(m).structure.name == "spherical_wrist (1-2 intersecting)"
    _check_all(m)
    target = m.fk(m.random_q(seed=4))
    res = optik.solve_ik(m, target, method="closed_form")
    assert res.success and res.method == "closed_form" and m.within_limits(res.q)
    np.testing.assert_allclose(m.fk(res.q), target, atol=1e-9)


@pytest.mark.parametrize("name", ["ur5", "ur10"])
def test_ur_urdf_arms_have_a_derived_closed_form(name: str) -> None:
    m = _ur(name)
    assert m.kind is None
    assert closed_form.derive(m).structure.name == "three_parallel (5-6 intersecting)"
    _check_all(m, n=40)
    target = m.fk(m.random_q(seed=1))
    sols = optik.solve_ik_all(m, target)
    assert sols.method == "closed_form" and all(m.within_limits(s.q) for s in sols)
    assert len(sols) + len(sols.outside_limits) == len(closed_form.ik(m, target, respect_limits=False))


def test_rounded_urdf_geometry_is_still_detected() -> None:
    """URDF files print lengths and angles to a few digits: axes off by 1e-6 rad and 1e-6 m are
    still parallel / intersecting, and the branches are polished onto the exact model."""
    rows = [(0.089159, 0, 1.570796), (0, -0.425, 0), (0, -0.39225, 0), (0.10915, 0, 1.570796),
            (0.09465, 0, -1.570796), (0.0823, 0, 0)]  # fmt: skip
    m = dh_chain(rows, "standard", name="rounded_ur5", task="pose")
    assert closed_form.derive(m).structure.name == "three_parallel (5-6 intersecting)"
    _check_all(m, n=30)


def test_singular_targets_give_fk_exact_representatives() -> None:
    """Wrist singularity (q5 = 0: axes 4 and 6 aligned) and shoulder singularity (wrist centre
    on axis 1): infinitely many solutions; the returned ones all reach the target."""
    m = optik.catalog.puma560()
    solver = closed_form.derive(m)
    q_wrist = np.array([0.3, 0.2, -0.4, 0.5, 0.0, 0.7])
    # shoulder: wrist centre on axis 1 needs the shoulder offset cancelled; search it numerically
    targets = [m.fk(q_wrist), m.fk(np.zeros(6))]
    for t in targets:
        q, ok = solver.solve(t)
        assert ok.any()
        np.testing.assert_allclose(m.fk(q[0][ok[0]]), np.broadcast_to(t, (int(ok.sum()), 4, 4)), atol=1e-9)


def test_unreachable_target_has_no_branch() -> None:
    m = optik.catalog.puma560()
    far = np.eye(4)
    far[:3, 3] = (3.0, 0.0, 0.0)
    _, ok = closed_form.derive(m).solve(far)
    assert not ok.any()
    assert closed_form.ik(m, far) == []
    res = optik.solve_ik(m, far, method="closed_form")
    assert not res.success and res.status == "unreachable"


def test_not_decomposable_or_not_6r_gives_no_derived_solver() -> None:
    rows = [
        (0.3, 0.15, 1.0),
        (0.1, 0.3, 0.7),
        (0.2, 0.05, -1.2),
        (0.1, 0.2, 0.5),
        (0.2, 0.1, 0.9),
        (0.1, 0.1, 0.3),
    ]
    general = dh_chain(rows, "standard", name="general_6r", task="pose")
    assert closed_form.derive(general) is None
    # ... but the general 6R solver is registered for it: solve_ik_all answers by it alone
    q = general.random_q(seed=1)
    sols = optik.solve_ik_all(general, general.fk(q))
    assert sols.method == "closed_form" and min(joint_distance(general, s.q, q) for s in sols) < 1e-9
    assert closed_form.derive(optik.catalog.panda()) is None  # 7 joints
    assert closed_form.derive(optik.catalog.five_bar()) is None  # closed chain
    assert closed_form.derive(optik.catalog.planar_3r()) is None  # pose2d task


def test_axes_reproduce_the_fk_and_lock_and_reverse_consistently() -> None:
    m = optik.catalog.panda()
    axes = axes_of(m)
    assert isinstance(axes, Axes) and axes.n == 7
    q = m.random_q(5, seed=2)
    np.testing.assert_allclose(axes.fk(q), m.fk(q), atol=1e-12)
    pose, jac = axes.jacobian(q[0])
    np.testing.assert_allclose(pose, m.fk(q[0]), atol=1e-12)
    np.testing.assert_allclose(jac, m.jacobian(q[0]), atol=1e-12)
    locked = axes.lock(6, q[0, 6])
    np.testing.assert_allclose(locked.fk(q[:, :6]), axes.fk(np.column_stack([q[:, :6], np.full(5, q[0, 6])])),
                               atol=1e-12)  # fmt: skip
    assert detect(locked).family == "spherical_base"
    back = axes.reversed()
    np.testing.assert_allclose(back.fk(-q[:, ::-1]), np.linalg.inv(m.fk(q)), atol=1e-12)


@pytest.mark.parametrize("name", ["sw_general", "tp_general", "spherical_base"])
def test_every_eaik_solution_is_found(name: str) -> None:
    eaik = pytest.importorskip("eaik.pybindings.EAIK")
    m = dh_chain(ARMS[name], "standard", name=name, task="pose")
    solver = closed_form.derive(m)
    ax = solver.axes
    offsets = np.vstack([ax.r[0], np.diff(ax.r, axis=0), ax.home[:3, 3] - ax.r[-1]])
    robot = eaik.Robot(ax.h.T, offsets.T, ax.home[:3, :3], [], True)
    targets = m.fk(m.random_q(30, seed=5))
    q, ok = solver.solve(targets)
    for i, t in enumerate(targets):
        theirs = [s for s in np.asarray(robot.calculate_IK(t).Q) if np.abs(m.fk(s) - t).max() < 1e-8]
        ours = q[i][ok[i]]
        assert len(ours) >= len(theirs)
        for s in theirs:
            assert min(joint_distance(m, s, o) for o in ours) < 1e-4  # EAIK's accuracy near singular poses


def test_all_solutions_benchmark_runs_and_agrees_with_eaik(monkeypatch: pytest.MonkeyPatch) -> None:
    from optik.benchmarks import bench_all_solutions

    monkeypatch.setenv("OPTIK_NO_CODEGEN", "1")  # no C compiler runs in the test suite
    assert bench_all_solutions.main(["--n", "3"]) == 0


def test_ik_geo_peer_finds_every_solution_optik_finds(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("ik_geo", reason="the ik-geo peer of the all-solutions benchmark")
    from optik.benchmarks import bench_all_solutions

    monkeypatch.setenv("OPTIK_NO_CODEGEN", "1")
    for m in (optik.catalog.puma560(), optik.catalog.seed_6r_arm()):
        row = bench_all_solutions.run_arm(m, 5, seed=2)
        # ik-geo ran on every pose and its answers pass the FK check
        assert len(row.ikgeo_times) == 5 and row.ikgeo_valid >= 5
        assert row.ikgeo_found == row.ikgeo_valid and row.optik_failed_check == 0


@pytest.mark.parametrize("name", ["tp_56_intersecting", "tp_general", "tp_reversed"])
def test_three_parallel_wrist_singularity_has_representatives(name: str) -> None:
    """Axis 6 parallel to axes 2-4 (q5 = 0 on a UR arm): only theta + q6 is fixed, and the
    representative must keep the two-link target reachable (it missed every branch before)."""
    m = dh_chain(ARMS[name], "standard", name=name, task="pose")
    rng = np.random.default_rng(11)
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, 6)
        q[4 if name != "tp_reversed" else 1] = 0.0
        target = m.fk(q)
        sols = optik.solve_ik_all(m, target)
        assert len(sols) >= 1
        for s in sols:
            np.testing.assert_allclose(m.fk(s.q), target, atol=1e-9)


def test_seed_6r_shoulder_singularity_has_a_representative() -> None:
    """Wrist point on axis 1 (q1 free for the position): the three-parallel solver's
    representative (three_parallel._pairs_decoupled) still answers, every branch exact."""
    m = optik.catalog.seed_6r_arm()
    rng = np.random.default_rng(0)
    grid = np.linspace(-np.pi, np.pi, 73)
    answered = 0
    for q in rng.uniform(-np.pi, np.pi, (40, 6)):

        def radial(a: float, q: np.ndarray = q) -> float:
            t = m.fk(np.r_[q[0], a, q[2:]])
            return t[0, 3] * np.cos(q[0]) + t[1, 3] * np.sin(q[0])

        values = [radial(a) for a in grid]
        k = next(i for i in range(72) if values[i] * values[i + 1] < 0)
        q[1] = brentq(radial, grid[k], grid[k + 1], xtol=1e-15)
        target = m.fk(q)
        assert np.hypot(target[0, 3], target[1, 3]) < 1e-9
        target[:2, 3] = 0.0  # exactly on axis 1
        got = closed_form.ik(m, target, respect_limits=False)
        assert got
        np.testing.assert_allclose(m.fk(np.array(got)), np.broadcast_to(target, (len(got), 4, 4)), atol=1e-9)
        answered += 1
    assert answered == 40


def test_orthogonal_wrist_second_solution_is_the_flip_of_the_first() -> None:
    """An orthogonal wrist (h5 perpendicular to h4, h6 = +-h4 at q = 0: PUMA) gets its second
    wrist solution as ``(q4 + pi, -q5, q6 + pi)``: per arm solution, the two candidates have
    the same FK and differ by that flip; a skewed wrist takes both SP2 roots and is still
    solved completely."""
    from optik.closed_form import spherical_wrist

    m = optik.catalog.puma560()
    solver = closed_form.derive(m)
    assert spherical_wrist.flips(solver.axes)
    qs = m.random_q(40, seed=3)
    cand = solver.candidates(m.fk(qs))  # (N, 8, 6): per arm solution, the first and its flip
    first, second = cand[:, 0::2], cand[:, 1::2]
    np.testing.assert_allclose(second[..., :3], first[..., :3], atol=0.0)
    turn = lambda a: (a + np.pi) % (2 * np.pi) - np.pi  # noqa: E731
    np.testing.assert_allclose(turn(second[..., 3] - first[..., 3] - np.pi), 0.0, atol=1e-12)
    np.testing.assert_allclose(second[..., 4], -first[..., 4], atol=0.0)
    np.testing.assert_allclose(turn(second[..., 5] - first[..., 5] - np.pi), 0.0, atol=1e-12)
    both = np.isfinite(first).all(axis=-1)
    np.testing.assert_allclose(m.fk(second[both]), m.fk(first[both]), atol=1e-12)
    skewed = list(ARMS["sw_12_intersecting"])
    skewed[3] = (0.43, 0, 1.2)  # h5 no longer perpendicular to h4
    arm = dh_chain(skewed, "standard", name="skewed_wrist", task="pose")
    skew_solver = closed_form.derive(arm)
    assert skew_solver.structure.name == FAMILY["sw_12_intersecting"]
    assert not spherical_wrist.flips(skew_solver.axes)
    _check_all(arm)
