"""The optional PyRoki batch peer (`optik.harness.peers.pyroki_peer`): a missing checkout is a
`PeerUnavailable` that names it (the benchmark then says it skipped PyRoki); with a checkout
(``OPTIK_PYROKI_DIR``) and its dependencies installed, its answers are judged by the referee."""

from __future__ import annotations

import os

import numpy as np
import pytest

import optik
from optik.catalog.arms import URDF_CHAINS, urdf_path
from optik.harness.peers import PeerUnavailable
from optik.harness.peers.pyroki_peer import PyRokiBatch
from optik.harness.peers.rules import Referee


def _panda() -> tuple[optik.Mechanism, str, str, str]:
    path, (base, tip) = str(urdf_path("panda")), URDF_CHAINS["panda"]
    return optik.Mechanism.from_urdf(path, base, tip), path, base, tip


def test_a_missing_checkout_is_unavailable_and_named(tmp_path):
    m, path, _, tip = _panda()
    with pytest.raises(PeerUnavailable, match=str(tmp_path / "src" / "pyroki")):
        PyRokiBatch(tmp_path, m, path, tip, batch=4)


@pytest.mark.slow
@pytest.mark.skipif("OPTIK_PYROKI_DIR" not in os.environ, reason="OPTIK_PYROKI_DIR: no PyRoki checkout given")
def test_pyroki_answers_are_judged_like_everyone_s():
    m, path, base, tip = _panda()
    peer = PyRokiBatch(os.environ["OPTIK_PYROKI_DIR"], m, path, tip, batch=8, seeds=8, keep=2)
    targets = optik.fk_batch(m, m.random_q(6, seed=0))
    q = peer.solve(targets, m.random_q(6, seed=1))  # 6 of a batch of 8: padded, then trimmed
    assert q.shape == (6, m.n_q)
    referee = Referee(m, path, base, tip)
    tol = optik.Tolerances(position=1e-3, orientation=1e-3)
    verdicts = [referee.judge(qi, t, tol) for qi, t in zip(q, targets, strict=True)]
    assert sum(v.success for v in verdicts) >= 3  # a beam of 8 seeds reaches most of them
    assert np.all(np.isfinite(q))
    with pytest.raises(ValueError, match="batch"):
        peer.solve(np.repeat(targets, 2, axis=0), np.repeat(q, 2, axis=0))
