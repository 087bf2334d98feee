"""The first solve on a robot never compiled before: optik against TRAC-IK and Pink, cold.

What a new user waits for in a fresh process: load the Panda URDF shipped with optik
(``Mechanism.from_urdf``) and answer the first ``solve_ik`` (or the first ``diffik.step``), on a
robot never compiled: ``$OPTIK_CACHE_DIR`` is a new folder that holds only what a machine builds
once for every robot (the generic QP stack of a frame task on 7 joints,
`optik.diffik.generic_stack`, and the compiler's version record; the generic lm kernel of 7
joints, `optik.solvers.generic_chain`, is compiled into the package at install, or copied there
too where the install had no compiler), so optik answers the first solves and steps through
those while the Panda's own C libraries build in the background. The case "empty cache" has
nothing in its cache (the first use of optik on a machine): only what the install compiled into
the package. Next to it, in the same
run, TRAC-IK's constructor plus its first ``ik`` call (``pytracik``, same URDF, same target) and,
for the differential step, Pink's model construction plus its first ``solve_ik`` (``pin-pink``,
same QP backend as optik's default). As a reference, optik with ``compile=True`` shows the wait
for the C build that the background build removes.

Method: every measurement runs in its own fresh Python process (interleaved case by case, one
repetition after the other, so that load changes hit all cases alike); the clock starts after
the imports (their time is reported apart) and stops when the first answer is back; the CPU
time of the process over the same window is reported too (on a loaded machine the wall time
includes waiting for a core). Targets are
the flange poses of seeded random joint vectors within the limits, one per repetition, the
same for every case. The first answer is checked in this process: IK success by optik's FK
(position and orientation error <= 1e-6, limits), the first ``diffik.step`` by equality (1e-12)
with a step computed here with the compiled code. Medians over the repetitions.

Run: ``optik benchmark first_solve [--reps 7] [--figure docs/img/first_solve.png]``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

BASE, TIP = "panda_link0", "panda_link8"
DT = 0.01
LIMIT = 0.005
"""Time limit of optik's first ``solve_ik`` (TRAC-IK keeps its 0.1 s timeout)."""
CASES = {
    "optik_ik": "optik: from_urdf + first solve_ik (robot never compiled)",
    "optik_ik_empty": "optik, empty cache (only the kernels built at install)",
    "optik_ik_wait": "optik, compile=True (waits for the C build)",
    "trac_ik": "TRAC-IK: constructor + first ik",
    "optik_step": "optik: from_urdf + first diffik.step (robot never compiled)",
    "pink_step": "Pink: model + first solve_ik",
}
SHORT = {
    "optik_ik": "optik IK",
    "optik_ik_empty": "optik IK, empty cache",
    "optik_ik_wait": "optik IK, waiting for gcc",
    "trac_ik": "TRAC-IK",
    "optik_step": "optik diffik.step",
    "pink_step": "Pink step",
}


def _urdf() -> Path:
    """The Panda URDF shipped with optik (a child reads its path from the environment, so that
    no optik import falls into a peer's timed window)."""
    if "OPTIK_BENCH_URDF" in os.environ:
        return Path(os.environ["OPTIK_BENCH_URDF"])
    import optik

    return Path(optik.__file__).parent / "data" / "urdf" / "panda.urdf"


# ------------------------------------------------------------------ the child processes
def _now() -> tuple[float, float]:
    """Wall clock and this process's CPU time (all its threads; not the compiler it starts)."""
    return time.perf_counter(), time.process_time()


def _result(t_import: tuple[float, float], t0: tuple[float, float], t1: tuple[float, float], q) -> dict:
    return {"import": t0[0] - t_import[0], "total": t1[0] - t0[0], "cpu": t1[1] - t0[1], "q": list(q)}


def _child_optik_ik(target: np.ndarray, wait: bool) -> dict:
    t_import = _now()
    import optik
    from optik import native

    t0 = _now()
    m = optik.Mechanism.from_urdf(_urdf(), BASE, TIP)
    res = optik.solve_ik(m, target, compile=True) if wait else optik.solve_ik(m, target, time_limit=LIMIT)
    t1 = _now()
    out = _result(t_import, t0, t1, res.q.tolist())
    if not wait:
        native.wait(timeout=120)
        out["compiled_ready"] = time.perf_counter() - t0[0]
        t2 = time.perf_counter()
        optik.solve_ik(m, target)
        out["compiled_call"] = time.perf_counter() - t2
    return out


def _child_trac_ik(target: np.ndarray) -> dict:
    t_import = _now()
    import pytracik
    from scipy.spatial.transform import Rotation

    t0 = _now()
    xml = _urdf().read_text(encoding="utf-8")
    # eps = twist_epsilon(Tolerances()) of optik.harness.peers.rules, written out: the child
    # process times TRAC-IK's own imports, not optik's
    solver = pytracik.TRAC_IK(BASE, TIP, xml, 0.1, 5e-7, pytracik.SolveType.Speed)
    n = pytracik.get_num_joints(solver)
    qx, qy, qz, qw = Rotation.from_matrix(target[:3, :3]).as_quat()
    q0 = _mid_q()[:n]
    out = np.asarray(pytracik.ik(solver, q0, *target[:3, 3], qx, qy, qz, qw))
    t1 = _now()
    q = out[1:] if out[0] > 0 else q0
    return _result(t_import, t0, t1, q.tolist())


def _mid_q() -> np.ndarray:
    """Mid-limit seed of the Panda arm (read from the URDF with optik, outside the timed window)."""
    return np.asarray(json.loads(os.environ["OPTIK_BENCH_MID_Q"]), dtype=float)


def _child_optik_step(target: np.ndarray) -> dict:
    t_import = _now()
    import optik
    from optik import diffik

    t0 = _now()
    m = optik.Mechanism.from_urdf(_urdf(), BASE, TIP)
    res = diffik.step(m, m.mid_q(), [diffik.FrameTask(target=target)], DT)
    t1 = _now()
    return _result(t_import, t0, t1, res.q.tolist())


def _child_pink_step(target: np.ndarray) -> dict:
    t_import = _now()
    import pink
    import pinocchio as pin

    solver = os.environ["OPTIK_BENCH_QP"]  # optik's default QP backend (set by the parent)
    t0 = _now()
    model = pin.buildModelFromUrdf(str(_urdf()))
    conf = pink.Configuration(model, model.createData(), _mid_q())
    task = pink.tasks.FrameTask(TIP, position_cost=1.0, orientation_cost=1.0)
    task.set_target(pin.SE3(target[:3, :3], target[:3, 3]))
    v = pink.solve_ik(conf, [task], DT, solver=solver, safety_break=False)
    conf.integrate_inplace(v, DT)
    t1 = _now()
    return _result(t_import, t0, t1, np.asarray(conf.q).tolist())


def _child(case: str, target: np.ndarray) -> dict:
    if case in ("optik_ik", "optik_ik_empty"):
        return _child_optik_ik(target, wait=False)
    if case == "optik_ik_wait":
        return _child_optik_ik(target, wait=True)
    if case == "trac_ik":
        return _child_trac_ik(target)
    if case == "optik_step":
        return _child_optik_step(target)
    return _child_pink_step(target)


# ------------------------------------------------------------------ this process
def _available(case: str) -> bool:
    import importlib.util

    needs = {"trac_ik": "pytracik", "pink_step": "pink"}.get(case)
    return needs is None or importlib.util.find_spec(needs) is not None


def run_child(case: str, target: np.ndarray, mid_q: np.ndarray, machine: Sequence[Path] = ()) -> dict:
    """One measurement in a fresh Python process with a new compile cache holding copies of the
    files ``machine`` (none for the case ``optik_ik_empty``)."""
    import optik
    from optik import native
    from optik.diffik import default_solver

    root = str(Path(optik.__file__).resolve().parents[1])  # the same optik in the child
    with tempfile.TemporaryDirectory(prefix="optik-first-solve-") as cache:
        for f in () if case == "optik_ik_empty" else machine:
            sub = Path(cache) / f.parent.relative_to(native.cache_dir())
            sub.mkdir(parents=True, exist_ok=True)
            shutil.copy2(f, sub / f.name)
        env = dict(os.environ, OPTIK_CACHE_DIR=cache, OPTIK_BENCH_MID_Q=json.dumps(mid_q.tolist()))
        env["OPTIK_BENCH_URDF"] = str(_urdf())
        env["OPTIK_BENCH_QP"] = default_solver()
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", case, json.dumps(target.tolist())]
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"{case} failed in its subprocess:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _check(case: str, m, target: np.ndarray, q: np.ndarray, step_ref: dict) -> bool:
    """IK: success by optik's FK (1e-6 m / rad, limits); optik's step: equal to the compiled step."""
    from optik import spatial

    if case == "optik_step":
        key = tuple(np.round(target, 12).ravel())
        return bool(np.max(np.abs(q - step_ref[key])) <= 1e-12)
    if case == "pink_step":
        return bool(np.all(np.isfinite(q)))
    t = m.fk(q)
    pos = float(np.linalg.norm(t[:3, 3] - target[:3, 3]))
    ori = float(spatial.angle_between(t[:3, :3], target[:3, :3]))
    return pos <= 1e-6 and ori <= 1e-6 and m.within_limits(q)


def figure(rows: dict[str, dict[str, list[float]]]):
    """Horizontal bars of the median time to the first answer (log scale), the 10 ms goal marked."""
    from matplotlib.figure import Figure

    names = list(rows)
    med = [1e3 * float(np.median(rows[n]["total"])) for n in names]
    fig = Figure(figsize=(7.5, 0.5 * len(names) + 1.5))
    ax = fig.subplots()
    colors = ["tab:blue" if n.startswith("optik") and n != "optik_ik_wait" else "tab:gray" for n in names]
    colors = ["tab:red" if n == "optik_ik_wait" else c for n, c in zip(names, colors, strict=True)]
    y = np.arange(len(names))[::-1]
    ax.barh(y, med, color=colors)
    for yi, v in zip(y, med, strict=True):
        ax.text(
            v * 1.08, yi, f"{v:.1f} ms", va="center", fontsize=9, bbox={"fc": "white", "ec": "none", "pad": 1}
        )
    ax.axvline(10.0, color="k", ls="--", lw=1)
    ax.text(10.0 * 1.05, y[0] + 0.45, "10 ms goal", fontsize=8)
    ax.set_yticks(y, [SHORT[n] for n in names], fontsize=9)
    ax.set_xscale("log")
    ax.set_xlim(0.5, max(med) * 5)
    ax.set_xlabel("ms from the URDF to the first answer (median, fresh processes, log scale)")
    ax.set_title("Panda never compiled before (empty cache), imports excluded", fontsize=10)
    fig.tight_layout()
    return fig


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--child"]:
        print(json.dumps(_child(argv[1], np.asarray(json.loads(argv[2]), dtype=float))))
        return 0
    from optik.benchmarks import benchmark_parser  # not at the top: a child times its own imports

    ap = benchmark_parser("first_solve", __doc__)
    ap.add_argument("--reps", type=int, default=7, help="fresh processes per case (default 7)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    ap.add_argument("--figure", help="write the bar chart to this PNG")
    args = ap.parse_args(argv)

    import optik
    from optik import diffik, native
    from optik.diffik import generic_stack
    from optik.diffik.problem import normalize_limits
    from optik.plot import save_figure
    from optik.solvers import generic_chain

    m = optik.Mechanism.from_urdf(_urdf(), BASE, TIP)
    # built once per machine, for every robot of 7 joints: copied into each child's new cache
    generic_chain.build(m.n_q, timeout=600)
    task = [diffik.FrameTask(target=m.fk(m.mid_q()))]
    machine = generic_chain.machine_files(m.n_q)
    machine += generic_stack.machine_files(m, task, normalize_limits(m, None), timeout=600)
    targets = [m.fk(q) for q in m.random_q(args.reps, seed=args.seed)]
    step_ref = {}  # the compiled step here, for the equality check of the children's first step
    for t in targets:
        diffik.step(m, m.mid_q(), [diffik.FrameTask(target=t)], DT)
    native.wait(timeout=300)
    for t in targets:
        step_ref[tuple(np.round(t, 12).ravel())] = diffik.step(
            m, m.mid_q(), [diffik.FrameTask(target=t)], DT
        ).q
    cases = [c for c in CASES if _available(c)]
    skipped = [c for c in CASES if c not in cases]
    rows: dict[str, dict[str, list[float]]] = {
        c: {"import": [], "total": [], "cpu": [], "ok": []} for c in cases
    }
    extra: dict[str, list[float]] = {"compiled_ready": [], "compiled_call": []}
    for r, target in enumerate(targets):
        for case in cases:  # interleaved: one repetition of every case, then the next
            out = run_child(case, target, m.mid_q(), machine)
            rows[case]["import"].append(out["import"])
            rows[case]["total"].append(out["total"])
            rows[case]["cpu"].append(out["cpu"])
            rows[case]["ok"].append(_check(case, m, target, np.asarray(out["q"]), step_ref))
            for key in extra:
                if key in out and case == "optik_ik":
                    extra[key].append(out[key])
        print(f"repetition {r + 1}/{args.reps} done", file=sys.stderr)
    ref = {
        "optik_ik": "trac_ik",
        "optik_ik_empty": "trac_ik",
        "optik_ik_wait": "trac_ik",
        "optik_step": "pink_step",
    }

    def med(xs: list[float]) -> float:
        return 1e3 * float(np.median(xs))

    from optik.harness.tally import timing_ms

    def _three(xs: list[float]) -> str:
        mean, median, p95 = timing_ms(xs)
        return f"{mean:.1f} / {median:.1f} / {p95:.1f}"

    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(
        f"Panda ({BASE} -> {TIP}), {args.reps} fresh processes per case, ms (imports and CPU: medians; "
        f"ratios of medians); load average {load}\n"
    )
    print(
        "| case | imports | URDF + first answer: mean / median / p95 | min | max | CPU | checked "
        "| x peer (wall) | x peer (CPU) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for case in cases:
        row = rows[case]
        peer = rows.get(ref.get(case, ""))
        ratios = [f"{med(row[k]) / med(peer[k]):.1f}" if peer else "-" for k in ("total", "cpu")]
        print(
            f"| {CASES[case]} | {med(row['import']):.0f} | {_three(row['total'])} | "
            f"{1e3 * min(row['total']):.1f} | {1e3 * max(row['total']):.1f} | {med(row['cpu']):.1f} | "
            f"{sum(row['ok'])}/{len(row['ok'])} | {ratios[0]} | {ratios[1]} |"
        )
    if extra["compiled_ready"]:
        print(
            f"\noptik_ik: compiled code ready {med(extra['compiled_ready']):.0f} ms after the start "
            f"(median), then one solve_ik takes {med(extra['compiled_call']):.2f} ms"
        )
    print(
        f"checked: IK success by optik's FK (1e-6, limits; optik's first solve_ik with time_limit={LIMIT}); "
        "optik's step equal to the compiled one (1e-12)"
    )
    if skipped:
        print(f"not installed, skipped: {', '.join(skipped)}")
    if args.figure:
        print(save_figure(figure(rows), Path(args.figure)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
