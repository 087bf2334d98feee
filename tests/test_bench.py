"""Tests of optik.harness: statistics, notes instead of crashes, output files, peers, progress bar."""

from __future__ import annotations

import csv
import io
import json
import math
import textwrap

import numpy as np
import pytest

from optik import problem_files
from optik.errors import InvalidArgumentError
from optik.harness import run_bench, run_problem
from optik.harness.contenders import Call, SolverRun
from optik.progress import Progress


def call(t, ok=True, cf=0.0, ref=0.0):
    return Call(t, ok, 0.0, 0.0, 0.0, True, cf, ref, "solved" if ok else "not_converged")


def test_stats_follow_the_definitions():
    times = [0.001 * k for k in range(1, 21)]  # 1 .. 20 ms
    run = SolverRun(
        "x", "method", [call(t, ok=k % 4 != 0, cf=1e-6 if k % 2 else 0.1) for k, t in enumerate(times)]
    )
    s = run.stats(fastest_median=0.005)
    assert s["n"] == 20
    assert s["success_pct"] == pytest.approx(75.0)
    assert s["mean_ms"] == pytest.approx(10.5)
    assert s["median_ms"] == pytest.approx(10.5)
    assert s["p95_ms"] == pytest.approx(np.percentile(np.arange(1, 21), 95))
    assert s["ratio"] == pytest.approx(10.5 / 5.0)
    successes = [k for k in range(20) if k % 4 != 0]
    on_branch = [k for k in successes if k % 2]
    assert s["branch_pct"] == pytest.approx(100.0 * len(on_branch) / len(successes))
    assert s["cf_err_max"] == pytest.approx(0.1)
    assert s["failures"] == {"not_converged": 5}


def test_stats_without_closed_form_are_nan():
    s = SolverRun("x", "peer", [call(0.002, cf=math.nan)]).stats(0.001)
    assert math.isnan(s["cf_err_max"]) and math.isnan(s["branch_pct"])
    assert s["ratio"] == pytest.approx(2.0)


def write_problem(tmp_path, extra):
    path = tmp_path / "tiny.toml"
    path.write_text(
        textwrap.dedent(
            """
            [problem]
            description = "tiny 2R"
            [mechanism]
            constructor = "planar_2r"
            """
        )
        + textwrap.dedent(extra)
    )
    return problem_files.load_problem(path)


def test_missing_methods_and_peers_become_notes(tmp_path):
    p = write_problem(
        tmp_path,
        """
        [solvers]
        methods = ["lm", "warp_drive"]
        peers = ["trac_ik"]
        """,
    )
    res = run_problem(p, n=3, time_limit=0.05)
    assert [r.name for r in res.runs] == ["lm"]
    assert len(res.runs[0].calls) == 3
    joined = " ".join(res.notes)
    assert "warp_drive" in joined and "not registered" in joined
    assert "trac_ik" in joined and "URDF" in joined


def test_run_problem_same_targets_for_everyone(tmp_path):
    p = write_problem(tmp_path, "[targets]\nseed = 4\n")
    res = run_problem(p, n=4, time_limit=0.05, only=["lm", "closed_form"])
    assert {r.name for r in res.runs} == {"lm", "closed_form"}
    np.testing.assert_array_equal(res.targets.q, p.sample_targets(4, seed=4).q)
    for r in res.runs:
        assert len(r.calls) == 4
        assert all(c.time > 0 for c in r.calls)
    cf = next(r for r in res.runs if r.name == "closed_form")
    assert all(c.success and c.cf_distance < 1e-9 for c in cf.calls)


def test_quick_bench_writes_every_file(tmp_path):
    out = tmp_path / "out"
    table = io.StringIO()
    outcome = run_bench(
        ["planar_2r", "five_bar"],
        solvers=["lm", "closed_form"],
        n=3,
        quick=True,
        out=out,
        stream=table,
        progress=False,
    )
    names = sorted(p.name for p in out.iterdir())
    assert names == ["five_bar.png", "planar_2r.png", "report.md", "results.csv", "results.json"]
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary files left
    data = json.loads((out / "results.json").read_text())
    assert [p["problem"]["name"] for p in data["problems"]] == ["planar_2r", "five_bar"]
    for prob in data["problems"]:
        assert {s["solver"] for s in prob["summary"]} == {"lm", "closed_form"}
        assert len(prob["calls"]["lm"]["time"]) == 3
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert len(rows) == 4 and {r["problem"] for r in rows} == {"planar_2r", "five_bar"}
    md = (out / "report.md").read_text()
    assert "## five_bar" in md and "| solver |" in md and "![five_bar](five_bar.png)" in md
    assert (out / "five_bar.png").read_bytes()[:4] == b"\x89PNG"
    text = table.getvalue()
    assert "success %" in text and "planar_2r" in text
    assert len(outcome.runs) == 2


def test_run_bench_rejects_bad_arguments(tmp_path):
    with pytest.raises(InvalidArgumentError, match="solvers"):
        run_bench(["planar_2r"], solvers=["nope"], out=tmp_path, progress=False)
    with pytest.raises(InvalidArgumentError, match=r"^n:"):
        run_bench(["planar_2r"], n=0, out=tmp_path, progress=False)
    with pytest.raises(InvalidArgumentError, match="problem"):
        run_bench(["no_such_problem"], out=tmp_path, progress=False)


def test_peers_run_on_the_panda():
    pytest.importorskip("pytracik")
    p = problem_files.find_problem("panda")
    # TRAC-IK's answers on a limit overshoot it (it stores the limits as float32); clipped into the
    # limits like optik's, they pass the same check, re-checked by Pinocchio where installed
    res = run_problem(p, n=20, time_limit=0.5, only=["trac_ik"])
    assert [r.name for r in res.runs] == ["trac_ik"], res.notes
    s = res.summary()[0]
    assert s["kind"] == "peer" and s["success_pct"] >= 95.0, s
    assert 0.0 <= s["overshoot_max"] < 1e-6
    tol = p.tolerances
    for c in res.runs[0].calls:
        assert c.limits_ok  # every answer was settled into the limits before it was judged
        if c.success:
            assert c.position_error <= tol.position and c.orientation_error <= tol.orientation


def test_progress_bar_on_a_plain_stream():
    stream = io.StringIO()
    bar = Progress(2, stream=stream)
    bar.start("five_bar", 4)
    for _ in range(4):
        bar.step()
    bar.finish()
    line = stream.getvalue()
    assert line.startswith("[1/2] five_bar") and "100%" in line and "4/4" in line and line.endswith("\n")


@pytest.mark.parametrize(
    ("peer", "package"),
    [("trac_ik", "pytracik"), ("rtb_lm", "roboticstoolbox"), ("pink", "pink"), ("ikpy", "ikpy")],
)
def test_each_peer_matches_the_model_and_solves(peer, package):
    pytest.importorskip(package)
    from optik.harness.peers import load_peer
    from optik.solvers.base import evaluate

    p = problem_files.find_problem("iiwa14")
    m = p.mechanism()
    adapter = load_peer(peer, p)  # checks the peer's FK against the mechanism's
    t = p.sample_targets(2, seed=5)
    for q_ref, target in zip(t.q, t.poses, strict=True):
        q0 = np.clip(q_ref + 0.05, m.lower, m.upper)  # a nearby start: every peer must converge
        q = adapter.solve(q0, target, 0.5, p.tolerances)
        assert evaluate(m, q, target, "pose", None).ok(p.tolerances)


def test_peer_with_a_different_chain_is_unavailable(tmp_path):
    pytest.importorskip("pytracik")
    from optik.harness.peers import PeerUnavailable, load_peer

    path = tmp_path / "mix.toml"
    path.write_text('[problem]\ndescription = "x"\n[mechanism]\nconstructor = "iiwa14"\nurdf = "panda"\n')
    with pytest.raises(PeerUnavailable, match="differs"):
        load_peer("trac_ik", problem_files.load_problem(path))


def test_missing_peer_package_is_a_clean_note(monkeypatch):
    from optik.harness.peers import ADAPTERS

    monkeypatch.setattr(ADAPTERS["ikpy"], "package", "no_such_ikpy_module")
    res = run_problem(problem_files.find_problem("panda"), n=2, time_limit=0.02, only=["ikpy", "lm"])
    assert [r.name for r in res.runs] == ["lm"]
    assert any("no_such_ikpy_module" in n and 'pip install "optik[peers]"' in n for n in res.notes), res.notes
