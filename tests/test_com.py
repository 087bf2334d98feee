"""Centre of mass (optik.mechanism.inertia, Mechanism.com / com_jacobian) and floating bases
(the ``free`` joint, ``from_urdf(..., floating_base=True)``): a two-link arm by hand, finite
differences, MuJoCo's ``subtree_com`` and ``mj_jacSubtreeCom`` on MJCF models, Pinocchio's
``centerOfMass`` / ``jacobianCenterOfMass`` and frame placements on the legged robots of
example-robot-data (free-flyer base)."""

from __future__ import annotations

import pickle
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik.errors import InvalidArgumentError, ModelError, UnknownFrameError
from optik.mechanism import Joint, Mechanism


def _two_link() -> Mechanism:
    t = np.eye(4)
    t[0, 3] = 1.0
    joints = [Joint("a", "revolute", "base", "l1"), Joint("b", "revolute", "l1", "l2", origin=t)]
    tool = np.eye(4)
    tool[0, 3] = 0.8
    return Mechanism(
        joints, frames={"tool": ("l2", tool)}, inertials={"l1": (2.0, [0.5, 0, 0]), "tool": (1.0, [0, 0, 0])}
    )


def test_two_link_by_hand():
    m = _two_link()
    q = np.array([0.3, -0.7])
    p1 = 0.5 * np.array([np.cos(q[0]), np.sin(q[0]), 0])
    p2 = np.array([np.cos(q[0]) + 0.8 * np.cos(q[0] + q[1]), np.sin(q[0]) + 0.8 * np.sin(q[0] + q[1]), 0])
    np.testing.assert_allclose(m.com(q), (2 * p1 + p2) / 3, atol=1e-14)
    assert m.mass == 3.0
    np.testing.assert_allclose(
        m.com(np.array([q, q, 2 * q])), [(2 * p1 + p2) / 3] * 2 + [m.com(2 * q)], atol=1e-14
    )


@settings(max_examples=20)
@given(seed=st.integers(0, 2**31 - 1))
def test_com_jacobian_is_the_derivative(seed):
    m = _two_link()
    q = m.random_q(seed=seed)
    eps = 1e-6
    fd = np.array([(m.com(q + eps * e) - m.com(q - eps * e)) / (2 * eps) for e in np.eye(m.n_q)]).T
    np.testing.assert_allclose(m.com_jacobian(q), fd, atol=1e-8)


def test_inertials_are_checked_and_kept():
    m = _two_link()
    for bad, err in (
        ({"nowhere": (1.0, [0, 0, 0])}, UnknownFrameError),
        ({"l1": (-1.0, [0, 0, 0])}, InvalidArgumentError),
        ({"l1": (np.inf, [0, 0, 0])}, InvalidArgumentError),
        ({"l1": (1.0, [0, 0])}, InvalidArgumentError),
        ({"l1": 1.0}, InvalidArgumentError),
        ([1.0], InvalidArgumentError),
    ):
        with pytest.raises(err, match="inertials"):
            Mechanism(m.joints, frames={"tool": m.frames["tool"]}, inertials=bad)
    with pytest.raises(ModelError, match="no mass"):
        optik.catalog.planar_2r().com([0.0, 0.0])
    q = np.array([0.1, 0.2])
    for copy in (pickle.loads(pickle.dumps(m)), m.with_limits(lower=[-1, -1], upper=[1, 1])):
        np.testing.assert_allclose(copy.com(q), m.com(q), atol=1e-15)


def test_floating_urdf_base(tmp_path):
    urdf = """<robot name="r">
    <link name="torso"><inertial><origin xyz="0 0 0.1"/><mass value="2"/></inertial></link>
    <link name="leg"><inertial><origin xyz="0 0 -0.2"/><mass value="1"/></inertial></link>
    <joint name="hip" type="revolute"><parent link="torso"/><child link="leg"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1"/></joint></robot>"""
    fixed = optik.Mechanism.from_urdf(urdf)
    m = optik.Mechanism.from_urdf(urdf, floating_base=True)
    assert m.base == "world" and m.joints[0].type == "free" and m.joints[0].name == "root_joint"
    assert (
        m.coordinate_names[:6] == tuple(f"root_joint[{i}]" for i in range(6))
        and m.coordinate_names[6] == "hip"
    )
    q = np.array([0.3, -0.2, 1.0, 0.1, 0.4, -0.3, 0.5])
    base = m.fk(q, "torso")
    np.testing.assert_allclose(base[:3, 3], q[:3])
    np.testing.assert_allclose(base[:3, :3], optik.spatial.so3_exp(q[3:6]), atol=1e-14)
    np.testing.assert_allclose(m.fk(q, "leg"), base @ fixed.fk(q[6:], "leg"), atol=1e-14)
    np.testing.assert_allclose(m.com(q), base[:3, :3] @ fixed.com(q[6:]) + q[:3], atol=1e-14)
    with pytest.raises(ModelError, match="'world'"):
        optik.Mechanism.from_urdf(urdf.replace('"torso"', '"world"'), floating_base=True)


# ---------------------------------------------------------------------- MuJoCo


def test_mjcf_com_equals_mujoco():
    mujoco = pytest.importorskip("mujoco", reason="MJCF import needs MuJoCo (extra 'mjcf')")
    pytest.importorskip("dm_control", reason="the MJCF test set (dm_control) is not installed")
    import dm_control

    from optik.mechanism.mjcf import to_qpos

    root = Path(dm_control.__file__).parent
    for rel in (
        "suite/humanoid.xml",
        "suite/quadruped.xml",
        "suite/manipulator.xml",
        "third_party/kinova/jaco_arm.xml",
    ):
        model = mujoco.MjModel.from_xml_path(str(root / rel))
        m = optik.Mechanism.from_mjcf(model)
        assert m.mass == pytest.approx(model.body_subtreemass[0], rel=1e-14)
        data = mujoco.MjData(model)
        # columns of hinge and slide coordinates: MuJoCo's velocity is their rate, plus the rate of
        # every joint coupled to them (qpos_mimics: qpos[a] = multiplier q_i + offset); joints are
        # matched by qpos address (a coupled joint has no optik coordinate of its own)
        dof_of_qpos = {
            int(model.jnt_qposadr[j]): int(model.jnt_dofadr[j])
            for j in range(model.njnt)
            if int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE))
        }
        cols = [(i, dof_of_qpos[a]) for kind, i, a in m.params["qpos_map"] if kind >= 2]
        coupled = [(i, dof_of_qpos[a], k) for a, i, k, _ in m.params.get("qpos_mimics", ())]
        for q in m.random_q(4, seed=1):
            data.qpos[:] = to_qpos(m, q)
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            np.testing.assert_allclose(m.com(q), data.subtree_com[0], atol=1e-12)
            jac = np.zeros((3, model.nv))
            mujoco.mj_jacSubtreeCom(model, data, jac, 0)
            ours = m.com_jacobian(q)
            for i, dof in cols:
                want = jac[:, dof] + sum(k * jac[:, d] for j, d, k in coupled if j == i)
                np.testing.assert_allclose(ours[:, i], want, atol=1e-12)
        eps = 1e-6  # every column (free and ball joints too) against central differences
        fd = np.array([(m.com(q + eps * e) - m.com(q - eps * e)) / (2 * eps) for e in np.eye(m.n_q)]).T
        np.testing.assert_allclose(m.com_jacobian(q), fd, atol=1e-8)


# ---------------------------------------------------------------------- Pinocchio
LEGGED = (
    "go1_description/urdf/go1.urdf",
    "go2_description/urdf/go2.urdf",
    "a1_description/urdf/a1.urdf",
    "anymal_b_simple_description/robots/anymal.urdf",
    "anymal_c_simple_description/urdf/anymal.urdf",
    "solo_description/robots/solo.urdf",
    "solo_description/robots/solo12.urdf",
    "hyq_description/robots/hyq_no_sensors.urdf",
    "talos_data/robots/talos_full_v2.urdf",
    "talos_data/robots/talos_reduced.urdf",
    "g1_description/urdf/g1_29dof_rev_1_0.urdf",
    "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf",
    "icub_description/robots/icub.urdf",
    "romeo_description/urdf/romeo.urdf",
)


def _pin_q(pin, m: Mechanism, pm, q: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration of optik's ``q`` (free flyer: position and ``(x, y, z, w)``;
    continuous joints as ``(cos, sin)``; mimic joints, independent in Pinocchio, at their coupled value)."""
    qp = pin.neutral(pm)
    qp[:3] = q[:3]
    qp[3:7] = pin.Quaternion(pin.exp3(q[3:6])).coeffs()
    index = dict(zip(m.coordinate_names, range(m.n_q), strict=True))
    for j in m.joints[1:]:
        value = q[index[j.name]] if j.mimic is None else j.mimic.value(q[index[j.mimic.joint]])
        pj = pm.joints[pm.getJointId(j.name)]
        qp[pj.idx_q : pj.idx_q + pj.nq] = [np.cos(value), np.sin(value)] if pj.nq == 2 else [value]
    return qp


@pytest.mark.parametrize("rel", LEGGED, ids=[Path(r).stem for r in LEGGED])
def test_legged_robots_equal_pinocchio(rel):
    pin = pytest.importorskip("pinocchio", reason="the reference is Pinocchio (pin)")
    from optik.catalog.robots import robots_dir

    try:
        path = robots_dir() / rel
    except optik.OptikError as exc:
        pytest.skip(f"example-robot-data is not installed: {exc}")
    if not path.is_file():
        pytest.skip(f"{rel} is not in this example-robot-data")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = optik.Mechanism.from_urdf(path, floating_base=True)
    pm = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    pd = pm.createData()
    bodies = [f.name for f in pm.frames if f.type == pin.FrameType.BODY and f.name in m.frames]
    assert len(bodies) >= len(m.topology.bodies) - 1
    # Pinocchio's mimic joints are independent: d com/d q_source collects theirs, times the multiplier
    couple = np.zeros((pm.nv, m.n_q))
    couple[:6, :6] = np.eye(6)
    for j in m.joints[1:]:
        source = j.name if j.mimic is None else j.mimic.joint
        factor = 1.0 if j.mimic is None else j.mimic.multiplier
        couple[pm.joints[pm.getJointId(j.name)].idx_v, m.coordinate_names.index(source)] = factor
    for q in m.random_q(3, seed=7):
        qp = _pin_q(pin, m, pm, q)
        np.testing.assert_allclose(m.com(q), pin.centerOfMass(pm, pd, qp), atol=1e-12)
        assert m.mass == pytest.approx(pd.mass[0], rel=1e-13)
        jac = pin.jacobianCenterOfMass(pm, pd, qp)
        ours = m.com_jacobian(q)
        np.testing.assert_allclose(ours[:, 6:], (jac @ couple)[:, 6:], atol=1e-12)  # joints
        np.testing.assert_allclose(ours[:, :3], jac[:, :3] @ pin.exp3(q[3:6]).T, atol=1e-12)  # base position
        pin.forwardKinematics(pm, pd, qp)
        pin.updateFramePlacements(pm, pd)
        for name in bodies:
            want = pd.oMf[pm.getFrameId(name, pin.FrameType.BODY)].homogeneous
            np.testing.assert_allclose(m.fk(q, name), want, atol=1e-12, err_msg=name)


def test_com_and_its_jacobian_each_evaluate_only_what_they_return():
    """``com`` evaluates a function of the CoM alone and ``com_jacobian`` one of the Jacobian
    alone (neither computes the other's output to drop it): fewer instructions than the pair,
    the same numbers as `com_function`."""
    m = _two_link()
    q = np.array([0.3, -0.7])
    pair = m.com_function
    com_only, jac_only = m._com_only_function, m._com_jacobian_function
    assert com_only.n_out() == 1 and jac_only.n_out() == 1
    assert com_only.n_instructions() < pair.n_instructions()
    assert jac_only.n_instructions() < pair.n_instructions()
    c, j = pair(q)
    np.testing.assert_array_equal(m.com(q), np.asarray(c).reshape(3))
    np.testing.assert_array_equal(m.com_jacobian(q), np.asarray(j))
