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


def test_only_a_complete_closed_form_is_certified() -> None:
    """Regression (issue 18, item 1): numerical answers said ``certified=True`` (an empty
    ``uncertified_reason``). Every numerical answer now says why it is not certified: the
    Panda (no closed form: multi-start ``lm``), the Panda with a joint locked asked for by
    ``lm``, an arm with a closed form asked for by ``lm``; the closed form stays certified."""
    panda = optik.catalog.panda()
    q = np.array([0.1, -0.4, 0.3, -1.8, 0.2, 1.6, 0.5])
    free = optik.solve_ik_all(panda, panda.fk(q), seed=0, time_limit=0.3, patience=3, max_solutions=2)
    assert free.method == "lm" and len(free) and not free.certified
    locked = optik.solve_ik_all(panda, panda.fk(q), None, "lm", fixed={"q3": 0.3}, seed=0, time_limit=0.5)
    assert locked.method == "lm" and len(locked)
    assert not locked.certified and "numerical multi-start (lm)" in locked.uncertified_reason
    assert "not certified complete" in locked.message
    m, target = _seed_target()
    numeric = optik.solve_ik_all(m, target, method="lm", seed=0, time_limit=0.5, patience=5)
    assert not numeric.certified and numeric.uncertified_reason
    exact = optik.solve_ik_all(m, target)
    assert exact.method == "closed_form" and exact.certified and exact.uncertified_reason == ""
    assert not optik.results.IKSolutions([], method="lm").certified  # whatever the reason says


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


@pytest.mark.parametrize(("arm", "joint"), [("panda", "q7"), ("iiwa14", "q3"), ("panda", "q4")])
def test_locked_joint_gives_every_analytic_solution(arm: str, joint: str) -> None:
    m = getattr(optik.catalog, arm)()
    k = m.coordinate_names.index(joint)
    for seed in range(5):
        q_true = m.random_q(seed=seed)
        target = m.fk(q_true)
        sols = optik.solve_ik_all(m, target, fixed={joint: q_true[k]})
        assert sols.method == "closed_form" and {s.method for s in sols} == {"closed_form"}
        assert min(joint_distance(m, s.q, q_true) for s in sols) < 1e-9
        for s in sols:  # independent check on the 7-DOF model
            assert s.q[k] == q_true[k] and m.within_limits(s.q)
            np.testing.assert_allclose(m.fk(s.q), target, atol=1e-9)
        pairs = [(a, b) for i, a in enumerate(sols) for b in sols[i + 1 :]]
        assert all(joint_distance(m, a.q, b.q) >= 1e-6 for a, b in pairs)


def test_locked_joint_finds_every_eaik_solution() -> None:
    eaik = pytest.importorskip("eaik.pybindings.EAIK")
    from optik.closed_form.derived import chain_axes

    m = optik.catalog.panda()
    ax = chain_axes(m)
    offsets = np.vstack([ax.r[0], np.diff(ax.r, axis=0), ax.home[:3, 3] - ax.r[-1]])
    for seed in range(10):
        q_true = m.random_q(seed=seed)
        target = m.fk(q_true)
        robot = eaik.Robot(ax.h.T, offsets.T, ax.home[:3, :3], [(6, float(q_true[6]))], True)
        theirs = [
            s for s in np.asarray(robot.calculate_IK(target).Q) if np.abs(m.fk(s) - target).max() < 1e-8
        ]
        sols = optik.solve_ik_all(m, target, fixed={"q7": q_true[6]})
        assert len(sols) + len(sols.outside_limits) >= len(theirs)
        for s in theirs:
            if m.within_limits(s):
                assert min(joint_distance(m, s, r.q) for r in sols) < 1e-4


def test_locked_joint_with_a_general_remainder_gets_the_general_6r_solver() -> None:
    """Regression (issue 18, item 3): a 7-joint arm locked to a 6R chain of no decomposable
    family got the numerical multi-start (uncertified, answers off by up to 4e-7, since the
    polish stopped at once: its step moved the pinned joint out of its limits). It now gets the
    certified general 6R solver, like the standalone arm; the multi-start asked for finds
    nothing outside that set, and its answers meet the FK to rounding too."""
    m = optik.mechanism.dh_chain(
        [(0.3, 0.2, 1.1), (0.1, 0.5, -0.7), (0.2, 0.4, 0.9), (0.15, 0.3, 1.3), (0.1, 0.2, -1.2),
         (0.05, 0.3, 0.8), (0.1, 0.1, 0.4)]
    )  # fmt: skip
    q = np.array([0.3, 0.5, 0.7, -0.4, 0.8, -0.2, 0.6])
    target = m.fk(q)
    sols = optik.solve_ik_all(m, target, fixed={"q3": 0.7})
    assert sols.method == "closed_form" and sols.certified and len(sols) >= 2
    assert min(joint_distance(m, s.q, q) for s in sols) < 1e-9
    for s in sols:  # independent check by the mechanism's own FK
        assert s.q[2] == 0.7 and np.abs(m.fk(s.q) - target).max() < 1e-12
    numeric = optik.solve_ik_all(m, target, None, "lm", fixed={"q3": 0.7}, seed=0, time_limit=1.0)
    assert numeric.method == "lm" and len(numeric)
    for s in numeric:
        assert np.abs(m.fk(s.q) - target).max() < 1e-12
        assert min(joint_distance(m, s.q, c.q) for c in sols) < 1e-8


def test_locked_joint_input_checks_and_fallback() -> None:
    m = optik.catalog.panda()
    target = m.fk(m.mid_q())
    for bad in ({}, {"q9": 0.0}, {"q4": 0.5}, {"q1": float("nan")}, [("q1", 0.0)]):
        with pytest.raises(InvalidArgumentError, match=r"^fixed"):
            optik.solve_ik_all(m, target, fixed=bad)
    # q1 locked leaves a 6R chain of no decomposable family: the general 6R solver, certified
    q = np.array([0.1, -0.4, 0.3, -1.8, 0.2, 1.6, 0.5])
    locked = optik.solve_ik_all(m, m.fk(q), fixed={"q1": 0.1})
    assert locked.method == "closed_form" and locked.certified
    assert min(joint_distance(m, s.q, q) for s in locked) < 1e-9
    # the mid-limit pose is special (axes aligned): the count check fails and says so
    assert not optik.solve_ik_all(m, target, fixed={"q1": 0.0}).certified
    point = optik.Position(target[:3, 3])
    with pytest.raises(SolverUnavailableError, match="no closed form"):
        optik.solve_ik_all(m, point, method="closed_form", fixed={"q1": 0.0})
    # no closed form for a position task: the numerical search with q1 pinned
    sols = optik.solve_ik_all(m, point, fixed={"q1": 0.0}, time_limit=1.0, patience=3, seed=0)
    assert sols and all(s.q[0] == 0.0 and s.method == "lm" for s in sols)
    for s in sols:
        np.testing.assert_allclose(m.fk(s.q)[:3, 3], target[:3, 3], atol=1e-6)


def test_self_motion_samples_follow_the_swept_joint() -> None:
    m = optik.catalog.iiwa14()
    target = m.fk(m.random_q(seed=7))
    values = np.linspace(-1.0, 1.0, 5)
    samples = optik.self_motion(m, target, "q3", values)
    assert len(samples) == len(values) and all(len(s) > 0 for s in samples)
    for v, sols in zip(values, samples, strict=True):
        for s in sols:
            assert s.q[2] == v
            np.testing.assert_allclose(m.fk(s.q), target, atol=1e-9)


def test_closed_form_is_not_used_for_another_frame() -> None:
    """The closed form solves for the end effector: another task frame takes the numerical
    method by default and is refused by method="closed_form"."""
    m = optik.catalog.puma560()
    q = m.random_q(seed=2)
    target = m.fk(q, "link5")
    with pytest.raises(SolverUnavailableError, match="frame 'link5'"):
        optik.solve_ik(m, target, method="closed_form", frame="link5")
    res = optik.solve_ik(m, target, frame="link5", seed=0, time_limit=1.0)
    assert res.method == "lm" and res.success
    np.testing.assert_allclose(m.fk(res.q, "link5"), target, atol=1e-6)


def _compiled_arms() -> list[optik.Mechanism]:
    """Arms whose closed form is derived, with limits that need the 2 pi shift (seed arm in
    [0, 2 pi] and [-3 pi, -pi]; one-sided limits: [-inf, -2], [1, inf], ...) or drop solutions
    (PUMA 560)."""
    seed = optik.catalog.seed_6r_arm()
    lo, hi = np.zeros(6), np.full(6, 2 * np.pi)
    lo[1], hi[1] = -3 * np.pi, -np.pi
    one_lo = np.array([-np.inf, 1.0, -np.inf, 0.5, -np.inf, -4.0])
    one_hi = np.array([-2.0, np.inf, 1.5, np.inf, 0.0, np.inf])
    return [optik.catalog.puma560(), seed, seed.with_limits(lo, hi), seed.with_limits(one_lo, one_hi)]


ARM_IDS = ["puma560", "seed_6r_arm", "seed_6r_arm_shifted", "seed_6r_arm_one_sided"]


@pytest.mark.parametrize("m", _compiled_arms(), ids=ARM_IDS)
def test_compiled_path_equals_the_general_path(m: optik.Mechanism, monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled driver (optik.closed_form.ik_all) gives exactly what the general closed-form
    path gives: the same solutions in the same order, the same errors, the same solutions
    outside the limits; every solution passes an independent FK and limit check."""
    from optik.solvers import all as all_module
    from optik.solvers.base import make_request

    solver = closed_form.derive(m)
    solver.compile()
    if solver.driver() is None:
        pytest.skip("no C compiler: the compiled driver is not built")
    rng = np.random.default_rng(2)
    qs = rng.uniform(-np.pi, np.pi, (40, 6))
    qs[:8, 4] = 0.0  # wrist singularity (stand-ins, close candidates)
    targets = list(m.fk(qs))
    far = m.fk(qs[0])
    far[:3, 3] *= 10.0  # unreachable
    targets.append(far)
    general = all_module._closed_form_all
    answered = 0
    for t in targets:
        q0 = rng.uniform(-np.pi, np.pi, 6)
        want = general(make_request(m, t, q0, None, None, 1.0, None, None, {}))
        monkeypatch.setattr(all_module, "_closed_form_all", None)  # the compiled path or a TypeError
        try:
            got = optik.solve_ik_all(m, t, q0)
            answered += 1
        except TypeError:
            got = want  # sent to the general path: a candidate to polish or two close ones
        monkeypatch.setattr(all_module, "_closed_form_all", general)
        assert len(got) == len(want)
        np.testing.assert_array_equal(got.q.reshape(-1, 6), np.array([r.q for r in want]).reshape(-1, 6))
        np.testing.assert_array_equal(np.array(got.outside_limits).reshape(-1, 6),
                                      np.array(want.outside_limits).reshape(-1, 6))  # fmt: skip
        for a, b in zip(got, want, strict=True):
            assert (a.position_error, a.orientation_error, a.success, a.method) == (
                b.position_error, b.orientation_error, b.success, b.method)  # fmt: skip
            assert m.within_limits(a.q)
            np.testing.assert_allclose(m.fk(a.q), t, atol=1e-9)
    assert answered >= 30  # the regular targets take the compiled path


def test_compiled_path_validates_like_the_general_path() -> None:
    """Bad targets and starts raise the same named errors through the compiled path."""
    m = optik.catalog.puma560()
    closed_form.derive(m).compile()
    t = m.fk(m.mid_q())
    bad = t.copy()
    bad[0, 0] = np.nan
    with pytest.raises(optik.errors.NonFiniteError, match=r"^target"):
        optik.solve_ik_all(m, bad)
    skew = t.copy()
    skew[:3, :3] *= 1.1
    with pytest.raises(InvalidArgumentError, match=r"^target"):
        optik.solve_ik_all(m, skew)
    with pytest.raises(optik.errors.NonFiniteError, match=r"^q0"):
        optik.solve_ik_all(m, t, np.full(6, np.inf))
    with pytest.raises(optik.errors.ShapeError, match=r"^q0"):
        optik.solve_ik_all(m, t, np.zeros(5))
    with pytest.raises(InvalidArgumentError, match=r"^time_limit"):
        optik.solve_ik_all(m, t, time_limit=-1.0)
    sols = optik.solve_ik_all(m, t, list(m.mid_q()))  # a list start: the same answer
    np.testing.assert_array_equal(sols.q, optik.solve_ik_all(m, t, m.mid_q()).q)


def test_driver_through_ctypes_equals_its_python_binding(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without the Python headers the driver is called through ctypes buffers: the same answers
    as through its Python binding (any layout of the arrays: the targets of m.fk are views)."""
    from optik.closed_form import ik_all

    m = optik.catalog.seed_6r_arm()
    solver = closed_form.derive(m)
    solver.compile()
    binding = solver.driver()
    if binding is None or binding.fast is None:
        pytest.skip("no C compiler or no Python headers: nothing to compare")
    monkeypatch.setattr(ik_all, "python_flags", lambda: ())
    plain = closed_form.derived._driver_kernel(solver)  # the same driver, without the binding
    plain.library.wait()
    assert plain.ready and plain.fast is None
    qs = m.random_q(30, seed=4)
    qs[:5, 4] = 0.0
    for t, q0 in zip(m.fk(qs), m.random_q(30, seed=5), strict=True):
        for start, sort in ((q0, True), (None, True), (None, False)):
            a, b = binding(t, start, m.lower, m.upper, sort), plain(t, start, m.lower, m.upper, sort)
            assert (a is None) == (b is None)
            for x, y in zip(a or (), b or (), strict=True):
                np.testing.assert_array_equal(x, y)


def _layouts(t: np.ndarray) -> list[object]:
    """The same target in other layouts and types, and hostile variants."""
    far = t.copy()
    far[:3, 3] = 1e300
    tiny = t.copy()
    tiny[:3, 3] = 1e-300
    return [
        np.asfortranarray(t),
        t[::-1, ::-1][::-1, ::-1],  # negative strides, same values
        np.ascontiguousarray(t.T).T,
        t.astype(np.float32),
        t.tolist(),
        np.array(t, dtype=object),
        far,
        tiny,
    ]


def test_compiled_path_takes_any_layout_and_hostile_values() -> None:
    """Targets and starts of any layout or type give what the general path gives (or its named
    error): the compiled binding reads strided memory, and declines what it does not take."""
    from optik.solvers import all as all_module
    from optik.solvers.base import make_request

    m = optik.catalog.puma560()
    closed_form.derive(m).compile()
    q = m.random_q(seed=3)
    t = m.fk(q)
    for target in _layouts(t):
        for q0 in (None, m.mid_q(), m.mid_q()[::-1][::-1], m.mid_q().astype(np.float32), [0.1] * 6):
            try:
                request = make_request(m, target, q0, None, None, 1.0, None, None, {})
                want = all_module._closed_form_all(request)
            except optik.OptikError as exc:
                with pytest.raises(type(exc)):
                    optik.solve_ik_all(m, target, q0)
                continue
            got = optik.solve_ik_all(m, target, q0)
            assert len(got) == len(want)
            for a, b in zip(got, want, strict=True):
                np.testing.assert_array_equal(a.q, b.q)
                assert a.success and m.within_limits(a.q)


def test_without_a_compiler_the_evaluator_gives_the_same_solutions(monkeypatch: pytest.MonkeyPatch) -> None:
    """No C compiler: CasADi's evaluator runs the symbolic kernel (same steps as the driver), and
    solve_ik_all answers as with the compiled driver."""
    from optik import native

    arm = optik.catalog.seed_6r_arm(0.9, 0.7, 0.25)
    compiled = closed_form.derive(arm)
    compiled.compile()
    assert compiled.driver() is not None or native.compiler() is None
    qs = arm.random_q(20, seed=8)
    want = [optik.solve_ik_all(arm, t) for t in arm.fk(qs)]
    monkeypatch.setattr(native, "compiler", lambda: None)
    plain = optik.catalog.seed_6r_arm(0.9, 0.7, 0.25)  # a new mechanism: its own derived solver
    assert closed_form.derive(plain).driver() is None
    for t, w in zip(plain.fk(qs), want, strict=True):
        got = optik.solve_ik_all(plain, t)
        assert len(got) == len(w)
        for a, b in zip(got, w, strict=True):
            np.testing.assert_allclose(a.q, b.q, atol=1e-12)


@pytest.mark.parametrize("m", _compiled_arms(), ids=ARM_IDS)
def test_solve_ik_closed_form_through_the_driver_equals_the_general_path(
    m: optik.Mechanism, monkeypatch: pytest.MonkeyPatch
) -> None:
    """solve_ik(method="closed_form") takes the nearest solution within the limits from the
    compiled driver: the same result as through every branch (errors by the mechanism's FK)."""
    from optik.solvers import closed

    closed_form.derive(m).compile()
    rng = np.random.default_rng(5)
    qs = rng.uniform(-np.pi, np.pi, (40, 6))
    qs[:5, 4] = 0.0
    starts = rng.uniform(-np.pi, np.pi, (40, 6))
    fast = [optik.solve_ik(m, t, q0, "closed_form") for t, q0 in zip(m.fk(qs), starts, strict=True)]
    monkeypatch.setattr(closed, "binding_of", lambda _: None)
    for t, q0, a in zip(m.fk(qs), starts, fast, strict=True):
        b = optik.solve_ik(m, t, q0, "closed_form")
        np.testing.assert_array_equal(a.q, b.q)
        assert (a.success, a.status, a.position_error, a.orientation_error) == (
            b.success, b.status, b.position_error, b.orientation_error)  # fmt: skip
