"""Regression tests of issue 9: each reproducer of a leaked exception, a hang, a huge allocation
or a contradictory result, now an `OptikError` naming the argument or a correct result."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import optik
from optik import catalog, diffik, problem_files
from optik.cli import main
from optik.closed_form.derived import CHECK_TOL
from optik.mechanism import Joint, planar_chain
from optik.problem_files import find_problem, load_problem


def _raises(argument: str, call, *args, **kwargs) -> optik.InvalidArgumentError:
    """``call(*args, **kwargs)`` raises an InvalidArgumentError whose argument is ``argument``."""
    with pytest.raises(optik.InvalidArgumentError) as info:
        call(*args, **kwargs)
    assert info.value.argument == argument, str(info.value)
    assert str(info.value).startswith(argument)
    return info.value


# ------------------------------------------------------------------------------------ hang, memory
def test_wrap_of_a_huge_rotation_vector_is_constant_time(cpu_clock):
    """A spherical rotation vector was reduced by 2 pi per loop turn (|s1| = 1e8: > 20 s)."""
    sg = catalog.stewart_gough()
    s1 = sg.coordinate_names.index("s1[0]")
    q = sg.mid_q()
    for value in (1e8, 1e300, -7.5):
        q[s1] = value
        with cpu_clock() as cpu:  # the work done, which a busy machine does not lengthen (conftest)
            w = sg.wrap(q)
        assert cpu.seconds < 0.05
        r = w[s1 : s1 + 3]
        assert np.linalg.norm(r) <= np.pi + 1e-12 and np.isfinite(r).all()
    q[s1] = 7.5  # same rotation: angle 7.5 - 2 pi about +x
    np.testing.assert_allclose(sg.wrap(q)[s1 : s1 + 3], [7.5 - 2 * np.pi, 0, 0], atol=1e-12)
    np.testing.assert_allclose(
        optik.spatial.so3_exp(sg.wrap(q)[s1 : s1 + 3]), optik.spatial.so3_exp([7.5, 0, 0])
    )


def test_solve_fk_with_a_huge_leg_returns_within_its_time_limit(cpu_clock):
    with cpu_clock() as cpu:  # the work done, which a busy machine does not lengthen (conftest)
        res = optik.solve_fk(catalog.stewart_gough(), [1e9, 1, 1, 1, 1, 1], time_limit=0.2)
    assert cpu.seconds < 3 * 0.2 + 0.5
    assert not res.success


def test_polyline_path_sample_count_is_capped_before_allocating():
    err = _raises("speed/dt", diffik.polyline_path, [[0.3, 0, 0.5], [0.4, 0.1, 0.5]], 1e-9, 0.05)
    assert str(diffik.paths.MAX_SAMPLES) in str(err)
    assert diffik.polyline_path([[0.3, 0, 0.5], [0.4, 0.1, 0.5]], 0.1, 0.01).shape[1:] == (4, 4)


# ------------------------------------------------------------------------------ huge finite targets
@pytest.mark.parametrize("ctor", [catalog.planar_2r, catalog.planar_3r])
def test_huge_finite_planar_target_is_unreachable(ctor):
    """Position targets go to the closed forms of both arms (a pose2d target of the 2R arm goes
    to lm, which fails at its time limit)."""
    res = optik.solve_ik(ctor(), optik.Position(1e300, 0))
    assert not res.success and math.isfinite(res.q.sum())
    if ctor is catalog.planar_2r:
        assert res.method == "closed_form" and res.status == "unreachable"
    res = optik.solve_ik(ctor(), optik.Pose2D(1e300, 0, 0), time_limit=0.02)
    assert not res.success and res.status in ("unreachable", "time_limit")


def test_huge_finite_target_closed_form_ik_is_empty():
    t = np.eye(4)
    t[0, 3] = 1e300
    assert optik.closed_form.ik(catalog.seed_6r_arm(), t) == []
    assert optik.closed_form.ik(catalog.planar_3r(), t) == []
    assert optik.solve_ik(catalog.seed_6r_arm(), t).status == "unreachable"


def test_cli_huge_target_is_unreachable_not_a_traceback(capsys):
    code = main(["solve", "planar_2r", "--target", "1e300", "0"])
    out = capsys.readouterr().out
    assert code != 0 or "success" in out.lower() or "unreachable" in out.lower()
    assert "Traceback" not in out


# -------------------------------------------------------------------------------------- Tolerances
@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"closure": None}, "closure"),
        ({"position": 0, "orientation": 0, "closure": 0}, "position"),
        ({"orientation": 0.0}, "orientation"),
        ({"position": float("nan")}, "position"),
        ({"position": -1}, "position"),
        ({"closure": math.inf}, "closure"),
        ({"position": "1e-6"}, "position"),
    ],
)
def test_tolerances_are_validated(kwargs, argument):
    _raises(argument, optik.Tolerances, **kwargs)


def test_tolerances_accept_numbers():
    t = optik.Tolerances(1, np.float32(1e-3), np.int64(1))
    assert (t.position, t.closure) == (1.0, 1.0) and type(t.orientation) is float


def test_a_float_tol_is_validated_once_per_value():
    """``tol=<float>`` gives one shared frozen `Tolerances` per value; a bad float is refused
    every time (NaN is never a hit), and a subclass still gets its own instances."""
    a = optik.Tolerances.from_arg(1e-5)
    assert a is optik.Tolerances.from_arg(1e-5)
    assert (a.position, a.orientation, a.closure) == (1e-5, 1e-5, 1e-9)
    assert optik.Tolerances.from_arg(2e-5).position == 2e-5
    for bad in (float("nan"), float("nan"), -1.0, -1.0, 0.0, math.inf):
        _raises("tol", optik.Tolerances.from_arg, bad)

    class Loose(optik.Tolerances):
        pass

    assert type(Loose.from_arg(1e-5)) is Loose


# -------------------------------------------------------------------------------- unhashable names
@pytest.mark.parametrize(
    ("kwargs", "argument"), [({"task": ["pose"]}, "task"), ({"method": ["lm"]}, "method")]
)
def test_unhashable_task_and_method(kwargs, argument):
    _raises(argument, optik.solve_ik, catalog.planar_3r(), optik.Pose2D(1, 0.5, 0), **kwargs)


def test_step_with_osqp_and_a_list_option():
    m = catalog.planar_3r()
    task = diffik.Pose2DTask(target=optik.Pose2D(1, 0.5, 0))
    _raises("options", diffik.step, m, m.mid_q(), [task], 0.01, solver="osqp", joint_weights=[1, 1, 1])
    _raises("solver", diffik.step, m, m.mid_q(), [task], 0.01, solver=["osqp"])


# ---------------------------------------------------------------------------------- constructors
@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda: catalog.five_bar(base="ab"), "base"),
        (lambda: catalog.doggy(hips=object()), "hips"),
        (lambda: catalog.stewart_gough(base=[[0, 0, 0]] * 5 + [[0, 0]]), "base"),
        (lambda: catalog.stewart_gough(platform=[[0, 0, 0]] * 5), "platform"),
        (lambda: planar_chain(3, [1.0]), "types"),
        (lambda: planar_chain("RRR", [1.0]), "lengths"),
        (lambda: Joint("j", "revolute", "a", "b", axis="z"), "axis (joint 'j')"),
        (lambda: Joint("j", "revolute", "a", "b", lower="a"), "lower (joint 'j')"),
        (lambda: Joint("j", "revolute", "a", "b", lower=float("nan")), "lower"),
        (lambda: Joint("j", ["revolute"], "a", "b"), "type"),
        (lambda: Joint("j", "revolute", None, "b"), "parent"),
        (lambda: Joint("j", "revolute", "a", "b", actuated="yes"), "actuated"),
        (lambda: Joint("j", "revolute", "a", "b", origin="eye"), "origin"),
    ],
)
def test_constructors_name_the_bad_argument(call, argument):
    _raises(argument, call)


def test_joint_without_parent_and_child_is_a_type_error_of_python():
    """The issue's ``Joint(axis='z')`` lacked the required parent/child: that stays Python's own
    TypeError for a wrong call signature (as for any function); the values are what optik checks."""
    with pytest.raises(TypeError):
        Joint("j", "revolute", axis="z")  # type: ignore[call-arg]


# --------------------------------------------------------------------------------------- diffik
@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda: diffik.FrameTask(priority=float("nan")), "priority"),
        (lambda: diffik.FrameTask(frame=["ee"]), "frame"),
        (lambda: diffik.JointLimitTask(3, exponent=float("nan")), "exponent"),
        (lambda: diffik.PositionTask(None, "abc"), "target"),
        (lambda: diffik.PositionTask(axes=3), "axes"),
        (lambda: diffik.ManipulabilityTask(3, space=["pose"]), "space"),
        (lambda: diffik.VelocityLimit("a"), "v_max"),
        (lambda: diffik.ConfigurationLimit("a"), "gain"),
        (lambda: diffik.line_path(np.eye(4), [1, 0, 0], float("nan"), 0.01), "speed"),
        (lambda: diffik.line_path(np.eye(4), [1, 0, 0], 1.0, 1e-9), "speed/dt"),
        (lambda: diffik.circle_path([0, 0, 0], 0.1, 1.0, 0.01, turns="x"), "turns"),
        (lambda: diffik.polyline_path([[0, 0, 0], [1, 0]], 0.1, 0.01), "points"),
    ],
)
def test_diffik_constructors_name_the_bad_argument(call, argument):
    _raises(argument, call)


def test_orientation_task_accepts_a_pose2d():
    task = diffik.OrientationTask(None, optik.Pose2D(0.1, 0.2, 0.3))
    np.testing.assert_allclose(task.target[:3, :3], optik.spatial.rot_z(0.3), atol=1e-15)


@pytest.mark.parametrize("q", [object(), [1j] * 3, "abc", [1.0, 2.0]])
def test_step_bad_q(q):
    m = catalog.planar_3r()
    _raises("q", diffik.step, m, q, [diffik.Pose2DTask(target=optik.Pose2D(1, 0.5, 0))], 0.01)


def test_track_bad_path():
    m = catalog.planar_3r()
    _raises("path", diffik.track, m, m.mid_q(), "path", 0.01)
    _raises("path", diffik.track, m, m.mid_q(), [], 0.01)
    _raises("path", diffik.track, m, m.mid_q(), [optik.Pose2D(1, 0, 0), optik.Position(1, 0)], 0.01)
    bad = np.tile(np.eye(4), (3, 1, 1))
    bad[1, 0, 0] = 2.0
    _raises("path[1]", diffik.track, m, m.mid_q(), bad, 0.01)


def test_track_accepts_what_solve_ik_accepts():
    """Sequences of Position / Pose2D and (N, 3) points, with the task they imply."""
    m = catalog.planar_2r(lengths=(1.0, 1.0))
    xs = np.linspace(1.2, 1.3, 6)
    points = [optik.Position(x, 0.3) for x in xs]
    q0 = optik.solve_ik(m, points[0]).q
    a = diffik.track(m, q0, points, 0.01, method="qp")
    b = diffik.track(m, q0, np.stack([xs, np.full(6, 0.3), np.zeros(6)], axis=1), 0.01, method="qp")
    c = diffik.track(m, q0, np.stack([p.as_transform() for p in points]), 0.01, space="position2d")
    np.testing.assert_allclose(a.q, b.q)
    np.testing.assert_allclose(a.q, c.q)
    assert a.position_error.max() < 1e-3
    np.testing.assert_allclose(m.fk(a.q[-1])[:2, 3], [xs[-1], 0.3], atol=1e-3)
    m3 = catalog.planar_3r()
    poses = [optik.Pose2D(1.2, 0.5 + 0.01 * k, 0.2) for k in range(5)]
    r = diffik.track(m3, m3.mid_q() + 0.3, poses, 0.01, method="qp")
    pose = m3.fk(r.q[-1])
    xy_phi = [pose[0, 3], pose[1, 3], math.atan2(pose[1, 0], pose[0, 0])]
    np.testing.assert_allclose(xy_phi, [1.2, 0.54, 0.2], atol=1e-3)


# ------------------------------------------------------------------------------ status / success
def test_success_and_status_agree_for_fixed_joints():
    """planar_2r with lower == upper: the closed form's nearest branch clipped into the limits
    met the tolerances and was reported as success together with status outside_limits."""
    m = catalog.planar_2r().with_limits([0.3, 0.2], [0.3, 0.2])
    res = optik.solve_ik(m, optik.Position(*m.fk([0.3, 0.2])[:2, 3]))
    assert res.success and res.status == "solved" and res.message == ""


@pytest.mark.parametrize("method", ["lm", "qp", "dls", "nlp", "closed_form"])
def test_success_iff_status_solved(method):
    m = catalog.planar_3r()
    for k, target in enumerate(
        [optik.Pose2D(1.2, 0.8, 0.5), optik.Pose2D(5, 0, 0), optik.Pose2D(0.3, 0.2, 2.0)]
    ):
        res = optik.solve_ik(m, target, method=method, time_limit=0.05, seed=k)
        assert res.success == (res.status == "solved"), (res.status, res.success)


# ------------------------------------------------------------------------------------------ files
_FIVE_BAR = """[problem]
description = "five-bar"
[mechanism]
constructor = "{constructor}"
[mechanism.params]
{params}
[targets]
n = {n}
"""


def _problem_file(tmp_path, constructor="five_bar", params="", n=10, text=None):
    p = tmp_path / "p.toml"
    if text is None:
        text = _FIVE_BAR.format(constructor=constructor, params=params, n=n)
    p.write_bytes(text.encode() if isinstance(text, str) else text)
    return p


def test_problem_file_not_utf8(tmp_path):
    p = _problem_file(tmp_path, text=b'[problem]\ndescription = "\xff\xfe"\n')
    with pytest.raises(optik.ProblemFileError, match="not UTF-8"):
        load_problem(p)


def test_problem_file_path_with_nul():
    with pytest.raises(optik.ProblemFileError, match="NUL"):
        load_problem("problems/a\0b.toml")
    _raises("problem", find_problem, "a\0b.toml")
    _raises("problem", find_problem, ["planar_2r"])


def test_problem_file_deeply_nested_arrays(tmp_path):
    p = _problem_file(tmp_path, text="[problem]\ndescription = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(optik.ProblemFileError, match="nested too deeply"):
        load_problem(p)


def test_problem_file_too_large(tmp_path):
    p = _problem_file(tmp_path, text="# " + "x" * (2 << 20) + "\n")
    with pytest.raises(optik.ProblemFileError, match="larger than"):
        load_problem(p)


@pytest.mark.parametrize("name", ["urdf_path", "__class__", "URDF_CHAINS", "no_such"])
def test_problem_file_constructor_must_build_a_mechanism(tmp_path, name):
    with pytest.raises(optik.ProblemFileError, match=r"mechanism\.constructor"):
        load_problem(_problem_file(tmp_path, constructor=name))


def test_problem_file_constructors_are_the_mechanism_functions():
    names = problem_files.constructors()
    assert {"five_bar", "panda", "planar_2r", "stewart_gough"} <= set(names)
    assert "urdf_path" not in names and "URDF_CHAINS" not in names


def test_problem_file_huge_n(tmp_path):
    with pytest.raises(optik.ProblemFileError, match=r"targets\.n"):
        load_problem(_problem_file(tmp_path, n=10**12))
    problem = load_problem(_problem_file(tmp_path))
    _raises("n", problem.sample_targets, 10**12)


def test_problem_file_bad_constructor_parameter_fails_at_build(tmp_path):
    problem = load_problem(_problem_file(tmp_path, params='base = "ab"'))
    with pytest.raises(optik.ProblemFileError, match=r"mechanism\.params\.base"):
        problem.mechanism()


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["solve", "planar_2r", "--target", "1", "0.5", "--plot", "{file}/x.png"], "--plot"),
        (["solve", "planar_2r", "--target", "1", "0.5", "--plot", "{dir}"], "--plot"),
        (["solve", "planar_2r", "--target", "1", "0.5", "--plot", "{dir}/x.zzz"], "--plot"),
        (["fk", "planar_2r", "--q", "0.1", "0.2", "--plot", "{file}/x.png"], "--plot"),
        (["bench", "planar_2r", "--n", "1", "--out", "{file}/out"], "--out"),
        (["plot", "planar_2r", "--out", "{file}"], "--out"),
    ],
)
def test_cli_unwritable_output_fails_before_the_run(tmp_path, capsys, argv, option):
    """A regular file where a folder is needed, a folder where a file is needed, an unknown
    image format: exit code 2 with one line naming the option, before any work."""
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    args = [a.format(file=blocker, dir=tmp_path) for a in argv]
    assert main(args) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # nothing ran
    assert option in captured.err and "Traceback" not in captured.err


# ----------------------------------------------------------------- closed forms at extreme sizes
def test_planar_3r_branches_at_extreme_proportions_pass_fk():
    """lengths (1e-9, 1e3, 1e3), identity target: the branches were off by 7.6e-3 (1 + c2 and
    1 - c2 did not add up to 2 in rounding, so theta1 missed by l2 times the mismatch)."""
    m = catalog.planar_3r(lengths=(1e-9, 1e3, 1e3))
    branches = optik.closed_form.ik(m, np.eye(4))
    assert branches
    for q in branches:
        assert np.abs(m.fk(q) - np.eye(4)).max() < 1e-12 * 2e3


_SIZES = st.sampled_from([1e-9, 1e-6, 1e-3, 1.0, 1e3, 1e6, 1e9])


@settings(derandomize=True, max_examples=40, deadline=None, database=None)
@given(
    lengths=st.tuples(_SIZES, _SIZES, _SIZES), q=st.lists(st.floats(-np.pi, np.pi), min_size=6, max_size=6)
)
@example(lengths=(1e-9, 1e-6, 1000.0), q=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0])  # the 6R branch at 4e-10
def test_serial_closed_forms_pass_fk_at_any_proportion(lengths, q):
    """Every branch returned (scalar and vectorized kernels, 3R and seed 6R arms) reproduces the
    target to rounding relative to the arm's size."""
    scale = sum(lengths)
    arms = (
        catalog.planar_2r(lengths=lengths[:2]),
        catalog.planar_3r(lengths=lengths),
        catalog.seed_6r_arm(*lengths),
    )
    for m in arms:
        qq = q[: m.n_q]
        t = m.fk(qq)
        rows = optik.closed_form.ik(m, t, respect_limits=False)
        assert rows, m.name  # a target made by FK is reachable
        # the 3R kernels reproduce the target to rounding; the derived 6R kernel keeps what passes
        # its FK check, CHECK_TOL times the arm's size: at proportions of 1e12 (1e-9, 1e-6, 1e3) a
        # second, symmetric branch misses by 4e-10 of the size, which is all the check promises
        # there (the links below the check's resolution cannot tell that branch from a solution)
        bound = CHECK_TOL if m.n_q == 6 else 1e-12
        for b in rows:
            f = m.fk(b)
            assert np.abs(f[:3, 3] - t[:3, 3]).max() <= bound * scale, (m.name, b)
            if m.task != "position2d":
                assert np.abs(f[:3, :3] - t[:3, :3]).max() <= 1e-9, (m.name, b)
    x, y, phi = optik.spatial.planar_pose_of(catalog.planar_3r(lengths=lengths).fk(q[:3]))
    qs, ok = optik.closed_form.ik_planar_3r(lengths, x, y, phi)
    m = catalog.planar_3r(lengths=lengths)
    for b in qs[0][ok[0]]:
        assert np.abs(m.fk(b)[:2, 3] - [x, y]).max() <= 1e-12 * scale


# ------------------------------------------------------------------------------ DLS stays bounded
def test_dls_tracking_beyond_reach_stays_bounded():
    """planar 2R (1, 1) from (0.5, -1) along y = 0.05, x = 1.5 -> 2.2 (out of reach from x = 2),
    141 steps of 10 ms: the elbow flipped every step at up to 326 rad/s. Now the arm follows the
    path to the edge, then stays stretched towards the target (the closest configuration)."""
    m = catalog.planar_2r(lengths=(1.0, 1.0))
    xs = np.linspace(1.5, 2.2, 141)
    r = diffik.track(m, [0.5, -1.0], [optik.Position(x, 0.05) for x in xs], 0.01, method="dls")
    speed = np.abs(r.v).max(axis=1)
    beyond = xs > 2.0 + 1e-3
    assert speed[1:].max() < 15.0  # the first step closes the 6 cm start error
    assert speed[beyond][1:].max() < 1.0  # out of reach: nearly still
    elbow = r.q[1:, 1]
    assert np.abs(elbow[beyond]).max() < 5e-3  # stretched (rad), no flip through the singularity
    assert np.all(elbow[xs < 1.99] < 0)  # the elbow branch of the start is kept up to the edge
    assert r.position_error[(xs > 1.52) & (xs < 1.99)].max() < 2e-3
    closest = np.hypot(2.2, 0.05) - 2.0
    assert abs(r.position_error[-1] - closest) < 1e-3
    assert "shortened" in r.status


def test_dls_step_at_a_stretched_arm_stays_put():
    m = catalog.planar_2r(lengths=(1.0, 1.0))
    task = diffik.PositionTask(target=optik.Position(3.0, 0.0), axes="xy")
    res = diffik.step(m, [0.0, 0.0], [task], 0.01, method="dls")
    np.testing.assert_allclose(res.q, [0.0, 0.0], atol=1e-12)
    res = diffik.step(m, [0.0, 1e-3], [task], 0.01, method="dls")
    assert np.abs(res.v).max() < 1.0 and res.q[1] >= 0.0  # straightens, does not flip


def test_iterated_dls_converges_at_a_near_singular_solution():
    """A seed 6R target with s5 = 0.03 (inside the adaptive damping's threshold): the damped
    steps converged linearly and the method failed within its time limit from every seed."""
    m = catalog.seed_6r_arm()
    t = m.fk([-1.54, -0.345, 0.029, 0.336, 3.113, 1.839])
    for seed in range(3):
        res = optik.solve_ik(m, t, method="dls", time_limit=1.0, seed=seed)
        assert res.success and res.iterations < 100, (res.iterations, res.position_error)


# --------------------------------------------------------------------- found by the fuzz suite
def test_task_sizes_are_capped():
    """ManipulabilityTask(1e9) allocated 8 GB for its cost vector."""
    _raises("n_q", diffik.ManipulabilityTask, 1e9)
    _raises("n_q", diffik.JointLimitTask, 10**6)


@pytest.mark.parametrize("dt", [5e-324, 0.0, float("nan"), "0.01"])
def test_step_time_step_is_a_finite_float_of_at_least_a_nanosecond(dt):
    """dt = 5e-324 gave v = inf (and a path of NaN in track)."""
    m = catalog.planar_2r()
    task = diffik.PositionTask(target=optik.Position(1, 0.5), axes="xy")
    _raises("dt", diffik.step, m, m.mid_q(), [task], dt)


def test_step_time_step_as_a_huge_int():
    """dt = 10**30, an int numpy cannot convert, leaked a TypeError from np.isfinite."""
    m = catalog.planar_2r()
    res = diffik.step(m, m.mid_q(), [diffik.PositionTask(target=optik.Position(1, 0.5), axes="xy")], 10**30)
    assert np.isfinite(res.q).all() and m.within_limits(res.q)


@pytest.mark.parametrize("method", ["qp", "dls"])
def test_iterated_ik_of_a_huge_target_is_a_failure_not_an_svd_error(method):
    """slider_crank, Position(1e300, 0), qp: the QP Hessian overflowed and the DLS fallback's SVD
    raised LinAlgError."""
    m = catalog.slider_crank()
    res = optik.solve_ik(m, optik.Position(1e300, 0.0), method=method, time_limit=0.02)
    assert not res.success and np.isfinite(res.q).all()
    step = diffik.step(
        m, m.mid_q(), [diffik.PositionTask(target=optik.Position(1e300, 0.0), axes="xy")], 0.01
    )
    assert step.status == "overflow" and np.isfinite(step.q).all()


def test_track_time_step_as_a_huge_int():
    """track(..., dt=10**30) leaked OverflowError from np.arange(n) * dt."""
    m = catalog.planar_3r()
    res = diffik.track(m, m.mid_q(), [optik.Position(1.0, 0.5), optik.Position(1.1, 0.5)], 10**30)
    assert np.isfinite(res.q).all() and res.t[-1] == 2e30


def test_problem_file_number_beyond_the_float_range(tmp_path):
    """A TOML integer of 21 digits leaked a TypeError from np.isfinite."""
    text = _FIVE_BAR.format(
        constructor="five_bar", params="lengths = [1, 1, 1, 999999999999999999999999999999999]", n=1
    )
    problem = load_problem(_problem_file(tmp_path, text=text))  # params go to the constructor
    assert problem.params["lengths"][3] == 999999999999999999999999999999999
    text = text.replace("[targets]", "[tolerances]\nposition = 1" + "0" * 400 + "\n[targets]")
    with pytest.raises(optik.ProblemFileError, match=r"tolerances\.position: expected a finite number"):
        load_problem(_problem_file(tmp_path, text=text))


@pytest.mark.parametrize("name", ["planar_3rpr", "stewart_gough", "five_bar"])
def test_closed_form_fk_of_overflowing_actuated_values(name):
    """planar_3rpr with a leg of 1e300: OverflowError / IndexError inside the solver."""
    m = getattr(catalog, name)()
    a = m.mid_q()[m.actuated_indices]
    a[0] = 1e300
    _raises("actuated", optik.closed_form.fk, m, a)
    a[0] = 1e40  # huge but within the range: cannot assemble
    assert optik.closed_form.fk(m, a) == []


@pytest.mark.parametrize("module", ["optik.solvers.lm_kernel", "optik.closed_form.ik_all"])
def test_a_missing_c_driver_falls_back_to_the_evaluator_logged(module, monkeypatch, tmp_path, caplog):
    """A wheel without `ik_all.c` crashed `optik bench --quick` with FileNotFoundError: a C driver
    that cannot be read is a logged fallback to CasADi's evaluator (the answers stay right), and an
    error only when compiled code is demanded (``compile=True``)."""
    import importlib

    from optik.native import driver_source

    gone = tmp_path / "gone.c"
    monkeypatch.setattr(importlib.import_module(module), "DRIVER", gone)
    with pytest.raises(optik.SolverUnavailableError, match="cannot be read"):
        driver_source(gone, compile=True)
    q = np.array([0.3, -0.5, 0.4, 0.2, -0.6, 0.7])
    with caplog.at_level("WARNING", logger="optik"):
        if module.endswith("lm_kernel"):
            m = catalog.planar_3r()  # a new model: a new kernel, built with the patched driver path
            q = q[:3]
            res = optik.solve_ik(m, m.fk(q), method="lm")
            assert res.success and res.position_error <= 1e-6
        else:
            m = catalog.puma560()
            sols = optik.solve_ik_all(m, m.fk(q))
            assert sols.certified and min(np.max(np.abs(s - q)) for s in sols.q) < 1e-9
    assert f"{gone} cannot be read" in caplog.text
