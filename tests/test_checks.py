"""Input validation (optik.checks) and the IK request / result bookkeeping (solvers.base).

The fast plain-float paths must raise the same errors, naming the same arguments, as the numpy
formulations they replace, and compute the same errors.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import optik
from optik import spatial
from optik.checks import as_bool, as_transform, as_vector
from optik.solvers.base import Tolerances, make_request, make_result, task_errors


def _rot(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _transform(seed: int) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = _rot(seed)
    t[:3, 3] = np.random.default_rng(seed + 100).normal(size=3)
    return t


def _reference_valid(t: np.ndarray) -> bool:
    """The numpy formulation of as_transform's rotation / last-row checks."""
    r = t[:3, :3]
    return bool(
        np.allclose(t[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9)
        and np.allclose(r.T @ r, np.eye(3), atol=1e-6)
        and np.linalg.det(r) >= 0
    )


def test_as_transform_accepts_rotations_and_returns_the_array() -> None:
    for seed in range(20):
        t = _transform(seed)
        assert as_transform(t, "target") is t
    out = as_transform(np.eye(4).tolist(), "target")
    assert isinstance(out, np.ndarray) and out.dtype == float
    np.testing.assert_array_equal(out, np.eye(4))


@pytest.mark.parametrize(
    ("value", "error"),
    [
        (np.eye(3), optik.ShapeError),
        (np.eye(4)[:3], optik.ShapeError),
        (np.zeros((2, 4, 4)), optik.ShapeError),
        (np.full((4, 4), np.nan), optik.NonFiniteError),
        (np.where(np.eye(4) > 0, np.inf, 0.0), optik.NonFiniteError),
        ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0.5, 1]], optik.InvalidArgumentError),
        ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 2]], optik.InvalidArgumentError),
        (np.diag([1.0, 1.0, -1.0, 1.0]), optik.InvalidArgumentError),  # reflection, det -1
        (np.diag([2.0, 1.0, 1.0, 1.0]), optik.InvalidArgumentError),  # not orthonormal
        (np.diag([0.0, 0.0, 0.0, 1.0]), optik.InvalidArgumentError),
    ],
)
def test_as_transform_errors_name_the_argument(value: object, error: type) -> None:
    with pytest.raises(error) as info:
        as_transform(value, "target")
    assert isinstance(info.value, optik.InvalidArgumentError)
    assert info.value.argument == "target"


def test_as_transform_nan_is_a_nonfinite_error_not_a_rotation_error() -> None:
    t = np.eye(4)
    t[0, 3] = np.nan
    with pytest.raises(optik.NonFiniteError):
        as_transform(t, "target")


def test_as_transform_large_finite_entries_are_finite() -> None:
    # the entries' sum overflows to inf; that alone must not count as non-finite
    t = np.eye(4)
    t[:3, 3] = 1.5e308
    as_transform(t, "target")


def test_as_transform_matches_the_numpy_checks_near_the_tolerances() -> None:
    rng = np.random.default_rng(7)
    for k in range(400):
        t = _transform(k)
        scale = 10.0 ** rng.uniform(-9, -4)
        t[:3, :3] += scale * rng.normal(size=(3, 3))
        if k % 3 == 0:
            t[3, :3] += 10.0 ** rng.uniform(-11, -7) * rng.normal(size=3)
        if k % 5 == 0:
            t[:3, :3] = -t[:3, :3]
        ok = _reference_valid(t)
        if ok:
            as_transform(t, "T")
        else:
            with pytest.raises(optik.InvalidArgumentError):
                as_transform(t, "T")


def test_as_vector_fast_path_and_errors() -> None:
    v = np.array([0.1, 0.2, 0.3])
    assert as_vector(v, "q", 3) is v
    big = np.array([1.5e308, 1.5e308])  # sum overflows, entries finite
    assert as_vector(big, "q", 2) is big
    with pytest.raises(optik.ShapeError) as info:
        as_vector(v, "q0", 2)
    assert info.value.argument == "q0"
    for bad in (np.array([np.nan, 0.0, 0.0]), np.array([np.inf, -np.inf, 0.0])):
        with pytest.raises(optik.NonFiniteError) as info:
            as_vector(bad, "q0", 3)
        assert info.value.argument == "q0"
    with pytest.raises(optik.ShapeError):
        as_vector(np.zeros((3, 1)), "q0", 3)
    np.testing.assert_array_equal(as_vector(np.arange(3), "q", 3), [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(as_vector(2.5, "x", 1), [2.5])


def _reference_task_errors(task: str, pose: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    dp = pose[:3, 3] - target[:3, 3]
    pos = float(np.linalg.norm(dp[:2] if task in ("pose2d", "position2d") else dp))
    if task in ("position", "position2d"):
        return pos, 0.0
    if task == "orientation":
        pos = 0.0
    if task == "pose2d":
        phi = np.arctan2(pose[1, 0], pose[0, 0]) - np.arctan2(target[1, 0], target[0, 0])
        return pos, float(abs(spatial.wrap_angle(phi)))
    return pos, float(spatial.angle_between(pose[:3, :3], target[:3, :3]))


@pytest.mark.parametrize("task", ["pose", "position", "orientation", "pose2d", "position2d"])
def test_task_errors_match_the_numpy_definitions(task: str) -> None:
    for k in range(50):
        a, b = _transform(k), _transform(k + 1000)
        if task in ("pose2d", "position2d"):
            a = spatial.planar_pose(*a[:3, 3])
            b = spatial.planar_pose(*b[:3, 3])
        if k == 0:
            b = a.copy()  # zero error
        got = task_errors(task, a, b)
        ref = _reference_task_errors(task, a, b)
        assert all(isinstance(x, float) for x in got)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)


def test_task_errors_half_turn_and_heading_wrap() -> None:
    a = np.eye(4)
    b = np.diag([1.0, -1.0, -1.0, 1.0])  # half-turn about x
    assert task_errors("pose", a, b)[1] == pytest.approx(np.pi)
    p = spatial.planar_pose(0.0, 0.0, 3.1)
    q = spatial.planar_pose(0.0, 0.0, -3.1)
    assert task_errors("pose2d", p, q)[1] == pytest.approx(2 * np.pi - 6.2)


@pytest.mark.parametrize(
    ("time_limit", "error"),
    [
        (-1.0, optik.InvalidArgumentError),
        (0.0, optik.InvalidArgumentError),
        (float("nan"), optik.NonFiniteError),
        (float("inf"), optik.NonFiniteError),
        ("soon", optik.InvalidArgumentError),
        ([0.1, 0.2], optik.ShapeError),
    ],
)
def test_make_request_time_limit_errors(time_limit: object, error: type) -> None:
    m = optik.catalog.planar_3r()
    with pytest.raises(error) as info:
        make_request(m, optik.Pose2D(1.0, 0.5, 0.3), time_limit=time_limit)
    assert info.value.argument == "time_limit"


def test_make_request_defaults_and_conversions() -> None:
    m = optik.catalog.planar_3r()
    req = make_request(m, optik.Pose2D(1.0, 0.5, 0.3))
    assert req.time_limit == 0.1 and req.tol == Tolerances()
    np.testing.assert_array_equal(req.q0, m.mid_q())
    req = make_request(m, m.fk(m.mid_q()), q0=[0, 0, 0], time_limit=1, tol=1e-4, seed=np.int64(3))
    assert req.time_limit == 1.0 and isinstance(req.time_limit, float)
    assert req.tol == Tolerances(position=1e-4, orientation=1e-4)
    assert req.q0.dtype == float
    with pytest.raises(optik.InvalidArgumentError) as info:
        make_request(m, optik.Pose2D(1.0, 0.5, 0.3), tol=-1.0)
    assert info.value.argument == "tol"
    with pytest.raises(optik.InvalidArgumentError) as info:
        make_request(m, np.diag([1.0, 1.0, -1.0, 1.0]))
    assert info.value.argument == "target"


def test_make_result_wraps_clips_and_judges() -> None:
    m = optik.catalog.planar_3r()
    q = np.array([0.3, -0.4, 0.5])
    req = make_request(m, m.fk(q))
    res = make_result(req, q, "test", 1)
    assert res.success and res.limits_ok and res.status == "solved"
    assert res.q is not q
    np.testing.assert_array_equal(res.q, q)
    # wrapped by 2 pi: the same configuration, reported wrapped
    res = make_result(req, q + np.array([2 * np.pi, 0.0, -2 * np.pi]), "test", 1)
    assert res.success
    np.testing.assert_allclose(res.q, q, atol=1e-12)
    # a list is accepted; a far-off q fails with a message
    res = make_result(req, [1.0, 1.0, 1.0], "test", 2, restarts=1)
    assert not res.success and res.status == "not_converged" and "position error" in res.message
    assert res.iterations == 2 and res.restarts == 1 and res.method == "test"
    # a compiled error callback is used and the limits are judged on the clipped q
    res = make_result(req, q, "test", 1, errors=lambda qq: (0.0, 0.0, 0.0))
    assert res.success and res.limits_ok
    res = make_result(req, q, "test", 1, errors=lambda qq: (1.0, 0.0, 0.0), status="custom")
    assert not res.success and res.status == "custom"


def test_target_transforms_match_spatial() -> None:
    rng = np.random.default_rng(3)
    for _ in range(200):
        x, y, phi = (float(v) for v in rng.normal(size=3) * [1.0, 1.0, 10.0])
        a = optik.Pose2D(x, y, phi).as_transform()
        assert a.tobytes() == spatial.planar_pose(x, y, phi).tobytes()
        b = optik.Position(x, y, phi).as_transform()
        assert b.tobytes() == spatial.translation(x, y, phi).tobytes()
    p = optik.Pose2D(1, np.float64(0.5), 2)
    assert (p.x, p.y, p.phi) == (1.0, 0.5, 2.0)
    assert all(type(v) is float for v in (p.x, p.y, p.phi))


@pytest.mark.parametrize(
    ("args", "error"),
    [
        ((float("nan"), 0.0, 0.0), optik.NonFiniteError),
        ((0.0, float("inf"), 0.0), optik.NonFiniteError),
        ((0.0, 0.0, "x"), optik.InvalidArgumentError),
        ((0.0, 0.0, [1.0, 2.0]), optik.InvalidArgumentError),
    ],
)
def test_pose2d_errors(args: tuple, error: type) -> None:
    with pytest.raises(error) as info:
        optik.Pose2D(*args)
    assert info.value.argument == "Pose2D"


def test_make_result_limits_and_nan() -> None:
    m = optik.catalog.planar_3r()
    req = make_request(m, m.fk(m.mid_q()))
    far = m.upper + 0.5  # outside: clipped into the limits (wrapped first where angular)
    res = make_result(req, far, "test", 0, errors=lambda qq: (0.0, 0.0, 0.0))
    assert res.limits_ok and res.success
    assert np.all(res.q >= m.lower) and np.all(res.q <= m.upper)
    with pytest.raises(optik.NonFiniteError):
        make_result(req, np.array([np.nan, 0.0, 0.0]), "test", 0)


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda m: optik.solve_ik(m, "abc"), "target"),
        (lambda m: optik.closed_form.ik(m, "abc"), "target"),
        (lambda m: m.fk("ab"), "q"),
        (lambda m: m.fk(np.array([1j, 1.0, 1.0])), "q"),
        (lambda m: m.fk([[1.0, 2.0], [3.0]]), "q"),
        (lambda m: optik.solve_ik(m, optik.Pose2D(1.0, 0.5, 0.0), q0=[1, "a", 2]), "q0"),
        (lambda m: optik.solve_ik(m, optik.Pose2D(1.0, 0.5, 0.0), seed=-1), "seed"),
        (lambda m: optik.solve_ik(m, optik.Pose2D(1.0, 0.5, 0.0), seed=1.5), "seed"),
        (lambda m: optik.solve_ik(m, optik.Pose2D(1.0, 0.5, 0.0), seed=True), "seed"),
    ],
)
def test_non_real_input_and_bad_seeds_raise_named_errors(call, argument) -> None:
    m = optik.catalog.planar_3r()
    with pytest.raises(optik.InvalidArgumentError) as info:
        call(m)
    assert info.value.argument == argument
    assert str(info.value).startswith(f"{argument}:")


@pytest.mark.parametrize("flag", ["no", "False", 0, 1, None, [True]])
def test_boolean_options_accept_booleans_only(flag: object) -> None:
    """``as_bool`` and the public boolean options that use it: a string, a number or None is
    an error naming the option, not a truthy or falsy guess (issue 18, item 10)."""
    with pytest.raises(optik.OptikError, match=r"^flag"):
        as_bool(flag, "flag")
    m = optik.catalog.planar_2r()
    with pytest.raises(optik.OptikError, match=r"^progress"):
        optik.solve_ik_batch(m, [optik.Position(1.0, 0.5)], progress=flag)
    with pytest.raises(optik.OptikError, match=r"^progress"):
        optik.reach(m, resolution=0.5, progress=flag)
    urdf = Path(optik.__file__).parent / "data" / "urdf" / "iiwa14.urdf"
    with pytest.raises(optik.OptikError, match=r"^floating_base"):
        optik.Mechanism.from_urdf(urdf, floating_base=flag)
    assert as_bool(True, "flag") is True and as_bool(np.bool_(False), "flag") is False


def test_check_seed_takes_what_as_rng_takes():
    """`check_seed` (which `make_request` calls, without making a generator) accepts and refuses
    the seeds `as_rng` accepts and refuses."""
    from optik.checks import as_rng, check_seed
    from optik.errors import InvalidArgumentError

    for good in (None, 0, 7, np.int64(3), np.random.default_rng(1)):
        check_seed(good)
        as_rng(good)
    for bad in (-1, 1.5, True, "3", [1]):
        with pytest.raises(InvalidArgumentError, match="seed"):
            check_seed(bad)
        with pytest.raises(InvalidArgumentError, match="seed"):
            as_rng(bad)


@pytest.mark.parametrize("name", ["panda", "planar_3r", "rp_arm", "puma560", "stewart_gough"])
def test_canonical_coordinates_are_their_own_wrap(name) -> None:
    """`is_canonical` (the fast path of `make_result` and of lm's prepared call) only where
    `Mechanism.wrap` returns ``q`` as it is within the limits; on each mechanism and on a copy
    whose finite limits span more than a turn, at draws around the limits, the limits themselves
    and +-pi, rotation vectors scaled beyond a half-turn."""
    from optik.solvers.base import is_canonical

    rng = np.random.default_rng(11)
    base = getattr(optik.catalog, name)()
    lo, hi = base.sampling_bounds
    finite = np.isfinite(base.lower) & np.isfinite(base.upper)
    wide = base.with_limits(
        np.where(finite, base.lower - 2.0, base.lower), np.where(finite, base.upper + 2.0, base.upper)
    )
    kept = 0
    for m in (base, wide):
        rows = rng.uniform(lo - 0.5, hi + 0.5, size=(3000, m.n_q))
        rows[::7] = np.where(rng.random((len(rows[::7]), m.n_q)) < 0.5, m.lower, m.upper)
        rows[1::7] = rng.choice(
            [-np.pi, np.pi, np.nextafter(np.pi, 0), -np.nextafter(np.pi, 0)], size=rows[1::7].shape
        )
        for sl in m.spherical_slices:
            rows[2::7, sl] *= rng.uniform(0.5, 4.0, size=(len(rows[2::7]), 1))
        for q in np.where(np.isfinite(rows), rows, 0.0):
            if is_canonical(m, q.tolist()):
                kept += 1
                assert m.within_limits(q), q
                np.testing.assert_array_equal(m.wrap(q), q)
    assert kept > 100


def test_panda_joint_6_beyond_pi_is_canonical() -> None:
    """The Panda's joint 6 (limits -0.0175 .. 3.7525) spans less than a turn: a value beyond pi
    within it is its own wrap, so `make_result` keeps it without wrapping (the same answer)."""
    from optik.solvers.base import is_canonical

    m = optik.catalog.panda()
    q = m.mid_q()
    q[5] = 3.5
    assert is_canonical(m, q.tolist())
    np.testing.assert_array_equal(m.wrap(q), q)
    res = make_result(make_request(m, m.fk(q)), q, "test", 1)
    assert res.success and res.limits_ok
    np.testing.assert_array_equal(res.q, q)
    q[5] = 3.7525 + 1e-6  # outside its limits: not canonical (clipped by make_result)
    assert not is_canonical(m, q.tolist())
