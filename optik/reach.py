"""Capability maps: how many orientations a robot reaches at each point of its workspace.

Following Zacharias' capability maps, the reachable workspace is cut into cubic voxels of edge
``resolution``: the voxels that contain the frame's position for at least one of ``samples``
random configurations (uniform within the limits). Every voxel centre is combined with the same
``orientations`` rotations, spread uniformly over SO(3) by a super-Fibonacci spiral (Alexa,
2022: rotation ``i`` is the unit quaternion
``(sqrt(s/n) sin(2 pi s / sqrt 2), sqrt(s/n) cos(2 pi s / sqrt 2), sqrt(1 - s/n) sin(2 pi s / psi),
sqrt(1 - s/n) cos(2 pi s / psi))`` with ``s = i + 1/2`` and ``psi^4 = psi + 4``), or over the
headings about z for a planar mechanism, and each pose is an IK target
(`optik.solve_ik_batch`, method ``"lm"``). The *reachability index* of a voxel is the fraction
of its orientations reached within the tolerances.

With ``out=DIR`` the map is resumable: the voxels are processed in chunks, each written
atomically to ``DIR/chunks/chunk_NNNNN.npz`` once solved; a rerun with the same settings skips
the chunks on disk (other settings are refused), and Ctrl-C loses only the chunk in progress.
When every chunk is done, ``DIR/reach.npz`` holds the map (NumPy's standard ``.npz``: voxel
indices and centres, the index per voxel and as a 3-D grid, the per-orientation success, the
rotations), ``DIR/meta.json`` its metadata (robot, settings, tolerances, seeds, optik version,
wall times of the runs) and ``DIR/reach_slices.png`` / ``DIR/reach_3d.png`` its figures.
Chunk ``k`` is solved with the batch seed ``target_seeds(seed, k, 1)[0]``, so a resumed map
equals one computed in one go.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import math
import pickle
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from optik.batch import fk_batch, solve_ik_batch
from optik.checks import as_bool
from optik.collision.world import World
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.problem_files import add_source_arguments, load_source
from optik.progress import Progress
from optik.solvers.base import positive_int
from optik.solvers.lm_kernel import target_seeds

if TYPE_CHECKING:  # matplotlib and optik.plot are imported on first use: slow to import
    from matplotlib.figure import Figure

__all__ = ["ReachMap", "reach", "so3_samples"]

_PSI = 1.533751168755204288118041  # the real root > 1 of psi^4 = psi + 4
CHUNK_TARGETS = 2048
"""Default IK targets per chunk (voxels per chunk = this / orientations)."""


def so3_samples(n: int) -> np.ndarray:
    """``n`` rotation matrices ``(n, 3, 3)`` spread uniformly over SO(3) (super-Fibonacci)."""
    s = np.arange(n) + 0.5
    t = s / n
    r, big = np.sqrt(t), np.sqrt(1.0 - t)
    a, b = 2 * np.pi * s / math.sqrt(2.0), 2 * np.pi * s / _PSI
    x, y, z, w = r * np.sin(a), r * np.cos(a), big * np.sin(b), big * np.cos(b)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def _headings(n: int) -> np.ndarray:
    """``n`` rotations about z at headings ``2 pi (i + 1/2) / n``."""
    phi = 2 * np.pi * (np.arange(n) + 0.5) / n
    rot = np.tile(np.eye(3), (n, 1, 1))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1] = (
        np.cos(phi),
        -np.sin(phi),
        np.sin(phi),
        np.cos(phi),
    )
    return rot


@dataclass
class ReachMap:
    """A capability map (see the module docstring).

    Attributes:
        voxels: integer voxel indices ``(V, 3)`` of the workspace voxels.
        centers: their centres ``(V, 3)`` (m).
        index: reachability index per voxel ``(V,)`` (NaN for voxels not solved yet).
        success: per voxel and orientation ``(V, O)``: that pose was reached.
        rotations: the orientations ``(O, 3, 3)``.
        origin: corner of voxel ``(0, 0, 0)``.
        resolution: voxel edge (m).
        shape: grid shape ``(nx, ny, nz)``.
        meta: the metadata (as in ``meta.json``).
        complete: every chunk solved.
        files: the files written (with ``out``).
    """

    voxels: np.ndarray
    centers: np.ndarray
    index: np.ndarray
    success: np.ndarray
    rotations: np.ndarray
    origin: np.ndarray
    resolution: float
    shape: tuple[int, int, int]
    meta: dict[str, Any]
    complete: bool
    files: list[Path] = field(default_factory=list)

    def grid(self) -> np.ndarray:
        """The index as a 3-D array ``shape`` (NaN outside the workspace voxels)."""
        g = np.full(self.shape, np.nan)
        g[tuple(self.voxels.T)] = self.index
        return g

    @classmethod
    def load(cls, path: str | Path) -> ReachMap:
        """The map a `reach` run saved: ``path`` is its ``reach.npz`` or the folder holding it
        (with the ``meta.json`` beside it, when there is one).

        Raises:
            InvalidArgumentError: naming ``path``: no such file, or not a capability map.
        """
        try:
            npz = Path(path)
        except TypeError:
            raise InvalidArgumentError("path", f"expected a folder or a reach.npz, got {path!r}") from None
        if npz.is_dir():
            npz = npz / "reach.npz"
        if not npz.is_file():
            raise InvalidArgumentError("path", f"no capability map at {npz} (no such file)")
        try:
            with np.load(npz) as data:
                arrays = {name: np.asarray(data[name]) for name in _MAP_ARRAYS}
            meta_path = npz.with_name("meta.json")
            meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
        except (OSError, ValueError, KeyError) as exc:
            raise InvalidArgumentError("path", f"{npz} is not a reach.npz capability map ({exc})") from None
        grid = arrays["grid"]
        return cls(
            voxels=arrays["voxels"].astype(np.int64).reshape(-1, 3),
            centers=arrays["centers"].astype(float).reshape(-1, 3),
            index=arrays["index"].astype(float).reshape(-1),
            success=arrays["success"].astype(bool),
            rotations=arrays["rotations"].astype(float),
            origin=arrays["origin"].astype(float),
            resolution=float(arrays["resolution"]),
            shape=(int(grid.shape[0]), int(grid.shape[1]), int(grid.shape[2])),
            meta=meta,
            complete=bool(np.isfinite(arrays["index"]).all()),
            files=[npz, *([meta_path] if meta_path.is_file() else [])],
        )


_MAP_ARRAYS = ("voxels", "centers", "index", "grid", "success", "rotations", "origin", "resolution")
"""The arrays of ``reach.npz`` (written by `_write_outputs`, read by `ReachMap.load`)."""


def _fingerprint(m: Mechanism) -> str:
    return hashlib.sha256(pickle.dumps(m)).hexdigest()[:16]


def _workspace(
    m: Mechanism, frame: str | None, resolution: float, samples: int, seed: int
) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int]]:
    """Voxels ``(V, 3)`` holding at least one sampled frame position, the grid origin and shape."""
    pts = fk_batch(m, m.random_q(samples, seed=seed), frame)[:, :3, 3]
    origin = np.floor(pts.min(axis=0) / resolution) * resolution
    if m.planar:  # one layer of voxels centred on the plane z = 0
        origin[2] = -0.5 * resolution
    idx = np.floor((pts - origin) / resolution).astype(np.int64)
    voxels = np.unique(idx, axis=0)
    shape = tuple(int(v) for v in voxels.max(axis=0) + 1)
    return voxels, origin, shape  # type: ignore[return-value]


def reach(
    m: Mechanism,
    resolution: float = 0.05,
    orientations: int = 32,
    *,
    frame: str | None = None,
    out: str | Path | None = None,
    tol: float = 1e-4,
    time_limit: float = 0.005,
    max_restarts: int = 8,
    seed: int = 0,
    samples: int = 200_000,
    chunk_voxels: int | None = None,
    max_chunks: int | None = None,
    scheduler: Any = None,
    workers: int | None = None,
    progress: bool = False,
    world: Any = None,
    self_collision: bool | None = None,
    margin: float = 0.0,
) -> ReachMap:
    """Compute (or resume) a capability map of a frame (default: the end effector).

    Args:
        m: the mechanism.
        resolution: voxel edge (m).
        orientations: rotations per voxel (headings about z for a planar mechanism; one for a
            position task).
        frame: the frame (default: the end effector).
        out: directory for the chunks, ``reach.npz``, ``meta.json`` and the figures (None: keep
            everything in memory, no resume).
        tol: position and orientation tolerance of a reached pose.
        time_limit: seconds per IK target.
        max_restarts: restarts per target before it counts as not reached.
        seed: seed of the workspace samples and of the IK restarts.
        samples: random configurations that delimit the workspace voxels.
        chunk_voxels: voxels per chunk (default: about 2048 targets per chunk).
        max_chunks: stop after solving this many chunks (the map is then incomplete; a rerun
            continues).
        scheduler: a ``dask.distributed.Client`` or address: chunks solved on that cluster.
        workers: local threads (default: the cores available).
        progress: progress bar on stderr.
        world: obstacles ([`optik.World`][optik.World]): with it or ``self_collision=True`` a
            pose counts as reached only by a collision-free answer (`optik.solve_ik_batch` with
            the same arguments: one collision-aware solve per target, local threads only).
        self_collision: keep the robot clear of itself (None: True when ``world`` is given).
        margin: the clearance (m).

    Returns:
        The `ReachMap` (``complete`` False when ``max_chunks`` stopped it early).

    Raises:
        InvalidArgumentError: bad settings (named), or ``out`` holds a map of other settings.
    """
    if not (isinstance(resolution, (int, float)) and math.isfinite(resolution) and resolution > 0):
        raise InvalidArgumentError("resolution", f"must be a positive number of meters, got {resolution!r}")
    orientations = positive_int(orientations, "orientations")
    samples = positive_int(samples, "samples")
    m._frame(frame)
    if max_chunks is not None:
        max_chunks = positive_int(max_chunks, "max_chunks")
    progress = as_bool(progress, "progress")
    position_only = m.task in ("position", "position2d")
    rotations = (
        np.eye(3)[None]
        if position_only
        else _headings(orientations)
        if m.planar
        else so3_samples(orientations)
    )
    n_rot = len(rotations)
    voxels, origin, shape = _workspace(m, frame, float(resolution), samples, seed)
    per_chunk = chunk_voxels or max(1, CHUNK_TARGETS // n_rot)
    per_chunk = positive_int(per_chunk, "chunk_voxels")
    n_chunks = -(-len(voxels) // per_chunk)
    from optik import __version__

    settings = {
        "robot": m.name,
        "fingerprint": _fingerprint(m),
        "frame": frame or m.ee,
        "task": m.task,
        "resolution": float(resolution),
        "orientations": n_rot,
        "tol": float(tol),
        "time_limit": float(time_limit),
        "max_restarts": int(max_restarts),
        "seed": int(seed),
        "samples": samples,
        "chunk_voxels": per_chunk,
        "n_voxels": len(voxels),
        "n_chunks": n_chunks,
        "origin": origin.tolist(),
        "shape": list(shape),
    }
    collisions: dict[str, Any] = {}
    if world is not None and not isinstance(world, World):
        raise InvalidArgumentError("world", f"expected an optik.World or None, got {type(world).__name__}")
    if world is not None or self_collision:
        collisions = {"world": world, "self_collision": self_collision, "margin": margin}
        settings["collisions"] = _world_fingerprint(world, self_collision, margin)
    folder = Path(out) if out is not None else None
    meta = _open_folder(folder, settings, __version__)
    centers = origin + (voxels + 0.5) * resolution
    success = np.zeros((len(voxels), n_rot), dtype=bool)
    solved = np.zeros(len(voxels), dtype=bool)
    done = set()
    for k in range(n_chunks):
        data = _load_chunk(folder, k)
        if data is not None:
            sl = slice(k * per_chunk, (k + 1) * per_chunk)
            success[sl], solved[sl] = data["success"], True
            done.add(k)
    bar = Progress(1) if progress else None
    if bar is not None:
        bar.start(f"reach {m.name}", len(voxels) * n_rot)
        bar.step(int(solved.sum()) * n_rot)
    t0, new = time.perf_counter(), 0
    try:
        for k in range(n_chunks):
            if k in done:
                continue
            if max_chunks is not None and new >= max_chunks:
                break
            sl = slice(k * per_chunk, (k + 1) * per_chunk)
            pos = centers[sl]
            targets = np.tile(np.eye(4), (len(pos) * n_rot, 1, 1))
            targets[:, :3, :3] = np.tile(rotations, (len(pos), 1, 1))
            targets[:, :3, 3] = np.repeat(pos, n_rot, axis=0)
            res = solve_ik_batch(
                m,
                targets,
                frame=frame,
                tol=tol,
                time_limit=time_limit,
                max_restarts=max_restarts,
                seed=int(target_seeds(seed, k, 1)[0]),
                scheduler=scheduler,
                workers=workers,
                **collisions,
            )
            success[sl], solved[sl] = res.success.reshape(len(pos), n_rot), True
            if folder is not None:
                _save_chunk(folder, k, res, len(pos), n_rot)
            new += 1
            if bar is not None:
                bar.step(len(targets))
    finally:
        wall = time.perf_counter() - t0
        if folder is not None:
            meta["runs"].append({"date": _now(), "wall_time_s": round(wall, 3), "chunks_solved": new})
            _write_json(folder / "meta.json", meta)
    if bar is not None:
        bar.finish()
    index = np.where(solved, success.mean(axis=1), np.nan)
    complete = bool(solved.all())
    rmap = ReachMap(
        voxels, centers, index, success, rotations, origin, float(resolution), shape, meta, complete
    )
    if folder is not None and complete:
        rmap.files = _write_outputs(folder, rmap)
    return rmap


def _world_fingerprint(world: Any, self_collision: bool | None, margin: float) -> str:
    """A digest of the collision settings of a map (a resumed map must have the same world)."""
    objects = [] if world is None else world.snapshot()
    text = repr((self_collision, float(margin))) + "".join(
        f"{o.name}:{o.shape.kind}:{o.shape.size}:{o.shape.path}:{np.asarray(o.pose).round(12).tolist()}:"
        f"{None if o.shape.points is None else o.shape.points.tolist()}"
        for o in objects
    )
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _now() -> str:
    return datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")


def _write_json(path: Path, data: dict[str, Any]) -> Path:
    from optik.plot import write_atomic

    return write_atomic(path, lambda tmp: Path(tmp).write_text(json.dumps(data, indent=2) + "\n"))


def _open_folder(folder: Path | None, settings: dict[str, Any], version: str) -> dict[str, Any]:
    """The metadata of ``folder``: new, or the existing one when its settings match."""
    meta = {"settings": settings, "optik_version": version, "created": _now(), "runs": []}
    if folder is None:
        return meta
    path = folder / "meta.json"
    if path.exists():
        old = json.loads(path.read_text())
        if old.get("settings") != settings:
            diff = sorted(k for k in settings if old.get("settings", {}).get(k) != settings[k])
            raise InvalidArgumentError(
                "out",
                f"{str(folder)!r} holds a map with other settings ({', '.join(diff)}); use another folder",
            )
        return old
    (folder / "chunks").mkdir(parents=True, exist_ok=True)
    _write_json(path, meta)
    return meta


def _chunk_path(folder: Path, k: int) -> Path:
    return folder / "chunks" / f"chunk_{k:05d}.npz"


def _load_chunk(folder: Path | None, k: int) -> dict[str, np.ndarray] | None:
    if folder is None or not _chunk_path(folder, k).exists():
        return None
    with np.load(_chunk_path(folder, k)) as data:
        return {name: data[name] for name in data.files}


def _save_npz(path: Path, **arrays: np.ndarray) -> Path:
    from optik.plot import write_atomic

    def write(tmp: str) -> None:
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        Path(tmp).write_bytes(buf.getvalue())

    return write_atomic(path, write)


def _save_chunk(folder: Path, k: int, res: Any, n_vox: int, n_rot: int) -> None:
    _save_npz(
        _chunk_path(folder, k),
        success=res.success.reshape(n_vox, n_rot),
        iterations=res.iterations.reshape(n_vox, n_rot).astype(np.int32),
        position_error=res.position_error.reshape(n_vox, n_rot).astype(np.float32),
        orientation_error=res.orientation_error.reshape(n_vox, n_rot).astype(np.float32),
    )


def _write_outputs(folder: Path, rmap: ReachMap) -> list[Path]:
    from optik.plot import save_figure

    files = [
        _save_npz(
            folder / "reach.npz",
            voxels=rmap.voxels,
            centers=rmap.centers,
            index=rmap.index,
            grid=rmap.grid(),
            success=rmap.success,
            rotations=rmap.rotations,
            origin=rmap.origin,
            resolution=np.array(rmap.resolution),
        ),
        folder / "meta.json",
        save_figure(plot_slices(rmap), folder / "reach_slices.png"),
        save_figure(plot_scatter(rmap), folder / "reach_3d.png"),
    ]
    return files


def plot_slices(rmap: ReachMap, n: int = 4) -> Figure:
    """The index on ``n`` horizontal slices (z levels through the workspace) and on the
    vertical x-z slice through the base (y = 0)."""
    from matplotlib.figure import Figure

    g = rmap.grid()
    fig = Figure(figsize=(3.2 * (n + 1), 3.4), layout="constrained")
    lo = rmap.origin
    hi = lo + np.array(rmap.shape) * rmap.resolution
    levels = (
        np.unique(np.linspace(0, rmap.shape[2] - 1, n + 2).round().astype(int)[1:-1])
        if rmap.shape[2] > 1
        else [0]
    )
    axes = fig.subplots(1, len(levels) + 1)
    image = None
    for ax, kz in zip(axes, levels, strict=False):
        image = ax.imshow(
            g[:, :, kz].T, origin="lower", extent=(lo[0], hi[0], lo[1], hi[1]), vmin=0, vmax=1, cmap="viridis"
        )
        ax.set_title(f"z = {lo[2] + (kz + 0.5) * rmap.resolution:.2f} m")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    ky = int(np.clip(np.floor(-lo[1] / rmap.resolution), 0, rmap.shape[1] - 1))
    ax = axes[-1]
    image = ax.imshow(
        g[:, ky, :].T, origin="lower", extent=(lo[0], hi[0], lo[2], hi[2]), vmin=0, vmax=1, cmap="viridis"
    )
    ax.set_title(f"y = {lo[1] + (ky + 0.5) * rmap.resolution:.2f} m")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    fig.colorbar(image, ax=list(axes), label="reachability index", shrink=0.9)
    fig.suptitle(
        f"{rmap.meta['settings']['robot']}: capability map, {rmap.resolution:g} m voxels, "
        f"{len(rmap.rotations)} orientations"
    )
    return fig


def plot_scatter(rmap: ReachMap) -> Figure:
    """3-D scatter of the voxels with a nonzero index, coloured by it, cut open at y = 0 (the
    half y <= 0 is drawn, so that the inside shows)."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    fig = Figure(figsize=(6.5, 5.5), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    keep = (rmap.index > 0) & (rmap.centers[:, 1] <= 0.5 * rmap.resolution)
    c = rmap.centers[keep]
    dots = ax.scatter(
        c[:, 0],
        c[:, 1],
        c[:, 2],
        c=rmap.index[keep],
        cmap="viridis",
        vmin=0,
        vmax=1,
        s=10,
        alpha=0.8,
        depthshade=False,
    )
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    if len(c):
        ax.set_box_aspect(np.ptp(c, axis=0) + rmap.resolution)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(4))
    ax.view_init(elev=20, azim=60)  # from +y: facing the cut
    fig.colorbar(dots, ax=ax, label="reachability index", shrink=0.7)
    ax.set_title(f"{rmap.meta['settings']['robot']}: reachability index, cut open at y = 0")
    return fig


# ---------------------------------------------------------------------- command line
def add_parser(sub: Any) -> None:
    """Register ``reach`` on the ``optik`` subcommand parsers."""
    p = sub.add_parser(
        "reach",
        help="capability map: the fraction of orientations reached in every workspace voxel",
        description=(
            "Compute a capability (reachability) map: workspace voxels times orientations uniform on "
            "SO(3), IK per pose, the reachability index per voxel. Writes DIR/reach.npz, meta.json and "
            "PNG figures; resumable (rerun the same command), Ctrl-C keeps every finished chunk."
        ),
    )
    add_source_arguments(p)
    p.add_argument(
        "--resolution", type=float, default=0.05, metavar="M", help="voxel edge in m (default: %(default)s)"
    )
    p.add_argument(
        "--orientations",
        type=int,
        default=32,
        metavar="N",
        help="orientations per voxel (default: %(default)s)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask scheduler address, e.g. tcp://host:8786 (default: local threads)",
    )
    p.add_argument("--out", metavar="DIR", default="reach-out", help="output folder (default: %(default)s)")
    p.add_argument(
        "--tol", type=float, default=1e-4, help="position / orientation tolerance (default: %(default)s)"
    )
    p.add_argument(
        "--time-limit",
        type=float,
        default=0.005,
        metavar="S",
        help="seconds per IK target (default: %(default)s)",
    )
    p.add_argument("--max-restarts", type=int, default=8, help="restarts per target (default: %(default)s)")
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the workspace samples and IK starts (default: %(default)s)",
    )
    p.add_argument(
        "--samples",
        type=int,
        default=200_000,
        help="random configurations whose frame positions delimit the workspace (default: %(default)s)",
    )
    p.add_argument("--workers", type=int, help="local threads (default: the cores available)")
    p.add_argument(
        "--max-chunks", type=int, help="stop after this many chunks, rerun to continue (default: all)"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Body of ``optik reach``: 0 when the map is complete, 1 when stopped early (``--max-chunks``),
    130 on Ctrl-C (the finished chunks are kept)."""
    m = load_source(args.source, args.base, args.tip, args.problems_dir)[0]
    client = None
    if args.scheduler:
        from optik.batch.distributed import client_of

        client = client_of(args.scheduler)
    try:
        rmap = reach(
            m,
            args.resolution,
            args.orientations,
            out=args.out,
            tol=args.tol,
            time_limit=args.time_limit,
            max_restarts=args.max_restarts,
            seed=args.seed,
            samples=args.samples,
            max_chunks=args.max_chunks,
            scheduler=client,
            workers=args.workers,
            progress=not args.no_progress,
        )
    except KeyboardInterrupt:
        print(f"\ninterrupted: the finished chunks are in {args.out}; run the same command again to resume")
        return 130
    finally:
        if client is not None:
            client.close()
    s = rmap.meta["settings"]
    wall = sum(r["wall_time_s"] for r in rmap.meta["runs"])
    if not rmap.complete:
        left = int(np.isnan(rmap.index).sum())
        print(f"stopped early: {left} of {s['n_voxels']} voxels left; run the same command again to resume")
        return 1
    print(
        f"{s['robot']}: {s['n_voxels']} voxels x {s['orientations']} orientations, mean index "
        f"{np.nanmean(rmap.index):.3f}, {sum(r['chunks_solved'] for r in rmap.meta['runs'])} chunks in "
        f"{wall:.1f} s; wrote {', '.join(str(f) for f in rmap.files)}"
    )
    return 0
