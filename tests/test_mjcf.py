"""MJCF import (optik.mechanism.mjcf, Mechanism.from_mjcf) on small models written here: every
joint type, anchors, ``ref``, several joints in one body, fixed and mocap bodies, sites, names,
limits and geoms, checked against MuJoCo's own ``mj_kinematics``; frame names that clash."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik.errors import InvalidArgumentError, ModelError, NonFiniteError
from optik.mechanism import Joint, LinearClosure, Mechanism

mujoco = pytest.importorskip("mujoco", reason="MJCF import needs MuJoCo (extra 'mjcf')")
from optik.mechanism.mjcf import from_qpos, to_qpos  # noqa: E402  (after the importorskip)

ARM = """
<mujoco model="arm">
  <compiler angle="degree" autolimits="true"/>
  <default><joint damping="0.1"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="base" pos="0.1 0 0.2" euler="0 0 30">
      <geom type="cylinder" size="0.05 0.1"/>
      <joint name="yaw" type="hinge" axis="0 0 1" range="-170 170" pos="0.01 0.02 0"/>
      <body name="upper" pos="0 0 0.3" quat="0.9 0.1 0.3 0.2">
        <joint name="pitch" axis="0 1 1" ref="20"/>
        <joint name="roll" axis="1 0 0" pos="0 0 0.05" range="-45 45"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.4" size="0.03"/>
        <site name="elbow" pos="0 0 0.4"/>
        <body name="plate" pos="0 0 0.4" euler="10 20 30">
          <geom type="box" size="0.1 0.05 0.01"/>
          <site name="plate" pos="0.02 0 0.01" euler="0 90 0"/>
          <body name="slider" pos="0 0 0.02">
            <joint name="slide" type="slide" axis="1 1 0" range="-0.1 0.2" ref="0.05"/>
            <geom type="ellipsoid" size="0.02 0.03 0.04"/>
            <body name="wrist">
              <joint name="ball" type="ball" pos="0.01 0 0.03"/>
              <geom size="0.01"/>
              <site name="tool" pos="0 0 0.1"/>
            </body>
          </body>
        </body>
      </body>
    </body>
    <body name="crate" pos="1 0 0.5">
      <freejoint name="crate_free"/>
      <geom type="box" size="0.1 0.1 0.1"/>
      <body name="lid" pos="0 0 0.1"><joint name="lid" axis="0 1 0" range="0 90"/><geom size="0.01"/></body>
    </body>
    <body name="target" mocap="true" pos="0.5 0.5 0.5"><site name="goal"/></body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def arm():
    return optik.Mechanism.from_mjcf(ARM), mujoco.MjModel.from_xml_string(ARM)


def _mj_poses(model, qpos):
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return data


def _max_fk_error(m, model, q) -> float:
    d = _mj_poses(model, to_qpos(m, q))
    err = 0.0
    for b in range(1, model.nbody):
        t = m.fk(q, model.body(b).name)
        err = max(err, np.abs(t[:3, 3] - d.xpos[b]).max(), np.abs(t[:3, :3] - d.xmat[b].reshape(3, 3)).max())
    for s in range(model.nsite):
        t = m.fk(q, m.params["site_frames"][model.site(s).name])
        err = max(err, np.abs(t[:3, 3] - d.site_xpos[s]).max())
        err = max(err, np.abs(t[:3, :3] - d.site_xmat[s].reshape(3, 3)).max())
    return err


def test_structure(arm):
    m, _ = arm
    assert m.base == "world" and m.name == "arm"
    kinds = [j.type for j in m.joints]
    assert kinds == ["revolute", "revolute", "revolute", "prismatic", "spherical", "free", "revolute"]
    assert m.n_q == 1 + 1 + 1 + 1 + 3 + 6 + 1
    assert m.coordinate_names[:4] == ("yaw", "pitch", "roll", "slide")
    # two joints in one body: an intermediate body after the first
    assert "upper/pitch" in m.topology.bodies
    # fixed bodies are frames on their moving ancestor, not bodies
    assert m.frames["plate"][0] == "upper" and "plate" not in m.topology.bodies
    assert m.frames["target"][0] == "world"
    # the site named like its body is kept under another name; the body keeps its own
    sites = {"elbow": "elbow", "plate": "site:plate", "tool": "tool", "goal": "goal"}
    assert m.params["site_frames"] == sites
    assert m.ee == "wrist"
    assert any("mocap body 'target'" in n for n in m.params["notes"])


def test_limits(arm):
    m, _ = arm
    lo = dict(zip(m.coordinate_names, m.lower, strict=True))
    hi = dict(zip(m.coordinate_names, m.upper, strict=True))
    assert lo["yaw"] == pytest.approx(np.radians(-170)) and hi["yaw"] == pytest.approx(np.radians(170))
    assert (lo["pitch"], hi["pitch"]) == (-np.inf, np.inf)  # not limited: the angle wraps
    assert (lo["slide"], hi["slide"]) == (-0.1, 0.2)
    assert all(np.isinf(m.lower[7:13])) and all(np.isinf(m.upper[7:13]))  # free joint


@settings(max_examples=25)
@given(seed=st.integers(0, 2**31 - 1))
def test_fk_equals_mujoco(arm, seed):
    m, model = arm
    q = m.random_q(seed=seed)
    q[7:10] *= 3.0  # free-base positions beyond the sampling box
    assert _max_fk_error(m, model, q) < 1e-10


def test_qpos_round_trip(arm):
    m, model = arm
    for q in m.random_q(20, seed=3):
        qpos = to_qpos(m, q)
        assert qpos.shape == (model.nq,)
        np.testing.assert_allclose(from_qpos(m, qpos), m.wrap(q), atol=1e-12)
    qpos = model.qpos0.copy()
    np.testing.assert_allclose(to_qpos(m, from_qpos(m, qpos)), qpos, atol=1e-12)
    with pytest.raises(InvalidArgumentError, match="q"):
        to_qpos(m, np.zeros(3))
    with pytest.raises(InvalidArgumentError, match="m"):
        to_qpos(optik.catalog.planar_2r(), np.zeros(2))


def test_hinge_ref_is_qpos(arm):
    """A hinge's coordinate is MuJoCo's qpos: at qpos0 (the ref angle) the body is at its
    compiled pose, as in MuJoCo."""
    m, model = arm
    q = from_qpos(m, model.qpos0)
    assert q[1] == pytest.approx(np.radians(20)) and q[3] == pytest.approx(0.05)
    assert _max_fk_error(m, model, q) < 1e-12


def test_visuals(arm):
    m, _ = arm
    kinds = {(v.link, v.geometry) for v in m.params["visuals"]}
    assert ("base", "cylinder") in kinds and ("upper", "capsule") in kinds and ("plate", "box") in kinds
    assert ("slider", "sphere") in kinds  # the ellipsoid: a unit sphere scaled
    assert not any(v.link == "world" for v in m.params["visuals"])  # the plane is not drawn
    box = next(v for v in m.params["visuals"] if v.geometry == "box" and v.link == "plate")
    assert box.size == pytest.approx((0.2, 0.1, 0.02))
    capsule = next(v for v in m.params["visuals"] if v.geometry == "capsule")
    assert capsule.size == pytest.approx((0.03, 0.4))
    np.testing.assert_allclose(capsule.origin[:3, 3], [0, 0, 0.2], atol=1e-12)


def test_mjmodel_and_file_sources(arm, tmp_path):
    m, model = arm
    path = tmp_path / "arm.xml"
    path.write_text(ARM)
    for source in (model, path, str(path)):
        m2 = optik.Mechanism.from_mjcf(source)
        assert m2.coordinate_names == m.coordinate_names
        q = m.random_q(seed=1)
        np.testing.assert_allclose(m2.fk(q, "tool"), m.fk(q, "tool"), atol=1e-14)


def test_rejections(tmp_path):
    with pytest.raises(InvalidArgumentError, match="source"):
        optik.Mechanism.from_mjcf(tmp_path / "missing.xml")
    with pytest.raises(InvalidArgumentError, match="source"):
        optik.Mechanism.from_mjcf(3)
    with pytest.raises(ModelError, match="cannot compile"):
        optik.Mechanism.from_mjcf("<mujoco><worldbody><body><joint type='x'/></body></worldbody></mujoco>")
    with pytest.raises(ModelError, match="no joint"):
        optik.Mechanism.from_mjcf("<mujoco><worldbody><body><geom size='1'/></body></worldbody></mujoco>")


def test_unnamed_objects_and_notes():
    xml = """<mujoco><worldbody><body pos="0 0 1"><joint type="ball" range="0 30"/><geom size="0.1"/>
    <site pos="0 0 1"/><body pos="0 1 0"><joint name="j1" axis="1 0 0"/><geom size="0.1"/></body></body>
    </worldbody><tendon><fixed><joint joint="j1" coef="1"/></fixed></tendon></mujoco>"""
    m = optik.Mechanism.from_mjcf(xml)
    assert m.coordinate_names == ("joint0[0]", "joint0[1]", "joint0[2]", "j1")
    assert set(m.topology.bodies) == {"world", "body1", "body2"} and "site0" in m.frames
    np.testing.assert_allclose(m.upper[:3], np.radians(30))  # degrees by default, as in MuJoCo
    notes = " ".join(m.params["notes"])
    assert "ball joint 'joint0'" in notes and "1 of 1 tendon(s) are not modelled ('tendon0')" in notes
    model = mujoco.MjModel.from_xml_string(xml)
    d = _mj_poses(model, to_qpos(m, [0.1, -0.2, 0.3, 0.7]))
    np.testing.assert_allclose(m.fk([0.1, -0.2, 0.3, 0.7], "site0")[:3, 3], d.site_xpos[0], atol=1e-12)


# ---------------------------------------------------------------------- frame names (issue 23)
def test_frame_may_not_take_a_body_name():
    j = Joint("j", "revolute", "base", "link")
    t = np.eye(4)
    t[:3, 3] = [1.0, 2.0, 3.0]
    with pytest.raises(InvalidArgumentError, match=r"frames.*'link' has the name of a body"):
        Mechanism([j], frames={"link": ("link", t)})
    with pytest.raises(InvalidArgumentError, match="'base' has the name of a body"):
        Mechanism([j], frames={"base": ("link", t)})
    m = Mechanism([j], frames={"tool": ("link", t)})
    np.testing.assert_allclose(m.fk([0.0], "link"), np.eye(4))
    np.testing.assert_allclose(m.fk([0.0], "tool"), t)


def test_free_joint_alone():
    """A free joint by hand: ``Trans(p) exp([w]x)`` with unbounded coordinates, wrapped like a
    spherical joint's rotation vector."""
    m = Mechanism([Joint("base", "free", "world", "torso")], base="world")
    assert m.coordinate_names == tuple(f"base[{i}]" for i in range(6))
    assert np.all(np.isinf(m.lower)) and m.spherical_slices == (slice(3, 6),)
    _, hi = m.sampling_bounds
    np.testing.assert_allclose(hi, [1, 1, 1, np.pi, np.pi, np.pi])
    q = np.array([0.5, -1.0, 2.0, 0.0, 0.0, 1.5 * np.pi])
    t = m.fk(q)
    np.testing.assert_allclose(t[:3, 3], q[:3])
    np.testing.assert_allclose(t[:3, :3], optik.spatial.rot_z(1.5 * np.pi), atol=1e-12)
    w = m.wrap(q)
    np.testing.assert_allclose(w[5], -0.5 * np.pi) and np.testing.assert_allclose(m.fk(w), t, atol=1e-12)
    j = m.jacobian(q)
    np.testing.assert_allclose(j[:3, :3], np.eye(3), atol=1e-12)


FOURBAR = """<mujoco model="fourbar"><compiler angle="radian"/>
<worldbody>
  <body name="crank"><joint name="a" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.01"/>
    <body name="coupler" pos="0.2 0 0"><joint name="b" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.01"/></body>
  </body>
  <body name="rocker" pos="0.6 0 0"><joint name="c" axis="0 0 1"/>
    <geom type="capsule" fromto="0 0 0 0 0.4 0" size="0.01"/></body>
  <body name="slider" pos="0 1 0"><joint name="d" type="slide" axis="1 0 0"/><geom size="0.05"/>
    <body name="follower"><joint name="e" type="slide" axis="0 1 0" ref="0.1"/><geom size="0.05"/>
    </body></body>
  <body name="box" pos="0 -1 0"><joint name="f" axis="1 0 0"/><geom size="0.05"/></body>
</worldbody>
<equality>
  <connect name="close" body1="coupler" body2="rocker" anchor="0.5 0 0"/>
  <joint name="couple" joint1="e" joint2="d" polycoef="0.05 -2 0 0 0"/>
  <weld name="glue" body1="box"/>
  <connect name="off" body1="crank" body2="slider" anchor="0 0 0" active="false"/>
</equality>
<actuator><motor joint="a"/><motor joint="d"/><motor joint="f"/></actuator></mujoco>"""


def test_equalities_as_closures_and_couplings():
    """``connect``: a cut spherical joint whose closure is MuJoCo's own constraint residual
    (``efc_pos`` of the equality rows, opposite sign); ``joint``: a coupling whose MuJoCo
    residual vanishes; ``weld`` (the box welded to the world): a cut fixed joint, its position rows
    MuJoCo's (opposite sign) and its rotation rows of norm ``2 sin(theta / 2)`` where MuJoCo's
    have ``sin(theta / 2)``; inactive equalities: not modelled, said in the notes."""
    m = optik.Mechanism.from_mjcf(FOURBAR)
    model = mujoco.MjModel.from_xml_string(FOURBAR)
    assert m.coordinate_names == ("a", "b", "c", "d", "f") and m.n_closure == 15 and m.is_closed
    notes = " ".join(m.params["notes"])
    assert "joint 'e' follows 'd'" in notes and "'off' is inactive" in notes and "weld" not in notes
    data = mujoco.MjData(model)
    for q in m.random_q(5, seed=4):
        qpos = to_qpos(m, q)
        assert qpos[model.jnt_qposadr[4]] == pytest.approx(0.1 + 0.05 - 2 * q[3])  # e - ref = c0 + c1 d
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        rows = data.efc_pos[data.efc_type == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)]
        c = m.closure(q)
        np.testing.assert_allclose(c[:3], -rows[:3], atol=1e-12)  # connect
        assert abs(rows[3]) < 1e-12  # the coupling holds
        np.testing.assert_allclose(c[3:6], -rows[4:7], atol=1e-12)  # weld: position
        # weld: rotation rows of norm 2 sin(theta / 2), MuJoCo's sin(theta / 2)
        assert np.linalg.norm(c[6:15]) == pytest.approx(2 * np.linalg.norm(rows[7:10]), abs=1e-12)
        assert abs(m.fk(q, "follower")[1, 3] - data.xpos[model.body("follower").id][1]) < 1e-12
    fk = optik.solve_fk(m, [0.3, 0.1, 0.0], q0=m.mid_q())  # the crank drives the closed four-bar
    assert fk.success and np.abs(m.closure(fk.q)).max() < 1e-9
    assert not optik.solve_fk(m, [0.3, 0.1, 0.2], q0=m.mid_q(), time_limit=0.2).success  # welded box


WELDED = """<mujoco><compiler angle="radian"/>
<worldbody>
 <body name="a" pos="0 0 0.1"><joint name="j1" axis="0 0 1"/><geom size="0.02"/>
  <body name="b" pos="0.3 0 0"><joint name="j2" axis="0 1 0"/><geom size="0.02"/>
   <body name="c" pos="0.3 0 0"><joint name="j3" type="ball"/><geom size="0.02"/>
    <body name="d" pos="0.2 0 0"><joint name="j4" axis="1 0 0"/><geom size="0.02"/>
     <site name="tip" pos="0.2 0 0" quat="0.9 0.1 0.3 0.2"/></body></body></body></body>
 <site name="goal" pos="0.5 0.2 0.3" quat="0.7 0.2 -0.1 0.4"/>
</worldbody>
<equality>{weld}</equality></mujoco>"""


@pytest.mark.parametrize(
    ("weld", "mobility"),
    [
        ('<weld body1="d" anchor="0.1 0.02 0" relpose="0.45 0.1 0.2 0.8 0.3 0.1 -0.2"/>', 0),
        # relpose from qpos0, the chain stretched along x: the ball's turn about x and j4 cancel
        ('<weld body1="d"/>', 1),
        ('<weld site1="tip" site2="goal"/>', 0),
    ],
)
def test_weld_residuals_equal_mujoco(weld, mobility):
    """A spatial chain (hinges and a ball) welded to the world, by bodies with an anchor and a
    relative pose, by bodies at qpos0, and by sites: 3 position rows, MuJoCo's ``efc_pos``
    (opposite sign), and 9 rotation rows of norm ``2 sin(theta / 2)`` where MuJoCo's have
    ``sin(theta / 2)``, on random configurations; the mobility; the weld holds at qpos0."""
    xml = WELDED.format(weld=weld)
    m, model = optik.Mechanism.from_mjcf(xml), mujoco.MjModel.from_xml_string(xml)
    assert m.n_q == 6 and m.n_closure == 12 and m.mobility() == mobility
    data = mujoco.MjData(model)
    for q in m.random_q(6, seed=2):
        data.qpos[:] = to_qpos(m, q)
        mujoco.mj_forward(model, data)
        rows = data.efc_pos[data.efc_type == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)]
        c = m.closure(q)
        np.testing.assert_allclose(c[:3], -rows[:3], atol=1e-12)
        assert np.linalg.norm(c[3:]) == pytest.approx(2 * np.linalg.norm(rows[3:]), abs=1e-12)
    if "relpose" not in weld and "site" not in weld:
        assert np.abs(m.closure(from_qpos(m, model.qpos0))).max() < 1e-12


def test_commands_take_mjcf_files(tmp_path):
    """``optik view`` / ``optik reach`` load their mechanism through load_source."""
    from optik.problem_files import load_source

    path = tmp_path / "fourbar.xml"
    path.write_text(FOURBAR)
    m, problem = load_source(str(path), None, None)
    assert problem is None and m.coordinate_names == ("a", "b", "c", "d", "f")
    with pytest.raises(InvalidArgumentError, match="--base"):
        load_source(str(path), "crank", None)
    with pytest.raises(InvalidArgumentError, match="no such file"):
        load_source(str(tmp_path / "missing.xml"), None, None)


FREE_TENDON = """<fixed name="free"><joint joint="wrist" coef="1"/><joint joint="thumb" coef="1"/>
    <joint joint="finger" coef="1"/></fixed>"""
COUPLED_FINGERS = (
    """<mujoco><compiler angle="radian"/>
<worldbody><body name="palm"><joint name="wrist" axis="0 0 1"/><geom size="0.02"/>
  <body name="thumb" pos="0.1 0 0"><joint name="thumb" axis="0 1 0" range="-1 1"/><geom size="0.02"/>
    <site name="thumb_tip" pos="0.05 0 0"/></body>
  <body name="finger" pos="0.1 0.05 0"><joint name="finger" axis="0 1 0" range="-1 1" ref="0.2"/>
    <geom size="0.02"/><site name="finger_tip" pos="0.05 0 0"/></body></body></worldbody>
<tendon><fixed name="grip"><joint joint="thumb" coef="-0.5"/><joint joint="finger" coef="0.7"/></fixed>
  """
    + FREE_TENDON
    + """</tendon>
<equality><tendon name="coupling" tendon1="grip" polycoef="0.03 0 0 0 0"/>
  <tendon name="three" tendon1="free" active="false"/></equality></mujoco>"""
)


def test_fixed_tendon_equality_is_a_coupling():
    """A tendon equality on a fixed tendon of two joints (MuJoCo holds its length at the qpos0
    length plus polycoef[0]) makes the second joint follow the first: MuJoCo's residual of that
    equality is 0 at every configuration, the site poses equal MuJoCo's."""
    m, model = optik.Mechanism.from_mjcf(COUPLED_FINGERS), mujoco.MjModel.from_xml_string(COUPLED_FINGERS)
    assert m.coordinate_names == ("wrist", "thumb")
    assert any("'finger' follows 'thumb'" in n for n in m.params["notes"])
    data = mujoco.MjData(model)
    for q in m.random_q(6, seed=3):
        data.qpos[:] = to_qpos(m, q)
        mujoco.mj_forward(model, data)
        rows = data.efc_pos[data.efc_type == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)]
        assert rows.shape == (1,) and abs(rows[0]) < 1e-12
        assert (
            np.abs(m.fk(q, "finger_tip")[:3, 3] - data.site_xpos[model.site("finger_tip").id]).max() < 1e-12
        )


def test_tendon_notes_name_only_the_tendons_not_made_couplings():
    """The note on tendons counts and names those that are not couplings, and says what of them
    is lost (a length range, an actuator); a model whose tendons are all couplings has none."""
    notes = optik.Mechanism.from_mjcf(COUPLED_FINGERS).params["notes"]
    tendon_notes = [n for n in notes if "tendon(s)" in n]
    assert tendon_notes == [
        "1 of 2 tendon(s) are not modelled ('free'): no coupling, constraint or limit comes from their "
        "lengths"
    ]
    limited = COUPLED_FINGERS.replace('<fixed name="free">', '<fixed name="free" range="-1 1">').replace(
        "</equality>", '</equality><actuator><motor tendon="free"/></actuator>'
    )
    (note,) = [n for n in optik.Mechanism.from_mjcf(limited).params["notes"] if "tendon(s)" in n]
    assert "the length range of 'free' is not enforced" in note and "actuators on 'free' drive" in note
    only_grip = COUPLED_FINGERS.replace(FREE_TENDON, "").replace(
        '<tendon name="three" tendon1="free" active="false"/>', ""
    )
    assert not any("tendon(s)" in n for n in optik.Mechanism.from_mjcf(only_grip).params["notes"])


TENDON_ROW = """<mujoco><compiler angle="radian"/>
<worldbody><body name="a"><joint name="j1" axis="0 0 1" range="-2 2"/><geom size="0.02"/>
  <body name="b" pos="0.3 0 0"><joint name="j2" axis="0 0 1" range="-2 2" ref="0.1"/><geom size="0.02"/>
    <body name="c" pos="0.3 0 0"><joint name="j3" axis="0 0 1" range="-2 2"/><geom size="0.02"/>
      <body name="d" pos="0.2 0 0"><joint name="j4" type="slide" axis="1 0 0" range="-0.1 0.1"/>
        <geom size="0.02"/><site name="tip" pos="0.05 0 0"/></body></body></body></body></worldbody>
<tendon><fixed name="sum"><joint joint="j1" coef="1"/><joint joint="j2" coef="-0.5"/>
  <joint joint="j4" coef="2"/><joint joint="j3" coef="0.7"/></fixed></tendon>
<equality><joint joint1="j3" joint2="j1" polycoef="0.1 0.5 0 0 0"/>
  <tendon name="hold" tendon1="sum" polycoef="0.02 0 0 0 0"/></equality>
<actuator><motor joint="j1"/><motor joint="j2"/></actuator></mujoco>"""


def test_three_joint_fixed_tendon_equality_is_mujocos_residual_as_a_closure_row():
    """A tendon equality on a fixed tendon of four joints (one of them a mimic joint) is one
    closure row: at random configurations ``m.closure`` is MuJoCo's ``efc_pos`` of that equality
    (same sign, to rounding); it costs one degree of freedom, and an FK solve assembles a
    configuration where MuJoCo's residuals vanish and the site is where MuJoCo puts it."""
    m, model = optik.Mechanism.from_mjcf(TENDON_ROW), mujoco.MjModel.from_xml_string(TENDON_ROW)
    assert m.coordinate_names == ("j1", "j2", "j4") and m.n_closure == 1 and m.mobility() == 2
    assert any("'hold': a loop-closure row" in n for n in m.params["notes"])
    assert not any("tendon(s) are not modelled" in n for n in m.params["notes"])
    data = mujoco.MjData(model)
    equality = int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    for q in np.random.default_rng(4).uniform(m.lower, m.upper, (8, 3)):
        data.qpos[:] = to_qpos(m, q)
        mujoco.mj_forward(model, data)
        rows = data.efc_pos[data.efc_type == equality]  # the joint coupling's row is 0: j3 follows j1
        assert rows.shape == (2,) and abs(rows[0]) < 1e-12
        assert abs(m.closure(q)[0] - rows[1]) < 1e-12 and abs(rows[1]) > 1e-6
    fk = optik.solve_fk(m, [0.05, 0.2])
    assert fk.success, fk.message
    data.qpos[:] = to_qpos(m, fk.q)
    mujoco.mj_forward(model, data)
    assert np.abs(data.efc_pos[data.efc_type == equality]).max() < 1e-9
    np.testing.assert_allclose(m.fk(fk.q, "tip")[:3, 3], data.site_xpos[model.site("tip").id], atol=1e-12)
    q = np.array([0.3, -0.2, 0.05])
    for copy in (pickle.loads(pickle.dumps(m)), m.with_limits(lower=m.lower - 0.1)):
        assert copy.linear_closures == m.linear_closures and copy.closure(q) == pytest.approx(m.closure(q))


def test_linear_closures_are_checked():
    """A linear closure on a joint that is not a one-value joint here, or malformed terms, raise
    naming the argument."""
    joints = [Joint("a", "revolute", "base", "l1"), Joint("b", "spherical", "l1", "l2")]
    with pytest.raises(ModelError, match="'b'"):
        optik.Mechanism(joints, linear_closures=[LinearClosure("row", (("b", 1.0),), 0.0)])
    with pytest.raises(ModelError, match="'c'"):
        optik.Mechanism(joints, linear_closures=[LinearClosure("row", (("c", 1.0),), 0.0)])
    with pytest.raises(InvalidArgumentError, match="linear_closures"):
        optik.Mechanism(joints, linear_closures=["row"])
    with pytest.raises(InvalidArgumentError, match=r"linear_closure\.coefficients"):
        LinearClosure("row", (), 0.0)
    with pytest.raises(InvalidArgumentError, match=r"linear_closure\.coefficients"):
        LinearClosure("row", (("a", 1.0, 2.0),), 0.0)
    with pytest.raises(NonFiniteError, match=r"linear_closure\.value"):
        LinearClosure("row", (("a", 1.0),), float("nan"))
    m = optik.Mechanism(joints, linear_closures=[LinearClosure("row", (("a", 2.0),), 1.0)])
    assert m.is_closed and m.closure(np.array([0.2, 0.0, 0.0, 0.0])) == pytest.approx([-0.6])


def test_two_joint_tendon_equality_on_a_coupled_joint_is_a_closure_row():
    """A two-joint fixed tendon on a joint that already follows another (j3, by the joint
    equality) cannot be a second coupling: it is a closure row, equal to MuJoCo's residual."""
    tendon = """<joint joint="j1" coef="1"/><joint joint="j2" coef="-0.5"/>
  <joint joint="j4" coef="2"/><joint joint="j3" coef="0.7"/>"""
    xml = TENDON_ROW.replace(tendon, '<joint joint="j4" coef="2"/><joint joint="j3" coef="0.7"/>')
    m, model = optik.Mechanism.from_mjcf(xml), mujoco.MjModel.from_xml_string(xml)
    assert m.n_closure == 1 and m.linear_closures[0].coefficients == (("j4", 2.0), ("j3", 0.7))
    data = mujoco.MjData(model)
    for q in np.random.default_rng(5).uniform(m.lower, m.upper, (4, 3)):
        data.qpos[:] = to_qpos(m, q)
        mujoco.mj_forward(model, data)
        rows = data.efc_pos[data.efc_type == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)]
        assert abs(m.closure(q)[0] - rows[1]) < 1e-12
