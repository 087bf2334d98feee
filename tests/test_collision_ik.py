"""Collision-aware IK (optik.solvers.collision_free): lm and nlp avoid the world and themselves, and
every success passes an exact check recomputed here from q."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik import spatial
from optik.collision import World, check
from optik.errors import InvalidArgumentError, SolverUnavailableError

pytest.importorskip("coal", reason="collision checks need coal (extra 'collision')")

MARGIN = 0.01


@pytest.fixture(scope="module")
def arm(toy_arm_urdf) -> optik.Mechanism:
    return optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip")


def _branches(arm):
    """Two elbow branches of one tip position (equal link lengths: ``(a + b, -b)`` mirrors ``(a, b)``)."""
    qa = np.array([0.3, 1.2])
    qb = np.array([1.5, -1.2])
    assert np.allclose(arm.fk(qa)[:3, 3], arm.fk(qb)[:3, 3], atol=1e-12)
    return qa, qb


def _blocking_world(arm, qa):
    """A ball on branch ``qa``'s elbow: that branch collides, the other is clear."""
    w = World()
    w.add_sphere("ball", 0.05, spatial.translation(*arm.fk(qa, "fore")[:3, 3]))
    return w


def _independent(arm, res, target, w):
    """Recompute from q: FK position, limits, and the exact distance at the margin."""
    assert np.linalg.norm(arm.fk(res.q)[:3, 3] - target) <= 1e-6
    assert np.all(res.q >= arm.lower) and np.all(res.q <= arm.upper)
    r = check(arm, res.q, w, margin=MARGIN)
    assert not r.in_collision and r.min_distance >= MARGIN
    assert res.min_distance == pytest.approx(r.min_distance, abs=1e-12)


@pytest.mark.parametrize(("method", "options"), [("lm", {}), ("lm", {"plain_rounds": 1}), ("nlp", {})])
def test_avoids_an_obstacle_on_the_nearest_branch(arm, method, options):
    """With ``plain_rounds=1`` the constrained lm kernel starts from the first, colliding answer."""
    qa, qb = _branches(arm)
    w = _blocking_world(arm, qa)
    target = arm.fk(qa)[:3, 3]
    assert check(arm, qa, w, margin=MARGIN).in_collision and not check(arm, qb, w, margin=MARGIN).in_collision
    plain = optik.solve_ik(arm, optik.Position(target), q0=qa + 0.05, method=method)
    assert plain.success and check(arm, plain.q, w, margin=MARGIN).in_collision  # without the world
    res = optik.solve_ik(
        arm,
        optik.Position(target),
        q0=qa + 0.05,
        method=method,
        world=w,
        margin=MARGIN,
        time_limit=5.0,
        seed=2,
        **options,
    )
    assert res.success, res.message
    _independent(arm, res, target, w)
    assert res.collision_pair is not None
    if method == "nlp":
        with pytest.raises(InvalidArgumentError, match="plain_rounds"):
            optik.solve_ik(arm, optik.Position(target), method="nlp", world=w, plain_rounds=2)


def test_no_collision_free_answer_says_which_pair_blocks(arm):
    qa, qb = _branches(arm)
    w = _blocking_world(arm, qa)
    w.add_sphere("ball2", 0.05, spatial.translation(*arm.fk(qb, "fore")[:3, 3]))
    target = arm.fk(qa)[:3, 3]
    # 0.3 s: the rounds run out of seeds or time; 1 ms: the time limit ends the solve early (a
    # loaded machine's 0.3 s), the answer still names the pair its configuration brings close
    for limit in (0.001, 0.3):
        _names_the_blocking_pair(arm, target, qa, w, limit)


def test_a_failed_collision_aware_lm_says_why(arm):
    """The rounds end only at a success or at the time limit, so a failure's status is
    ``"time_limit"``, or ``"in_collision"`` when the pose is reached, never the status of the last
    round's kernel (its one constrained start ends as ``"max_restarts"``): a target out of reach,
    and one inside an obstacle (every round reaches it in collision, then slides)."""
    w = World()
    target = arm.fk(arm.random_q(seed=3))[:3, 3]
    w.add_sphere("ball", 0.1, spatial.translation(*target))
    cases = {"out of reach": target * 10.0, "inside the ball": target}
    for name, goal in cases.items():  # which step ends the rounds depends on the clock: many tries
        for limit in (0.001, 0.002, 0.005, 0.01, 0.02, 0.05):
            for seed in range(5):
                res = optik.solve_ik(
                    arm, optik.Position(goal), world=w, margin=MARGIN, time_limit=limit, seed=seed
                )
                assert not res.success, (name, limit, seed)
                assert res.status in ("time_limit", "in_collision"), (name, limit, seed, res.status)


def test_the_constrained_kernel_starts_once_a_call(arm, monkeypatch):
    """Both branches blocked, ``plain_rounds=1``: every round's answer collides, and the
    constrained kernel starts from one of them once (a sphere model that keeps the pose's clear
    answers out, as TALOS's capsules do, makes each further start a waste of milliseconds); the
    rounds go on by rejection until the time limit."""
    from optik.solvers import collision_free
    from optik.solvers.lm_kernel import LMKernel

    qa, qb = _branches(arm)
    w = _blocking_world(arm, qa)
    w.add_sphere("ball2", 0.05, spatial.translation(*arm.fk(qb, "fore")[:3, 3]))
    target = optik.Position(arm.fk(qa)[:3, 3])
    optik.solve_ik(arm, target, q0=qa, world=w, margin=MARGIN, plain_rounds=1)  # builds the kernels
    constrained = {id(k) for key, k in collision_free._CACHE.items() if key[0] == "lm" and key[1] is arm}
    assert constrained
    starts = {"constrained": 0, "plain": 0}
    run_one = LMKernel.run_one

    def counted(self, *args):
        starts["constrained" if id(self) in constrained else "plain"] += 1
        return run_one(self, *args)

    monkeypatch.setattr(LMKernel, "run_one", counted)
    res = optik.solve_ik(arm, target, q0=qa, world=w, margin=MARGIN, time_limit=0.2, plain_rounds=1, seed=3)
    # the last round may end at the time limit short of the pose (cold cache: CasADi's evaluator)
    assert not res.success and res.status in ("time_limit", "in_collision"), res.status
    assert starts["constrained"] == 1 and starts["plain"] > 3, starts


def _names_the_blocking_pair(arm, target, qa, w, limit):
    res = optik.solve_ik(arm, optik.Position(target), q0=qa, world=w, margin=MARGIN, time_limit=limit)
    assert not res.success
    assert res.min_distance is not None and res.collision_pair is not None
    if res.status == "in_collision":
        assert "ball" in res.message
    # the rounds' searches stop at a first close pair; the answer returned is judged in full
    report = check(arm, res.q, w, margin=MARGIN)
    assert res.min_distance == report.min_distance and res.collision_pair == report.pair
    if report.in_collision:
        pair = report.close_pairs[0]
        assert f"{pair.a!r} and {pair.b!r} are {pair.distance:.4g} m apart" in res.message


def test_every_success_is_clear_by_the_exact_check(arm):
    """Random boxes, targets by FK of clear configurations: no success the exact check rejects."""
    rng = np.random.default_rng(4)
    solved = 0
    for _ in range(6):
        w = World()
        for k in range(3):
            c = rng.uniform([-0.9, -0.9, 0.0], [0.9, 0.9, 0.2])
            w.add_box(f"b{k}", rng.uniform(0.05, 0.2, 3), spatial.translation(*c))
        q = arm.random_q(seed=rng)
        if check(arm, q, w, margin=MARGIN).in_collision:
            continue
        target = arm.fk(q)[:3, 3]
        res = optik.solve_ik(arm, optik.Position(target), world=w, margin=MARGIN, time_limit=1.0, seed=1)
        if res.success:
            solved += 1
            _independent(arm, res, target, w)
    assert solved >= 1


def test_bad_arguments(arm):
    target = optik.Position(arm.fk(np.zeros(2))[:3, 3])
    with pytest.raises(InvalidArgumentError, match="margin"):
        optik.solve_ik(arm, target, world=World(), margin=-0.1)
    with pytest.raises(InvalidArgumentError, match="world"):
        optik.solve_ik(arm, target, world="table")
    with pytest.raises(SolverUnavailableError, match="dls"):
        optik.solve_ik(arm, target, world=World(), method="dls")


@pytest.mark.parametrize("method", ["lm", "nlp"])
def test_a_moved_object_reuses_the_kernel(arm, method):
    """The world is a parameter of the generated code: moving, adding or removing objects (within
    the slot capacity) builds nothing new, and each answer avoids the world as it is now."""
    from optik.solvers import collision_free

    qa, qb = _branches(arm)
    w = _blocking_world(arm, qa)
    target = arm.fk(qa)[:3, 3]
    kw = dict(method=method, world=w, margin=MARGIN, time_limit=5.0, seed=2)
    res = optik.solve_ik(arm, optik.Position(target), q0=qa + 0.05, **kw)
    assert res.success, res.message
    built = set(collision_free._CACHE)
    w.move("ball", spatial.translation(*arm.fk(qb, "fore")[:3, 3]))  # now on the other branch
    w.add_box("far", (0.1, 0.1, 0.1), spatial.translation(5.0, 5.0, 5.0))
    res = optik.solve_ik(arm, optik.Position(target), q0=qb + 0.05, **kw)
    assert res.success, res.message
    _independent(arm, res, target, w)
    assert np.allclose(arm.fk(res.q, "fore")[:3, 3], arm.fk(qa, "fore")[:3, 3], atol=0.05)
    assert set(collision_free._CACHE) == built


def test_solve_ik_all_keeps_the_collision_free_branches(arm):
    """The two elbow branches of one tip point: with a ball on one elbow, that branch is reported
    in ``in_collision`` (failed, with the blocking pair) and the other is returned, clear."""
    qa, qb = _branches(arm)
    w = _blocking_world(arm, qa)
    target = optik.Position(arm.fk(qa)[:3, 3])
    assert check(arm, qa, w, margin=MARGIN).in_collision and not check(arm, qb, w, margin=MARGIN).in_collision
    every = optik.solve_ik_all(arm, target, time_limit=2.0, seed=0)
    assert len(every) == 2 and not every.in_collision
    free = optik.solve_ik_all(arm, target, time_limit=2.0, seed=0, world=w, margin=MARGIN)
    assert len(free) == 1 and len(free.in_collision) == 1
    _independent(arm, free[0], target.xyz, w)
    blocked = free.in_collision[0]
    assert not blocked.success and blocked.status == "in_collision" and "ball" in blocked.message
    assert check(arm, blocked.q, w, margin=MARGIN).in_collision
    assert "1 in collision left out" in free.message
    with pytest.raises(InvalidArgumentError, match="world"):
        optik.solve_ik_all(arm, target, world="table")


def test_batch_with_a_world_solves_each_target_clear(arm):
    """``solve_ik_batch(..., world=W)``: every success passes the exact check (recomputed here);
    the blocked branch's start is led to the clear one."""
    qa, _ = _branches(arm)
    w = _blocking_world(arm, qa)
    targets = np.array([arm.fk(qa)[:3, 3], arm.fk(np.array([-0.4, 0.8]))[:3, 3]])
    starts = np.array([qa + 0.05, [-0.4, 0.7]])
    plain = optik.solve_ik_batch(arm, targets, starts, time_limit=2.0, workers=2)
    assert plain.success.all() and check(arm, plain.q[0], w, margin=MARGIN).in_collision
    out = optik.solve_ik_batch(arm, targets, starts, world=w, margin=MARGIN, time_limit=2.0, workers=2)
    assert out.success.all()
    for q, target in zip(out.q, targets, strict=True):
        assert np.linalg.norm(arm.fk(q)[:3, 3] - target) <= 1e-6
        assert not check(arm, q, w, margin=MARGIN).in_collision
    with pytest.raises(InvalidArgumentError, match="world"):
        optik.solve_ik_batch(arm, targets, world="table")


def test_reach_with_a_world_counts_only_clear_answers(toy_arm_urdf):
    """A capability map with a wall over part of the workspace: no voxel is reached with more
    orientations than without it, and the voxels inside the wall are not reached at all."""
    arm = optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip")
    arm.task = "position2d"  # a planar 2R tip: x-y positions only (voxel centres are off its plane)
    w = World()
    w.add_box("wall", (0.3, 2.0, 1.0), spatial.translation(0.75, 0.0, 0.1))
    kw = dict(resolution=0.25, orientations=1, samples=2000, time_limit=0.05, workers=1)
    free = optik.reach(arm, **kw)
    walled = optik.reach(arm, world=w, margin=MARGIN, **kw)
    assert np.array_equal(free.voxels, walled.voxels)
    assert np.all(walled.success <= free.success)
    inside = np.abs(walled.centers[:, 0] - 0.75) < 0.15  # the tip would be inside the wall
    assert inside.any() and not walled.success[inside].any() and free.success[inside].any()
    with pytest.raises(InvalidArgumentError, match="world"):
        optik.reach(arm, world="wall", **kw)


@pytest.mark.parametrize("method", ["lm", "nlp"])
def test_dual_panda_both_hands_clear_of_each_other(method):
    """Several frame targets at once with self-collisions: both hands of the dual Panda placed,
    each success recomputed from q (both FKs, the limits, the exact check at the margin). nlp's
    IPOPT (15 joints, the self rows) took ~40 s for the three targets when its rows were one
    expression in CasADi's evaluator; with `optik.solvers.collision_nlp`'s mapped functions it
    takes 1.5 s, 3.6-4.0 s on an empty cache (the first starts in the evaluator while the C builds)."""
    m = optik.catalog.dual_panda()
    if not len(optik.collision.robot_geometry(m).links) > 4:
        pytest.skip("the Panda meshes of example-robot-data are not installed (extra 'robots')")
    rng = np.random.default_rng(3)
    solved = tried = 0
    while tried < 3:
        q = m.random_q(seed=rng)
        report = check(m, q, margin=MARGIN)
        if report.in_collision or report.min_distance > 0.05:  # clear, and near its own body
            continue
        tried += 1
        targets = {f: m.fk(q, f) for f in ("left_tool", "right_tool")}
        res = optik.solve_ik(m, targets, self_collision=True, margin=MARGIN, method=method, time_limit=5.0)
        if not res.success:
            continue
        solved += 1
        for frame, target in targets.items():
            pose = m.fk(res.q, frame)
            assert np.linalg.norm(pose[:3, 3] - target[:3, 3]) <= 1e-6
            assert spatial.angle_between(pose[:3, :3], target[:3, :3]) <= 1e-6
        assert np.all(res.q >= m.lower) and np.all(res.q <= m.upper)
        exact = check(m, res.q, margin=MARGIN)
        assert not exact.in_collision and exact.min_distance >= MARGIN
    assert solved >= 2


def test_dual_panda_nlp_stops_each_ipopt_start_at_the_time_limit(cpu_clock):
    """One IPOPT start of the dual Panda's constrained NLP (15 joints, the self rows) takes
    seconds: the iteration callback stops it at the call's deadline (setup excluded: a warm-up
    call builds the solver), timed as process CPU time (a busy machine's waits are no overrun),
    and the answer stopped there is an honest failure re-checked from its q."""
    m = optik.catalog.dual_panda()
    if not len(optik.collision.robot_geometry(m).links) > 4:
        pytest.skip("the Panda meshes of example-robot-data are not installed (extra 'robots')")
    q = m.random_q(seed=np.random.default_rng(3))
    targets = {f: m.fk(q, f) for f in ("left_tool", "right_tool")}
    kw = {"self_collision": True, "margin": MARGIN, "method": "nlp", "time_limit": 0.05}
    optik.solve_ik(m, targets, **kw)  # builds the solver (setup, excluded from the limit)
    with cpu_clock() as cpu:
        res = optik.solve_ik(m, targets, **kw)
    assert cpu.seconds < 0.05 + 1.0  # a whole start from the mid-limit seed takes ~1-3 s
    assert not res.success and res.status == "time_limit" and "time limit" in res.message
    assert res.q.shape == (m.n_q,) and np.all(res.q >= m.lower) and np.all(res.q <= m.upper)
    errors = [np.linalg.norm(m.fk(res.q, f)[:3, 3] - t[:3, 3]) for f, t in targets.items()]
    assert max(errors) > 1e-6  # the call did fail: the pose is not met at the returned q


def _clear_targets(arm, w, count, seed):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        q = arm.random_q(seed=rng)
        if not check(arm, q, w, margin=MARGIN).in_collision:
            out.append(arm.fk(q)[:3, 3])
    return out


@pytest.mark.parametrize("method", ["lm", "nlp"])
def test_four_threads_give_the_answers_of_one(arm, method):
    """Collision-aware solves are thread-safe: the same requests from 4 threads at once give the
    answers of a sequential run, each clear by the exact check recomputed here."""
    from concurrent.futures import ThreadPoolExecutor

    qa, _ = _branches(arm)
    w = _blocking_world(arm, qa)
    targets = [arm.fk(qa)[:3, 3], *_clear_targets(arm, w, 7, seed=5)]

    def solve(i):
        kw = dict(method=method, world=w, margin=MARGIN, time_limit=10.0, seed=i)
        return optik.solve_ik(arm, optik.Position(targets[i]), q0=qa + 0.05, **kw)

    alone = [solve(i) for i in range(len(targets))]
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(solve, range(len(targets))))
    for a, b, target in zip(alone, together, targets, strict=True):
        assert a.success and b.success, (a.message, b.message)
        assert np.array_equal(a.q, b.q) and a.min_distance == b.min_distance
        _independent(arm, b, target, w)


class _MovedAfterRead(World):
    """A world whose ball is moved right after its first read, as another thread could."""

    def __init__(self, to) -> None:
        super().__init__()
        self.to, self.reads, self.first = to, 0, None

    def state(self):
        s = super().state()
        self.reads += 1
        if self.reads == 1:
            self.first = s
            self.move("ball", self.to)
        return s


@pytest.mark.parametrize("method", ["lm", "nlp"])
def test_a_world_moved_during_a_solve_leaves_the_solve_on_one_version(arm, method):
    """The solve reads the world once: the ball that blocked elbow branch ``qa`` when the solve
    started is moved onto branch ``qb`` just after; the answer avoids the world as it was read
    (branch ``qb``), its distance is that version's, and only the moved world finds it colliding."""
    from optik.collision.check import report_at

    qa, qb = _branches(arm)
    w = _MovedAfterRead(spatial.translation(*arm.fk(qb, "fore")[:3, 3]))
    w.add_sphere("ball", 0.05, spatial.translation(*arm.fk(qa, "fore")[:3, 3]))
    target = arm.fk(qa)[:3, 3]
    kw = dict(method=method, world=w, margin=MARGIN, time_limit=5.0, seed=2)
    res = optik.solve_ik(arm, optik.Position(target), q0=qa + 0.05, **kw)
    assert w.reads == 1
    assert res.success, res.message
    then = report_at(optik.collision.robot_geometry(arm), res.q, w.first, MARGIN, True)
    assert not then.in_collision and res.min_distance == then.min_distance
    assert check(arm, res.q, w, margin=MARGIN).in_collision  # the world as it is now


@pytest.mark.parametrize("method", ["lm", "nlp"])
def test_a_new_margin_builds_no_new_code(arm, method):
    """The margin is a parameter of the generated code: a solve at another margin builds
    nothing, and its answer is clear by that margin."""
    from optik.solvers import collision_free

    qa, _ = _branches(arm)
    w = _blocking_world(arm, qa)
    target = optik.Position(arm.fk(qa)[:3, 3])
    kw = dict(method=method, world=w, time_limit=5.0, seed=3)
    first = optik.solve_ik(arm, target, q0=qa + 0.05, margin=MARGIN, **kw)
    assert first.success, first.message
    built = set(collision_free._CACHE)
    for margin in (0.03, 0.0):
        res = optik.solve_ik(arm, target, q0=qa + 0.05, margin=margin, **kw)
        assert res.success, res.message
        assert not check(arm, res.q, w, margin=margin).in_collision and res.min_distance >= margin
    assert set(collision_free._CACHE) == built


def test_a_first_build_is_made_once_for_many_threads():
    """Threads asking at once for code not built yet wait for one build and share it."""
    import threading
    import time
    from concurrent.futures import ThreadPoolExecutor

    from optik.solvers import collision_free

    builds = []
    lock = threading.Lock()

    def build():
        with lock:
            builds.append(1)
        time.sleep(0.2)
        return object()

    key = ("test", object())
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda _: collision_free._cached(key, build), range(4)))
    assert len(builds) == 1 and all(g is got[0] for g in got)


@pytest.mark.parametrize("method", ["lm", "nlp"])
def test_world_only_without_self_collision_rows(arm, method):
    """``self_collision=False`` with a world: no self rows at all (the kernel had mapped a
    function over zero pairs, which CasADi refuses); the answer still avoids the world."""
    qa, _ = _branches(arm)
    w = _blocking_world(arm, qa)
    target = arm.fk(qa)[:3, 3]
    res = optik.solve_ik(
        arm,
        optik.Position(target),
        q0=qa + 0.05,
        method=method,
        world=w,
        self_collision=False,
        margin=MARGIN,
        time_limit=2.0,
    )
    assert res.success, res.message
    assert np.linalg.norm(arm.fk(res.q)[:3, 3] - target) <= 1e-6 and arm.within_limits(res.q)
    exact = check(arm, res.q, w, margin=MARGIN, self_collision=False)  # the world only, as asked
    assert not exact.in_collision and exact.min_distance >= MARGIN
    assert res.min_distance == pytest.approx(exact.min_distance, abs=1e-12)


def test_nlp_clear_stop_and_no_world_rows_for_an_empty_world(arm):
    """The collision-aware IPOPT's callback stops only at an iterate within the tolerances whose
    model rows all hold (or at the deadline); an empty world gives the NLP no world rows."""
    from optik.solvers.collision_free import _CACHE, ClearStop

    stop = ClearStop(2, 3, 0, 1)
    stop.goal = (1e-6, 1e-6, 1e-9)
    stop.errors = lambda x: (float(x[0]), 0.0, 0.0)
    x_ok, x_off = np.array([1e-7, 0.0]), np.array([1e-3, 0.0])
    assert stop.clear(x_ok, np.array([-5.0, 0.0, 1e-3]))  # row 0 is the closure, not a model row
    assert not stop.clear(x_ok, np.array([0.0, -1e-12, 1e-3]))
    assert not stop.clear(x_off, np.array([0.0, 0.0, 0.0]))
    assert not stop.check(x_off) and (stop.deadline == np.inf)
    q = np.array([0.3, 0.4])
    res = optik.solve_ik(
        arm, optik.Position(arm.fk(q)[:3, 3]), self_collision=True, margin=MARGIN, method="nlp", seed=1
    )
    assert res.success, res.message
    pools = [v for k, v in _CACHE.items() if k[0] == "nlp" and k[1] is arm and k[4] == 0]
    assert pools
    for pool in pools:  # g: the closures and one row per self pair; p: the task's, the bound, a flag per pair
        n_self = pool.functions.g.size1_out(0) - arm.n_closure
        assert pool.functions.g.size1_in(1) == pool.problem.parameters.shape[0] + 1 + n_self


def _no_calls(arm):
    """Drop the prepared calls `optik.solve_ik` keeps for the arm."""
    from optik.solvers import api

    api._CALLS.setdefault(arm, {}).clear()


def _prepared_call(arm):
    """The collision-aware prepared call `optik.solve_ik` keeps for the arm (one, after `_no_calls`)."""
    from optik.solvers import api
    from optik.solvers.collision_free import CollisionCall

    calls = [c for c in api._CALLS.get(arm, {}).values() if isinstance(c, CollisionCall)]
    assert len(calls) == 1
    return calls[0]


def _same(a, b):
    """Two results of one solve: the same answer, judgement and search counts."""
    assert np.array_equal(a.q, b.q)
    assert (a.success, a.status, a.message) == (b.success, b.status, b.message)
    assert (a.min_distance, a.collision_pair) == (b.min_distance, b.collision_pair)
    assert (a.iterations, a.restarts) == (b.iterations, b.restarts)


@pytest.mark.parametrize("options", [{}, {"plain_rounds": 1}])
def test_the_prepared_call_answers_as_the_general_path(arm, options):
    """Later calls with a 4x4 target go through `CollisionCall` (the first round as ``lm``'s own
    prepared call, judged by the exact check): the same answers as the general path (an
    ``np.int64`` seed takes it), the first target's first round colliding (more rounds, and with
    ``plain_rounds=1`` the constrained kernel, from the prepared call)."""
    import time

    qa, _ = _branches(arm)
    w = _blocking_world(arm, qa)
    targets = [arm.fk(qa), *(spatial.translation(*p) for p in _clear_targets(arm, w, 6, seed=8))]
    kw = dict(task="position", world=w, margin=MARGIN, time_limit=5.0, **options)
    _no_calls(arm)
    first = optik.solve_ik(arm, targets[0], q0=qa + 0.05, seed=0, **kw)
    call = _prepared_call(arm)
    assert first.success and first.restarts > 0, first.message  # its first round collided
    for i, target in enumerate(targets):
        general = optik.solve_ik(arm, target, q0=qa + 0.05, seed=np.int64(i), **kw)
        prepared = call(time.perf_counter(), target, qa + 0.05, i, w)
        assert prepared is not None
        _same(prepared, general)
        _same(optik.solve_ik(arm, target, q0=qa + 0.05, seed=i, **kw), general)
        assert general.success, general.message
        _independent(arm, general, target[:3, 3], w)


def test_the_prepared_call_reads_the_world_as_it_is_at_each_call(arm):
    """`CollisionCall` caches nothing of the world: after a move, a removal and an addition each
    answer avoids the world as it is then (the general path's answer too)."""
    qa, qb = _branches(arm)
    w = _blocking_world(arm, qa)
    target = arm.fk(qa)
    kw = dict(task="position", world=w, margin=MARGIN, time_limit=5.0, seed=3)

    def solve(q0):
        general = optik.solve_ik(arm, target, q0=q0, **{**kw, "seed": np.int64(3)})
        res = optik.solve_ik(arm, target, q0=q0, **kw)
        _same(res, general)
        assert res.success, res.message
        _independent(arm, res, target[:3, 3], w)
        return res

    _no_calls(arm)
    solve(qa + 0.05)
    _prepared_call(arm)
    elbow = lambda q: arm.fk(q, "fore")[:3, 3]  # noqa: E731
    w.move("ball", spatial.translation(*elbow(qb)))  # now on the other branch: qa is clear
    assert np.allclose(elbow(solve(qb + 0.05).q), elbow(qa), atol=0.05)
    w.remove("ball")  # nothing in the way: the nearest branch from the start
    assert np.allclose(elbow(solve(qb + 0.05).q), elbow(qb), atol=0.05)
    w.add_sphere("ball", 0.05, spatial.translation(*elbow(qa)))  # back on qa
    assert np.allclose(elbow(solve(qa + 0.05).q), elbow(qb), atol=0.05)


def test_the_prepared_call_from_four_threads_gives_the_answers_of_one(arm):
    """`CollisionCall` is thread-safe: 4 threads at once give the sequential answers."""
    from concurrent.futures import ThreadPoolExecutor

    qa, _ = _branches(arm)
    w = _blocking_world(arm, qa)
    targets = [arm.fk(qa), *(spatial.translation(*p) for p in _clear_targets(arm, w, 11, seed=9))]

    def solve(i):
        kw = dict(task="position", world=w, margin=MARGIN, time_limit=10.0, seed=i)
        return optik.solve_ik(arm, targets[i % len(targets)], q0=qa + 0.05, **kw)

    _no_calls(arm)
    alone = [solve(i) for i in range(24)]
    _prepared_call(arm)
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(solve, range(24)))
    for i, (a, b) in enumerate(zip(alone, together, strict=True)):
        assert a.success, a.message
        _same(a, b)
        _independent(arm, b, targets[i % len(targets)][:3, 3], w)


def test_the_solves_exact_check_is_the_full_report(arm):
    """A solve's judgement (`collision_free._Exact`: the search without report objects) agrees
    with `check`'s full report on seeded random configurations, a third of them in near contact
    (a ball placed within 0.2 mm of the margin from a link)."""
    from optik.results import IKResult
    from optik.solvers.collision_free import _Exact

    rng = np.random.default_rng(11)
    near = 0
    for k in range(60):
        q = arm.random_q(seed=rng)
        w = World()
        w.add_box("box", (0.2, 0.2, 0.2), spatial.translation(*rng.uniform(-0.8, 0.8, 3)))
        if k % 3 == 0:  # a ball whose clearance to the forearm's nearest point is margin +- 0.2 mm
            probe = World()
            probe.add_sphere("ball", 0.05, spatial.translation(*(arm.fk(q, "fore")[:3, 3] + [0, 0, 0.3])))
            d = check(arm, q, probe, self_collision=False).min_distance
            shift = d - MARGIN + rng.uniform(-2e-4, 2e-4)
            w.add_sphere("ball", 0.05, spatial.translation(*(arm.fk(q, "fore")[:3, 3] + [0, 0, 0.3 - shift])))
        report = check(arm, q, w, margin=MARGIN)
        near += abs(report.min_distance - MARGIN) < 5e-4
        res = IKResult(q, True, 0.0, 0.0, 0.0, True, 0, 0.0, "lm", "solved", "")
        judged = _Exact(arm, w.state(), True, MARGIN).finish(res)
        assert judged.success == (not report.in_collision)
        assert judged.min_distance == report.min_distance and judged.collision_pair == report.pair
        if report.in_collision:
            assert judged.status == "in_collision" and repr(report.close_pairs[0].a) in judged.message
    assert near >= 10


def _panda_in_clutter(count: int, seed: int) -> tuple[optik.Mechanism, World, list[np.ndarray]]:
    """The Panda (with its SRDF) in the scene of ``optik benchmark collision`` and ``count``
    targets, each the FK of a random configuration clear at a 1 cm margin (skips without
    example-robot-data)."""
    from optik.benchmarks.bench_collision import scene
    from optik.catalog.robots import robots_dir

    try:
        d = robots_dir() / "panda_description"
    except optik.MissingExtraError:
        pytest.skip("example-robot-data (extra 'robots') is not installed")
    urdf, srdf = d / "urdf" / "panda.urdf", d / "srdf" / "panda.srdf"
    m = optik.Mechanism.from_urdf(urdf, "panda_link0", "panda_hand_tcp", srdf=srdf)
    w = scene()
    rng = np.random.default_rng(seed)
    targets = []
    while len(targets) < count:
        q = m.random_q(seed=rng)
        if not check(m, q, w, margin=0.01).in_collision:
            targets.append(m.fk(q))
    return m, w, targets


def test_panda_in_clutter_four_threads_give_the_answers_of_one():
    """The clutter benchmark's scene and targets (the Panda's base against the table kept per
    world version, `optik.collision.check`): 4 threads at once, starting on a world version no
    solve has read, give the answers of one thread, each clear by the exact check."""
    from concurrent.futures import ThreadPoolExecutor

    m, w, targets = _panda_in_clutter(24, 4)

    def solve(i):
        return optik.solve_ik(m, targets[i], world=w, margin=0.01, time_limit=10.0, seed=i)

    w.move("box_a", spatial.translation(0.35, 0.46, 0.04))  # a new version: nothing known of it
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(solve, range(len(targets))))
    alone = [solve(i) for i in range(len(targets))]
    for a, b in zip(alone, together, strict=True):
        assert a.success and b.success, (a.message, b.message)
        assert np.array_equal(a.q, b.q) and a.min_distance == b.min_distance
        assert a.collision_pair == b.collision_pair
        assert check(m, b.q, w, margin=0.01).in_collision is False


def test_a_clear_answer_reads_its_distance_from_the_full_search(arm):
    """A clear ``lm`` answer (`optik.results.LazyDistanceResult`): its distance and pair are the
    full check's, the search made once on the first read; a copy, a pickle and a write before
    any read keep the same values (the write only its own field)."""
    import copy
    import pickle

    from optik.results import LazyDistanceResult

    qa, qb = _branches(arm)
    w = _blocking_world(arm, qa)
    target = arm.fk(qb)[:3, 3]
    res = optik.solve_ik(arm, optik.Position(target), q0=qb, world=w, margin=MARGIN, seed=1)
    assert res.success and type(res) is LazyDistanceResult
    report = check(arm, res.q, w, margin=MARGIN)
    calls = []
    nearest = res._nearest
    res._nearest = lambda: calls.append(1) or nearest()
    twin, kept = copy.copy(res), pickle.loads(pickle.dumps(res))
    assert calls == [1] and res.q is twin.q
    for r in (res, twin, kept):
        assert r.min_distance == report.min_distance and r.collision_pair == report.pair
    assert calls == [1]
    again = optik.solve_ik(arm, optik.Position(target), q0=qb, world=w, margin=MARGIN, seed=1)
    again.min_distance = -1.0
    assert again.min_distance == -1.0 and again.collision_pair == report.pair


def test_a_clear_answer_settles_once_across_threads_and_replaces(arm):
    """Eight threads reading a fresh `LazyDistanceResult` at once see one full search's values
    (the search runs once); ``dataclasses.replace`` gives a result with the same fields and the
    change."""
    import dataclasses
    import threading

    qa, qb = _branches(arm)
    w = _blocking_world(arm, qa)
    target = arm.fk(qb)[:3, 3]
    res = optik.solve_ik(arm, optik.Position(target), q0=qb, world=w, margin=MARGIN, seed=1)
    report = check(arm, res.q, w, margin=MARGIN)
    calls, nearest, start = [], res._nearest, threading.Barrier(8)
    res._nearest = lambda: calls.append(1) or nearest()
    seen: list = []

    def read():
        start.wait()
        seen.append((res.min_distance, res.collision_pair))

    threads = [threading.Thread(target=read) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert calls == [1] and seen == [(report.min_distance, report.pair)] * 8
    fresh = optik.solve_ik(arm, optik.Position(target), q0=qb, world=w, margin=MARGIN, seed=1)
    other = dataclasses.replace(fresh, message="changed")
    assert other.message == "changed" and other.min_distance == report.min_distance
    assert other.collision_pair == report.pair and np.array_equal(other.q, fresh.q)


def test_solve_time_covers_the_exact_check(arm):
    """``solve_time`` is the wall time of the whole call, the exact check of the answer included:
    with a cloud of 2000 points around the arm (2 m away: clear, but each point a slot the
    screening bounds of the check evaluate) the check takes most of a call, on the prepared call
    (an int seed) and on the general path (a Generator seed, which the prepared call leaves to it)."""
    import time

    w = World()
    d = np.random.default_rng(0).normal(size=(2000, 3))
    w.add_points("cloud", 2.0 * d / np.linalg.norm(d, axis=1, keepdims=True), 0.01)
    target = spatial.translation(*arm.fk(np.array([0.3, 1.2]))[:3, 3])
    kw = dict(task="position", world=w, margin=MARGIN, time_limit=5.0)
    _no_calls(arm)
    assert optik.solve_ik(arm, target, seed=0, **kw).success  # builds what the calls below read
    for seed in (lambda i: i, np.random.default_rng):
        ratios = []
        for i in range(5):
            t0 = time.perf_counter()
            res = optik.solve_ik(arm, target, seed=seed(i), **kw)
            wall = time.perf_counter() - t0
            assert res.success and res.solve_time <= wall
            ratios.append(res.solve_time / wall)
        assert max(ratios) >= 0.9, ratios
    _prepared_call(arm)  # the int seeds went through it


def test_panda_in_clutter_prepared_calls_decide_clear_answers_in_the_lm_call():
    """With the coarse screen compiled, the prepared call tests its answer in the LM call
    (`optik.collision.check.ClearTest`): most clear answers need no search, and the answers are
    the general path's (an ``np.int64`` seed takes it), every success clear by the exact check."""
    from optik import native

    m, w, targets = _panda_in_clutter(40, 12)
    kw = dict(world=w, margin=0.01, time_limit=5.0)
    _no_calls(m)
    optik.solve_ik(m, targets[0], seed=0, **kw)
    native.wait(600)
    call = _prepared_call(m)
    verdicts = []
    for i, target in enumerate(targets):
        prepared = optik.solve_ik(m, target, seed=i, **kw)
        judges = getattr(call._local, "judges", None)
        if judges is None or judges[1] is None:
            pytest.skip("no compiled screen (no C compiler)")
        verdicts.append(int(judges[1].verdict[0]))
        general = optik.solve_ik(m, target, seed=np.int64(i), **kw)
        _same(prepared, general)
        assert prepared.success and not check(m, prepared.q, w, margin=0.01).in_collision
    assert verdicts.count(1) > len(targets) / 2 and 0 in verdicts


@pytest.mark.parametrize("method", ["lm", "nlp"])
def test_the_screens_of_the_exact_check_are_built_in_the_setup(toy_arm_urdf, method):
    """Both screens the exact check may read (the coarse one, and the finer one a check asks for
    only when many world pairs stay close: 38 ms to build for the Panda among boxes, which a first
    such check once spent inside its time limit) exist once the first call's setup is over, and
    that build is reported as setup time, outside the time limit."""
    from optik.collision import robot_geometry
    from optik.collision import screen as screens

    fresh = optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip")  # its own geometry: nothing cached
    qa, _ = _branches(fresh)
    w = _blocking_world(fresh, qa)
    res = optik.solve_ik(fresh, optik.Position(fresh.fk(qa)[:3, 3]), method=method, world=w, margin=MARGIN)
    built = screens._CACHE[robot_geometry(fresh)]
    capacity = w.state().capacity
    assert {(capacity, True), (capacity, False)} <= set(built)
    assert res.extra.get("setup_time", 0.0) > 0.0
