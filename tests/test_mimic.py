"""Mimic joints: no coordinate of their own, ``q_mimic = multiplier * q + offset``, Jacobians
through the coupling, URDF <mimic> (composed chains, errors), and IK of a mimic model."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_mechanism import finite_difference_jacobian

import optik
from optik import Joint, Mechanism, spatial
from optik.errors import InvalidArgumentError, ModelError
from optik.mechanism.joint import Mimic

T = spatial.translation


def _spatial_mimic_arm() -> Mechanism:
    """A 4-joint spatial arm whose third joint follows the second: q_c = -0.7 q_b + 0.3."""
    joints = [
        Joint("a", "revolute", "base", "l1", axis=[0, 0, 1], lower=-2.5, upper=2.5),
        Joint("b", "revolute", "l1", "l2", origin=T(0, 0, 0.4), axis=[0, 1, 0], lower=-2, upper=2),
        Joint("c", "revolute", "l2", "l3", origin=T(0.5, 0, 0), axis=[0, 1, 0], mimic=Mimic("b", -0.7, 0.3)),
        Joint("d", "prismatic", "l3", "l4", origin=T(0.4, 0, 0), axis=[1, 0, 0], lower=0.0, upper=0.3),
        Joint("e", "revolute", "l4", "l5", origin=T(0.1, 0, 0), axis=[1, 0, 0], lower=-3, upper=3),
    ]
    return Mechanism(joints, "base", {"tool": ("l5", T(0.05, 0.02, 0))}, "tool")


def _reference_fk(q: np.ndarray) -> np.ndarray:
    """The same arm written out with the coupling by hand."""
    a, b, d, e = q
    c = -0.7 * b + 0.3
    return (
        spatial.transform(spatial.rot_z(a))
        @ T(0, 0, 0.4)
        @ spatial.transform(spatial.rot_y(b))
        @ T(0.5, 0, 0)
        @ spatial.transform(spatial.rot_y(c))
        @ T(0.4, 0, 0)
        @ T(d, 0, 0)
        @ T(0.1, 0, 0)
        @ spatial.transform(spatial.rot_x(e))
        @ T(0.05, 0.02, 0)
    )


def test_mimic_joint_has_no_coordinate_and_follows_its_source():
    m = _spatial_mimic_arm()
    assert m.coordinate_names == ("a", "b", "d", "e") and m.n_q == 4
    assert m.mobility() == 4  # the coupling removes the mimic joint's freedom
    for q in m.random_q(20, seed=3):
        np.testing.assert_allclose(m.fk(q), _reference_fk(q), atol=1e-14)


def test_jacobian_through_the_coupling_matches_finite_differences():
    m = _spatial_mimic_arm()
    for q in m.random_q(10, seed=5):
        np.testing.assert_allclose(m.jacobian(q), finite_difference_jacobian(m, q), atol=1e-8)
    # the column of the source joint carries both rotations: b and c = -0.7 b about parallel axes
    q = np.array([0.2, 0.4, 0.1, 0.3])
    assert abs(m.jacobian(q)[4, 1] - 0.3 * np.cos(0.2)) < 1e-12  # w_y = (1 - 0.7) * cos(a)


def test_with_limits_keeps_the_coupling():
    m = _spatial_mimic_arm().with_limits(upper=[2.5, 1.5, 0.3, 3.0])
    assert m.joints[2].mimic == Mimic("b", -0.7, 0.3) and m.upper[1] == 1.5
    q = m.random_q(seed=1)
    np.testing.assert_allclose(m.fk(q), _reference_fk(q), atol=1e-14)


@pytest.mark.parametrize("method", ["lm", "nlp", "dls", "qp"])
def test_ik_of_a_mimic_model(method):
    m = _spatial_mimic_arm()
    rng = np.random.default_rng(8)
    solved = 0
    for q_true in m.random_q(4, seed=rng):
        target = m.fk(q_true)
        res = optik.solve_ik(m, target, method=method, time_limit=2.0)
        if not res.success:
            continue
        solved += 1
        t = m.fk(res.q)  # success checked independently
        assert np.abs(t[:3, 3] - target[:3, 3]).max() < 1e-6
        assert np.linalg.norm(Rotation.from_matrix(t[:3, :3].T @ target[:3, :3]).as_rotvec()) < 1e-6
        assert m.within_limits(res.q)
    assert solved >= 3


def test_mimic_validation_errors():
    with pytest.raises(InvalidArgumentError, match="mimic itself"):
        Joint("a", "revolute", "p", "c", mimic=Mimic("a"))
    with pytest.raises(InvalidArgumentError, match="only revolute and prismatic"):
        Joint("a", "fixed", "p", "c", mimic=Mimic("b"))
    with pytest.raises(InvalidArgumentError, match="expected a Mimic"):
        Joint("a", "revolute", "p", "c", mimic=("b", 1.0, 0.0))  # type: ignore[arg-type]
    with pytest.raises(optik.NonFiniteError, match=r"mimic\.multiplier"):
        Mimic("b", float("nan"))
    with pytest.raises(InvalidArgumentError, match=r"mimic\.joint"):
        Mimic(["b"])  # type: ignore[arg-type]
    a = Joint("a", "revolute", "base", "l1")
    with pytest.raises(ModelError, match="mimics 'zz', which is not a joint"):
        Mechanism([a, Joint("b", "revolute", "l1", "l2", mimic=Mimic("zz"))])
    b = Joint("b", "revolute", "l1", "l2", mimic=Mimic("a"))
    with pytest.raises(ModelError, match="mimics 'b', which has no coordinate"):
        Mechanism([a, b, Joint("c", "revolute", "l2", "l3", mimic=Mimic("b"))])


def _urdf(*joints: str) -> str:
    used = sorted({n for j in joints for n in re.findall(r'link="([^"]+)"', j)})
    links = "".join(f'<link name="{n}"/>' for n in used)
    return f'<robot name="g">{links}{"".join(joints)}</robot>'


def _j(name, parent, child, extra="", kind="revolute", xyz="0.3 0 0"):
    lim = '<limit lower="-1" upper="1" effort="1" velocity="1"/>' if kind != "continuous" else ""
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}"/><axis xyz="0 0 1"/>{lim}{extra}</joint>'
    )


def test_urdf_mimic_chains_compose_and_errors_name_the_joints():
    text = _urdf(
        _j("a", "base", "l1"),
        _j("b", "l1", "l2", '<mimic joint="a" multiplier="2" offset="0.1"/>'),
        _j("c", "l2", "l3", '<mimic joint="b" multiplier="-0.5"/>'),  # c = -0.5 (2 a + 0.1)
        _j("d", "l3", "l4", '<mimic joint="c" offset="0.2"/>', kind="continuous"),
    )
    m = optik.Mechanism.from_urdf(text)
    assert m.coordinate_names == ("a",) and m.ee == "l4"
    for joint, (mult, off) in zip(m.joints[1:], [(2.0, 0.1), (-1.0, -0.05), (-1.0, 0.15)], strict=True):
        assert joint.mimic.joint == "a"
        assert joint.mimic.multiplier == pytest.approx(mult) and joint.mimic.offset == pytest.approx(off)
    ref = optik.planar_chain("RRRR", [0.3, 0.3, 0.3, 0.3])
    for a in (-0.7, 0.2, 0.9):
        qs = np.array([a, 2 * a + 0.1, -a - 0.05, -a + 0.15])
        np.testing.assert_allclose(
            m.fk([a])[:3, 3], ref.fk(qs, frame="link4")[:3, 3] + [0.3, 0, 0], atol=1e-14
        )
    cycle = _urdf(_j("a", "base", "l1", '<mimic joint="b"/>'), _j("b", "l1", "l2", '<mimic joint="a"/>'))
    with pytest.raises(ModelError, match="<string>: joint 'a': the <mimic> joints form a cycle"):
        optik.Mechanism.from_urdf(cycle)
    # a gripper: f2 mimics f1 on another branch; the chain to f2 alone lacks the source
    gripper = _urdf(_j("a", "base", "l1"), _j("f1", "l1", "f1"), _j("f2", "l1", "f2", '<mimic joint="f1"/>'))
    with pytest.raises(ModelError, match="'f2' mimics 'f1', which is not a moving joint of the loaded part"):
        optik.Mechanism.from_urdf(gripper, "base", "f2")
    whole = optik.Mechanism.from_urdf(gripper)
    assert whole.coordinate_names == ("a", "f1") and whole.joints[2].mimic == Mimic("f1")
    with pytest.warns(UserWarning, match="names no joint of the file; the mimic is ignored"):
        lost = optik.Mechanism.from_urdf(_urdf(_j("a", "base", "l1", '<mimic joint="ghost"/>')))
    assert lost.coordinate_names == ("a",) and "ghost" in lost.params["notes"][0]
