"""Figures of two-hand IK on URDF trees: docs/img/trees_dual_panda.png and trees_talos.png.

Run from the repository root: ``python docs/figures/trees.py``. Each figure draws a whole URDF
tree with ``optik.plot.draw`` at the start (grey: mid-limit; TALOS standing straight) and at
the answer of one ``optik.solve_ik(m, {left: T1, right: T2}, method="nlp", q_ref=start,
posture=1e-4)`` call (blue), with the targets as red crosses and a dashed segment from each
hand's last body to its target frame. The dual Panda is optik's shipped ``dual_panda.urdf``
(full poses as targets); TALOS is example-robot-data's ``talos_full_v2.urdf`` (``pip install
"optik[robots]"``; positions of the two gripper bases as targets; skipped without it).
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

import numpy as np
from _write import write_figures
from matplotlib.figure import Figure

import optik
from optik import spatial
from optik.mechanism import Mechanism
from optik.plot import draw


def _talos() -> Mechanism | None:
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return None
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    path = path / "talos_data" / "robots" / "talos_full_v2.urdf"
    return optik.Mechanism.from_urdf(path) if path.is_file() else None


def figure(m: Mechanism, targets: dict[str, object], title: str, q0: np.ndarray, azim: float) -> Figure:
    """The start and the two-hand IK answer of a tree, on equal axes, with a segment from each
    hand's last body to its target frame (``draw`` shows bodies, the frames sit beyond them)."""
    res = optik.solve_ik(m, targets, q0=q0, method="nlp", time_limit=5.0, q_ref=q0, posture=1e-4)
    if not res.success:
        raise RuntimeError(f"{m.name}: {res.message}")
    fig = Figure(figsize=(6.0, 6.0), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    draw(m, q0, ax=ax, color="0.75")
    draw(m, res.q, ax=ax)
    for q, color in ((q0, "0.75"), (res.q, "tab:blue")):
        for f in targets:
            a, b = m.fk(q, m.frames[f][0])[:3, 3], m.fk(q, f)[:3, 3]
            ax.plot(*np.array([a, b]).T, color=color, lw=2, ls="--")
    points = [m.fk(q, f)[:3, 3] for q in (q0, res.q) for f in m.frames]
    for target in targets.values():
        p = target.as_array() if isinstance(target, optik.Position) else np.asarray(target)[:3, 3]
        ax.scatter(*p, color="tab:red", marker="x", s=80, depthshade=False)
        points.append(p)
    pts = np.array(points)
    c, half = 0.5 * (pts.min(axis=0) + pts.max(axis=0)), 0.55 * float(np.ptp(pts, axis=0).max())
    ax.set(xlim=(c[0] - half, c[0] + half), ylim=(c[1] - half, c[1] + half), zlim=(c[2] - half, c[2] + half))
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=20, azim=azim)
    errs = ", ".join(f"{f}: {p:.1e} m, {o:.1e} rad" for f, (p, o) in res.frame_errors.items())
    ax.set_title(f"{title}\n{res.solve_time * 1e3:.0f} ms, {errs}", fontsize=8)
    return fig


def figures() -> dict[str, Figure]:
    """The dual Panda (and TALOS when example-robot-data is installed)."""
    dual = optik.catalog.dual_panda()
    down = spatial.transform(spatial.rot_x(np.pi))  # tool z axis pointing down
    out = {
        "dual_panda": figure(
            dual,
            {
                "left_tool": spatial.translation(0.55, 0.25, 0.45) @ down,
                "right_tool": spatial.translation(0.55, -0.25, 0.45) @ down,
            },
            "dual_panda: both tools on the table, 0.5 m apart",
            dual.mid_q(),
            35.0,
        )
    }
    talos = _talos()
    if talos is not None:
        out["talos"] = figure(
            talos,
            {
                "gripper_left_base_link": optik.Position([0.45, 0.2, 0.15]),
                "gripper_right_base_link": optik.Position([0.45, -0.2, 0.15]),
            },
            "TALOS (32 coordinates, 12 mimic joints): both grippers forward",
            np.clip(np.zeros(talos.n_q), talos.lower, talos.upper),  # standing straight
            -55.0,
        )
    return out


def main(argv: list[str] | None = None) -> list[Path]:
    return write_figures("trees", figures, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
