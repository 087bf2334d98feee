"""URDF as ROS loads it: vendors' quirks that urdfdom accepts load, DTDs / entities / oversize
files / malformed XML stay rejected, every example-robot-data robot loads, and the kinematics
agree with pinocchio frame by frame (mimic joints set through their coupling)."""

from __future__ import annotations

import warnings
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

import optik
from optik.errors import InvalidArgumentError, ModelError, UnknownFrameError
from optik.mechanism import urdf_xml

ARM = """<?xml version="1.0" encoding="utf-8"?>
<robot name="arm">
  {head}
  <link name="base"/><link name="l1"/><link name="l2"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3" rpy="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  {middle}
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.4 0 0" rpy="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="l2"/><child link="tool"/><origin xyz="0.2 0 0"/></joint>
  {tail}
</robot>
"""


def _arm(head: str = "", middle: str = "", tail: str = "") -> str:
    return ARM.format(head=head, middle=middle, tail=tail)


CLEAN = optik.Mechanism.from_urdf(_arm(), "base", "tool")
Q = CLEAN.random_q(5, seed=4)


def _same_robot(m: optik.Mechanism) -> None:
    assert m.coordinate_names == ("j1", "j2")
    np.testing.assert_allclose(m.fk(Q), CLEAN.fk(Q), atol=1e-15)


GAZEBO = """<gazebo reference="l2">
    <sensor:camera name="cam"><sensor:imageSize>640 480</sensor:imageSize>
      <controller:gazebo_ros_camera name="c" plugin="libgazebo_ros_camera.so"/></sensor:camera>
  </gazebo>"""


@pytest.mark.parametrize(
    ("where", "text"),
    [
        ("head", "<!-- ======== generated -- do not edit ======== -->"),  # `--` inside a comment
        ("middle", "<!-- old: <!-- j1b was here --> "),  # an opening <!-- inside a comment
        ("middle", "<!-- arrow ending --->"),  # a comment closed by --->
        ("tail", GAZEBO),  # undeclared namespace prefixes (sensor:, controller:)
        ("head", '<gazebo><plugin name="p"><![CDATA[ <!-- not a comment --> & ]]></plugin></gazebo>'),
        ("tail", '<transmission name="t"><xacro:property name="x" value="1"/></transmission>'),
    ],
)
def test_vendor_quirks_load_like_urdfdom(where, text):
    _same_robot(optik.Mechanism.from_urdf(_arm(**{where: text}), "base", "tool"))


@pytest.mark.parametrize(
    "after",
    [
        '\n<robot name="again"><link name="other"/></robot>\n',  # a second root: urdfdom takes the first
        "\n  </transmission>\n  -->\n",  # left by a comment holding an inner <!-- (TinyXML's rule)
        "\nsome text <transmission name='t'><joint name='j1'/>\n",  # unclosed, after the root
    ],
)
def test_content_after_the_robot_is_ignored_with_a_warning(after, tmp_path):
    f = tmp_path / "vendor.urdf"
    f.write_text(_arm() + after, encoding="utf-8")
    match = r"vendor.urdf: line 1[0-9]: content after </robot>"
    with pytest.warns(urdf_xml.UrdfTrailingContentWarning, match=match):
        _same_robot(optik.Mechanism.from_urdf(f, "base", "tool"))


def test_errors_inside_the_robot_stay_errors_with_trailing_content():
    bad = _arm().replace("</joint>\n  \n", "</link>\n", 1) + "<robot/>"
    with pytest.raises(ModelError, match="malformed XML"):
        optik.Mechanism.from_urdf(bad, "base", "tool")


def test_declarations_bom_default_namespace_and_line_numbers(tmp_path):
    latin = _arm().replace('encoding="utf-8"', 'encoding="ISO-8859-1"')  # decoded as UTF-8 anyway
    _same_robot(optik.Mechanism.from_urdf(latin, "base", "tool"))
    f = tmp_path / "bom.urdf"
    f.write_bytes(
        b"\xef\xbb\xbf" + _arm(head="<!-- caf\xc3\xa9 -->").encode("utf-8").replace(b"caf\\xc3\\xa9", b"")
    )
    _same_robot(optik.Mechanism.from_urdf(f, "base", "tool"))
    ns = _arm().replace('<robot name="arm">', '<robot name="arm" xmlns="http://example.org/urdf">')
    _same_robot(optik.Mechanism.from_urdf(ns, "base", "tool"))
    # a comment spanning lines keeps the line numbers of what follows
    bad = _arm(head="<!--\n\n\n-->").replace('xyz="0.4 0 0"', 'xyz="0.4 0 0')
    with pytest.raises(ModelError, match=r"malformed XML: line 1[0-9]"):
        optik.Mechanism.from_urdf(bad, "base", "tool")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (
            '<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;">]>'
            '<robot name="&b;"><link name="base"/></robot>',
            "DOCTYPE",
        ),
        ('<!ENTITY xxe SYSTEM "file:///etc/passwd"><robot name="x"/>', "ENTITY"),
        ('<!-- x --><!doctype robot SYSTEM "http://example.org/r.dtd"><robot name="x"/>', "DOCTYPE"),
        ('<robot name="&undefined;"><link name="base"/></robot>', "malformed XML.*undefined"),
        ('<robot name="r"><link name="base"/>', "malformed XML.*Premature end"),
        ('<robot name="r"><link name="base"></joint></robot>', "malformed XML.*mismatch"),
        ('<robot name="r"><link name=base/></robot>', "malformed XML"),
        (
            '<robot name="r"><!-- never closed <link name="base"/></robot>',
            "line 1: comment <!-- is not terminated",
        ),
        ('<robot name="r"><![CDATA[ open <link name="base"/></robot>', "CDATA section is not terminated"),
        ("<robot>" + "<a>" * 300 + "</a>" * 300 + "</robot>", "malformed XML.*depth"),
        ('<model name="r"><link name="base"/></model>', "expected <robot>"),
    ],
)
def test_unsafe_or_malformed_documents_are_rejected(text, match):
    with pytest.raises(ModelError, match=r"<string>: .*" + match):
        optik.Mechanism.from_urdf(text)


def test_oversize_texts_and_files_are_rejected(tmp_path, monkeypatch):
    big = '<robot name="r">' + " " * urdf_xml.MAX_URDF_BYTES + '<link name="a"/></robot>'
    with pytest.raises(ModelError, match=r"<string>: URDF text of \d+ characters > 33554432 bytes"):
        optik.Mechanism.from_urdf(big)
    multibyte = '<robot name="r">' + "\u00e9" * (urdf_xml.MAX_URDF_BYTES // 2 + 1) + "</robot>"
    with pytest.raises(ModelError, match=r"URDF text of \d+ bytes"):  # within the characters, not the bytes
        optik.Mechanism.from_urdf(multibyte)
    monkeypatch.setattr(urdf_xml, "MAX_URDF_BYTES", 1000)
    f = tmp_path / "big.urdf"
    f.write_text(_arm(head="<!-- " + "x" * 1000 + " -->"), encoding="utf-8")
    with pytest.raises(ModelError, match=r"big.urdf: URDF file of \d+ bytes > 1000 bytes"):
        optik.Mechanism.from_urdf(f)


def test_bad_text_and_bad_link_arguments_name_the_argument(tmp_path):
    with pytest.raises(InvalidArgumentError, match=r"^source: .*surrogates") as info:
        optik.Mechanism.from_urdf(_arm(head="<!-- \ud800 -->").replace("<!-- \ud800 -->", "\ud800"))
    assert info.value.argument == "source"
    f = tmp_path / "latin1.urdf"
    f.write_bytes(_arm().encode("utf-8").replace(b'name="arm"', b'name="\xe9"'))
    with pytest.raises(InvalidArgumentError, match=r"^source: cannot read URDF file"):
        optik.Mechanism.from_urdf(f)
    for argument, kwargs in (("base_link", {"base_link": ["base"]}), ("tip_link", {"tip_link": ["tool"]})):
        with pytest.raises(InvalidArgumentError, match=rf"^{argument}: expected a string") as info:
            optik.Mechanism.from_urdf(_arm(), **kwargs)
        assert info.value.argument == argument
    with pytest.raises(UnknownFrameError, match="no link 'nope'"):
        optik.Mechanism.from_urdf(_arm(), tip_link="nope")
    with pytest.raises(InvalidArgumentError, match=r"^name: expected a string"):
        optik.catalog.urdf_path(["panda"])


# ------------------------------------------------------------------ example-robot-data


def _robots_dir() -> Path:
    """The robots folder of the example-robot-data wheel (the ``robots`` extra; data only)."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install 'optik[robots]')")
    d = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    if not d.is_dir():
        pytest.skip(f"example-robot-data has no robots folder at {d}")
    return d


NO_MOVING_JOINT = {"quadrotor_base.urdf", "iris_simple.urdf", "ur3.urdf"}
"""Files of example-robot-data without a moving joint (a mechanism needs one): rejected."""


@pytest.mark.peers
def test_every_example_robot_data_urdf_loads():
    files = sorted(_robots_dir().rglob("*.urdf"))
    assert len(files) >= 60
    loaded = 0
    for f in files:
        if f.name in NO_MOVING_JOINT:
            with pytest.raises(ModelError, match=r"no moving joint|no <link>"):
                optik.Mechanism.from_urdf(f)
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # alex_psyonic_hands: mimics of a joint the file lacks
            m = optik.Mechanism.from_urdf(f)
        assert m.n_q >= 1 and m.ee in m.frames
        loaded += 1
    assert loaded == len(files) - len(NO_MOVING_JOINT)


def _pinocchio_q(pin, model, m: optik.Mechanism, q: np.ndarray) -> np.ndarray:
    """pinocchio's configuration for optik's q: mimic joints set through their coupling,
    continuous joints as (cos, sin)."""
    values = dict(zip(m.coordinate_names, q, strict=True))
    for j in m.joints:
        if j.mimic is not None:
            values[j.name] = j.mimic.value(values[j.mimic.joint])
    qp = pin.neutral(model)
    for name, v in values.items():
        jm = model.joints[model.getJointId(name)]
        qp[jm.idx_q : jm.idx_q + jm.nq] = [v] if jm.nq == 1 else [np.cos(v), np.sin(v)]
    return qp


@pytest.mark.peers
@pytest.mark.parametrize(
    "relative",
    [
        "talos_data/robots/talos_full_v2.urdf",  # humanoid, 12 mimic joints (grippers)
        "pr2_description/urdf/pr2.urdf",  # mimic and continuous joints, gazebo blocks
        "baxter_description/urdf/baxter.urdf",  # dual arm, mimic fingers
        "tiago_description/robots/tiago.urdf",  # continuous wheels
        "romeo_description/urdf/romeo.urdf",  # 22 mimic joints
    ],
)
def test_whole_trees_match_pinocchio_on_every_link(relative):
    pin = pytest.importorskip("pinocchio")
    path = _robots_dir() / relative
    m = optik.Mechanism.from_urdf(path)
    model = pin.buildModelFromUrdf(str(path))  # mimic joints as free joints: we set them
    data = model.createData()
    names = [f.name for f in model.frames if f.name in m.frames and f.name != "universe"]
    assert len(names) >= len(m.frames) - 1
    assert sum(j.mimic is not None for j in m.joints) == model.nq - m.n_q - m.unbounded.sum()
    for q in m.random_q(3, seed=np.random.default_rng(2)):
        pin.framesForwardKinematics(model, data, _pinocchio_q(pin, model, m, q))
        for name in names:
            got = m.fk(q, frame=name)
            np.testing.assert_allclose(got, data.oMf[model.getFrameId(name)].homogeneous, atol=1e-12)


# ------------------------------------------------------------------ visuals and meshes


VISUALS = """<robot name="v">
  <link name="base"><visual><origin xyz="0 0 0.1" rpy="0 0 1.0"/>
    <geometry><mesh filename="meshes/base.stl" scale="0.001 0.001 0.001"/></geometry></visual></link>
  <link name="arm">
    <visual><geometry><mesh filename="package://my_robot/meshes/arm.dae"/></geometry></visual>
    <visual><geometry><box size="0.1 0.2 0.3"/></geometry></visual>
    <visual><geometry><cylinder radius="0.05" length="0.4"/></geometry></visual>
    <visual><geometry><sphere radius="0.02"/></geometry></visual>
    <visual><geometry><mesh filename="package://elsewhere/missing.stl"/></geometry></visual>
    <collision><geometry><box size="1 1 1"/></geometry></collision>
  </link>
  <link name="tool"><visual><geometry><capsule radius="1" length="2"/></geometry></visual></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1"/></joint>
  <joint name="f" type="fixed"><parent link="arm"/><child link="tool"/><origin xyz="0.5 0 0"/></joint>
</robot>"""


def test_visuals_keep_geometry_and_resolve_mesh_paths(tmp_path, monkeypatch):
    pkg = tmp_path / "share" / "my_robot"
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "meshes").mkdir()
    (pkg / "urdf" / "meshes").mkdir()
    for f in (pkg / "meshes" / "arm.dae", pkg / "urdf" / "meshes" / "base.stl"):
        f.write_text("mesh", encoding="utf-8")
    urdf = pkg / "urdf" / "v.urdf"
    urdf.write_text(VISUALS, encoding="utf-8")
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    m = optik.Mechanism.from_urdf(urdf)
    vis = m.params["visuals"]
    assert [(v.link, v.geometry) for v in vis] == [
        ("base", "mesh"),
        ("arm", "mesh"),
        ("arm", "box"),
        ("arm", "cylinder"),
        ("arm", "sphere"),
        ("arm", "mesh"),
    ]  # collisions and unknown geometries (capsule) draw nothing
    base, arm, box, cyl, sphere, missing = vis
    assert base.filename == "meshes/base.stl" and base.path == pkg / "urdf" / "meshes" / "base.stl"
    assert base.scale == (0.001, 0.001, 0.001)
    np.testing.assert_allclose(
        base.origin, optik.spatial.translation(0, 0, 0.1) @ optik.spatial.transform(optik.spatial.rot_z(1.0))
    )
    assert arm.filename == "package://my_robot/meshes/arm.dae" and arm.path == pkg / "meshes" / "arm.dae"
    assert box.size == (0.1, 0.2, 0.3) and cyl.size == (0.05, 0.4) and sphere.size == (0.02,)
    assert missing.path is None and missing.filename == "package://elsewhere/missing.stl"
    other = tmp_path / "ros" / "elsewhere"
    other.mkdir(parents=True)
    (other / "missing.stl").write_text("mesh", encoding="utf-8")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "ros"))
    assert optik.Mechanism.from_urdf(urdf).params["visuals"][-1].path == other / "missing.stl"
    # from text, relative names cannot be located; the names are kept
    assert optik.Mechanism.from_urdf(VISUALS).params["visuals"][0].path is None
    with pytest.raises(ModelError, match=r"link 'arm' <visual> 1 <box size>"):
        optik.Mechanism.from_urdf(VISUALS.replace('size="0.1 0.2 0.3"', 'size="0.1 0.2"'))


@pytest.mark.peers
def test_example_robot_data_meshes_are_found():
    m = optik.Mechanism.from_urdf(_robots_dir() / "talos_data" / "robots" / "talos_full_v2.urdf")
    meshes = [v for v in m.params["visuals"] if v.geometry == "mesh"]
    # TALOS writes package:///example-robot-data/... (three slashes): the same package
    assert len(meshes) >= 40 and all(v.filename.startswith("package:///example-robot-data/") for v in meshes)
    assert all(v.path is not None and v.path.is_file() for v in meshes)
    assert all(v.link in m.frames for v in m.params["visuals"])
