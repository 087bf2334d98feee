"""optik.catalog.legged: the Go2 quadruped and the G1 humanoid of example-robot-data with a
floating base, their standing configurations and support polygons, and whole-body IK with the
feet held and the centre of mass over the polygon (re-checked from ``q``)."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik.catalog.legged import support_polygon
from optik.errors import InvalidArgumentError
from optik.solvers.balance import support_halfplanes


def _load(name: str) -> optik.Mechanism:
    try:
        return optik.catalog.legged(name)
    except optik.errors.MissingExtraError as exc:
        pytest.skip(f"example-robot-data is needed: {exc}")


@pytest.mark.parametrize("name", ["go2", "g1"])
def test_standing_and_base_pose_with_balance(name):
    m = _load(name)
    assert m.joints[0].type == "free" and m.kind == f"legged:{name}"
    q = m.params["standing"]
    feet = m.params["feet"]
    assert min(m.fk(q, f)[2, 3] for f in feet) == pytest.approx(0.0, abs=1e-12)
    polygon = support_polygon(m, q)
    n, b = support_halfplanes(polygon)  # counter-clockwise and convex, or it raises
    assert np.min(b - n @ m.com(q)[:2]) > 0.01  # standing is balanced
    flat = m.params["sole"] is not None
    contacts = {f: m.fk(q, f) if flat else optik.Position(m.fk(q, f)[:3, 3]) for f in feet}
    base = m.joints[0].child
    goal = m.fk(q, base)
    goal[:3, 3] += [0.02, 0.01, -0.03]
    goal[:3, :3] = optik.spatial.rot_z(0.08) @ goal[:3, :3]
    r = optik.solve_ik(
        m, {base: goal}, q0=q, contacts=contacts, support=polygon, com_margin=0.01, time_limit=10
    )
    assert r.success, r.message
    t = m.fk(r.q, base)
    assert np.abs(t[:3, 3] - goal[:3, 3]).max() < 1e-6
    assert optik.spatial.angle_between(t[:3, :3], goal[:3, :3]) < 1e-6
    for f, c in contacts.items():
        want = c if flat else None
        got = m.fk(r.q, f)
        if want is None:
            assert np.abs(got[:3, 3] - c.xyz).max() < 1e-6
        else:
            assert np.abs(got - want).max() < 1e-6
    assert np.min(b - n @ m.com(r.q)[:2]) >= 0.01 - 1e-9 and m.within_limits(r.q)


def test_rejections():
    with pytest.raises(InvalidArgumentError, match="name"):
        optik.catalog.legged("spot")
    with pytest.raises(InvalidArgumentError, match="m"):
        support_polygon(optik.catalog.planar_2r(), np.zeros(2))
