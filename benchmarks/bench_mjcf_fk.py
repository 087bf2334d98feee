"""MJCF forward kinematics against MuJoCo: every model of the installed test sets (dm_control,
gymnasium, gymnasium-robotics) that loads, the largest error of optik's body and site poses
against ``mj_kinematics`` and the time per FK of all frames.

Method: for each distinct ``.xml`` file that MuJoCo compiles and that has a joint,
``Mechanism.from_mjcf`` on the compiled model; ``--n`` configurations drawn within the limits
(seeded; free and unlimited joints over one turn and +-1 m); per configuration the poses of
every body and site by one compiled CasADi function of all frames (``m.frame_expr`` of each,
one ``casadi.Function`` with one ``4 x 4k`` output), compared with MuJoCo's ``xpos`` /
``xmat`` / ``site_xpos`` / ``site_xmat`` after ``mj_kinematics`` at ``to_qpos(m, q)``.
Times: the mean per call of that function and of ``mj_kinematics`` (which computes the same
poses and the geoms', cameras' and lights' too) over the ``--n`` configurations, after one warm-up call each.

``--menagerie DIR`` adds the models of a MuJoCo Menagerie checkout (google-deepmind/mujoco_menagerie,
with its mesh assets) to the test sets; the same files are tested by tests/test_mjcf_models.py
when ``$OPTIK_MENAGERIE`` names that folder.

Run: ``optik benchmark mjcf_fk [--n 100] [--seed 0] [--max-models 0] [--menagerie DIR]``.
"""

from __future__ import annotations

import hashlib
import importlib.util
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import optik
from optik.benchmarks import benchmark_parser

PACKAGES = ("dm_control", "gymnasium", "gymnasium_robotics")


def model_files(menagerie: Path | None = None) -> list[tuple[str, Path]]:
    """``(package-relative id, path)`` of every distinct ``.xml`` file of the installed packages
    and of a Menagerie folder ``menagerie`` (ids ``menagerie/...``; a file shipped twice, e.g.
    gymnasium's envs copied into gymnasium-robotics, counts once)."""
    out, seen = [], set()
    roots = []
    for pkg in PACKAGES:
        spec = importlib.util.find_spec(pkg)
        if spec is not None and spec.submodule_search_locations:
            roots.append((pkg, Path(next(iter(spec.submodule_search_locations)))))
    if menagerie is not None:
        roots.append(("menagerie", Path(menagerie)))
    for pkg, root in roots:
        for path in sorted(root.rglob("*.xml")):
            digest = hashlib.sha1(path.read_bytes()).hexdigest()
            if digest not in seen:
                seen.add(digest)
                out.append((f"{pkg}/{path.relative_to(root)}", path))
    return out


def measure(model, n: int, seed: int) -> tuple[optik.Mechanism, float, float, float]:
    """``(mechanism, max error, optik s per FK of all frames, MuJoCo s per mj_kinematics)``."""
    import casadi as ca
    import mujoco

    from optik.mechanism.mjcf import to_qpos

    m = optik.Mechanism.from_mjcf(model)
    frames = [model.body(b).name or f"body{b}" for b in range(1, model.nbody)]
    frames += [m.params["site_frames"][model.site(s).name or f"site{s}"] for s in range(model.nsite)]
    f = ca.Function("frames", [m.q_sym], [ca.horzcat(*(m.frame_expr(name) for name in frames))])
    data = mujoco.MjData(model)
    qs = m.random_q(n, seed=seed)
    qpos = [to_qpos(m, q) for q in qs]
    f(qs[0])
    mujoco.mj_kinematics(model, data)
    t0 = time.perf_counter()
    outs = [f(q) for q in qs]
    t_optik = (time.perf_counter() - t0) / n
    t_mj, err = 0.0, 0.0
    for out, qp in zip(outs, qpos, strict=True):
        data.qpos[:] = qp
        t0 = time.perf_counter()
        mujoco.mj_kinematics(model, data)
        t_mj += time.perf_counter() - t0
        got = np.split(np.asarray(out), len(frames), axis=1)
        want = [(data.xpos[b], data.xmat[b]) for b in range(1, model.nbody)]
        want += [(data.site_xpos[s], data.site_xmat[s]) for s in range(model.nsite)]
        for t, (p, r) in zip(got, want, strict=True):
            err = max(
                err, float(np.abs(t[:3, 3] - p).max()), float(np.abs(t[:3, :3] - r.reshape(3, 3)).max())
            )
    return m, err, t_optik, t_mj / n


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print a markdown table; returns 0."""
    ap = benchmark_parser("mjcf_fk", __doc__)
    ap.add_argument("--n", type=int, default=100, help="configurations per model")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--max-models", type=int, default=0, help="stop after this many models (0: all)")
    ap.add_argument("--menagerie", type=Path, default=None, help="a MuJoCo Menagerie checkout to test too")
    args = ap.parse_args(argv)
    if args.n < 1 or args.max_models < 0:
        ap.error("--n must be >= 1, --max-models >= 0")
    if args.menagerie is not None and not args.menagerie.is_dir():
        ap.error(f"--menagerie: no such folder {args.menagerie}")
    try:
        import mujoco
    except ImportError:
        print('MuJoCo is not installed (pip install "optik[mjcf]")')
        return 0
    print(f"{args.n} configurations per model; times per FK of every body and site")
    print("| model | n_q | frames | max error | optik us | mj_kinematics us | optik / MuJoCo |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    done, worst = 0, 0.0
    for rid, path in model_files(args.menagerie):
        try:
            model = mujoco.MjModel.from_xml_path(str(path))
        except ValueError:
            continue
        if model.njnt == 0:
            continue
        m, err, t_o, t_m = measure(model, args.n, args.seed)
        worst = max(worst, err)
        frames = model.nbody - 1 + model.nsite
        times = f"{t_o * 1e6:.1f} | {t_m * 1e6:.1f} | {t_o / t_m:.1f}"
        print(f"| `{rid}` | {m.n_q} | {frames} | {err:.1e} | {times} |")
        done += 1
        if args.max_models and done >= args.max_models:
            break
    print(f"{done} models, largest error {worst:.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
