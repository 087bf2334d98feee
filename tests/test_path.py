"""`optik.plan_path` (issue 24): the least-motion joint path over every IK solution.

The optimum is checked against brute force (every sequence of solutions enumerated), the
relaxation of wrapping joints against the graph of every turn, and every answer by an
independent FK per sample, the limits and the velocities recomputed from ``q`` and ``t``.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik.path import graph, redundant, samples
from optik.path.nodes import into_limits, turn_copies


def _robot(name):
    try:
        return optik.catalog.robot(name)
    except optik.MissingExtraError as exc:
        pytest.skip(f"the UR5 comes from the robots extra: {exc}")


@pytest.fixture(scope="module")
def ur5():
    return _robot("ur5")


@pytest.fixture(scope="module")
def ur5_limited():
    return _robot("ur5_limited")


@pytest.fixture(scope="module")
def puma():
    return optik.catalog.puma560()


Q0 = {"puma560": np.array([0.3, 0.5, -1.0, 0.4, 0.8, 0.2]), "ur5": np.array([0.3, -1.1, 1.2, -0.6, 0.8, 0.2])}


def line(m, n=200, d=(0.05, 0.03, -0.02)):
    """Poses along a straight line from ``fk(q0)``, orientation fixed."""
    poses = np.repeat(m.fk(Q0.get(m.name, Q0["ur5"]))[None], n, axis=0)
    poses[:, :3, 3] += np.linspace(0.0, 1.0, n)[:, None] * np.asarray(d)
    return poses


def length(q, w=None):
    w = np.ones(q.shape[1]) if w is None else w
    return float(np.linalg.norm(np.diff(q, axis=0) * w, axis=1).sum())


def brute_force(layers, w, bounds=None):
    """The least cost over every sequence of nodes (enumerated)."""
    best = np.inf
    for pick in itertools.product(*[range(len(layer)) for layer in layers]):
        q = np.stack([layer[i] for layer, i in zip(layers, pick, strict=True)])
        if bounds is not None and np.any(np.abs(np.diff(q, axis=0)) > bounds):
            continue
        best = min(best, length(q, w))
    return best


def independent_checks(m, path, poses, tol=1e-6):
    """FK of every sample by ``m.fk`` (one call each), the limits exactly."""
    for q, t in zip(path.q, poses, strict=True):
        f = m.fk(q)
        assert np.linalg.norm(f[:3, 3] - t[:3, 3]) <= tol
        assert optik.spatial.angle_between(f[:3, :3], t[:3, :3]) <= tol
    assert np.all(path.q >= m.lower) and np.all(path.q <= m.upper)


@settings(max_examples=40)
@given(
    st.integers(2, 4), st.integers(1, 4), st.integers(0, 10_000), st.booleans(), st.booleans(), st.booleans()
)
def test_dynamic_program_is_the_brute_force_optimum(n_layers, width, seed, bounded, periodic, cut):
    rng = np.random.default_rng(seed)
    layers = [rng.uniform(-4, 4, (int(rng.integers(1, width + 1)), 3)) for _ in range(n_layers)]
    w = rng.uniform(0.2, 2.0, 3)
    bounds = np.full((n_layers - 1, 3), 4.0) if bounded else None
    periods = np.array([2 * np.pi, 0.0, 2 * np.pi]) if periodic else np.zeros(3)
    every = [
        (k, a, b)
        for k in range(1, n_layers)
        for a in range(len(layers[k - 1]))
        for b in range(len(layers[k]))
    ]
    removed = np.array([e for e in every if rng.random() < 0.4] if cut else [], dtype=int).reshape(-1, 3)
    got_c = graph.least_motion(layers, w, bounds, periods, removed)
    got_np = graph.least_motion_numpy(layers, w, bounds, periods, removed)
    gone = {tuple(e) for e in removed.tolist()}
    want = np.inf  # the brute force over the wrapped differences and the edges left
    for pick in itertools.product(*[range(len(layer)) for layer in layers]):
        if any((k, pick[k - 1], pick[k]) in gone for k in range(1, n_layers)):
            continue
        q = np.stack([layer[i] for layer, i in zip(layers, pick, strict=True)])
        d = graph.differences(q[:-1], q[1:], periods)
        if bounds is None or np.all(np.abs(d) <= bounds):
            want = min(want, float(np.linalg.norm(d * w, axis=1).sum()))
    if not periodic and not cut:
        assert brute_force(layers, w, bounds) == pytest.approx(want, abs=1e-12)
    for got in (got_c, got_np):
        if np.isinf(want):
            assert got.blocked >= 1 and np.isinf(got.cost)
            continue
        assert got.blocked == -1
        assert got.cost == pytest.approx(want, abs=1e-9)
        q = np.stack([layer[i] for layer, i in zip(layers, got.index, strict=True)])
        d = graph.differences(q[:-1], q[1:], periods)
        assert float(np.linalg.norm(d * w, axis=1).sum()) == pytest.approx(got.cost, abs=1e-9)
        assert not any((k, got.index[k - 1], got.index[k]) in gone for k in range(1, n_layers))


@pytest.mark.parametrize("seed", range(40))
def test_periodic_key_many_turns_out_equals_numpy(seed):
    """The joint the C kernel scans by is periodic and its values lie several turns apart
    (raw angles in [-15, 15] rad, where the order of the values is not the order around the
    circle): the kernel's optimum costs what numpy's full edge matrices give."""
    rng = np.random.default_rng(seed)
    layers = [rng.uniform(-15.0, 15.0, (int(rng.integers(2, 10)), 2)) * [1.0, 0.01] for _ in range(4)]
    w, periods = np.array([1.0, 0.1]), np.array([2 * np.pi, 0.0])
    assert graph._key_joint(layers, w) == 0
    got = graph.least_motion(layers, w, None, periods)
    want = graph.least_motion_numpy(layers, w, None, periods)
    assert got.blocked == want.blocked == -1
    assert got.cost == pytest.approx(want.cost, abs=1e-9)


@pytest.mark.parametrize("seed", range(6))
def test_compiled_dynamic_program_equals_numpy_on_wide_layers(seed):
    """Wide layers listing their nodes mostly in the same order with small moves (the first bound
    is the node of the same index), sometimes reordered, some nodes past the previous layer's
    count, periodic joints, step bounds and removed edges: the C kernel's optimum costs what
    numpy's full edge matrices give."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(-3.0, 3.0, (40, 4))
    layers = []
    for _ in range(25):
        base = base + rng.normal(0.0, 0.05, base.shape)
        if rng.random() < 0.3:  # the order changes: the same index is another node
            base = base[rng.permutation(len(base))]
        layers.append(base[: int(rng.integers(30, 41))].copy())
    w = rng.uniform(0.2, 2.0, 4)
    periods = np.array([2 * np.pi, 0.0, 2 * np.pi, 0.0]) if seed % 2 else np.zeros(4)
    bounds = np.full((len(layers) - 1, 4), 0.4) if seed % 3 == 0 else None
    removed = np.array([(k, i, i) for k in range(1, len(layers)) for i in range(0, 30, 3)], dtype=int)
    for cut in (None, removed):
        got = graph.least_motion(layers, w, bounds, periods, cut)
        want = graph.least_motion_numpy(layers, w, bounds, periods, cut)
        assert got.blocked == want.blocked
        assert got.cost == pytest.approx(want.cost, abs=1e-9)
        if got.blocked == -1:
            q = np.stack([layer[i] for layer, i in zip(layers, got.index, strict=True)])
            d = graph.differences(q[:-1], q[1:], periods)
            assert float(np.linalg.norm(d * w, axis=1).sum()) == pytest.approx(got.cost, abs=1e-9)
            if cut is not None:
                assert not {tuple(e) for e in cut.tolist()} & {
                    (k, int(got.index[k - 1]), int(got.index[k])) for k in range(1, len(layers))
                }


def _fits(q, lo, hi, angle, margin):
    """Whether some whole-turn shift of ``q`` (any when ``angle``) lies in ``[lo + margin, hi - margin]``."""
    if not angle:
        return lo + margin <= q <= hi - margin
    x = q + 2.0 * np.pi * np.ceil((lo + margin - q) / (2.0 * np.pi))
    return x <= hi - margin


@settings(max_examples=60)
@given(
    q=st.lists(st.floats(-12.0, 12.0), min_size=4, max_size=4),
    lo=st.lists(st.floats(-7.0, 1.0), min_size=4, max_size=4),
    width=st.lists(st.floats(0.3, 9.0), min_size=4, max_size=4),
)
def test_into_limits_shifts_angles_by_whole_turns_or_drops_the_row(q, lo, width):
    q, lo = np.array(q), np.array(lo)
    hi, angles = lo + np.array(width), np.array([True, True, True, False])
    out = into_limits(np.stack([q, q]), lo, hi, angles)  # rows stay independent
    assert out.shape == (2, 4) and np.array_equal(out[0], out[1], equal_nan=True)
    row = out[0]
    if np.isfinite(row).all():
        assert np.all((row >= lo) & (row <= hi)) and row[3] == q[3]
        turns = (row[:3] - q[:3]) / (2.0 * np.pi)
        assert np.allclose(turns, np.round(turns), atol=1e-9)
    else:
        assert np.isnan(row).all()
        assert not all(_fits(*a, margin=1e-9) for a in zip(q, lo, hi, angles, strict=True))


def test_far_apart_poses_brute_force_over_every_solution(ur5_limited):
    m = ur5_limited
    rng = np.random.default_rng(3)
    poses = optik.fk_batch(m, rng.uniform(m.lower, m.upper, (4, 6)))
    w = np.array([2.0, 2.0, 1.5, 1.0, 1.0, 0.5])
    path = optik.plan_path(m, poses, weights=w, max_flips=None)
    assert path.success, path.message
    layers = [optik.solve_ik_all(m, t).q for t in poses]
    layers = [turn_copies(x, m.lower, m.upper, m.revolute_mask)[0] for x in layers]
    assert length(path.q, w) == pytest.approx(brute_force(layers, w), abs=1e-9)
    assert path.cost == pytest.approx(length(path.q, w), abs=1e-9)
    independent_checks(m, path, poses)


def test_relaxed_turns_equal_the_graph_of_every_turn(ur5):
    """UR5 joints span +-2 pi: the plan on representatives modulo 2 pi, its turns counted, has
    the optimum of the graph of every turn (up to 32 copies of each solution)."""
    m = ur5
    rng = np.random.default_rng(5)
    q = rng.uniform(-np.pi, np.pi, (6, 6))
    poses = optik.fk_batch(m, q)
    path = optik.plan_path(m, poses, max_flips=None)
    assert path.success, path.message
    layers = [turn_copies(optik.solve_ik_all(m, t).q, m.lower, m.upper, m.revolute_mask)[0] for t in poses]
    full = graph.least_motion(layers, np.ones(6))
    assert length(path.q) == pytest.approx(full.cost, abs=1e-9)
    independent_checks(m, path, poses)


@pytest.mark.parametrize("arm", ["puma", "ur5", "ur5_limited"])
def test_line_no_branch_change_fk_round_trip(arm, request):
    m = request.getfixturevalue(arm)
    poses = line(m)
    path = optik.plan_path(m, poses, velocity=np.full(6, 1.0))
    assert path.success, path.message
    assert path.flips == 0 and np.all(path.branch == 0)
    assert set(path.checks) == {"fk", "limits", "velocity", "branch"}
    independent_checks(m, path, poses)
    # a continuous path: no joint jumps between neighbouring samples
    assert np.abs(np.diff(path.q, axis=0)).max() < 0.05
    seg = np.abs(np.diff(path.q, axis=0)) / np.diff(path.t)[:, None]
    assert np.all(seg <= 1.0 + 1e-9) and np.all(np.abs(path.qd) <= 1.0 + 1e-9)
    # the nearest solution of each pose, stepped from the start, is no shorter
    step = [path.q[0]]
    for t in poses[1:]:
        sols = optik.solve_ik_all(m, t).q
        step.append(sols[np.argmin(np.linalg.norm(sols - step[-1], axis=1))])
    assert path.cost <= length(np.array(step)) + 1e-9


def test_circle_about_the_base_turns_past_pi(ur5):
    """A base rotation of 1.3 turns: the path of a UR5 (+-2 pi) sweeps joint 1 continuously."""
    m = ur5
    angles = np.linspace(0.0, 1.3 * 2 * np.pi, 300)
    q = np.tile(np.array([0.0, -1.2, 1.4, -0.5, 1.2, 0.3]), (300, 1))
    q[:, 0] = angles - np.pi
    poses = optik.fk_batch(m, q)
    path = optik.plan_path(m, poses)
    assert path.success, path.message
    assert np.ptp(path.q[:, 0]) == pytest.approx(1.3 * 2 * np.pi, abs=1e-6)
    assert np.abs(np.diff(path.q, axis=0)).max() < 0.05
    independent_checks(m, path, poses)
    tight = m.with_limits(lower=np.r_[-4.0, m.lower[1:]], upper=np.r_[4.0, m.upper[1:]])
    q[:, 0] = angles - 4.0  # within the limits at every sample, but 8.2 rad of sweep
    blocked = optik.plan_path(tight, optik.fk_batch(tight, q))
    # the relaxed optimum does not fit: over every turn, the only way is another branch
    assert "planned over every turn" in blocked.message
    assert not blocked.success and blocked.flips >= 1 and blocked.checks["branch"] is False
    assert blocked.checks["limits"] and blocked.checks["fk"]


def test_given_times_remove_fast_edges_and_none_stretch(puma):
    m = puma
    poses = line(m, n=100)
    ok = optik.plan_path(m, poses, times=np.linspace(0, 10, 100), velocity=np.full(6, 1.0))
    assert ok.success and ok.checks["velocity"]
    fast = optik.plan_path(m, poses, times=np.linspace(0, 1e-3, 100), velocity=np.full(6, 1.0))
    assert not fast.success and "velocity limits" in fast.message and "pose 1" in fast.message
    slow = optik.plan_path(m, poses, velocity=np.full(6, 0.01), speed=0.5)
    assert slow.success and slow.stretched > 0 and f"{slow.stretched} segments stretched" in slow.message
    seg = np.abs(np.diff(slow.q, axis=0)) / np.diff(slow.t)[:, None]
    assert np.all(seg <= 0.01 * (1 + 1e-9))
    # the nominal time of a segment at the tool speed, or longer
    travel = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    assert np.all(np.diff(slow.t) >= travel / 0.5 - 1e-12)
    acc = optik.plan_path(m, poses, velocity=np.full(6, 1.0), acceleration=np.full(6, 1e-6))
    assert not acc.success and acc.checks["acceleration"] is False and "acceleration" in acc.message


def test_unreachable_pose_is_a_failure_naming_it(puma):
    poses = line(puma, n=20)
    poses[7, :3, 3] += 10.0
    path = optik.plan_path(puma, poses)
    assert not path.success and "pose 7" in path.message and path.q.shape == (0, 6)


def test_bad_input_names_the_argument(puma):
    poses = line(puma, n=5)
    cases = [
        ({"poses": poses[:, :3]}, "poses"),
        ({"poses": poses, "times": [0, 1, 1, 2, 3]}, "times"),
        ({"poses": poses, "times": [0, 1, 2]}, "times"),
        ({"poses": poses, "weights": [-1, 1, 1, 1, 1, 1]}, "weights"),
        ({"poses": poses, "velocity": [0, 1, 1, 1, 1, 1]}, "velocity"),
        ({"poses": poses, "speed": -1.0}, "speed"),
    ]
    for kwargs, name in cases:
        with pytest.raises(optik.InvalidArgumentError) as err:
            optik.plan_path(puma, **kwargs)
        assert err.value.argument == name
    bad = poses.copy()
    bad[2, 0, 0] = np.nan
    with pytest.raises(optik.NonFiniteError, match=r"poses\[2\]"):
        optik.plan_path(puma, bad)
    with pytest.raises(optik.SolverUnavailableError):
        optik.plan_path(optik.catalog.panda(), np.eye(4)[None])


def test_world_drops_colliding_solutions(ur5_limited):
    pytest.importorskip("coal", reason="collision queries need coal (the collision extra)")
    m = ur5_limited
    poses = line(m, n=50)
    free = optik.plan_path(m, poses)
    ball = optik.World()
    ball.add_sphere("ball", 0.08, optik.spatial.translation(*m.fk(free.q[25], "forearm_link")[:3, 3]))
    path = optik.plan_path(m, poses, world=ball)
    assert path.success and path.checks["collision"], path.message
    assert "colliding configurations dropped" in path.message
    hits = [optik.collision.check(m, q, world=ball).in_collision for q in path.q]
    assert not any(hits)
    assert any(optik.collision.check(m, q, world=ball).in_collision for q in free.q)
    independent_checks(m, path, poses)


def test_world_removes_edges_colliding_between_samples(ur5_limited):
    """A ball in the sweep of the free optimum's single segment (the base turning 1.5 rad), at
    the elbow halfway: no solution of either pose touches it, so only the edge collides; the
    plan removes it and takes another branch whose sweep is clear, checked here independently
    at 400 configurations along the segment."""
    pytest.importorskip("coal", reason="collision queries need coal (the collision extra)")
    m = ur5_limited
    qa = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    poses = optik.fk_batch(m, np.array([qa, qa + np.array([1.5, 0, 0, 0, 0, 0])]))
    free = optik.plan_path(m, poses, max_flips=None)
    ball = optik.World()
    ball.add_sphere(
        "ball", 0.03, optik.spatial.translation(*m.fk(free.q.mean(axis=0), "forearm_link")[:3, 3])
    )
    for t in poses:
        assert not optik.collision.check_many(m, optik.solve_ik_all(m, t).q, world=ball).in_collision.any()

    def sweep_hits(q):
        s = np.linspace(0.0, 1.0, 400)[:, None]
        return optik.collision.check_many(m, q[0] + s * (q[1] - q[0]), world=ball).in_collision

    assert sweep_hits(free.q).any()
    path = optik.plan_path(m, poses, max_flips=None, world=ball)
    assert path.success and path.checks["collision"], path.message
    assert "edges colliding between their samples removed" in path.message
    assert not sweep_hits(path.q).any()
    assert np.abs(path.q - free.q).max() > 1.0  # another branch
    assert path.cost == pytest.approx(free.cost, abs=1e-9)  # as short: the free optimum's length
    independent_checks(m, path, poses)


def test_free_axis_absorbs_a_tool_spin(ur5_limited):
    """The poses spin back and forth about the tool axis: with ``free_axis="z"`` the path need
    not follow the spin, so it is shorter, and every sample still has the tool axis and point."""
    m = ur5_limited
    poses = line(m, n=120)
    spin = 0.6 * np.sin(np.linspace(0, 6 * np.pi, 120))
    poses[:, :3, :3] = poses[:, :3, :3] @ np.stack([optik.spatial.rot_z(a) for a in spin])
    fixed = optik.plan_path(m, poses)
    free = optik.plan_path(m, poses, free_axis="z", axis_step=np.pi / 18)
    assert fixed.success and free.success, free.message
    assert free.cost < 0.5 * fixed.cost
    assert free.flips == 0
    for q, t in zip(free.q, poses, strict=True):  # the tool point and axis, by one FK each
        f = m.fk(q)
        assert np.linalg.norm(f[:3, 3] - t[:3, 3]) <= 1e-6
        assert np.arccos(np.clip(f[:3, 2] @ t[:3, 2], -1, 1)) <= 1e-6
    assert np.all(free.q >= m.lower) and np.all(free.q <= m.upper)


def test_axis_shortcut_equals_one_ik_per_sample(ur5, puma):
    """Turning the last joint is the tool's z spin for both arms: the solutions so obtained are
    those of the IK of every sampled pose."""
    for m in (ur5, puma):
        assert samples.axis_joint(m, "z", None) is not None
        assert samples.axis_joint(m, "x", None) is None
        poses = line(m, n=3)
        sp = samples.sample_poses(poses, "z", np.pi / 4, None)
        quick, qg = samples.sample_solutions(m, sp, None, samples.axis_joint(m, "z", None))
        slow, sg = samples.sample_solutions(m, sp, None, None)
        per = graph.differences  # compare modulo 2 pi on the wrapping joints
        periods = optik.path.nodes.wrapping(m)
        for a, ga, b, gb in zip(quick, qg, slow, sg, strict=True):
            assert len(a) == len(b)
            for g in np.unique(gb):
                x, y = a[ga == g], b[gb == g]
                d = np.abs(per(x[:, None], y[None], periods)).max(axis=-1)
                assert d.min(axis=1).max() < 1e-9 and d.min(axis=0).max() < 1e-9


@pytest.mark.parametrize("arm", ["ur5", "ur5_limited", "puma560", "panda"])
def test_turned_angles_are_into_limits_to_a_rounding(arm, request):
    """The axis-joint copies (one 2 pi step, the rest through into_limits) are into_limits' values
    to a rounding, within the limits, the same angle modulo 2 pi; a value into_limits drops is
    kept only when it lies on a limit (into_limits' wrap can round it just past it)."""
    m = request.getfixturevalue(arm) if arm.startswith("ur5") else getattr(optik.catalog, arm)()
    rng = np.random.default_rng(3)
    for j in range(m.n_q):
        lo, hi = max(m.lower[j], -10.0), min(m.upper[j], 10.0)
        q = np.concatenate([rng.uniform(lo, hi, 400), [lo, hi, 0.0, np.pi, -np.pi]])
        q = q[(q >= m.lower[j]) & (q <= m.upper[j])]
        for turn in (np.arange(36) * np.pi / 18, -np.arange(12) * np.pi / 6):
            got = samples._turned(m, q[:, None], turn[None], j)
            want = into_limits((q[:, None] + turn)[..., None], m.lower[j : j + 1], m.upper[j : j + 1],
                               np.ones(1, dtype=bool))[..., 0]  # fmt: skip
            both = np.isfinite(got) & np.isfinite(want)
            assert np.abs(got - want)[both].max(initial=0.0) <= 1e-15
            assert not np.any(np.isfinite(want) & ~np.isfinite(got))
            extra = got[np.isfinite(got) & ~np.isfinite(want)]
            assert np.all((extra == m.lower[j]) | (extra == m.upper[j]))
            fin = got[np.isfinite(got)]
            assert np.all((fin >= m.lower[j]) & (fin <= m.upper[j]))
            step = (got - q[:, None] - turn) / (2 * np.pi)
            assert np.abs(step - np.round(step))[np.isfinite(got)].max(initial=0.0) <= 1e-14


def test_uniform_layers_equal_the_general_gather(ur5):
    """The broadcast built when every pose has as many solutions is the general gather's answer."""
    m = ur5
    sp = samples.sample_poses(line(m, n=5), "z", np.pi / 6, np.full(5, 0.001))
    shortcut = samples.axis_joint(m, "z", None)
    units = 7
    solved, counts = optik.path.nodes.closed_form_solutions(m, sp.columns(units).reshape(-1, 4, 4), None)
    unit = np.repeat(np.arange(5 * units) % units, counts)
    block = counts.reshape(5, units).sum(axis=1)
    assert np.all(block == block[0])
    turn = sp.angle[0, ::units] - sp.angle[0, 0]
    fast = samples._uniform(m, solved, unit, 5, int(block[0]), 12, units, shortcut, turn)
    slow = samples._gathered(m, solved, unit, block, 12, units, shortcut, turn)
    for a, b in zip(fast, slow, strict=True):
        np.testing.assert_array_equal(a.offset, b.offset)
        np.testing.assert_array_equal(a.data, b.data)
    assert samples.sample_solutions(m, sp, None, shortcut)[0].data.shape == fast[0].data.shape


def test_free_axis_optimum_over_the_sampled_graph(ur5_limited):
    m = ur5_limited
    rng = np.random.default_rng(11)
    poses = optik.fk_batch(m, rng.uniform(-2, 2, (3, 6)))
    path = optik.plan_path(m, poses, free_axis="z", axis_step=np.pi / 3, max_flips=None)
    assert path.success, path.message
    sp = samples.sample_poses(poses, "z", np.pi / 3, None)
    layers, _ = samples.sample_solutions(m, sp, None, None)
    want = graph.least_motion_numpy(layers, np.ones(6), None, np.zeros(6))
    assert path.cost == pytest.approx(want.cost, abs=1e-9)
    for q, t, a in zip(path.q, poses, path.axis_angle, strict=True):  # the reported turn
        assert np.abs(m.fk(q)[:3, :3] - t[:3, :3] @ optik.spatial.rot_z(a)).max() < 1e-9


def test_position_tolerance_widens_the_graph(puma):
    m = puma
    poses = line(m, n=60)
    poses[::2, :3, 3] += [0.0, 0.0, 0.004]  # a 4 mm ripple
    exact = optik.plan_path(m, poses)
    loose = optik.plan_path(m, poses, position_tolerance=0.004)
    assert exact.success and loose.success, loose.message
    assert loose.cost < exact.cost
    tips = optik.fk_batch(m, loose.q)[:, :3, 3]
    assert np.all(np.linalg.norm(tips - poses[:, :3, 3], axis=1) <= 0.004 + 1e-6)
    with pytest.raises(optik.InvalidArgumentError, match="position_tolerance"):
        optik.plan_path(m, poses, position_tolerance=-1.0)
    with pytest.raises(optik.InvalidArgumentError, match="free_axis"):
        optik.plan_path(m, poses, free_axis="w")


def test_densification_keeps_the_tool_near_the_segments(puma):
    m = puma
    poses = line(m, n=200, d=(0.0, 0.2, 0.0))[::40]  # 5 samples 4 cm apart
    loose = optik.plan_path(m, poses)
    assert loose.deviation.max() > 1e-4
    dense = optik.plan_path(m, poses, max_deviation=1e-4)
    assert dense.success and dense.checks["deviation"], dense.message
    assert len(dense) > len(poses) and "samples inserted" in dense.message
    for t in poses:  # the poses asked for are all still samples
        assert np.min(np.abs(dense.poses - t).reshape(len(dense), -1).max(axis=1)) < 1e-12
    mid = 0.5 * (dense.q[:-1] + dense.q[1:])  # independent: the tool at each joint midpoint
    tips, p = optik.fk_batch(m, mid)[:, :3, 3], dense.poses[:, :3, 3]
    ab = p[1:] - p[:-1]
    s = np.clip(np.einsum("ij,ij->i", tips - p[:-1], ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    assert np.linalg.norm(tips - (p[:-1] + s[:, None] * ab), axis=1).max() <= 1e-4
    independent_checks(m, dense, dense.poses)


PANDA_Q0 = np.array([0.1, -0.3, 0.2, -2.0, 0.1, 1.8, 0.6])


@pytest.fixture(scope="module")
def panda_line():
    m = optik.catalog.panda()
    poses = np.repeat(m.fk(PANDA_Q0)[None], 60, axis=0)
    poses[:, :3, 3] += np.linspace(0.0, 1.0, 60)[:, None] * [0.0, 0.2, 0.0]
    return m, poses


def test_redundant_arm_over_self_motion_samples(panda_line):
    m, poses = panda_line
    values = np.linspace(-2.8, 2.8, 15)
    path = optik.plan_path(m, poses, self_motion=("q7", values))
    assert path.success and path.flips == 0, path.message
    assert np.all(np.isin(path.q[:, 6], values))  # every sample on a sampled self-motion value
    independent_checks(m, path, poses)
    layers, _ = samples.sample_solutions(
        m, samples.sample_poses(poses, None, 1.0, None), None, None, (6, values)
    )
    want = graph.least_motion_numpy(layers, np.ones(7), None, optik.path.nodes.wrapping(m))
    assert path.cost == pytest.approx(want.cost, abs=1e-9)
    smooth = optik.plan_path(m, poses, self_motion=("q7", values), smooth=True)
    assert smooth.success and "refined from" in smooth.message, smooth.message
    assert smooth.cost < path.cost
    assert smooth.cost == pytest.approx(length(smooth.q), abs=1e-9)
    independent_checks(m, smooth, poses)


def test_self_motion_solutions_by_pose_and_value(panda_line):
    """Every row solves its pose with q7 at its value, within the limits; rows are ordered by pose,
    then value, and the sampled layers hold each path sample's rows with their groups."""
    m, poses = panda_line
    values = np.array([-2.0, 0.5, 1.5])
    q, pose, tag = redundant.self_motion_solutions(m, poses[:5], 6, values)
    assert len(q) > 5 and np.all(np.diff(pose) >= 0) and set(pose) == set(range(5))
    assert np.all(np.diff(tag)[np.diff(pose) == 0] >= 0)
    assert np.array_equal(q[:, 6], values[tag]) and np.all((q >= m.lower) & (q <= m.upper))
    f = optik.fk_batch(m, q)
    assert np.abs(f - poses[pose]).max() < 1e-9
    sampled = samples.sample_poses(poses[:5], None, 1.0, None)
    layers, groups = samples.sample_solutions(m, sampled, None, None, (6, values))
    assert np.array_equal(layers.data, q) and np.array_equal(groups.data, tag)
    assert np.array_equal(layers.sizes, np.bincount(pose, minlength=5))


def test_refinement_nlp_is_cached_with_the_poses_as_parameters(panda_line):
    """A second path of the same length reuses the built NLP and meets its own poses (not the
    first path's: the poses are parameters, not constants of the build)."""
    m, poses = panda_line
    values = np.linspace(-2.8, 2.8, 15)
    first = optik.plan_path(m, poses, self_motion=("q7", values), smooth=True)
    built = optik.path.redundant.refiner(m, None, len(poses), 1e-6)
    shifted = poses.copy()
    shifted[:, :3, 3] += [0.0, 0.0, -0.05]
    second = optik.plan_path(m, shifted, self_motion=("q7", values), smooth=True)
    assert optik.path.redundant.refiner(m, None, len(poses), 1e-6) is built
    for path, want in ((first, poses), (second, shifted)):
        assert path.success and "refined from" in path.message, path.message
        independent_checks(m, path, want)


def test_redundant_arm_bad_input(panda_line):
    m, poses = panda_line
    for value in [("q9", [0.0]), ("q7", [5.0]), "q7"]:
        with pytest.raises(optik.InvalidArgumentError) as err:
            optik.plan_path(m, poses[:3], self_motion=value)
        assert err.value.argument == "self_motion"
    with pytest.raises(optik.SolverUnavailableError, match="q1"):
        optik.plan_path(m, poses[:3], self_motion=("q1", [0.0]))
    with pytest.raises(optik.InvalidArgumentError, match="smooth"):
        optik.plan_path(m, poses[:3], self_motion=("q7", [0.6]), free_axis="z", smooth=True)


def test_redundant_spin_that_diffik_track_cannot_follow():
    """A tool spin of 1.6 rad from q7 = 1.5: tracking turns q7 into its limit (2.90) and loses
    the pose; the plan over the self-motion finds an exact path within the limits."""
    m = optik.catalog.panda()
    q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 1.5])
    poses = np.repeat(m.fk(q0)[None], 150, axis=0)
    poses[:, :3, :3] = poses[0, :3, :3] @ np.asarray(optik.spatial.rot_z(np.linspace(0.0, 1.6, 150)))
    tracked = optik.diffik.track(m, q0, poses[1:], 0.01)
    assert tracked.position_error.max() > 0.01
    path = optik.plan_path(m, poses, self_motion=("q7", np.linspace(-2.85, 2.85, 39)), smooth=True)
    assert path.success and path.flips == 0, path.message
    independent_checks(m, path, poses)
