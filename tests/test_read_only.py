"""A mechanism's arrays are read-only (issue 18, item 5): the compiled solvers, sampling bounds
and closed forms prepared for its limits can never answer for changed values; `with_limits`
makes a mechanism with new limits, whose answers respect them."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik.errors import ReadOnlyError


def test_limits_cannot_be_changed_in_place_or_replaced():
    m = optik.catalog.panda()
    before = m.lower.copy(), m.upper.copy()
    for arr in (m.lower, m.upper, *m.sampling_bounds):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 0.1
    for name in ("lower", "upper"):
        with pytest.raises(ReadOnlyError, match=rf"^{name}: .*with_limits") as info:
            setattr(m, name, np.zeros(m.n_q))
        assert info.value.argument == name
        assert isinstance(info.value, AttributeError)
    np.testing.assert_array_equal(m.lower, before[0])
    np.testing.assert_array_equal(m.upper, before[1])


def test_actuation_and_its_indices_cannot_be_changed():
    """The actuated and passive indices are computed once per mechanism (each FK call reads
    them): the actuation they come from is read-only, and so are the shared index arrays."""
    m = optik.catalog.planar_3rpr()
    assert m.actuated_indices is m.actuated_indices
    np.testing.assert_array_equal(m.actuated_indices, np.flatnonzero(m.actuated))
    np.testing.assert_array_equal(np.sort(np.r_[m.actuated_indices, m.passive_indices]), np.arange(m.n_q))
    for arr in (m.actuated_indices, m.passive_indices):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1
    with pytest.raises(ReadOnlyError, match=r"^actuated: ") as info:
        m.actuated = (True,) * m.n_q
    assert info.value.argument == "actuated"
    np.testing.assert_array_equal(m.actuated_indices, np.flatnonzero(m.actuated))


def test_joint_and_frame_arrays_are_read_only_copies():
    origin = np.eye(4)
    j = optik.Joint("q1", "revolute", "base", "l1", origin=origin, axis=[0.0, 0.0, 1.0])
    origin[0, 3] = 5.0  # the caller's array is copied, not kept
    assert j.origin[0, 3] == 0.0
    m = optik.Mechanism([j], frames={"tool": ("l1", np.eye(4))}, ee="tool")
    for arr in (j.origin, j.axis, j.child_offset, m.frames["tool"][1], m.frames["l1"][1]):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1.0


def test_with_limits_gives_answers_within_the_new_limits_and_leaves_the_old_ones():
    m = optik.catalog.panda()
    q = np.array([0.5, 0.3, -0.2, -1.5, 0.4, 1.8, 0.6])
    target = m.fk(q)
    assert optik.solve_ik(m, target, method="lm", seed=1).success  # prepares m's kernel
    lower = m.lower.copy()
    lower[0] = 0.45  # joint 1 narrowed to [0.45, 0.55]: the answer must keep q1 there
    upper = m.upper.copy()
    upper[0] = 0.55
    narrow = m.with_limits(lower, upper)
    assert narrow.sampling_bounds[0][0] == 0.45
    r = optik.solve_ik(narrow, target, method="lm", seed=1, time_limit=2.0)
    assert r.success and r.limits_ok
    assert 0.45 <= r.q[0] <= 0.55
    np.testing.assert_allclose(narrow.fk(r.q)[:3, 3], target[:3, 3], atol=1e-6)
    np.testing.assert_array_equal(m.lower, optik.catalog.panda().lower)  # the original is unchanged
