"""Every MJCF file shipped by the installed test-set packages (dm_control, gymnasium,
gymnasium-robotics): where MuJoCo compiles it, `Mechanism.from_mjcf` loads it and the pose of
every body and site equals MuJoCo's ``mj_kinematics`` (``xpos``, ``xmat``, ``site_xpos``,
``site_xmat``) to 1e-10 on random configurations, and so does the centre of mass (MuJoCo's
``subtree_com`` of the world); a model without joints is refused. Files that
MuJoCo itself cannot compile (include fragments, schemas, files whose assets are missing) are
skipped with MuJoCo's message. With ``$OPTIK_MENAGERIE`` naming a MuJoCo Menagerie checkout, its
models are tested the same way. The table in ``docs/mjcf.md`` lists the outcome per file."""

from __future__ import annotations

import os
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import optik
from optik.errors import ModelError

mujoco = pytest.importorskip("mujoco", reason="MJCF import needs MuJoCo (extra 'mjcf')")
from optik.benchmarks.bench_mjcf_fk import model_files  # noqa: E402  (after the importorskip)
from optik.mechanism.mjcf import to_qpos  # noqa: E402

SAMPLES = 3

MENAGERIE = os.environ.get("OPTIK_MENAGERIE")
# each distinct file once (gymnasium's envs are copied into gymnasium-robotics)
FILES = model_files(Path(MENAGERIE) if MENAGERIE and Path(MENAGERIE).is_dir() else None)


def test_the_test_sets_are_installed():
    if not FILES:
        pytest.skip("none of dm_control, gymnasium, gymnasium-robotics is installed")
    assert len(FILES) > 20


def _max_fk_error(m: optik.Mechanism, model, q: np.ndarray, frames: list[str], f: ca.Function) -> float:
    data = mujoco.MjData(model)
    data.qpos[:] = to_qpos(m, q)
    mujoco.mj_kinematics(model, data)
    want = [(data.xpos[b], data.xmat[b]) for b in range(1, model.nbody)]
    want += [(data.site_xpos[s], data.site_xmat[s]) for s in range(model.nsite)]
    out = f(q)
    got = [np.asarray(t) for t in (out if isinstance(out, tuple | list) else [out])]
    assert len(got) == len(want) == len(frames)
    return max(
        max(np.abs(t[:3, 3] - p).max(), np.abs(t[:3, :3] - r.reshape(3, 3)).max())
        for t, (p, r) in zip(got, want, strict=True)
    )


@pytest.mark.parametrize("path", [p for _, p in FILES], ids=[i for i, _ in FILES])
def test_fk_equals_mujoco(path: Path):
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        pytest.skip(f"MuJoCo does not compile it either: {str(exc).splitlines()[0]}")
    if model.njnt == 0:
        with pytest.raises(ModelError, match="no joint"):
            optik.Mechanism.from_mjcf(model)
        return
    m = optik.Mechanism.from_mjcf(model)
    coupled = len(m.params["qpos_mimics"])  # joints that follow others (<equality joint>)
    assert m.n_q == model.nq - sum(int(t) in (0, 1) for t in model.jnt_type) - coupled  # quaternions: 3
    frames = [model.body(b).name or f"body{b}" for b in range(1, model.nbody)]
    frames += [m.params["site_frames"][model.site(s).name or f"site{s}"] for s in range(model.nsite)]
    f = ca.Function("frames", [m.q_sym], [m.frame_expr(name) for name in frames])
    data = mujoco.MjData(model)
    for q in m.random_q(SAMPLES, seed=0):
        assert _max_fk_error(m, model, q, frames, f) < 1e-10
        data.qpos[:] = to_qpos(m, q)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        assert np.abs(m.com(q) - data.subtree_com[0]).max() < 1e-10


def test_the_fk_benchmark_runs(capsys):
    from optik.benchmarks import bench_mjcf_fk

    assert bench_mjcf_fk.main(["--n", "2", "--max-models", "2"]) == 0
    out = capsys.readouterr().out
    assert out.count("| `") == 2 and "2 models, largest error" in out


def test_mesh_visuals_sit_where_mujoco_puts_them():
    """A mesh visual placed by optik (asset file, ``origin``, ``scale``, the frame's FK) covers
    MuJoCo's compiled, re-centred vertices at ``geom_xpos`` / ``geom_xmat`` (float32 in MuJoCo)."""
    trimesh = pytest.importorskip("trimesh", reason="reading mesh files needs trimesh (extra 'view')")
    from scipy.spatial import cKDTree

    path = next((p for i, p in FILES if i == "gymnasium_robotics/envs/assets/fetch/reach.xml"), None)
    if path is None:
        pytest.skip("gymnasium-robotics (the Fetch) is not installed")
    model = mujoco.MjModel.from_xml_path(str(path))
    m = optik.Mechanism.from_mjcf(model)
    data = mujoco.MjData(model)
    q = m.random_q(seed=2)
    data.qpos[:] = to_qpos(m, q)
    mujoco.mj_kinematics(model, data)
    visuals = [v for v in m.params["visuals"] if v.geometry == "mesh"]
    geoms = [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
    assert len(visuals) == len(geoms) > 10
    for v, g in zip(visuals, geoms, strict=True):
        mesh = int(model.geom_dataid[g])
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        want = model.mesh_vert[start : start + count] @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        t = m.fk(q, v.link) @ v.origin
        points = np.asarray(trimesh.load(v.path, force="mesh", process=False).vertices) * np.asarray(v.scale)
        distance, _ = cKDTree(points @ t[:3, :3].T + t[:3, 3]).query(want)
        assert distance.max() < 1e-5, v.filename
