"""optik.collision: World, robot collision geometry from URDF/SRDF, exact checks against coal and
against closed-form distances of primitives, and an independent Pinocchio + coal check."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik import spatial
from optik.collision import World, check, check_many, robot_geometry
from optik.errors import InvalidArgumentError, UnknownFrameError

coal = pytest.importorskip("coal", reason="collision checks need coal (extra 'collision')")


@pytest.fixture(scope="module")
def arm(toy_arm_urdf) -> optik.Mechanism:
    return optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip")


def _panda(srdf: bool = True):
    from optik.catalog.robots import robots_dir

    try:
        d = robots_dir() / "panda_description"
    except optik.MissingExtraError:
        pytest.skip("example-robot-data (extra 'robots') is not installed")
    if not d.is_dir():
        pytest.skip("example-robot-data has no panda_description")
    s = d / "srdf" / "panda.srdf" if srdf else None
    return optik.Mechanism.from_urdf(d / "urdf" / "panda.urdf", "panda_link0", "panda_hand_tcp", srdf=s), d


# ------------------------------------------------------------------ World


def test_world_builds_moves_and_removes():
    w = World()
    w.add_box("table", (1.0, 1.0, 0.05), spatial.translation(0.5, 0, -0.025))
    w.add_sphere("ball", 0.1)
    w.add_cylinder("post", 0.05, 1.0, spatial.translation(1, 1, 0.5))
    w.add_capsule("rod", 0.02, 0.3)
    w.add_points("cloud", [[0, 0, 1], [0, 0.1, 1]], 0.01)
    assert w.names == ("table", "ball", "post", "rod", "cloud") and len(w) == 5 and "ball" in w
    v = w.version
    w.move("ball", spatial.translation(0, 0, 2))
    assert w.version > v and np.allclose(w["ball"].pose[:3, 3], [0, 0, 2])
    w.remove("rod")
    assert w.names == ("table", "ball", "post", "cloud")
    with pytest.raises(InvalidArgumentError, match="name"):
        w.add_sphere("ball", 0.2)
    with pytest.raises(UnknownFrameError, match="name"):
        w.move("nothing", np.eye(4))
    with pytest.raises(UnknownFrameError, match="name"):
        w.remove("nothing")
    with pytest.raises(InvalidArgumentError, match="size"):
        w.add_box("bad", (1.0, -1.0, 1.0))
    with pytest.raises(InvalidArgumentError, match="radius"):
        w.add_sphere("bad", float("nan"))
    with pytest.raises(InvalidArgumentError, match="pose"):
        w.add_sphere("bad", 0.1, np.ones((4, 4)))
    with pytest.raises(InvalidArgumentError, match="xyz"):
        w.add_points("bad", [[0, 0]], 0.1)
    with pytest.raises(InvalidArgumentError, match="path"):
        w.add_mesh("bad", "/no/such/mesh.stl")


def test_world_from_problem_table(tmp_path):
    table = {
        "table": {"box": [1.0, 1.2, 0.04], "xyz": [0.5, 0.0, -0.02]},
        "ball": {"sphere": 0.05, "xyz": [0.4, 0.2, 0.3]},
        "post": {"cylinder": [0.05, 1.0], "xyz": [1, 1, 0.5], "rpy": [0, 0, 0.3]},
        "cloud": {"points": [[0, 0, 1]], "radius": 0.01, "xyz": [0, 0, 1]},
    }
    w = World.from_table(table)
    assert w.names == ("table", "ball", "post", "cloud")
    assert w["post"].shape.size == (0.05, 1.0)
    assert np.allclose(w["cloud"].shape.points, [[0, 0, 2]])
    with pytest.raises(InvalidArgumentError, match=r"world\.x"):
        World.from_table({"x": {"box": [1, 1, 1], "sphere": 1.0}})
    with pytest.raises(InvalidArgumentError, match=r"world\.x"):
        World.from_table({"x": {"box": [1, 1, 1], "colour": "red"}})


# ------------------------------------------------------------------ robot geometry


def test_chain_keeps_links_off_its_path(arm, toy_arm_urdf):
    """The sensor hangs off the chain on a fixed joint: it is a frame and keeps its geometry."""
    assert "sensor" in arm.frames
    links = {c.link for c in arm.params["collisions"]}
    assert links == {"base", "upper", "fore", "hand", "sensor"}
    whole = optik.Mechanism.from_urdf(toy_arm_urdf)
    q = np.array([0.4, -0.9])
    assert np.allclose(arm.fk(q, "sensor"), whole.fk(q, "sensor"), atol=1e-12)


def test_moving_joints_off_the_chain_are_held_at_zero_within_limits():
    m, _ = _panda()
    assert m.params["held_joints"] == {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    assert {"panda_leftfinger", "panda_rightfinger"} <= set(m.frames)
    assert m.n_q == 7
    full = optik.Mechanism.from_urdf(m.params["urdf"])
    q = m.random_q(seed=3)
    qf = np.zeros(full.n_q)
    qf[: m.n_q] = q  # the fingers' coordinates are last in the whole tree, at 0
    assert full.coordinate_names[:7] == m.coordinate_names
    assert np.allclose(m.fk(q, "panda_leftfinger"), full.fk(qf, "panda_leftfinger"), atol=1e-12)


def test_srdf_pairs_are_not_checked():
    m, _ = _panda()
    geo = robot_geometry(m)
    assert geo.disabled[("panda_link0", "panda_link2")] == "srdf"
    checked = {
        tuple(sorted((geo.links[geo.part_link[i]], geo.links[geo.part_link[j]]))) for i, j in geo.self_pairs
    }
    assert ("panda_link0", "panda_link2") not in checked
    assert ("panda_link1", "panda_link7") in checked or ("panda_link1", "panda_link7") not in geo.disabled
    with pytest.raises(InvalidArgumentError, match="srdf"):
        optik.Mechanism.from_urdf(m.params["urdf"], "panda_link0", srdf="/no/such.srdf")


def test_structural_pairs_without_srdf(arm):
    geo = robot_geometry(arm)
    assert geo.disabled[("fore", "hand")] == "same body"
    assert geo.disabled[("base", "upper")] == "adjacent"
    assert geo.disabled[("fore", "upper")] == "adjacent"
    assert geo.disabled[("sensor", "upper")] == "same body"
    checked = {
        tuple(sorted((geo.links[geo.part_link[i]], geo.links[geo.part_link[j]]))) for i, j in geo.self_pairs
    }
    # a link fixed to a body (sensor on the upper arm, hand on the forearm) meets the next body
    expected = {("base", "fore"), ("base", "hand"), ("base", "sensor"), ("fore", "sensor")}
    assert checked == expected | {("hand", "sensor"), ("hand", "upper")}


def test_mechanism_without_geometry_is_an_error():
    with pytest.raises(InvalidArgumentError, match=r"m: .*collision geometry"):
        check(optik.catalog.panda(), np.zeros(7))


# ------------------------------------------------------------------ exact distances


def test_sphere_hand_distance_to_a_ball_is_exact(arm):
    """Closed form: two spheres at distance |c1 - c2| - r1 - r2."""
    q = np.array([0.3, -0.6])
    hand = arm.fk(q, "hand")[:3, 3]
    centre = hand + np.array([0.0, 0.0, 0.3])
    w = World()
    w.add_sphere("ball", 0.1, spatial.translation(*centre))
    r = check(arm, q, w, self_collision=False)
    assert r.pair == ("hand", "ball")
    assert r.min_distance == pytest.approx(0.3 - 0.05 - 0.1, abs=1e-6)
    pa, pb = r.witness
    assert np.linalg.norm(pa - pb) == pytest.approx(r.min_distance, abs=1e-6)
    assert np.allclose(pa, hand + np.array([0, 0, 0.05]), atol=1e-6)
    assert not r.in_collision
    near = check(arm, q, w, margin=0.2, self_collision=False)
    assert near.in_collision and near.close_pairs[0].b == "ball" and near.close_pairs[0].world


def test_penetration_is_a_negative_distance(arm):
    q = np.array([0.0, 0.0])
    w = World()
    w.add_box("wall", (0.1, 1.0, 1.0), spatial.translation(0.45, 0.0, 0.1))  # cuts the upper arm
    r = check(arm, q, w)
    assert r.in_collision and r.min_distance < 0 and r.pair == ("upper", "wall")
    assert r.close_pairs == tuple(sorted(r.close_pairs, key=lambda p: p.distance))


def test_self_collision_of_a_folded_arm(arm):
    """Folding the forearm back over the base puts the hand into the base cylinder's column."""
    free = check(arm, np.array([0.0, 0.0]))
    assert not free.in_collision and np.isfinite(free.min_distance)
    w = World()
    far = check(arm, np.array([0.0, 0.0]), w, self_collision=False)
    assert far.pair is None and far.min_distance == np.inf and not far.in_collision


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    st.lists(st.floats(-2.8, 2.8), min_size=2, max_size=2),
    st.lists(
        st.tuples(st.floats(-0.8, 0.8), st.floats(-0.8, 0.8), st.floats(-0.2, 0.4)), min_size=1, max_size=4
    ),
    st.floats(0.0, 0.1),
)
def test_pruned_search_equals_every_pair(arm, q, centres, margin):
    """The bounding-sphere search gives the distance and the close pairs of the brute force."""
    from optik.collision.distance import signed_distance

    w = World()
    for k, c in enumerate(centres):
        w.add_box(f"b{k}", (0.1, 0.2, 0.15), spatial.translation(*c))
    q = np.array(q)
    r = check(arm, q, w, margin=margin)
    geo = robot_geometry(arm)
    poses = geo.part_poses(q)
    dists = [signed_distance(geo.parts[i], poses[i], geo.parts[j], poses[j])[0] for i, j in geo.self_pairs]
    for o in w.parts():
        dists += [signed_distance(p, poses[i], o, o.offset)[0] for i, p in enumerate(geo.parts)]
    assert r.min_distance == pytest.approx(min(dists), abs=1e-9)
    assert len(r.close_pairs) == sum(d < margin or d <= 0 for d in dists)
    assert r.in_collision == any(d < margin or d <= 0 for d in dists)


def test_check_many_matches_check(arm):
    w = World()
    w.add_sphere("ball", 0.1, spatial.translation(0.6, 0.2, 0.1))
    Q = arm.random_q(12, seed=1)
    b = check_many(arm, Q, w, margin=0.01)
    for q, d, c in zip(Q, b.min_distance, b.in_collision, strict=True):
        r = check(arm, q, w, margin=0.01)
        assert r.min_distance == d and r.in_collision == c


def test_bad_arguments(arm):
    with pytest.raises(InvalidArgumentError, match="margin"):
        check(arm, np.zeros(2), margin=-1.0)
    with pytest.raises(InvalidArgumentError, match="world"):
        check(arm, np.zeros(2), world="table")
    with pytest.raises(InvalidArgumentError, match="q"):
        check(arm, np.zeros(3))


def test_panda_distances_match_pinocchio_and_coal():
    """Independent check: Pinocchio's own URDF + geometry loading, coal distances on its models."""
    pin = pytest.importorskip("pinocchio", reason="the independent check needs Pinocchio")
    m, d = _panda()
    urdf = str(d / "urdf" / "panda.urdf")
    full = pin.buildModelFromUrdf(urdf)
    geom = pin.buildGeomFromUrdf(full, urdf, pin.GeometryType.COLLISION, package_dirs=[str(d.parents[2])])
    w = World()
    w.add_box("table", (1.0, 1.2, 0.04), spatial.translation(0.5, 0.0, -0.03))
    w.add_box("box", (0.2, 0.2, 0.2), spatial.translation(0.45, 0.0, 0.35))
    data, gdata = full.createData(), geom.createData()
    for q in m.random_q(10, seed=5):
        qp = pin.neutral(full)
        qp[:7] = q
        pin.updateGeometryPlacements(full, data, geom, gdata, qp)
        best = np.inf
        for go in geom.geometryObjects:
            tf = gdata.oMg[geom.getGeometryId(go.name)]
            for o in w.snapshot():
                box = coal.Box(*o.shape.size)
                tb = coal.Transform3s(o.pose[:3, :3], o.pose[:3, 3])
                req, res = coal.DistanceRequest(), coal.DistanceResult()
                geo = go.geometry
                if isinstance(geo, coal.BVHModelBase):
                    geo.buildConvexHull(True, "Qt")
                    geo = geo.convex
                best = min(
                    best, coal.distance(geo, coal.Transform3s(tf.rotation, tf.translation), box, tb, req, res)
                )
        r = check(m, q, w, self_collision=False)
        assert r.min_distance == pytest.approx(best, abs=1e-6)


def test_sphere_model_bounds_never_exceed_exact_distances(arm, tmp_path):
    """Conservative where the solvers rely on it: when a part's spheres are all clear by ``b >= 0``
    of an obstacle's slot (a rounded box containing it: a cylinder's box), the part is clear by ``b``
    (smallest row <= exact coal distance; penetration depths of a union of spheres are not ordered
    so, and no constraint uses them); empty slots are inactive."""
    import casadi as ca

    from optik.collision.distance import signed_distance
    from optik.collision.slots import SLOT_SIZE, capacity_for, slot_values
    from optik.collision.spheres import distance_expressions, sphere_model

    w = World()
    w.add_box("box", (0.2, 0.3, 0.1), spatial.transform(spatial.rot_z(0.4), [0.5, 0.3, 0.1]))
    w.add_sphere("ball", 0.05, spatial.translation(-0.4, 0.2, 0.15))
    w.add_cylinder("post", 0.04, 0.5, spatial.translation(0.2, -0.5, 0.2))
    w.add_capsule("rod", 0.03, 0.3, spatial.transform(spatial.rot_x(1.2), [-0.3, -0.4, 0.1]))
    geo = robot_geometry(arm)
    model = sphere_model(geo)
    obstacles = w.parts()
    capacity = capacity_for(len(obstacles))
    slots = ca.SX.sym("slots", capacity * SLOT_SIZE)
    rows = distance_expressions(geo, [arm.frame_expr(link) for link in geo.links], slots, False)
    f = ca.Function("d", [arm.q_sym, slots], [rows.world, rows.active])
    values = slot_values(obstacles, capacity)
    for q in arm.random_q(30, seed=8):
        d, active = (np.asarray(v).ravel() for v in f(q, values))
        moving = model.part != 0  # part 0, the base, is on the base body: no rows
        d = d.reshape(int(moving.sum()), capacity)
        assert len(rows.world_pairs) == d.size
        assert np.all(active.reshape(d.shape) == (np.arange(capacity) < len(obstacles)))
        poses = geo.part_poses(q)
        for k, part in enumerate(geo.parts):
            if k == 0:
                continue
            exact = [signed_distance(part, poses[k], o, o.offset)[0] for o in obstacles]
            bound = d[model.part[moving] == k][:, : len(obstacles)].min(axis=0)
            clear = bound >= 0
            assert np.all(bound[clear] <= np.array(exact)[clear] + 1e-6)


def test_separable_pairs_keep_none_when_no_sample_clears_them_together():
    """TALOS (torso and left arm solved): its pairs pass one by one, but its capsules are so much
    fatter than its meshes that no sampled configuration has them all apart, nor do the exact
    check's clear configurations: none is kept, so the self rows are left to the exact check,
    and the collision-aware lm still solves (every success clear by the exact check)."""
    from optik.catalog.robots import robots_dir
    from optik.collision.spheres import capsule_gaps, separable_pairs

    try:
        d = robots_dir() / "talos_data"
    except optik.OptikError as exc:
        pytest.skip(str(exc))
    urdf = d / "robots" / "talos_reduced.urdf"
    m = optik.Mechanism.from_urdf(urdf, "base_link", "gripper_left_base_link", srdf=d / "srdf" / "talos.srdf")
    geo = robot_geometry(m)
    gaps = capsule_gaps(geo) >= 0.012
    one_by_one = gaps.mean(axis=1) >= 0.05
    assert one_by_one.sum() > len(geo.self_pairs) // 2 and not gaps[one_by_one].all(axis=0).any()
    assert not separable_pairs(geo, 0.012).any()
    rng = np.random.default_rng(0)
    q = m.random_q(seed=rng)
    while check(m, q, margin=0.01).in_collision:
        q = m.random_q(seed=rng)
    target = m.fk(q, "gripper_left_base_link")
    res = optik.solve_ik(m, target, self_collision=True, margin=0.01, time_limit=5.0, tol=1e-6, seed=1)
    assert res.success, res.message
    assert np.linalg.norm(m.fk(res.q, "gripper_left_base_link")[:3, 3] - target[:3, 3]) <= 1e-6
    assert not check(m, res.q, margin=0.01).in_collision


def test_capsule_gaps_are_the_self_rows_at_the_sampled_configurations():
    """`capsule_gaps` (link poses of all samples at once, then one mapped segment distance) equals
    the kernel's own self rows (`distance_expressions`) evaluated one sampled configuration at a
    time; `separable_pairs` thresholds it; the entry dies with its geometry (no mechanism kept)."""
    import gc
    import weakref

    import casadi as ca

    from optik.collision.spheres import SEPARABLE_SAMPLES, capsule_gaps, distance_expressions, separable_pairs

    m, _ = _panda()
    geo = robot_geometry(m)
    gaps = capsule_gaps(geo)
    assert gaps.shape == (len(geo.self_pairs), SEPARABLE_SAMPLES)
    rows = distance_expressions(geo, [m.frame_expr(link) for link in geo.links], ca.SX(0, 1), True)
    f = ca.Function("self_rows", [m.q_sym], [rows.self_rows])
    samples = m.random_q(SEPARABLE_SAMPLES, seed=0)
    for s in range(0, SEPARABLE_SAMPLES, 7):
        assert np.allclose(np.asarray(f(samples[s])).ravel(), gaps[:, s], rtol=0, atol=1e-12)
    mixed = np.quantile(np.quantile(gaps, 0.95, axis=1), 0.5)  # a bound half the pairs keep
    for bound in (0.0, 0.01, mixed):
        kept = (gaps >= bound).mean(axis=1) >= 0.05
        assert (gaps[kept] >= bound).all(axis=0).any()  # some sample has them all apart
        assert np.array_equal(separable_pairs(geo, bound), kept)
    assert 0 < separable_pairs(geo, mixed).sum() < len(geo.self_pairs)
    ref = weakref.ref(geo)
    del m, geo, f, rows
    gc.collect()
    assert ref() is None  # _GAPS holds its keys weakly and its values (arrays) hold no geometry


def test_slots_contain_their_obstacles(tmp_path):
    """Every slot's rounded box holds its obstacle (points of the solid have slot distance <= 0) and
    is exact for boxes, spheres and capsules (coal's distance of a probe sphere, shifted by its radius)."""
    import casadi as ca
    import trimesh

    from optik.collision.distance import signed_distance
    from optik.collision.parts import parts_of
    from optik.collision.shapes import Shape
    from optik.collision.slots import SLOT_SIZE, slot_distance, slot_values

    mesh = trimesh.creation.icosphere(subdivisions=1, radius=0.1)
    mesh.apply_transform(np.diag([1.0, 0.4, 0.7, 1.0]))
    mesh.export(tmp_path / "blob.stl")
    w = World()
    w.add_box("box", (0.2, 0.3, 0.1), spatial.transform(spatial.rot_z(0.4), [0.5, 0.3, 0.1]))
    w.add_sphere("ball", 0.05, spatial.translation(-0.4, 0.2, 0.15))
    w.add_capsule("rod", 0.03, 0.3, spatial.transform(spatial.rot_x(1.2), [-0.3, -0.4, 0.1]))
    w.add_cylinder("post", 0.04, 0.5, spatial.transform(spatial.rot_y(0.3), [0.2, -0.5, 0.2]))
    w.add_mesh("blob", tmp_path / "blob.stl", spatial.transform(spatial.rot_x(0.7), [0.1, 0.1, 0.6]))
    parts = w.parts()
    slot, p = ca.SX.sym("slot", SLOT_SIZE), ca.SX.sym("p", 3)
    f = ca.Function("sdf", [slot, p], [slot_distance(slot, p, 0.0)])
    values = slot_values(parts, 8).reshape(8, SLOT_SIZE)
    probe = parts_of("probe", Shape("sphere", (1e-3,)), np.eye(4))[0]
    rng = np.random.default_rng(3)
    for part, row in zip(parts, values[: len(parts)], strict=True):
        inside = 0
        for x in part.centre + rng.uniform(-0.7, 0.7, (100, 3)) * part.radius:
            exact = signed_distance(probe, spatial.translation(*x), part, part.offset)[0] + 1e-3
            bound = float(f(row, x))
            assert bound <= exact + 1e-6  # inside the solid (exact < 0): inside the slot
            inside += exact < 0
            if part.shape.kind in ("box", "sphere", "capsule"):
                assert bound == pytest.approx(exact, abs=1e-6)
        assert inside >= 2
    assert np.all(values[len(parts) :] == 0)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.floats(-1, 1), min_size=12, max_size=12))
def test_segment_distance_is_the_minimum_over_both_segments(xs):
    import casadi as ca

    from optik.collision.spheres import segment_distance

    p1, q1, p2, q2 = (np.array(xs[i : i + 3]) for i in range(0, 12, 3))
    if len(set(map(tuple, (p1, q1)))) == 1:
        q1 = p1.copy()  # a point, also covered
    d = float(segment_distance(*(ca.DM(v) for v in (p1, q1, p2, q2))))
    t = np.linspace(0, 1, 401)
    a = p1 + t[:, None] * (q1 - p1)
    b = p2 + t[:, None] * (q2 - p2)
    grid = np.linalg.norm(a[:, None] - b[None], axis=2).min()
    assert d <= grid + 1e-9
    assert d >= grid - 2e-3 * (np.linalg.norm(q1 - p1) + np.linalg.norm(q2 - p2)) - 1e-9


def test_allowed_collision_matrix_is_cached_on_disk(toy_arm_urdf, tmp_path, monkeypatch, caplog):
    """Without an SRDF the sampled pairs are written once (atomically) and read by a fresh model;
    a damaged file is logged and replaced by a new sampling."""
    import json
    import logging

    import optik.collision.robot as robot

    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    first = robot_geometry(optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip"))
    (path,) = (tmp_path / "acm").glob("*.json")
    assert json.loads(path.read_text())["format"] == robot.ACM_FORMAT
    sample = robot._always_colliding

    def refuse(*args):
        raise AssertionError("sampled again")

    monkeypatch.setattr(robot, "_always_colliding", refuse)
    again = robot_geometry(optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip"))
    assert again is not first and again.disabled == first.disabled
    monkeypatch.setattr(robot, "_always_colliding", sample)
    for damage in ("{not json", '{"format": 1, "always": [["base", "no_such_link"]]}', ""):
        path.write_text(damage)
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="optik.collision.robot"):
            fresh = robot_geometry(optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip"))
        assert "damaged" in caplog.text
        assert fresh.disabled == first.disabled
        assert json.loads(path.read_text())["format"] == robot.ACM_FORMAT


def _cluttered_world(tmp_path):
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=1, radius=0.08)
    mesh.apply_transform(np.diag([1.0, 0.5, 0.8, 1.0]))
    mesh.export(tmp_path / "blob.stl")
    w = World()
    w.add_box("table", (1.4, 1.6, 0.04), spatial.translation(0.3, 0.0, -0.06))
    w.add_box("shelf", (0.3, 0.84, 0.02), spatial.transform(spatial.rot_z(0.3), [0.55, 0.0, 0.45]))
    w.add_sphere("ball", 0.08, spatial.translation(0.3, 0.35, 0.5))
    w.add_cylinder("post", 0.04, 0.6, spatial.translation(-0.3, -0.4, 0.3))
    w.add_capsule("rod", 0.03, 0.4, spatial.transform(spatial.rot_x(1.2), [0.2, -0.3, 0.7]))
    w.add_mesh("blob", tmp_path / "blob.stl", spatial.transform(spatial.rot_y(0.7), [-0.2, 0.3, 0.8]))
    w.add_points("cloud", [[0.4, -0.2, 0.3], [0.45, -0.2, 0.3]], 0.03)
    return w


def test_panda_screened_search_equals_every_pair(tmp_path):
    """The Panda among every kind of obstacle, self pairs included: the screened search gives the
    minimum distance, the closest pair and the close pairs of the brute force over every pair, at
    clear and at colliding configurations, and computes far fewer exact distances at clear ones;
    both with the coarse world bounds alone and with them refined (`check.search`)."""
    from optik.collision.check import search
    from optik.collision.distance import signed_distance

    m, _ = _panda()
    w = _cluttered_world(tmp_path)
    geo = robot_geometry(m)
    obstacles = w.parts()
    clear_checked = []
    refined = set()
    for q in m.random_q(40, seed=21):
        refined.add(search(geo, q, w.state(), 0.02, True).refined)
        poses = geo.part_poses(q)
        pairs = [
            (
                geo.parts[i].name,
                geo.parts[j].name,
                signed_distance(geo.parts[i], poses[i], geo.parts[j], poses[j])[0],
            )
            for i, j in geo.self_pairs
        ]
        pairs += [
            (p.name, o.name, signed_distance(p, poses[i], o, o.offset)[0])
            for i, p in enumerate(geo.parts)
            for o in obstacles
        ]
        r = check(m, q, w, margin=0.02)
        best = min(pairs, key=lambda p: p[2])
        assert r.min_distance == pytest.approx(best[2], abs=1e-9)
        assert (r.pair == best[:2]) or r.min_distance == pytest.approx(
            sorted(p[2] for p in pairs)[1], abs=1e-9
        )
        close = sorted((a, b) for a, b, d in pairs if d < 0.02)
        assert sorted((p.a, p.b) for p in r.close_pairs) == close
        assert r.in_collision == bool(close)
        if not close:
            clear_checked.append(r.checked / r.candidates)
    assert clear_checked and max(clear_checked) < 0.25
    assert refined == {False, True}


@pytest.mark.parametrize("coarse", [False, True])
def test_screen_bounds_never_exceed_exact_distances(tmp_path, coarse):
    """The screening bounds (`optik.collision.screen`, the sphere model's or the coarse bounding
    spheres') of every pair are at most the exact distance wherever that is >= 0, and the part
    poses are those of `RobotGeometry.part_poses`."""
    from optik.collision.distance import signed_distance
    from optik.collision.screen import screen

    m, _ = _panda()
    w = _cluttered_world(tmp_path)
    geo = robot_geometry(m)
    state = w.state()
    fine = screen(geo, state.capacity)
    for q in m.random_q(15, seed=22):
        poses, to_world, own = screen(geo, state.capacity, coarse).bounds(q, state.slots, len(state.parts))
        if coarse:  # other world bounds (neither is always the larger), the same poses and self bounds
            finer = fine.bounds(q, state.slots, len(state.parts))
            assert np.array_equal(poses, finer[0]) and np.array_equal(own, finer[2])
            assert not np.allclose(to_world, finer[1])
        exact = geo.part_poses(q)
        assert np.allclose(poses[:, :9].reshape(-1, 3, 3), exact[:, :3, :3], atol=1e-12)
        assert np.allclose(poses[:, 9:], exact[:, :3, 3], atol=1e-12)
        for (i, j), bound in zip(geo.self_pairs, own, strict=True):
            d = signed_distance(geo.parts[i], exact[i], geo.parts[j], exact[j])[0]
            assert d < 0 or bound <= d + 1e-9
        for i, p in enumerate(geo.parts):
            for o, bound in zip(state.parts, to_world[i], strict=True):
                d = signed_distance(p, exact[i], o, o.offset)[0]
                assert d < 0 or bound <= d + 1e-9


def test_a_world_state_is_one_version():
    """`World.state` is immutable: a check against a state taken before a move answers for the
    world as it was, a new state for the world as it is; unchanged worlds share one state."""
    from optik.collision.check import report_at

    m, _ = _panda()
    q = m.mid_q()
    hand = m.fk(q, "panda_hand")[:3, 3]
    w = World()
    w.add_sphere("ball", 0.05, spatial.translation(*hand))
    before = w.state()
    assert w.state() is before and before.parts == w.parts()
    w.move("ball", spatial.translation(*(hand + np.array([0.0, 0.0, 2.0]))))
    after = w.state()
    assert after.version > before.version and after.parts != before.parts
    geo = robot_geometry(m)
    assert report_at(geo, q, before, 0.0, True).in_collision
    assert not report_at(geo, q, after, 0.0, True).in_collision
    assert not check(m, q, w).in_collision


def test_negative_mesh_scale_mirrors_the_hull(tmp_path):
    """A URDF ``scale="1 -1 1"`` (TALOS's mirrored meshes) is the hull with y negated; 0 is refused."""
    from optik.collision.shapes import Shape, shape_vertices

    path = tmp_path / "wedge.obj"  # an asymmetric tetrahedron
    vertices = "v 0 0 0\nv 0.3 0.05 0\nv 0.02 0.2 0.01\nv 0.05 0.07 0.4\n"
    path.write_text(vertices + "f 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    plain, _ = shape_vertices(Shape("mesh", (1.0, 1.0, 1.0), path=path))
    mirrored, _ = shape_vertices(Shape("mesh", (1.0, -1.0, 1.0), path=path))
    flip = plain * np.array([1.0, -1.0, 1.0])
    assert len(mirrored) == len(plain) == 4
    assert {tuple(np.round(v, 12)) for v in mirrored} == {tuple(np.round(v, 12)) for v in flip}
    with pytest.raises(InvalidArgumentError, match="nonzero"):
        Shape("mesh", (1.0, 0.0, 1.0), path=path)


def test_a_search_that_stops_at_the_first_close_pair(tmp_path):
    """``search(..., stop=True)`` (how a solve judges a round's answer): the same verdict as the
    full search, its one close pair one of the full search's, and where nothing is close no more
    coal queries in all than the full search (the bounds of the pairs it checks are under the
    margin, while the full search also checks the nearest pair beyond it)."""
    from optik.collision.check import search

    m, _ = _panda()
    w = _cluttered_world(tmp_path)
    geo = robot_geometry(m)
    state = w.state()
    stopped = decided = 0
    for q in m.random_q(200, seed=23):
        full, quick = search(geo, q, state, 0.02, True), search(geo, q, state, 0.02, True, stop=True)
        assert quick.in_collision == full.in_collision
        if full.in_collision:
            assert len(quick.close) == 1 and quick.close[0][:4] in [e[:4] for e in full.close]
            stopped += full.checked - quick.checked
        else:
            assert not quick.close and full.nearest[0] >= 0.02
            assert quick.nearest is None or quick.nearest[0] >= full.nearest[0]
            decided += full.checked - quick.checked
    assert stopped > 0 and decided > 0


def test_fixed_parts_are_those_no_joint_moves(arm):
    """`RobotGeometry.fixed_parts`: the parts of links whose pose is the same at every ``q``."""
    m, _ = _panda()
    geo = robot_geometry(m)
    assert {geo.parts[k].name for k in geo.fixed_parts} == {"panda_link0"}
    toy = robot_geometry(arm)
    for k, part in enumerate(toy.parts):
        poses = [toy.part_poses(q)[k] for q in arm.random_q(5, seed=3)]
        same = all(np.array_equal(p, poses[0]) for p in poses)
        assert same == (k in toy.fixed_parts), part.name


def test_fixed_part_distances_follow_the_world():
    """A fixed part's distance to an object is kept per world version (`check._FIXED`): after
    every add, move and remove the search still gives the brute force's nearest distance and
    close pairs, and a repeated search (entries known) gives the same nearest pair and close
    pairs as the first (found in another order: a known entry's bound is its distance)."""
    from optik.collision.check import search
    from optik.collision.distance import signed_distance

    m, _ = _panda()
    geo = robot_geometry(m)
    w = World()
    w.add_box("floor", (1.0, 1.0, 0.02), spatial.translation(0.0, 0.0, -0.02))
    qs = m.random_q(6, seed=5)

    def brute(q):
        poses = geo.part_poses(q)
        ds = [signed_distance(geo.parts[i], poses[i], geo.parts[j], poses[j])[0] for i, j in geo.self_pairs]
        ds += [
            signed_distance(p, poses[i], o, o.offset)[0] for i, p in enumerate(geo.parts) for o in w.parts()
        ]
        return min(ds), sorted(d for d in ds if d < 0.02)

    def agrees():
        state = w.state()
        for q in qs:
            first, again = search(geo, q, state, 0.02, True), search(geo, q, state, 0.02, True)
            assert first.nearest[:4] == again.nearest[:4]
            assert sorted(e[:4] for e in first.close) == sorted(e[:4] for e in again.close)
            nearest, close = brute(q)
            assert first.nearest[0] == pytest.approx(nearest, abs=1e-9)
            assert sorted(e[0] for e in first.close) == pytest.approx(close, abs=1e-9)

    agrees()
    w.move("floor", spatial.translation(0.0, 0.0, -0.015))  # 5 mm closer to the base link
    agrees()
    w.add_box("post", (0.05, 0.05, 0.3), spatial.translation(0.16, 0.0, 0.1))  # next to panda_link0
    agrees()
    w.remove("floor")
    agrees()


def test_search_with_fixed_entries_is_the_same_from_threads():
    """Searches from 4 threads at once (the fixed parts' entries found by whichever thread comes
    first) give every thread the answers of one thread alone."""
    from concurrent.futures import ThreadPoolExecutor

    from optik.collision.check import search

    m, _ = _panda()
    geo = robot_geometry(m)
    w = World()
    w.add_box("table", (1.4, 1.6, 0.04), spatial.translation(0.3, 0.0, -0.04))
    w.add_box("post", (0.05, 0.05, 0.3), spatial.translation(0.16, 0.0, 0.1))
    qs = m.random_q(40, seed=8)

    def run(_=None):
        state = w.state()
        found = (search(geo, q, state, 0.02, True) for q in qs)
        return [(s.nearest[:4], sorted(e[:4] for e in s.close)) for s in found]

    w.move("post", spatial.translation(0.17, 0.0, 0.1))  # a version no thread has searched yet
    with ThreadPoolExecutor(4) as pool:
        answers = list(pool.map(run, range(4)))
    assert all(a == run() for a in answers)


def test_self_pairs_left_do_not_refine_the_world_bounds():
    """A folded Panda (elbow near its shoulder, an answer of the clutter benchmark) leaves more
    than `REFINE` self pairs under the limit and one world pair: the search computes them without
    the fine world screen (it could skip none of them) and finds the brute force's nearest pair."""
    from optik.benchmarks.bench_collision import scene
    from optik.collision.check import REFINE, search
    from optik.collision.distance import signed_distance

    m, _ = _panda()
    geo = robot_geometry(m)
    w = scene()
    q = np.array([1.74, -0.79, -1.62, -2.84, 0.48, 1.05, -2.9])
    found = search(geo, q, w.state(), 0.01, True)
    assert not found.refined and found.checked > REFINE + 1
    poses = geo.part_poses(q)
    ds = [signed_distance(geo.parts[i], poses[i], geo.parts[j], poses[j])[0] for i, j in geo.self_pairs]
    ds += [signed_distance(p, poses[i], o, o.offset)[0] for i, p in enumerate(geo.parts) for o in w.parts()]
    assert found.nearest[0] == pytest.approx(min(ds), abs=1e-9) and not found.close


@pytest.mark.parametrize(("margin", "self_collision"), [(0.0, True), (0.02, True), (0.02, False)])
def test_the_clear_test_is_the_stopped_searchs_first_decision(tmp_path, margin, self_collision):
    """`check.ClearTest` (the C test a collision-aware solve runs in its LM call): clear exactly
    where ``search(..., stop=True)`` finds no bound under the limit and makes no coal query, at
    clear and colliding configurations of the Panda among every kind of obstacle, its base's
    known distances included; its screen outputs are the screen's own, which the search reads."""
    import ctypes

    from optik import native
    from optik.collision.check import ClearTest, search
    from optik.collision.screen import screen

    m, _ = _panda()
    w = _cluttered_world(tmp_path)
    geo, state = robot_geometry(m), w.state()
    coarse = screen(geo, state.capacity, coarse=True)
    native.wait(600)
    clear = coarse.clear_function()
    if clear is None:
        pytest.skip("no compiled screen (no C compiler)")
    test = ClearTest(geo, state, margin, self_collision, clear)
    run = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)(clear[0])
    n_self = len(geo.self_pairs) if self_collision else 0
    verdicts = []
    for q in m.random_q(200, seed=31):
        test.verdict[0] = -1
        assert run(test.address + ctypes.sizeof(ctypes.c_void_p), q.ctypes.data) == 0
        verdicts.append(int(test.verdict[0]))
        mine = coarse.pair_bounds(q, state.slots, len(state.parts), n_self, test.outputs)
        mine = mine[0].copy(), mine[1].copy()
        own = coarse.pair_bounds(q, state.slots, len(state.parts), n_self)
        assert np.array_equal(mine[0], own[0]) and np.array_equal(mine[1], own[1])
        found = search(geo, q, state, margin, self_collision, stop=True)
        assert (verdicts[-1] == 1) == (found.checked == 0 and not found.in_collision)
    assert set(verdicts) == {0, 1}
    assert test.use.any()  # the base link's entries against the table were read
