"""Tests of optik.problem_files: schema validation with named errors, shipped files, target sampling."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

import optik
from optik import problem_files
from optik.errors import InvalidArgumentError, ProblemFileError

MINIMAL = """
[problem]
description = "test"

[mechanism]
constructor = "planar_3r"
[mechanism.params]
lengths = [1.0, 0.8, 0.5]
"""


def write(tmp_path, text, name="p.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_minimal_file_gets_the_design_defaults(tmp_path):
    p = problem_files.load_problem(write(tmp_path, MINIMAL, "mine.toml"))
    assert p.name == "mine" and p.default
    assert (p.tolerances.position, p.tolerances.orientation, p.tolerances.closure) == (1e-6, 1e-6, 1e-9)
    assert p.methods is None and p.peers == ()
    assert p.mechanism().params["lengths"] == (1.0, 0.8, 0.5)
    assert p.mechanism_task == "pose2d"


@pytest.mark.parametrize(
    ("extra", "key", "what"),
    [
        ("[targets]\nn = 0\n", "targets.n", "integer >= 1"),
        ("[targets]\nn = 2.5\n", "targets.n", "integer"),
        ("[targets]\nsampling = 'random'\n", "targets.sampling", "expected one of"),
        ("[tolerances]\nposition = -1.0\n", "tolerances.position", "> 0"),
        ("[tolerances]\nposition = 'tight'\n", "tolerances.position", "number"),
        ("[solvers]\npeers = ['moveit']\n", "solvers.peers", "moveit"),
        ("[solvers]\ntime_limit = true\n", "solvers.time_limit", "number"),
        ("[solvers]\nspeed = 3\n", "solvers.speed", "unknown key"),
        ("[limits]\nlower = []\n", "limits.lower", "non-empty array"),
        ("[extras]\nx = 1\n", "[extras]", "unknown table"),
    ],
)
def test_schema_errors_name_file_and_key(tmp_path, extra, key, what):
    path = write(tmp_path, MINIMAL + extra)
    with pytest.raises(ProblemFileError) as info:
        problem_files.load_problem(path)
    msg = str(info.value)
    assert msg.startswith(str(path)), msg
    assert key in msg and what in msg, msg


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("[problem]\ndescription = 'x'\n", r"\[mechanism\]: missing required table"),
        ("[problem]\n[mechanism]\nconstructor = 'planar_2r'\n", "problem.description: missing required key"),
        (MINIMAL.replace('"planar_3r"', '"hexapod"'), "mechanism.constructor"),
        (MINIMAL.replace("lengths =", "widths ="), "mechanism.params.widths"),
        ("[problem\n", "invalid TOML"),
    ],
)
def test_structural_errors(tmp_path, text, key):
    path = write(tmp_path, text)
    with pytest.raises(ProblemFileError, match=key) as info:
        problem_files.load_problem(path)
    assert str(path) in str(info.value)


def test_constructor_and_limit_errors_surface_when_building(tmp_path):
    bad_len = problem_files.load_problem(
        write(tmp_path, MINIMAL.replace("[1.0, 0.8, 0.5]", "[1.0, -0.8, 0.5]"))
    )
    with pytest.raises(ProblemFileError, match=r"mechanism\.params\.lengths"):
        bad_len.mechanism()
    short = problem_files.load_problem(write(tmp_path, MINIMAL + "[limits]\nlower = [0.0, 0.0]\n", "s.toml"))
    with pytest.raises(ProblemFileError, match=r"limits\.lower: expected 3 values"):
        short.mechanism()
    crossed = problem_files.load_problem(
        write(tmp_path, MINIMAL + "[limits]\nlower = [1.0, 0.0, 0.0]\nupper = [0.0, 1.0, 1.0]\n", "c.toml")
    )
    with pytest.raises(ProblemFileError, match="limits"):
        crossed.mechanism()


def test_sampling_mode_must_fit_the_chain(tmp_path):
    p = problem_files.load_problem(write(tmp_path, MINIMAL + "[targets]\nsampling = 'actuated'\n"))
    with pytest.raises(ProblemFileError, match=r"targets\.sampling"):
        p.sample_targets(3)


def test_missing_file_and_unknown_problem(tmp_path):
    with pytest.raises(ProblemFileError, match="cannot read"):
        problem_files.load_problem(tmp_path / "nope.toml")
    with pytest.raises(InvalidArgumentError, match="unknown problem 'nope'"):
        problem_files.find_problem("nope")
    with pytest.raises(InvalidArgumentError, match="problems"):
        problem_files.list_problems(tmp_path / "absent")


SHIPPED = sorted(p.stem for p in problem_files.PROBLEM_DIR.glob("*.toml"))


def test_the_default_problems_cover_twelve_catalog_mechanisms():
    """The default set is the one list of the twelve mechanisms (the fuzzer's pool and the plot
    tests take it from `default_constructors`): one problem each, named after it."""
    names = problem_files.default_constructors()
    assert len(names) == 12 and set(names) <= set(optik.catalog.__all__)
    assert sorted(p.name for p in problem_files.default_problems()) == names
    assert set(names) <= set(SHIPPED)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_problem_targets(name):
    p = problem_files.find_problem(name)
    m = p.mechanism()
    t = p.sample_targets(6, seed=1)  # every shipped problem must be sampleable (no skip)
    assert len(t) >= 1 and t.q.shape[1] == m.n_q
    assert np.all(t.q >= m.lower) and np.all(t.q <= m.upper)
    for q, pose in zip(t.q, t.poses, strict=True):
        np.testing.assert_allclose(m.fk(q), pose, atol=1e-12)
        if m.is_closed:
            assert np.max(np.abs(m.closure(q))) <= p.tolerances.closure
    again = p.sample_targets(6, seed=1)
    np.testing.assert_array_equal(t.q, again.q)
    if p.urdf:
        chain = p.urdf_chain()
        assert chain is not None and chain[0].is_file()


def test_joint_sampling_is_uniform_within_limits():
    p = problem_files.find_problem("planar_2r")
    t = p.sample_targets(400, seed=0)
    m = p.mechanism()
    assert t.sampling == "joint" and t.draws == 400
    # uniform on [-pi, pi]: mean near 0, std near pi / sqrt(3)
    assert np.all(np.abs(t.q.mean(axis=0)) < 0.3)
    np.testing.assert_allclose(t.q.std(axis=0), (m.upper - m.lower) / np.sqrt(12), rtol=0.1)


ARM_XML = """<mujoco model="arm2">
  <compiler angle="radian"/>
  <worldbody>
    <body name="upper"><joint name="shoulder" type="hinge" axis="0 0 1" range="-2 2" limited="true"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.02"/>
      <body name="fore" pos="0.5 0 0"><joint name="elbow" type="hinge" axis="0 0 1" range="-2.5 2.5"
          limited="true"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.02"/>
        <site name="tip" pos="0.4 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_an_mjcf_model_in_a_problem_file(tmp_path):
    """``mechanism.mjcf`` (relative to the file) loads the model through Mechanism.from_mjcf;
    its targets are FK of joint draws and solve to the tolerances; exactly one of constructor and
    mjcf, an existing file and no params are required."""
    pytest.importorskip("mujoco", reason="MJCF needs MuJoCo (extra 'mjcf')")
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "arm2.xml").write_text(ARM_XML)
    text = '[problem]\ndescription = "arm"\n[mechanism]\nmjcf = "models/arm2.xml"\ntask = "position"\n'
    p = problem_files.load_problem(write(tmp_path, text))
    m = p.mechanism()
    assert p.mjcf == tmp_path / "models" / "arm2.xml" and m.coordinate_names == ("shoulder", "elbow")
    np.testing.assert_allclose(m.upper, [2.0, 2.5])
    targets = p.sample_targets(5)
    assert targets.task == "position"
    for q, t in zip(targets.q, targets.poses, strict=True):
        assert m.within_limits(q)
        r = optik.solve_ik(
            m, optik.Position(t[:3, 3]), frame=m.ee, method="lm", time_limit=1.0, compile=False
        )
        assert r.success, r.message
    for mech, what in (
        ('constructor = "planar_3r"\nmjcf = "models/arm2.xml"', "one of constructor"),
        ("", "one of constructor"),
        ('mjcf = "models/none.xml"', "no such file"),
        ('mjcf = "models/arm2.xml"\n[mechanism.params]\nn = 1', "no parameters"),
    ):
        bad = f'[problem]\ndescription = "arm"\n[mechanism]\n{mech}\n'
        with pytest.raises(ProblemFileError, match=what):
            problem_files.load_problem(write(tmp_path, bad, "bad.toml"))


WORLD = """
[world.table]
box = [1.0, 1.2, 0.04]
xyz = [0.5, 0.0, -0.03]

[world.ball]
sphere = 0.05
xyz = [0.4, 0.1, 0.5]
"""


def test_a_world_table_becomes_the_problems_world(tmp_path):
    pytest.importorskip("coal", reason="worlds need coal (extra 'collision')")
    p = problem_files.load_problem(write(tmp_path, MINIMAL + WORLD))
    assert sorted(p.world.names) == ["ball", "table"]
    assert np.allclose(p.world["ball"].pose[:3, 3], [0.4, 0.1, 0.5])
    assert problem_files.load_problem(write(tmp_path, MINIMAL, "none.toml")).world is None


@pytest.mark.parametrize(
    ("extra", "key"),
    [
        ("[world.table]\nbox = [1.0, 1.2, 0.04]\nsphere = 0.1\n", "world.table"),
        ("[world.table]\nbox = [1.0, 1.2, 0.04]\ncolour = 'red'\n", "world.table"),
        ("[world.ball]\nsphere = 0.05\nxyz = [0.4, 0.1]\n", "world.ball.xyz"),
        ("world = 3\n", "world: expected a table"),
    ],
)
def test_a_bad_world_table_names_the_object(tmp_path, extra, key):
    pytest.importorskip("coal", reason="worlds need coal (extra 'collision')")
    body = extra + MINIMAL if extra.startswith("world =") else MINIMAL + extra
    with pytest.raises(ProblemFileError, match=key.replace(".", r"\.").replace("[", r"\[")):
        problem_files.load_problem(write(tmp_path, body))
