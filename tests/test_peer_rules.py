"""The rules every benchmarked solver is held to (optik.harness.peers.rules): the tolerance each peer is
asked for implies the Euclidean check, clipping and overshoot are the same for all, the referee rejects
what it must, and every peer's claimed success passes the referee."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik.catalog.arms import URDF_CHAINS, urdf_path
from optik.errors import InvalidArgumentError
from optik.harness.peers import ADAPTERS
from optik.harness.peers.rules import HALF, Referee, overshoot, residual_bound, settle, twist_epsilon

TOL = optik.Tolerances(position=1e-5, orientation=2e-5)


def _panda() -> tuple[optik.Mechanism, tuple[str, str, str]]:
    path = str(urdf_path("panda"))
    base, tip = URDF_CHAINS["panda"]
    return optik.Mechanism.from_urdf(path, base, tip), (path, base, tip)


@settings(derandomize=True, max_examples=200, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3))
def test_a_twist_within_the_component_bound_meets_the_euclidean_tolerance(signs):
    eps = twist_epsilon(TOL)
    error = eps * np.asarray(signs)  # every component within eps, corners included
    assert np.linalg.norm(error) <= math.sqrt(3) * eps <= min(TOL.position, TOL.orientation)
    corner = np.full(3, eps)  # the worst case leaves room: sqrt(3) / 2 of the tolerance
    assert np.linalg.norm(corner) == pytest.approx(math.sqrt(3) * HALF * 1e-5)


@settings(derandomize=True, max_examples=200, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6))
def test_a_residual_within_the_toolbox_bound_is_within_half_the_tolerance(direction):
    e = np.asarray(direction)
    if np.linalg.norm(e) < 1e-3:
        e = np.ones(6)
    e *= math.sqrt(2 * residual_bound(TOL)) / np.linalg.norm(e)  # E = |e|^2 / 2 exactly at the bound
    limit = HALF * min(TOL.position, TOL.orientation) * (1 + 1e-12)
    assert np.linalg.norm(e[:3]) <= limit and np.linalg.norm(e[3:]) <= limit


def test_settle_clips_like_solve_ik_and_overshoot_measures_the_raw_answer():
    m, _ = _panda()
    q = m.mid_q()
    q[0] = m.upper[0] + 1e-7
    q[3] = m.lower[3] - 3e-7
    assert overshoot(m, q) == pytest.approx(3e-7, rel=1e-6)
    qq = settle(m, q)
    assert qq[0] == m.upper[0] and qq[3] == m.lower[3] and overshoot(m, qq) == 0.0
    assert overshoot(m, np.full(m.n_q, np.nan)) == math.inf
    res = optik.solve_ik(m, m.fk(q), q0=q, method="lm", tol=1e-5)  # optik clips its own answers
    assert overshoot(m, res.q) == 0.0


def test_the_referee_is_pinocchio_and_rejects_wrong_or_violating_answers():
    pytest.importorskip("pinocchio", reason="the referee's independent FK")
    m, chain = _panda()
    ref = Referee(m, *chain)
    assert ref.source == "pinocchio"
    q = m.random_q(1, seed=3)[0]
    target = m.fk(q)
    good = ref.judge(q, target, TOL)
    assert good.success and good.position < 1e-12 and good.overshoot == 0.0
    off = q.copy()
    off[1] += 1e-4  # moves the tip by ~1e-4 m: far outside the tolerance
    assert not ref.judge(off, target, TOL).success
    assert not ref.judge(None, target, TOL).success
    q_edge = m.mid_q()
    q_edge[0] = m.upper[0]
    over = q_edge.copy()
    over[0] += 1e-8  # a float32-like overshoot: clipped (as for every solver), then judged
    verdict = ref.judge(over, m.fk(q_edge), TOL)
    assert verdict.success and verdict.overshoot == pytest.approx(1e-8, rel=1e-6)


def test_an_answer_a_rounding_past_a_limit_beyond_pi_is_clipped_not_wrapped():
    """TRAC-IK's answer 3.7525 + 5.7e-8 on the Panda's joint 6 (upper limit 3.7525) was wrapped
    to -2.53 and clipped to the lower limit: a claimed success judged 0.26 m off."""
    m, _ = _panda()
    q = m.mid_q()
    q[5] = m.upper[5] + 5.7e-8
    settled = settle(m, q)
    assert settled[5] == m.upper[5] and np.array_equal(np.delete(settled, 5), np.delete(q, 5))
    q[5] = m.upper[5] + 2 * np.pi  # a whole turn past: wrapped back onto the limit's side
    assert settle(m, q)[5] == pytest.approx(m.upper[5], abs=1e-12)


def test_the_referee_refuses_another_chain():
    pytest.importorskip("pinocchio", reason="the referee's independent FK")
    m, (path, base, _) = _panda()
    with pytest.raises(InvalidArgumentError, match="urdf"):
        Referee(m, path, base, "panda_link6")


@pytest.mark.parametrize(("peer", "package"), [("trac_ik", "pytracik"), ("rtb_lm", "roboticstoolbox")])
def test_every_claimed_success_of_a_peer_passes_the_referee(peer, package):
    pytest.importorskip(package, reason=f"the {peer} peer")
    pytest.importorskip("pinocchio", reason="the referee's independent FK")
    m, chain = _panda()
    adapter = ADAPTERS[peer](m, *chain)
    ref = Referee(m, *chain)
    qs = m.random_q(30, seed=11)
    claimed = 0
    for q_ref in qs:
        target = ref.fk(q_ref)
        q, found = adapter.attempt(m.mid_q(), target, 0.05, TOL)
        if found:
            claimed += 1
            verdict = ref.judge(q, target, TOL)
            assert verdict.success, (peer, verdict)
            assert verdict.position <= math.sqrt(3) * twist_epsilon(TOL) * (1 + 1e-9)
    assert claimed >= 25  # the peers solve nearly all of these with 50 ms


def test_fksgp_without_a_checkout_is_unavailable_with_the_reason(tmp_path):
    from optik.harness.peers import PeerUnavailable
    from optik.harness.peers.fksgp_peer import load_fksgp

    with pytest.raises(PeerUnavailable, match=r"solver66\.py not found"):
        load_fksgp(tmp_path)
