"""The Stewart-Gough FK in 40 paths: shipped start instance, compiled parameter homotopy, Cauchy
endgame, count check and the fall back to the total-degree method for special geometries."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik.closed_form import homotopy, parameter_homotopy
from optik.closed_form.parallel import stewart_gough, stewart_parameter, stewart_poses, study

pytestmark = pytest.mark.skipif(not parameter_homotopy.available(), reason="needs a C compiler")


def _legs(b, p, r, t):
    return np.linalg.norm(p @ r.T + t - b, axis=1)


def _max_leg_error(b, p, rho, poses):
    return max(float(np.max(np.abs(_legs(b, p, r, t) - rho))) for r, t in poses)


def _pose(rng):
    r = optik.spatial.so3_exp(0.4 * rng.normal(size=3))
    return r, np.r_[0.2 * rng.normal(size=2), 1.0]


def _general(rng):
    return rng.normal(size=(6, 3)), 0.6 * rng.normal(size=(6, 3))


def _same_postures(a, b):
    def key(poses):
        return sorted(np.r_[r.ravel(), t].round(6).tolist() for r, t in poses)

    return len(a) == len(b) and np.allclose(key(a), key(b), atol=1e-5)


def test_shipped_start_instance_is_certified():
    start = stewart_parameter.load()
    assert start.solutions.shape == (40, 8)
    mats = study.study_matrices(start.base, start.platform, start.constants)
    assert len(stewart_parameter.distinct(mats, start.solutions)) == 40
    assert start.residual() <= 1e-13
    assert np.all(parameter_homotopy.condition_numbers(mats, start.solutions) < 1e6)


def test_start_instance_regenerates_from_its_seed(tmp_path):
    start = stewart_parameter.load()
    again = stewart_parameter.generate(start.seed)
    assert np.allclose(again.base, start.base) and np.allclose(again.constants, start.constants)
    u = start.solutions / np.linalg.norm(start.solutions, axis=1, keepdims=True)
    v = again.solutions / np.linalg.norm(again.solutions, axis=1, keepdims=True)
    assert np.all(np.max(np.abs(np.conj(u) @ v.T), axis=1) > 1 - 1e-10)  # the same 40 points
    stewart_parameter.write(again, tmp_path / "start.json")
    back = stewart_parameter.load(tmp_path / "start.json")
    assert np.array_equal(back.solutions, again.solutions)


def test_the_start_file_is_written_with_a_plain_writes_mode(tmp_path):
    plain = tmp_path / "plain.json"
    plain.write_text("{}", encoding="utf-8")
    stewart_parameter.write(stewart_parameter.load(), tmp_path / "start.json")
    assert (tmp_path / "start.json").stat().st_mode & 0o777 == plain.stat().st_mode & 0o777  # not 0600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain.json", "start.json"]


def test_general_6_6_in_40_paths_matches_the_total_method():
    rng = np.random.default_rng(11)
    for _ in range(4):
        b, p = _general(rng)
        r, t = _pose(rng)
        rho = _legs(b, p, r, t)
        fast = stewart_poses(b, p, rho, method="parameter", seed=rng)
        assert fast.complete and fast.method == "parameter" and fast.paths == 40 and fast.rounds == 0
        assert fast.complex_solutions == 40
        assert any(np.allclose(x, r, atol=1e-9) and np.allclose(y, t, atol=1e-9) for x, y in fast.poses)
        assert _max_leg_error(b, p, rho, fast.poses) <= 1e-12
        total = stewart_poses(b, p, rho, method="total", seed=rng)
        assert _same_postures(fast.poses, total.poses)
        assert stewart_poses(b, p, rho, seed=rng).method == "parameter"  # auto needs no fall back


# Dietmaier's general 6-6 platform with 40 real postures (P. Dietmaier, "The Stewart-Gough
# platform of general geometry can have 40 real postures", Advances in Robot Kinematics, 1998):
# base points, platform points (platform frame) and leg lengths as published
_DIETMAIER_BASE = np.array(
    [
        [0.0, 0.0, 0.0],
        [1.107915, 0.0, 0.0],
        [0.549094, 0.756063, 0.0],
        [0.735077, -0.223935, 0.525991],
        [0.514188, -0.526063, -0.368418],
        [0.590473, 0.094733, -0.205018],
    ]
)
_DIETMAIER_PLATFORM = np.array(
    [
        [0.0, 0.0, 0.0],
        [0.542805, 0.0, 0.0],
        [0.956919, -0.528915, 0.0],
        [0.665885, -0.353482, 1.402538],
        [0.478359, 1.158742, 0.107672],
        [-0.137087, -0.235121, 0.353913],
    ]
)
_DIETMAIER_LEGS = np.array([1.0, 0.645275, 1.086284, 1.503439, 1.281933, 0.771071])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dietmaiers_platform_has_all_40_real_postures(seed):
    b, p, rho = _DIETMAIER_BASE, _DIETMAIER_PLATFORM, _DIETMAIER_LEGS
    fk = stewart_poses(b, p, rho, seed=seed)
    assert fk.complete and fk.method == "parameter" and fk.complex_solutions == 40
    assert len(fk.poses) == 40
    assert _max_leg_error(b, p, rho, fk.poses) <= 1e-12  # the legs recomputed from each posture
    for r, _ in fk.poses:
        assert np.allclose(r.T @ r, np.eye(3), atol=1e-12) and np.linalg.det(r) > 0
    # 40 different postures: every pair differs in rotation or translation
    flat = np.array([np.r_[r.ravel(), t] for r, t in fk.poses])
    gaps = np.linalg.norm(flat[:, None] - flat[None], axis=-1) + np.eye(40)
    assert np.min(gaps) > 1e-6


def _catalog_special(kind):
    m = optik.catalog.stewart_gough()
    b, p = m.params["base"].copy(), m.params["platform"].copy()
    if kind == "6-4":  # two pairs of platform points coincide
        p[1], p[3] = p[0], p[2]
    elif kind == "3-3":  # base and platform points pairwise coincide (octahedral)
        b[1], b[3], b[5] = b[0], b[2], b[4]
        p[1], p[3], p[5] = p[2], p[4], p[0]
    return b, p


@pytest.mark.parametrize("kind", ["planar", "6-4", "3-3"])
def test_special_geometries_fall_back_and_stay_complete(kind):
    b, p = _catalog_special(kind)
    rng = np.random.default_rng(5)
    r, t = _pose(rng)
    rho = _legs(b, p, r, t)
    auto = stewart_poses(b, p, rho, seed=1)
    assert auto.complete and auto.method == "parameter+total"
    assert auto.paths == 40 + 128 * auto.rounds  # many paths stopped: no parameter retry
    assert any(np.allclose(x, r, atol=1e-9) and np.allclose(y, t, atol=1e-9) for x, y in auto.poses)
    assert _max_leg_error(b, p, rho, auto.poses) <= 1e-12
    assert _same_postures(auto.poses, stewart_poses(b, p, rho, method="total", seed=2).poses)
    alone = stewart_poses(b, p, rho, method="parameter", seed=1)
    assert not alone.complete  # the count check fails: fewer than 40 isolated solutions


def test_complex_solutions_on_request_solve_the_unscaled_equations():
    rng = np.random.default_rng(3)
    b, p = _general(rng)
    rho = _legs(b, p, *_pose(rng))
    fk = stewart_poses(b, p, rho, keep_complex=True)
    assert stewart_poses(b, p, rho).solutions is None
    z = fk.solutions
    assert z.shape == (40, 8)
    mats = study.study_matrices(b, p, study.leg_constants(b, p, rho))
    assert np.max(stewart_parameter.relative_residual(mats, z)) <= 1e-10
    real = np.max(np.abs(z.imag), axis=1) <= 1e-8
    assert np.sum(real) == len(fk.poses)


def test_cauchy_endgame_finds_a_double_root_with_winding_number_two():
    # z1^2 - s z0^2 = 0: roots z1 / z0 = +-sqrt(s) merge at s = 0 (a double root)
    c0 = np.array([[[0.0, 0.0], [0.0, 1.0]]])
    c1 = np.array([[[-1.0, 0.0], [0.0, 0.0]]])
    res = parameter_homotopy.track(
        (c0, c1, np.zeros_like(c0)), np.array([[1.0, 1.0], [1.0, -1.0]]), np.random.default_rng(0)
    )
    assert list(res.status) == ["endgame", "endgame"]
    assert list(res.winding) == [2, 2]
    assert np.all(np.abs(res.z[:, 1] / res.z[:, 0]) < 1e-10)
    assert np.all(res.condition > parameter_homotopy.SINGULAR_CONDITION)  # a double root is singular


def test_without_a_compiler_the_total_method_answers(monkeypatch):
    monkeypatch.setattr(parameter_homotopy, "available", lambda: False)
    m = optik.catalog.stewart_gough()
    b, p = m.params["base"], m.params["platform"]
    rho = _legs(b, p, np.eye(3), np.array([0.0, 0.0, 1.0]))
    fk = stewart_gough.stewart_poses(b, p, rho)
    assert fk.method == "total" and fk.complete


def test_unknown_method_is_rejected():
    m = optik.catalog.stewart_gough()
    with pytest.raises(optik.OptikError, match="method"):
        stewart_poses(m.params["base"], m.params["platform"], np.ones(6), method="fast")


def test_tracker_rejects_malformed_systems():
    c = np.zeros((1, 2, 2))
    with pytest.raises(optik.OptikError, match="system"):
        parameter_homotopy.track((c, c, np.zeros((1, 3, 3))), np.ones((2, 2)), np.random.default_rng(0))
    with pytest.raises(optik.OptikError, match="starts"):
        parameter_homotopy.track((c, c, c), np.ones((2, 3)), np.random.default_rng(0))


def _leg_line(rng):
    b, p = _general(rng)
    rho = _legs(b, p, *_pose(rng))
    size = max(np.max(np.linalg.norm(b, axis=1)), np.max(rho))
    b, p, rho = b / size, p / size, rho / size
    c = study.leg_constants(b, p, rho)
    start = stewart_parameter.load()
    db, dp, dc = start.base - b, start.platform - p, start.constants - c
    # M(s) = C0 + s C1 + s^2 C2 from M(0), M(1), M(-1) (M is quadratic in s)
    m0, m_plus, m_minus = (study.study_matrices(b + s * db, p + s * dp, c + s * dc) for s in (0.0, 1.0, -1.0))
    mats = (m0.astype(complex), (m_plus - m_minus) / 2, (m_plus + m_minus) / 2 - m0)
    legs = parameter_homotopy.LegLine(b, db, p, dp, c, dc)
    return mats, legs, start


def test_leg_line_evaluation_tracks_the_same_paths_as_the_matrices():
    mats, legs, start = _leg_line(np.random.default_rng(21))
    by_matrix = parameter_homotopy.track(mats, start.solutions, np.random.default_rng(4))
    by_legs = parameter_homotopy.track(legs, start.solutions, np.random.default_rng(4))
    assert list(by_legs.status) == list(by_matrix.status)
    assert np.allclose(by_legs.z, by_matrix.z, rtol=0, atol=1e-9)
    # and every end point solves the target (s = 0) quadrics
    assert np.max(stewart_parameter.relative_residual(mats[0], by_legs.z)) <= 1e-8


@pytest.mark.skipif(not parameter_homotopy.has_avx(), reason="needs a processor with AVX")
def test_avx_and_baseline_builds_track_the_same_points_bit_for_bit(monkeypatch):
    """The AVX build evaluates four legs a lane group, the baseline one two: the same operations
    on every lane, so the same end points, statuses and step counts exactly."""
    _, legs, start = _leg_line(np.random.default_rng(25))
    runs = {}
    for flags in (parameter_homotopy._FLAGS, (*parameter_homotopy._FLAGS, *parameter_homotopy.AVX_FLAGS)):
        monkeypatch.setattr(parameter_homotopy, "has_avx", lambda f=flags: len(f) > 1)
        monkeypatch.setattr(parameter_homotopy, "_LIB", [])
        res = parameter_homotopy.track(legs, start.solutions, np.random.default_rng(5), refine=2)
        runs[flags] = (res.z, res.status, res.steps, res.condition, res.residual)
    (z1, st1, n1, c1, r1), (z2, st2, n2, c2, r2) = runs.values()
    assert n1 == n2 and list(st1) == list(st2) and np.sum(st1 == "regular") >= 30
    assert np.array_equal(z1, z2, equal_nan=True) and np.array_equal(c1, c2) and np.array_equal(r1, r2)


def test_a_compiler_that_rejects_the_avx_flags_gets_the_baseline_build(monkeypatch):
    monkeypatch.setattr(parameter_homotopy, "has_avx", lambda: True)
    monkeypatch.setattr(parameter_homotopy, "AVX_FLAGS", ("-mno-such-option-optik",))
    monkeypatch.setattr(parameter_homotopy, "_LIB", [])
    assert parameter_homotopy.available()
    _, legs, start = _leg_line(np.random.default_rng(26))
    res = parameter_homotopy.track(legs, start.solutions, np.random.default_rng(6))
    assert np.sum(res.status == "regular") >= 30


@pytest.mark.parametrize("seed", [23, 24])
@pytest.mark.parametrize("by_legs", [False, True])
def test_tracker_condition_numbers_residuals_and_refinement_equal_numpy(seed: int, by_legs: bool):
    mats, legs, start = _leg_line(np.random.default_rng(seed))
    system = legs if by_legs else mats
    plain = parameter_homotopy.track(system, start.solutions, np.random.default_rng(seed))
    refined = parameter_homotopy.track(system, start.solutions, np.random.default_rng(seed), refine=2)
    ended = (plain.status == "regular") | (plain.status == "endgame")
    assert list(refined.status) == list(plain.status) and ended.sum() >= 30
    for res in (plain, refined):
        z = res.z[ended]
        want = parameter_homotopy.condition_numbers(mats[0], z)
        assert np.allclose(res.condition[ended], want, rtol=1e-9, atol=0)
        want = stewart_parameter.relative_residual(mats[0], z)
        assert np.allclose(res.residual[ended], want, rtol=1e-6, atol=1e-15)  # rounding: 1e-16
        assert np.all(np.isinf(res.condition[~ended])) and np.all(np.isinf(res.residual[~ended]))
    # the tracker's refinement is homotopy.refine's Newton steps, here from points moved off the
    # solutions (the end points are exact to rounding already)
    noise = np.random.default_rng(seed).normal(size=(2, *plain.z[ended].shape))
    moved = plain.z[ended] + 1e-4 * (noise[0] + 1j * noise[1])
    tracker = parameter_homotopy._Tracker(system, 1.0, np.ones(8, dtype=complex))
    for iters in (1, 2):
        got, cond, resid = tracker.finish(moved, iters)
        want = homotopy.refine(mats[0], moved, iters=iters)
        assert np.max(np.linalg.norm(got - want, axis=1) / np.linalg.norm(want, axis=1)) <= 1e-12
        assert np.allclose(resid, stewart_parameter.relative_residual(mats[0], want), rtol=1e-6, atol=1e-15)
        assert np.allclose(cond, parameter_homotopy.condition_numbers(mats[0], want), rtol=1e-9, atol=0)
    assert np.max(resid) <= 1e-9 < 1e-6 < np.min(stewart_parameter.relative_residual(mats[0], moved))


def test_leg_line_of_the_wrong_shape_is_rejected():
    _, legs, start = _leg_line(np.random.default_rng(22))
    short = parameter_homotopy.LegLine(legs.base[:5], *list(vars(legs).values())[1:])
    with pytest.raises(optik.OptikError, match="system"):
        parameter_homotopy.track(short, start.solutions, np.random.default_rng(0))
    with pytest.raises(optik.OptikError, match="starts"):
        parameter_homotopy.track(legs, np.ones((1, 3)), np.random.default_rng(0))


def test_tracker_solves_a_generic_pair_of_conics_from_a_product_start():
    # two conics in P^2 (n = 3: the matrix evaluation and the general-size LU): Bezout's 4
    # intersections, from the start z1^2 = z0^2, z2^2 = z0^2 (solutions (1, +-1, +-1)) on the
    # line M(s) = T + s (S - T)
    rng = np.random.default_rng(5)
    target = rng.normal(size=(2, 3, 3)) + 1j * rng.normal(size=(2, 3, 3))
    target = target + np.swapaxes(target, 1, 2)
    start = np.zeros((2, 3, 3))
    start[:, 0, 0] = -1.0
    start[0, 1, 1] = start[1, 2, 2] = 1.0
    starts = np.array([[1.0, a, b] for a in (1.0, -1.0) for b in (1.0, -1.0)])
    res = parameter_homotopy.track((target, start - target, np.zeros_like(target)), starts, rng, refine=2)
    assert list(res.status) == ["regular"] * 4
    assert len(stewart_parameter.distinct(target, res.z)) == 4
    assert np.max(stewart_parameter.relative_residual(target, res.z)) <= 1e-13
    assert np.all(res.condition < 1e6)


# Two random general 6-6 platforms of `optik benchmark parallel_fk` (seed 0, platforms 495 and 562)
# whose drawn posture has a second real posture about 1e-4 away (both nonsingular, condition
# numbers near 1e6): a fixed distinctness threshold merged the pair, the count check found 39,
# and the drawn posture (495) or its neighbour (562) was lost with an odd real count. fkSGP finds
# 2 and 6 real postures. (base, platform, drawn R, drawn t, real postures)
CLOSE_PAIRS = [
    (
        [
            [0.786883322847242, -0.6225303865934003, -0.06970318324864382],
            [0.9650572282889605, -0.5284484927801881, 0.1534713640304652],
            [-0.8275160986107158, 0.6026770148832671, 1.1512452972811225],
            [-0.08638723892696673, -0.024176162601041214, -1.3311905304520246],
            [0.04996219090018616, -1.5884947870702049, 1.3032999133376688],
            [-1.6197263240700255, 1.5314336445754848, 0.8990147898083549],
        ],
        [
            [0.4929590161856489, 0.4661499761783277, 0.219266035950282],
            [1.0590492279527637, 0.3726811923706987, -0.7198301750036206],
            [-0.08437791371184362, 0.773935022743793, -0.5186298764413583],
            [0.10168052522897432, -0.4417767364729544, 0.023535196622409407],
            [-0.6421234260410651, 0.12489987557163525, 0.20326337349715762],
            [-0.4119138371439414, -0.04437796439382887, 0.09041744351341224],
        ],
        [
            [0.08110739331463068, -0.5691389327485123, -0.8182313034708398],
            [0.9937449347691347, -0.01704961430114027, 0.11036446562580715],
            [-0.07676324231292897, -0.8220645874151654, 0.5641960818257605],
        ],
        [0.07695243609507842, 0.025587716634166813, 1.1667963078781347],
        2,
    ),
    (
        [
            [0.8432885360381779, -0.5653593436645371, 0.5632054917674696],
            [0.3872077789758758, 0.12819222748612855, 0.03750814205529572],
            [0.09507639313296141, 0.5307729776272294, -0.5273343821621721],
            [0.38748753296154814, -0.7139452956637847, 1.963214030035177],
            [0.001806198111695017, 0.5126688588307085, 0.22142341189019507],
            [2.245469959428984, -0.4865476255082497, -1.7384926597350367],
        ],
        [
            [-0.3822280842470939, 0.10884169900550832, 0.1283498964336751],
            [-1.27575362757941, 0.6021311558831514, -0.5050793579340176],
            [-0.3931528364547799, 0.2184959487330744, 0.4983276583213821],
            [-0.19030589035938208, -0.059073811243833346, -0.5821763812809853],
            [-0.7596077359414869, -0.438898692497434, 1.2399834924573951],
            [-0.0636156410295932, 0.5025070886255308, -0.19852452727157358],
        ],
        [
            [0.8132058700815717, -0.37145730407279254, 0.44801304011808263],
            [-0.24742651058552279, -0.9174471868784646, -0.3115618416113618],
            [0.5267602250781146, 0.14251361527855533, -0.8379818224376288],
        ],
        [-0.2838803082751397, 0.17409535702547838, 0.9384387481756454],
        6,
    ),
]


@pytest.mark.parametrize("case", range(len(CLOSE_PAIRS)))
def test_two_real_postures_1e4_apart_are_both_found(case):
    b, p, r, t = (np.array(x, dtype=float) for x in CLOSE_PAIRS[case][:4])
    n_real = CLOSE_PAIRS[case][4]
    rho = _legs(b, p, r, t)
    fk = stewart_poses(b, p, rho, seed=case, keep_complex=True)
    assert fk.complete and fk.complex_solutions == 40
    assert len(fk.poses) == n_real
    assert any(np.allclose(r2, r, atol=1e-8) and np.allclose(t2, t, atol=1e-8) for r2, t2 in fk.poses)
    gaps = [np.linalg.norm(t1 - t2) for i, (_, t1) in enumerate(fk.poses) for _, t2 in fk.poses[:i]]
    assert 1e-5 < min(gaps) < 1e-3  # the close pair, both kept
    assert _max_leg_error(b, p, rho, fk.poses) <= 1e-9
    _assert_conjugate_closed(b, p, rho, fk)


def _assert_conjugate_closed(b, p, rho, fk):
    """A complete set of a real platform: 40 solutions closed under conjugation, the real ones
    (each its own conjugate) exactly the postures, so their number is even."""
    assert fk.complete and fk.complex_solutions == 40
    mats = study.study_matrices(b, p, study.leg_constants(b, p, rho))  # fk.solutions: unscaled
    both = np.concatenate([fk.solutions, np.conj(fk.solutions)])
    assert len(stewart_parameter.distinct(mats, both)) == 40
    assert np.sum(stewart_parameter.self_conjugate(mats, fk.solutions)) == len(fk.poses)
    assert len(fk.poses) % 2 == 0


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_complete_sets_of_random_platforms_have_an_even_real_count(seed):
    rng = np.random.default_rng(seed)
    b, p = _general(rng)
    r, t = optik.spatial.so3_exp(rng.normal(size=3)), np.r_[0.2 * rng.normal(size=3)] + [0, 0, 1.0]
    rho = _legs(b, p, r, t)
    fk = stewart_poses(b, p, rho, seed=seed, keep_complex=True)
    if fk.complete:  # a general platform: always, within the default time limit
        _assert_conjugate_closed(b, p, rho, fk)
    assert any(np.allclose(r2, r, atol=1e-8) and np.allclose(t2, t, atol=1e-8) for r2, t2 in fk.poses)


def _on_solution_curve(mats, z0, rng, count):
    """``count`` points of the solution set of ``mats`` near ``z0`` (a curve): Gauss-Newton on
    the quadrics, one random hyperplane through a perturbed start and the patch ``|z| = 1``."""
    points = []
    for _ in range(count):
        z = z0 + 0.05 * (rng.normal(size=8) + 1j * rng.normal(size=8))
        a, c = rng.normal(size=8) + 1j * rng.normal(size=8), np.conj(z) / np.vdot(z, z)
        level = a @ z
        for _ in range(50):
            f = np.r_[np.einsum("kij,i,j->k", mats, z, z), a @ z - level, c @ z - 1]
            jac = np.vstack([2 * np.einsum("kij,j->ki", mats, z), a, c])
            z = z - np.linalg.lstsq(jac, f, rcond=None)[0]
        points.append(z)
    return np.array(points)


def test_singular_end_points_on_a_solution_curve_never_count_towards_40():
    """An architecturally singular platform (planar base on a circle, platform its affine image:
    det J = 0 at every posture) has a curve of solutions. 45 distinct points of it would pass a
    count of distinct solutions (the old rule of the total method); the count check counts only
    nonsingular ones, so they certify nothing."""
    rng = np.random.default_rng(0)
    angles = rng.uniform(0, 2 * np.pi, 6)
    b = np.c_[np.cos(angles), np.sin(angles), np.zeros(6)]
    p = b @ np.array([[0.5, 0.2, 0.0], [-0.1, 0.6, 0.0], [0.0, 0.0, 0.0]]).T + [0.1, -0.05, 0.0]
    w = 0.4 * rng.normal(size=3)
    e = np.r_[np.cos(np.linalg.norm(w) / 2), np.sin(np.linalg.norm(w) / 2) * w / np.linalg.norm(w)]
    r, t = study.quat_to_rot(e), np.r_[0.2 * rng.normal(size=2), 1.0]
    assert np.min(np.linalg.svd(stewart_gough.stewart_jacobian(b, p, r, t), compute_uv=False)) < 1e-12
    rho = _legs(b, p, r, t)
    mats = study.stewart_quadrics(b, p, rho)
    z0 = np.r_[e, study.quat_left(np.r_[0.0, t]) @ e / 2].astype(complex)
    assert stewart_parameter.relative_residual(mats, z0[None])[0] <= 1e-14
    z = _on_solution_curve(mats, z0, rng, 45)
    assert np.max(stewart_parameter.relative_residual(mats, z)) <= 1e-12  # solutions, to rounding
    assert len(stewart_parameter.distinct(mats, z)) == 45  # 45 distinct solutions ...
    assert not np.any(stewart_gough._nonsingular(mats, z))  # ... none of them nonsingular
    fk = stewart_poses(b, p, rho, seed=1)
    assert not fk.complete


def test_a_general_platform_with_one_abandoned_path_completes_without_the_total_method():
    """Platform 329 of `optik benchmark parallel_fk`'s draws: for seed 1218 (the first seed that
    does it at the tracker's step settings; 329 did under the earlier ones) one of the 40 paths
    stalls near the degenerate set and is abandoned, although every path of a general platform
    ends at a solution. The retry (all 40 paths, fresh gamma and patch) finds the 40th solution,
    so the 128-path method is not needed."""
    b = np.array(
        [
            [-0.42446340572428154, 0.4855908541446909, -1.073939962767264],
            [-0.06564455080248946, -0.15261728902872068, 0.27351607353815593],
            [-0.09519372737428546, 0.620829834643128, 1.110706726409124],
            [0.8079947978166283, -0.34074294474173994, 0.07092195254457881],
            [0.2561881454557774, 0.6896862473645787, -0.8770030507700027],
            [0.027828636858290155, 0.5607888688371415, 2.1137619935794927],
        ]
    )
    p = np.array(
        [
            [0.3669044604797777, -0.5358901057075748, 0.590258008513791],
            [1.105705672468466, -0.8963055334231264, -0.281118341807652],
            [-0.9633825168245035, 0.13158956612905748, 0.36578459129513663],
            [0.3880992436168, 0.2194396413398841, -0.4141239779594015],
            [1.043822973361444, 0.005127770683692344, 0.6496924608898725],
            [0.940616429330144, 0.19974326510881016, -0.8259196407908993],
        ]
    )
    rho = np.array(
        [
            2.127745868008261,
            0.8358700816009661,
            1.4305279445743821,
            1.6280010698403673,
            1.340291706023462,
            2.004390033681389,
        ]
    )
    r = np.array(
        [
            [0.2164497151864755, 0.4382130211168974, 0.8724212680347124],
            [0.28734824015946436, 0.8254282427421415, -0.485900406421809],
            [-0.9330490392647927, 0.35586172062645627, 0.052743967615506815],
        ]
    )
    t = np.array([-0.26653324033037573, -0.09586753123126485, 1.1034061092074747])
    assert np.max(np.abs(_legs(b, p, r, t) - rho)) <= 1e-14
    size = max(np.max(np.linalg.norm(b, axis=1)), np.max(np.linalg.norm(p, axis=1)), np.max(rho))
    bs, ps, rs = b / size, p / size, rho / size
    first = stewart_parameter.solve(bs, ps, study.leg_constants(bs, ps, rs), np.random.default_rng(1218), 5.0)
    assert list(first.status).count("abandoned") == 1 and first.nonsingular == 39  # the case
    fk = stewart_poses(b, p, rho, seed=1218)
    assert fk.complete and fk.method == "parameter" and fk.paths == 80 and fk.complex_solutions == 40
    assert any(np.allclose(x, r, atol=1e-9) and np.allclose(y, t, atol=1e-9) for x, y in fk.poses)
    assert _max_leg_error(b, p, rho, fk.poses) <= 1e-12
    assert _same_postures(fk.poses, stewart_poses(b, p, rho, method="total", seed=1).poses)
