"""Several frame targets at once: ``solve_ik(m, {"left_tool": T1, "right_tool": T2})`` with lm,
nlp, dls and qp on tree models, per-frame errors, success checked by recomputing each frame's
FK, diffik frame tasks on trees, and the errors of malformed requests."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import optik
from optik import Joint, Mechanism, Pose2D, Position, diffik, spatial
from optik.errors import InvalidArgumentError, SolverUnavailableError, UnknownFrameError

DUAL = optik.catalog.dual_panda()
TOOLS = ("left_tool", "right_tool")


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(Rotation.from_matrix(a[:3, :3].T @ b[:3, :3]).magnitude())


def _check(m: Mechanism, res: optik.IKResult, targets: dict) -> None:
    """Success recomputed independently: each frame's FK against its own target."""
    assert res.success, res.message
    assert m.within_limits(res.q)
    for frame, target in targets.items():
        pose = m.fk(res.q, frame)
        if isinstance(target, Position):
            assert np.linalg.norm(pose[:3, 3] - target.as_array()) < 1e-6
        elif isinstance(target, Pose2D):
            assert np.hypot(pose[0, 3] - target.x, pose[1, 3] - target.y) < 1e-6
            assert abs(spatial.wrap_angle(np.arctan2(pose[1, 0], pose[0, 0]) - target.phi)) < 1e-6
        else:
            assert np.linalg.norm(pose[:3, 3] - target[:3, 3]) < 1e-6
            assert _angle(pose, target) < 1e-6
    assert set(res.frame_errors) == set(targets)
    assert res.position_error == max(p for p, _ in res.frame_errors.values())
    assert res.orientation_error == max(o for _, o in res.frame_errors.values())


def test_dual_panda_tree():
    assert DUAL.n_q == 15 and DUAL.base == "world" and set(TOOLS) <= set(DUAL.frames)
    assert DUAL.ee == "left_tool"  # as documented, not a finger link (the hand's leaves come after it)
    np.testing.assert_array_equal(DUAL.fk(DUAL.mid_q()), DUAL.fk(DUAL.mid_q(), "left_tool"))
    # both tools depend on the shared torso joint and only on their own arm otherwise
    jl, jr = DUAL.jacobian(DUAL.mid_q(), "left_tool"), DUAL.jacobian(DUAL.mid_q(), "right_tool")
    assert np.abs(jl[:, 0]).max() > 0.1 and np.abs(jr[:, 0]).max() > 0.1
    assert np.abs(jl[:, 8:]).max() == 0 and np.abs(jr[:, 1:8]).max() == 0
    with pytest.raises(InvalidArgumentError, match=r"^name"):
        optik.catalog.urdf_path("dual")


@pytest.mark.parametrize("method", ["lm", "nlp", "dls", "qp"])
def test_both_hands_placed(method):
    rng = np.random.default_rng(21)
    solved = 0
    for q in DUAL.random_q(4, seed=rng):
        targets = {"left_tool": DUAL.fk(q, "left_tool"), "right_tool": DUAL.fk(q, "right_tool")}
        if method == "qp":  # mixed target types: the right hand only positioned
            targets["right_tool"] = Position(targets["right_tool"][:3, 3])
        # a generous limit: the test is about the answers, and a busy machine must not fail it
        res = optik.solve_ik(DUAL, targets, method=method, time_limit=5.0)
        if res.success:
            _check(DUAL, res, targets)
            solved += 1
    assert solved >= 3


def test_default_method_one_entry_dict_and_a_far_target():
    q = DUAL.random_q(seed=5)
    targets = {f: DUAL.fk(q, f) for f in TOOLS}
    res = optik.solve_ik(DUAL, targets, time_limit=5.0)  # answers, not speed
    assert res.method == "lm"
    _check(DUAL, res, targets)
    one = optik.solve_ik(DUAL, {"right_tool": targets["right_tool"]}, method="lm")
    same = optik.solve_ik(DUAL, targets["right_tool"], frame="right_tool", method="lm")
    np.testing.assert_array_equal(one.q, same.q)  # a one-entry dict is the plain request
    assert one.frame_errors == {}
    far = dict(targets, right_tool=spatial.translation(3.0, -3.0, 0.5))
    miss = optik.solve_ik(DUAL, far, method="lm", time_limit=0.05)
    assert not miss.success and "right_tool" in miss.message and "left_tool" in miss.message
    assert miss.frame_errors["right_tool"][0] > 2.0
    assert miss.position_error == miss.frame_errors["right_tool"][0]


def _planar_tree() -> Mechanism:
    """A planar Y: a shared link, then two 2R branches ending at the frames ``a`` and ``b``."""
    t = spatial.translation
    joints = [
        Joint("s", "revolute", "base", "trunk", lower=-2, upper=2),
        Joint("a1", "revolute", "trunk", "a1", origin=t(1.0, 0, 0), lower=-2.5, upper=2.5),
        Joint("a2", "revolute", "a1", "a2", origin=t(0.6, 0, 0), lower=-2.5, upper=2.5),
        Joint("b1", "revolute", "trunk", "b1", origin=t(1.0, 0, 0), lower=-2.5, upper=2.5),
        Joint("b2", "revolute", "b1", "b2", origin=t(0.5, 0, 0), lower=-2.5, upper=2.5),
    ]
    return Mechanism(joints, "base", {"a": ("a2", t(0.4, 0, 0)), "b": ("b2", t(0.3, 0, 0))}, "a")


@pytest.mark.parametrize("method", ["lm", "nlp", "dls", "qp"])
def test_planar_tree_pose2d_and_position_targets(method):
    m = _planar_tree()
    assert m.planar
    q = np.array([0.3, 0.8, -0.6, -1.1, 0.9])
    ta, tb = m.fk(q, "a"), m.fk(q, "b")
    targets = {"a": Pose2D(ta[0, 3], ta[1, 3], np.arctan2(ta[1, 0], ta[0, 0])), "b": Position(tb[:2, 3])}
    res = optik.solve_ik(m, targets, method=method, seed=1, time_limit=5.0)  # answers, not speed
    _check(m, res, targets)


def test_several_targets_request_errors():
    t = DUAL.fk(DUAL.mid_q(), "left_tool")
    both = {"left_tool": t, "right_tool": t}
    with pytest.raises(InvalidArgumentError, match=r"^frame"):
        optik.solve_ik(DUAL, both, frame="left_tool")
    with pytest.raises(InvalidArgumentError, match=r"^target: an empty"):
        optik.solve_ik(DUAL, {})
    with pytest.raises(InvalidArgumentError, match=r"^target: the keys"):
        optik.solve_ik(DUAL, {1: t, 2: t})
    with pytest.raises(UnknownFrameError, match="nope"):
        optik.solve_ik(DUAL, {"left_tool": t, "nope": t})
    with pytest.raises(optik.ShapeError, match=r"^target\['right_tool'\]"):
        optik.solve_ik(DUAL, {"left_tool": t, "right_tool": np.eye(3)})
    with pytest.raises(InvalidArgumentError, match=r"^task: give one task space per frame"):
        optik.solve_ik(DUAL, both, task={"left_tool": "pose"})
    with pytest.raises(SolverUnavailableError, match="solves one frame target"):
        optik.solve_ik(optik.catalog.panda(), {"link7": t, "ee": t}, method="closed_form")
    with pytest.raises(InvalidArgumentError, match=r"^target: solve_ik_all takes one frame target"):
        optik.solve_ik_all(DUAL, both)
    res = optik.solve_ik(
        DUAL, both, task={"left_tool": "position", "right_tool": "orientation"}, method="nlp"
    )
    assert (
        res.success and res.frame_errors["left_tool"][1] == 0.0 and res.frame_errors["right_tool"][0] == 0.0
    )


def test_diffik_frame_tasks_on_a_tree():
    q = DUAL.mid_q()
    goal = DUAL.random_q(seed=9)
    tasks = [diffik.FrameTask(f, target=DUAL.fk(goal, f)) for f in TOOLS]
    for _ in range(40):
        q = diffik.step(DUAL, q, tasks, 1.0, "qp").q
    for f in TOOLS:
        pose, target = DUAL.fk(q, f), DUAL.fk(goal, f)
        assert np.linalg.norm(pose[:3, 3] - target[:3, 3]) < 1e-6 and _angle(pose, target) < 1e-6
    assert DUAL.within_limits(q)


def _robots_dir():
    from importlib import metadata
    from pathlib import Path

    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install 'optik[robots]')")
    return Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))


@pytest.mark.peers
def test_talos_both_grippers_placed():
    path = _robots_dir() / "talos_data" / "robots" / "talos_full_v2.urdf"
    if not path.is_file():
        pytest.skip(f"no {path}")
    m = optik.Mechanism.from_urdf(path)  # the whole humanoid: 32 coordinates, 12 mimic joints
    q = m.random_q(seed=2)
    targets = {f: m.fk(q, f) for f in ("gripper_left_base_link", "gripper_right_base_link")}
    res = optik.solve_ik(m, targets, method="nlp", time_limit=2.0)
    _check(m, res, targets)


def test_two_hands_benchmark_runs(capsys):
    from optik.benchmarks import bench_two_hands

    assert bench_two_hands.main(["--n", "2", "--time-limit", "0.02", "--methods", "lm,qp"]) == 0
    out = capsys.readouterr().out
    assert "| optik lm |" in out and "| optik qp |" in out and "Pink" in out
