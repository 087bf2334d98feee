"""URDF import (optik.mechanism.urdf), Mechanism.from_urdf, and the Panda / iiwa14 arms vs their URDFs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from test_mechanism import finite_difference_jacobian

import optik
from optik.catalog import URDF_CHAINS, iiwa14, panda, urdf_path
from optik.errors import InvalidArgumentError, ModelError, OptikError, UnknownFrameError

load_urdf = optik.Mechanism.from_urdf


def _joint(name, kind, parent, child, xyz=None, rpy=None, axis=None, limit=None, extra=""):
    origin = ""
    if xyz is not None or rpy is not None:
        attrs = "".join(f' {k}="{v}"' for k, v in (("xyz", xyz), ("rpy", rpy)) if v is not None)
        origin = f"<origin{attrs}/>"
    ax = "" if axis is None else f'<axis xyz="{axis}"/>'
    lim = "" if limit is None else f'<limit lower="{limit[0]}" upper="{limit[1]}" effort="1" velocity="1"/>'
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f"{origin}{ax}{lim}{extra}</joint>"
    )


def _robot(*joints: str, links: tuple[str, ...] = ()) -> str:
    names = set(links)
    for j in joints:
        for tag in ("parent", "child"):
            names.add(j.split(f'<{tag} link="')[1].split('"')[0])
    body = "".join(f'<link name="{n}"/>' for n in sorted(names)) + "".join(joints)
    return f'<?xml version="1.0"?>\n<robot name="test">{body}</robot>'


def _origin_ref(xyz, rpy) -> np.ndarray:
    """URDF origin by an independent route: scipy's extrinsic x-y-z Euler angles = Rz Ry Rx."""
    t = np.eye(4)
    t[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    t[:3, 3] = xyz
    return t


def _rot_ref(axis, q) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = Rotation.from_rotvec(np.asarray(axis, float) / np.linalg.norm(axis) * q).as_matrix()
    return t


def _trans_ref(axis, q) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = np.asarray(axis, float) / np.linalg.norm(axis) * q
    return t


# A chain with every supported joint type, fixed joints before, between and after moving
# joints, and a branch (with a floating joint) off the base-tip path.
MIXED = _robot(
    _joint("mount", "fixed", "world", "base", xyz="0 0 0.5", rpy="0 0 1.0"),
    _joint(
        "j1", "revolute", "base", "l1", xyz="0.1 0.2 0.3", rpy="0.3 -0.2 0.7", axis="0 0 1", limit=(-1, 2)
    ),
    _joint("bracket", "fixed", "l1", "l1b", xyz="0.4 0 0", rpy="1.5707963267948966 0 0"),
    _joint("j2", "continuous", "l1b", "l2", xyz="0 0.1 0", axis="1 1 0"),
    _joint("j3", "prismatic", "l2", "l3", rpy="0 0.5 0", axis="0 0 2", limit=(0.0, 0.4)),
    _joint("adapter", "fixed", "l3", "plate", rpy="0 0 0.4"),
    _joint("tool", "fixed", "plate", "tcp", xyz="0 0 0.05", rpy="0.2 0 0"),
    _joint("flying", "floating", "l1", "drone"),
    _joint("side", "revolute", "base", "arm2", axis="0 1 0", limit=(-1, 1)),
)


def _mixed_ref(q) -> np.ndarray:
    return (
        _origin_ref((0, 0, 0.5), (0, 0, 1.0))
        @ _origin_ref((0.1, 0.2, 0.3), (0.3, -0.2, 0.7))
        @ _rot_ref((0, 0, 1), q[0])
        @ _origin_ref((0.4, 0, 0), (np.pi / 2, 0, 0))
        @ _origin_ref((0, 0.1, 0), (0, 0, 0))
        @ _rot_ref((1, 1, 0), q[1])
        @ _origin_ref((0, 0, 0), (0, 0.5, 0))
        @ _trans_ref((0, 0, 1), q[2])
        @ _origin_ref((0, 0, 0), (0, 0, 0.4))
        @ _origin_ref((0, 0, 0.05), (0.2, 0, 0))
    )


# ------------------------------------------------------------------ parsing


def test_mixed_chain_structure_and_limits():
    m = load_urdf(MIXED, "world", "tcp")
    assert m.coordinate_names == ("j1", "j2", "j3")
    assert [j.type for j in m.joints] == ["revolute", "revolute", "prismatic"]
    assert m.base == "world" and m.ee == "tcp" and m.name == "test" and m.task == "pose"
    # fixed joints folded: no body for the links they lead to, but a frame for each
    assert set(m.topology.bodies) == {"world", "l1", "l2", "l3"}
    assert {"base", "l1b", "plate", "tcp"} <= set(m.frames)
    np.testing.assert_array_equal(m.lower, [-1.0, -np.inf, 0.0])  # continuous: unbounded
    np.testing.assert_array_equal(m.upper, [2.0, np.inf, 0.4])
    assert m.unbounded.tolist() == [False, True, False]
    np.testing.assert_array_equal(m.sampling_bounds[0], [-1.0, -np.pi, 0.0])
    np.testing.assert_array_equal(m.mid_q(), [0.5, 0.0, 0.2])
    np.testing.assert_allclose(m.joints[1].axis, np.array([1, 1, 0]) / np.sqrt(2), atol=1e-15)
    np.testing.assert_allclose(m.joints[2].axis, [0, 0, 1], atol=1e-15)
    assert m.revolute_mask.tolist() == [True, True, False]


def test_mixed_chain_fk_matches_independent_product():
    m = load_urdf(MIXED, "world", "tcp")
    rng = np.random.default_rng(1)
    for q in m.random_q(20, seed=rng):
        np.testing.assert_allclose(m.fk(q), _mixed_ref(q), atol=1e-12)
    q = m.random_q(seed=2)
    # the folded fixed-joint links are frames with the right poses
    np.testing.assert_allclose(m.fk(q, frame="base"), _origin_ref((0, 0, 0.5), (0, 0, 1.0)), atol=1e-12)
    l1b = (
        _origin_ref((0, 0, 0.5), (0, 0, 1.0))
        @ _origin_ref((0.1, 0.2, 0.3), (0.3, -0.2, 0.7))
        @ _rot_ref((0, 0, 1), q[0])
        @ _origin_ref((0.4, 0, 0), (np.pi / 2, 0, 0))
    )
    np.testing.assert_allclose(m.fk(q, frame="l1b"), l1b, atol=1e-12)


def test_sub_chain_and_branch_selection():
    m = load_urdf(MIXED, "l1", "l3")
    assert m.coordinate_names == ("j2", "j3") and m.base == "l1"
    other = load_urdf(MIXED, "world", "arm2")
    assert other.coordinate_names == ("side",)


def test_defaults_origin_and_axis():
    m = load_urdf(_robot(_joint("j", "revolute", "a", "b", limit=(-1, 1))), "a", "b")
    np.testing.assert_array_equal(m.joints[0].origin, np.eye(4))
    np.testing.assert_array_equal(m.joints[0].axis, [1.0, 0.0, 0.0])  # URDF default axis
    np.testing.assert_array_equal(m.params["velocity_limits"], [1.0])
    # a continuous joint without <limit velocity> leaves the chain without velocity limits
    assert "velocity_limits" not in load_urdf(MIXED, "world", "tcp").params


@settings(max_examples=25, deadline=None)
@given(
    xyz=st.lists(st.floats(-2, 2), min_size=3, max_size=3),
    rpy=st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3),
    axis=st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda a: np.linalg.norm(a) > 0.1),
    q=st.floats(-3, 3),
    prismatic=st.booleans(),
)
def test_one_joint_fk_property(xyz, rpy, axis, q, prismatic):
    kind = "prismatic" if prismatic else "revolute"
    text = _robot(
        _joint(
            "j",
            kind,
            "a",
            "b",
            xyz=" ".join(repr(v) for v in xyz),
            rpy=" ".join(repr(v) for v in rpy),
            axis=" ".join(repr(v) for v in axis),
            limit=(-3, 3),
        )
    )
    m = load_urdf(text, "a", "b")
    motion = _trans_ref(axis, q) if prismatic else _rot_ref(axis, q)
    np.testing.assert_allclose(m.fk([q]), _origin_ref(xyz, rpy) @ motion, atol=1e-12)


def test_from_urdf_accepts_path_str_and_text(tmp_path):
    f = tmp_path / "r.urdf"
    f.write_text(MIXED, encoding="utf-8")
    q = np.array([0.3, -1.2, 0.1])
    for src in (f, str(f), MIXED):
        m = optik.Mechanism.from_urdf(src, "world", "tcp")
        np.testing.assert_allclose(m.fk(q), _mixed_ref(q), atol=1e-12)
    assert optik.Mechanism.from_urdf(f, "world", "tcp").params["urdf"] == str(f)


# ------------------------------------------------------------------ errors


def _raises(exc, text, match, base="a", tip="b"):
    with pytest.raises(exc, match=match) as info:
        load_urdf(text, base, tip)
    assert isinstance(info.value, OptikError)
    return info.value


def test_doctype_and_entity_rejected():
    laughs = (
        '<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;">]>'
        '<robot name="&lol2;"><link name="a"/><link name="b"/></robot>'
    )
    _raises(ModelError, laughs, r"<string>.*DOCTYPE")
    external = '<!ENTITY xxe SYSTEM "file:///etc/passwd"><robot name="x"/>'
    _raises(ModelError, external, "ENTITY")
    lower_case = '<!doctype robot><robot name="x"/>'
    _raises(ModelError, lower_case, "DOCTYPE")


def test_errors_name_the_file_and_joint(tmp_path):
    f = tmp_path / "bad.urdf"
    f.write_text(
        _robot(_joint("elbow", "revolute", "a", "b", xyz="0 0 abc", limit=(-1, 1))), encoding="utf-8"
    )
    with pytest.raises(ModelError) as info:
        optik.Mechanism.from_urdf(f, "a", "b")
    assert str(f) in str(info.value) and "'elbow'" in str(info.value) and "xyz" in str(info.value)


@pytest.mark.parametrize(
    ("joint", "match"),
    [
        (_joint("j", "revolute", "a", "b", xyz="0 0", limit=(-1, 1)), r"'j' <origin xyz>.*3 numbers"),
        (_joint("j", "revolute", "a", "b", rpy="0 nan 0", limit=(-1, 1)), r"'j' <origin rpy>.*finite"),
        (_joint("j", "revolute", "a", "b", axis="0 0 0", limit=(-1, 1)), r"'j'.*non-zero"),
        (_joint("j", "revolute", "a", "b", limit=("x", 1)), r"'j' <limit lower>"),
        (_joint("j", "revolute", "a", "b", limit=(1, -1)), r"'j'.*lower 1.0 > upper -1.0"),
        (
            _joint("j", "revolute", "a", "b", extra='<limit lower="0" upper="1" velocity="fast"/>'),
            r"'j' <limit velocity>",
        ),
        (_joint("j", "revolute", "a", "b"), r"'j'.*needs <limit"),
        (_joint("j", "prismatic", "a", "b"), r"'j'.*prismatic joint needs <limit"),
        (_joint("j", "floating", "a", "b"), r"'j'.*'floating' is not supported; .*base_link='b'"),
        (_joint("j", "planar", "a", "b"), r"'j'.*'planar' is not supported"),
        (_joint("j", "ball", "a", "b"), r"'j'.*'ball' is unknown"),
        (_joint("j", "fixed", "a", "b"), r"no moving joint between 'a' and 'b'"),
        (
            _joint("j", "revolute", "a", "b", limit=(-1, 1), extra='<mimic joint="k" multiplier="x"/>'),
            r"'j' <mimic multiplier>",
        ),
    ],
)
def test_malformed_joints(joint, match):
    _raises(ModelError, _robot(joint), r"<string>: .*" + match)


def test_unknown_links_and_tip_not_below_base():
    text = _robot(
        _joint("j1", "revolute", "a", "b", limit=(-1, 1)),
        _joint("j2", "revolute", "a", "c", limit=(-1, 1)),
    )
    err = _raises(UnknownFrameError, text, "no link 'nope'", base="nope")
    assert err.argument == "base_link"
    assert _raises(UnknownFrameError, text, "no link 'z'", tip="z").argument == "tip_link"
    _raises(ModelError, text, "'a' is not downstream of base_link 'b'", base="b", tip="a")
    _raises(ModelError, text, "'c' is not downstream of base_link 'b'", base="b", tip="c")


def test_malformed_documents(tmp_path):
    _raises(ModelError, "<robot><link name='a'/>", "malformed XML")
    _raises(ModelError, "<model name='x'/>", "expected <robot>")
    two_parents = _robot(
        _joint("j1", "revolute", "a", "b", limit=(-1, 1)),
        _joint("j2", "revolute", "c", "b", limit=(-1, 1)),
    )
    _raises(ModelError, two_parents, "child of two joints")
    dangling = (
        "<robot name='r'><link name='a'/><link name='b'/>" + _joint("j", "fixed", "a", "zz") + "</robot>"
    )
    _raises(ModelError, dangling, "unknown link 'zz'")
    with pytest.raises(InvalidArgumentError, match="no URDF file"):
        load_urdf(tmp_path / "missing.urdf", "a", "b")
    with pytest.raises(InvalidArgumentError, match="source"):
        load_urdf(42, "a", "b")  # type: ignore[arg-type]


# ------------------------------------------------------------------ shipped robots


ARMS = [("panda", panda), ("iiwa14", iiwa14)]


def test_urdf_path():
    for name, _ in ARMS:
        p = urdf_path(name)
        assert isinstance(p, Path) and p.is_file() and p.parent.name == "urdf"
    with pytest.raises(InvalidArgumentError, match="available"):
        urdf_path("ur5")


@pytest.mark.parametrize(("name", "ctor"), ARMS)
def test_catalog_matches_urdf(name, ctor):
    m = ctor()
    u = optik.Mechanism.from_urdf(urdf_path(name), *URDF_CHAINS[name])
    assert m.kind == name and m.task == "pose" and m.n_q == u.n_q == 7
    assert u.ee == URDF_CHAINS[name][1]
    np.testing.assert_array_equal(m.lower, u.lower)
    np.testing.assert_array_equal(m.upper, u.upper)
    q = m.random_q(200, seed=np.random.default_rng(7))
    np.testing.assert_allclose(m.fk(q), u.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.params["velocity_limits"], u.params["velocity_limits"], rtol=1e-15)


def test_published_dimensions():
    p = panda()
    t0 = p.fk(np.zeros(7))
    np.testing.assert_allclose(t0[:3, 3], [0.088, 0.0, 0.333 + 0.316 + 0.384 - 0.107], atol=1e-12)
    np.testing.assert_allclose(t0[:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    k = iiwa14()
    np.testing.assert_allclose(k.fk(np.zeros(7)), optik.spatial.translation(0, 0, 1.306), atol=1e-12)
    np.testing.assert_allclose(k.upper, np.deg2rad([170, 120, 170, 120, 170, 120, 175]), atol=1e-15)
    np.testing.assert_allclose(p.params["velocity_limits"], [2.175] * 4 + [2.61] * 3)
    np.testing.assert_allclose(np.rad2deg(k.params["velocity_limits"]), [85, 85, 100, 75, 130, 135, 135])


@pytest.mark.peers
@pytest.mark.parametrize(("name", "ctor"), ARMS)
def test_pinocchio_loads_the_same_robot(name, ctor):
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(urdf_path(name)))
    data = model.createData()
    frame = model.getFrameId(URDF_CHAINS[name][1])
    m = ctor()
    np.testing.assert_allclose(model.lowerPositionLimit, m.lower)
    np.testing.assert_allclose(model.upperPositionLimit, m.upper)
    np.testing.assert_allclose(model.velocityLimit, m.params["velocity_limits"], rtol=1e-15)
    for q in m.random_q(50, seed=np.random.default_rng(3)):
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(data.oMf[frame].homogeneous, m.fk(q), rtol=0, atol=1e-12)


@pytest.mark.parametrize(("name", "ctor"), ARMS)
def test_bad_input_raises_optik_errors(name, ctor):
    for m in (ctor(), optik.Mechanism.from_urdf(urdf_path(name), *URDF_CHAINS[name])):
        q = m.mid_q()
        with pytest.raises(optik.NonFiniteError, match=r"^q:"):
            m.fk(np.where(np.arange(7) == 2, np.nan, q))
        with pytest.raises(optik.NonFiniteError, match=r"^q:"):
            m.jacobian(np.where(np.arange(7) == 0, np.inf, q))
        with pytest.raises(optik.ShapeError, match=r"^q:"):
            m.fk(q[:6])
        with pytest.raises(UnknownFrameError, match="no_such_link"):
            m.fk(q, frame="no_such_link")


@pytest.mark.parametrize("source", ["catalog", "urdf"])
def test_panda_jacobian_vs_finite_differences(source):
    m = (
        panda()
        if source == "catalog"
        else optik.Mechanism.from_urdf(urdf_path("panda"), *URDF_CHAINS["panda"])
    )
    for q in m.random_q(10, seed=np.random.default_rng(11)):
        np.testing.assert_allclose(m.jacobian(q), finite_difference_jacobian(m, q), atol=1e-8)


def _tree_with_fingers(tool: str, finger_kind: str = "fixed") -> str:
    """An arm whose flange carries a hand with two fingers (collision boxes), listed before a
    geometry-free tool frame ``tool``."""
    box = '<collision><geometry><box size="0.02 0.02 0.02"/></geometry></collision>'
    lim = '<limit lower="0" upper="0.04" effort="1" velocity="1"/>' if finger_kind != "fixed" else ""
    joints = [
        _joint("j1", "revolute", "base", "l1", xyz="0 0 0.3", axis="0 0 1", limit=(-1, 1)),
        _joint("j2", "revolute", "l1", "flange", xyz="0.4 0 0", axis="0 1 0", limit=(-1, 1)),
        _joint("hand_joint", "fixed", "flange", "hand", xyz="0 0 0.05"),
        *(
            f'<joint name="{f}_joint" type="{finger_kind}"><parent link="hand"/><child link="{f}"/>'
            f'<origin xyz="0 0 0.05"/><axis xyz="0 1 0"/>{lim}</joint>'
            for f in ("finger_a", "finger_b")
        ),
        _joint(f"{tool}_joint", "fixed", "flange", tool, xyz="0 0 0.1"),
    ]
    links = "".join(f'<link name="{n}">{box}</link>' for n in ("hand", "finger_a", "finger_b"))
    links += "".join(f'<link name="{n}"/>' for n in ("base", "l1", "flange", tool))
    return f'<?xml version="1.0"?>\n<robot name="test">{links}{"".join(joints)}</robot>'


@pytest.mark.parametrize(
    ("tool", "finger_kind", "ee"),
    [
        ("tcp", "fixed", "tcp"),  # named as a tool, listed after the fingers
        ("tcp", "prismatic", "tcp"),  # named as a tool, the fingers one moving joint deeper
        ("grasp_point", "fixed", "grasp_point"),  # no tool name: the geometry-free leaf
        ("grasp_point", "prismatic", "finger_a"),  # no tool name: the deepest leaf, first listed
    ],
)
def test_whole_tree_end_effector_is_the_tool_not_a_finger(tool, finger_kind, ee):
    m = load_urdf(_tree_with_fingers(tool, finger_kind))
    assert m.ee == ee
    np.testing.assert_array_equal(m.fk(m.mid_q()), m.fk(m.mid_q(), ee))


def test_whole_tree_end_effectors_of_the_pandas(tmp_path):
    assert load_urdf(urdf_path("panda")).ee == "panda_link8"  # the shipped arm ends at the flange
    text = urdf_path("dual_panda").read_text(encoding="utf-8")
    start, end = text.index('  <link name="left_tool"/>'), text.index('  <link name="left_panda_hand">')
    mark = "  <!-- right arm -->"
    moved = text[:start] + text[end:].replace(mark, text[start:end] + mark)
    assert moved.index('<link name="left_tool"/>') > moved.index("left_panda_rightfinger")  # fingers first
    path = tmp_path / "dual_panda.urdf"
    path.write_text(moved, encoding="utf-8")
    assert load_urdf(urdf_path("dual_panda")).ee == load_urdf(path).ee == "left_tool"
    try:
        erd = optik.catalog.robots.robot_urdf("panda")
    except optik.errors.MissingExtraError:
        pytest.skip("example-robot-data (extra 'robots') is not installed")
    # example-robot-data's Panda: prismatic fingers below panda_hand_tcp, which wins by its name
    assert load_urdf(erd).ee == "panda_hand_tcp"
