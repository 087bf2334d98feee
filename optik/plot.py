"""Matplotlib figures of mechanisms: one configuration, all branches, the reachable workspace.

Geometry comes from the mechanism's own CasADi model. For every joint ``j`` between a parent and
a child body the two sides of the joint are

``A_j(q) = T_parent(q) origin_j``  and  ``B_j(q) = T_child(q) child_offset_j``

(see [`optik.mechanism.joint`][optik.mechanism.joint]). For a revolute, universal or spherical tree joint
their origins coincide; for a prismatic joint ``B_j = A_j Trans(q_j axis_j)``, so the segment ``A_j -> B_j``
is the slide; for a cut joint they coincide exactly when the loop is closed. One CasADi function ``q -> (p_A,
p_B, T_ee)`` is compiled once per mechanism. A body is drawn as the polyline through the joint locations it
carries (a filled polygon when they span an area, e.g. a platform); joints are markers (actuated filled,
passive hollow), the ground as hatching, the end-effector frame as a small x-y(-z) triad. Planar mechanisms
are drawn in 2-D, spatial ones in 3-D.

No ``pyplot`` state is used: figures are `matplotlib.figure.Figure` objects, saved with
[`save_figure`][optik.plot.save_figure] (temporary file + ``os.replace``, so a reader never sees half a PNG).
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backend_bases import FigureCanvasBase
from matplotlib.figure import Figure

from optik.checks import as_rng
from optik.errors import InvalidArgumentError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.problem_files import assemble
from optik.solvers.base import joint_distance

__all__ = [
    "Geometry",
    "body_points",
    "draw",
    "draw_branches",
    "geometry",
    "ordered_outline",
    "save_figure",
    "showcase_q",
    "workspace",
    "workspace_points",
    "write_atomic",
]

_MARKERS = {"revolute": "o", "prismatic": "s", "universal": "D", "spherical": "o", "free": "*"}
_TRIAD_COLORS = ("tab:red", "tab:green", "tab:blue")
_GEOMETRY: PerMechanism[ca.Function] = PerMechanism()


@dataclass(frozen=True)
class Geometry:
    """Drawable geometry of one configuration.

    Attributes:
        parent_side: ``(n_joints, 3)`` origins of ``A_j`` (joint frame on the parent body).
        child_side: ``(n_joints, 3)`` origins of ``B_j`` (joint frame on the child body).
        ee: 4x4 pose of the end-effector frame.
    """

    parent_side: np.ndarray
    child_side: np.ndarray
    ee: np.ndarray

    def points(self) -> np.ndarray:
        """All points (for axis limits)."""
        return np.vstack([self.parent_side, self.child_side, self.ee[None, :3, 3]])


def _geometry_function(m: Mechanism) -> ca.Function:
    """``q -> (p_A (3 x J), p_B (3 x J), T_ee)``, compiled once per mechanism."""
    f = _GEOMETRY.get(m)
    if f is None:
        poses = m.body_transforms
        a_cols = [ca.mtimes(poses[j.parent], ca.DM(j.origin))[:3, 3] for j in m.joints]
        b_cols = [ca.mtimes(poses[j.child], ca.DM(j.child_offset))[:3, 3] for j in m.joints]
        outputs = [ca.horzcat(*a_cols), ca.horzcat(*b_cols), m.frame_expr()]
        f = ca.Function("plot_geometry", [m.q_sym], outputs)
        _GEOMETRY[m] = f
    return f


def geometry(m: Mechanism, q: Any) -> Geometry:
    """Joint locations and end-effector pose of ``m`` at ``q``.

    Raises:
        ShapeError, NonFiniteError: ``q`` is not a finite vector of ``m.n_q`` values.
    """
    a, b, t = _geometry_function(m)(m.check_q(q))
    return Geometry(np.asarray(a).T, np.asarray(b).T, np.asarray(t))


def body_points(m: Mechanism, g: Geometry, body: str) -> list[np.ndarray]:
    """Joint locations carried by ``body``, and the end effector when it sits on a bar-like body
    (on a plate, e.g. a platform, the end-effector triad marks it instead)."""
    pts = []
    for k, j in enumerate(m.joints):
        if j.parent == body:
            pts.append(g.parent_side[k])
        if j.child == body:
            pts.append(g.child_side[k])
    distinct: list[np.ndarray] = []
    for p in pts:
        if all(np.linalg.norm(p - d) > 1e-9 for d in distinct):
            distinct.append(p)
    if m.frames[m.ee][0] == body and not ordered_outline(distinct)[1]:  # a tool point on a bar, not a plate
        distinct.append(g.ee[:3, 3])
    return distinct


def ordered_outline(pts: list[np.ndarray]) -> tuple[np.ndarray, bool]:
    """Points ordered along their principal direction (collinear) or by angle (a polygon).

    Returns the ordered ``(k, 3)`` points and whether they enclose an area.
    """
    p = np.array(pts)
    if len(p) < 3:
        return p, False
    c = p.mean(axis=0)
    _, s, vt = np.linalg.svd(p - c)
    if s[1] <= 1e-9 * max(s[0], 1e-12):
        return p[np.argsort((p - c) @ vt[0])], False
    u, v = (p - c) @ vt[0], (p - c) @ vt[1]
    return p[np.argsort(np.arctan2(v, u))], True


def _extent(points: np.ndarray) -> float:
    span = np.ptp(points, axis=0)
    return float(max(np.max(span), 1e-3))


def _plot_line(ax: Axes, pts: np.ndarray, planar: bool, **kw: Any) -> None:
    if planar:
        ax.plot(pts[:, 0], pts[:, 1], **kw)
    else:
        ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], **kw)


def _ground(ax: Axes, p: np.ndarray, size: float, planar: bool, color: str) -> None:
    """Hatching under a ground point: a short bar and four diagonal strokes below it."""
    down = np.array([0.0, -1.0, 0.0]) if planar else np.array([0.0, 0.0, -1.0])
    side = np.array([1.0, 0.0, 0.0])
    base = p + 0.6 * size * down
    _plot_line(ax, np.array([base - size * side, base + size * side]), planar, color=color, lw=1.2)
    for s in np.linspace(-0.8, 0.8, 4):
        start = base + s * size * side
        _plot_line(ax, np.array([start, start + 0.5 * size * (down - side)]), planar, color=color, lw=0.8)


def _render(ax: Axes, m: Mechanism, g: Geometry, style: dict[str, Any]) -> None:
    planar = m.planar
    color = style.get("color", "tab:blue")
    lw = style.get("linewidth", 2.5)
    alpha = style.get("alpha", 1.0)
    ms = style.get("marker_size", 7.0 if planar else 5.0)
    size = style.get("scale", 0.04 * _extent(g.points()))
    first = True
    for body in m.topology.bodies:
        pts = body_points(m, g, body)
        if body == m.base:
            if style.get("ground", True):
                for p in pts:
                    _ground(ax, p, size, planar, "0.3")
            if len(pts) >= 2:
                outline, area = ordered_outline(pts)
                ring = np.vstack([outline, outline[:1]]) if area else outline
                _plot_line(ax, ring, planar, color="0.5", lw=1.0, alpha=alpha)
            continue
        if len(pts) < 2:
            continue
        outline, area = ordered_outline(pts)
        kw: dict[str, Any] = {"color": color, "lw": lw, "alpha": alpha, "solid_capstyle": "round"}
        if first and style.get("label"):
            kw["label"] = style["label"]
            first = False
        if area:
            closed = np.vstack([outline, outline[:1]])
            _plot_line(ax, closed, planar, **kw)
            if planar:
                ax.fill(outline[:, 0], outline[:, 1], color=color, alpha=0.15 * alpha)
        else:
            _plot_line(ax, outline, planar, **kw)
    for k, j in enumerate(m.joints):
        if j.type == "fixed":
            continue
        a, b = g.parent_side[k], g.child_side[k]
        gap = float(np.linalg.norm(b - a))
        if j.type == "prismatic":
            _plot_line(ax, np.array([a, b]), planar, color=color, lw=1.6 * lw, alpha=0.6 * alpha)
            at = 0.5 * (a + b)
        else:
            at = a
            if gap > 1e-6:  # an open cut joint: the loop is not closed at this q
                _plot_line(ax, np.array([a, b]), planar, color="tab:red", lw=1.0, ls="--")
        face = color if j.actuated else "white"
        size_j = ms * (1.3 if j.type == "spherical" else 1.0)
        coords = at[:2] if planar else at
        ax.plot(
            *[[c] for c in coords],
            marker=_MARKERS[j.type],
            ms=size_j,
            mfc=face,
            mec=color,
            mew=1.5,
            alpha=alpha,
            ls="none",
            zorder=3,
        )
    if style.get("triad", True):
        t = g.ee
        n_axes = 2 if planar else 3
        for i in range(n_axes):
            tip = t[:3, 3] + 2.5 * size * t[:3, i]
            _plot_line(ax, np.array([t[:3, 3], tip]), planar, color=_TRIAD_COLORS[i], lw=1.5, alpha=alpha)


def _set_limits(ax: Axes, points: np.ndarray, planar: bool) -> None:
    lo, hi = points.min(axis=0), points.max(axis=0)
    c = 0.5 * (lo + hi)
    half = 0.5 * _extent(points) * 1.25
    ax.set_xlim(c[0] - half, c[0] + half)
    ax.set_ylim(c[1] - half, c[1] + half)
    if planar:
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    else:
        ax.set_zlim(c[2] - half, c[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")


def _new_axes(fig: Figure, m: Mechanism, *grid: int) -> Axes:
    return fig.add_subplot(*grid) if m.planar else fig.add_subplot(*grid, projection="3d")


def _limit_points(m: Mechanism, g: Geometry) -> np.ndarray:
    """Points that fix the axis limits: the geometry plus the ground hatching below it."""
    pts = g.points()
    down = np.array([0.0, -1.0, 0.0]) if m.planar else np.array([0.0, 0.0, -1.0])
    return np.vstack([pts, pts.min(axis=0) + 0.1 * _extent(pts) * down])


def draw(m: Mechanism, q: Any, ax: Axes | None = None, **style: Any) -> Axes:
    """Draw a mechanism in configuration ``q``.

    Args:
        m: the mechanism (planar ones are drawn in the x-y plane, spatial ones in 3-D).
        q: coordinates, ``m.n_q`` values (passive ones included).
        ax: axes to draw into (a 3-D axes for spatial mechanisms); None creates a new figure.
        **style: ``color``, ``linewidth``, ``alpha``, ``marker_size``, ``scale`` (size of the
            triad and hatching, default 4 % of the drawing), ``label``, ``triad`` (draw the
            end-effector frame, default True), ``ground`` (draw hatching, default True).

    Returns:
        The axes drawn into. When ``ax`` is None the axis limits are set around the mechanism
        with equal scales.

    Raises:
        ShapeError, NonFiniteError: bad ``q``.
        InvalidArgumentError: ``ax`` is 2-D for a spatial mechanism.
    """
    g = geometry(m, q)
    if ax is None:
        ax = _new_axes(Figure(figsize=(5, 5), layout="constrained"), m, 1, 1, 1)
        _set_limits(ax, _limit_points(m, g), m.planar)
    elif not m.planar and ax.name != "3d":
        raise InvalidArgumentError("ax", f"{m.name!r} is spatial: pass a 3-D axes (projection='3d')")
    _render(ax, m, g, style)
    return ax


MAX_PANELS = 8
"""Most subplots `draw_branches` draws (two rows of four): beyond that the ticks and links of the
panels are no longer readable."""


def draw_branches(
    m: Mechanism,
    qs: Sequence[Any],
    title: str | None = None,
    label: str = "branch",
    *,
    near: Any = None,
    max_panels: int = MAX_PANELS,
    **style: Any,
) -> Figure:
    """One subplot per branch (IK) or assembly mode (FK), on common axis limits; at most
    ``max_panels`` of them: with more configurations, those nearest ``near`` are drawn and the
    figure says how many are not.

    Args:
        m: the mechanism.
        qs: one coordinate vector per branch (an empty list gives a figure saying so).
        title: figure title (default: the mechanism's name and the number of branches).
        label: subplot titles are ``f"{label} {i}"`` (e.g. ``"assembly mode"``), ``i`` the index
            in ``qs`` from 1.
        near: with more than ``max_panels`` configurations, keep those nearest this one
            (joint-space max-norm, angles modulo 2 pi; default: the middle of the limits).
        max_panels: most subplots drawn.
        **style: passed to [`draw`][optik.plot.draw].

    Returns:
        A figure with ``min(len(qs), max_panels)`` axes (one axes with a note when ``qs`` is
        empty).
    """
    max_panels = int(max_panels)
    if max_panels < 1:
        raise InvalidArgumentError("max_panels", f"expected a positive integer, got {max_panels}")
    keep = list(range(len(qs)))
    if len(qs) > max_panels:
        ref = m.mid_q() if near is None else np.asarray(near, dtype=float)
        nearest = sorted(keep, key=lambda i: joint_distance(m, np.asarray(qs[i], float), ref))
        keep = sorted(nearest[:max_panels])
    geoms = [geometry(m, qs[i]) for i in keep]
    n = len(geoms)
    cols = min(max(n, 1), 4)
    rows = max(1, math.ceil(n / cols))
    fig = Figure(figsize=(3.6 * cols, 3.6 * rows + 0.6), layout="constrained")
    heading = title or f"{m.name}: {len(qs)} branch{'es' if len(qs) != 1 else ''}"
    if len(qs) > n:
        to = "the reference q" if near is not None else "mid-limit q"
        heading += f"\n{n} of {len(qs)} drawn, the nearest to {to}; {len(qs) - n} more not drawn"
    fig.suptitle(heading)
    if not geoms:
        ax = fig.add_subplot(1, 1, 1)
        ax.text(0.5, 0.5, "no configuration (unreachable or not assemblable)", ha="center", va="center")
        ax.set_axis_off()
        return fig
    pts = np.vstack([_limit_points(m, g) for g in geoms])
    for k, (i, g) in enumerate(zip(keep, geoms, strict=True)):
        ax = _new_axes(fig, m, rows, cols, k + 1)
        _render(ax, m, g, style)
        _set_limits(ax, pts, m.planar)
        ax.set_title(f"{label} {i + 1}", fontsize=10)
        if not m.planar:  # fewer, smaller ticks: 3-D panels side by side otherwise overlap
            ax.tick_params(labelsize=7, pad=0)
            ax.locator_params(nbins=4)
    return fig


def workspace_points(
    m: Mechanism, n: int = 2000, seed: int | np.random.Generator | None = 0
) -> tuple[np.ndarray, np.ndarray, int]:
    """Sampled reachable end-effector positions.

    Open chains: ``q ~ U(lower, upper)``, point ``p_ee(q)``. Closed chains: the actuated
    coordinates ``a ~ U(lower_a, upper_a)`` are assembled and the non-assemblable samples are
    dropped. Planar closed chains use the closed-form FK (every assembly mode within limits);
    spatial ones the numerical [`optik.solve_fk`][optik.solve_fk] (one mode per sample from the mid-limit
    start), since the closed-form FK of a 6-6 platform costs about a second per sample.

    Returns:
        ``(points (k, 3), mode (k,) assembly-mode index, samples drawn)``.
    """
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise InvalidArgumentError("n", f"expected a positive integer, got {n!r}")
    rng = as_rng(seed)
    if not m.is_closed:
        qs = m.random_q(int(n), rng)
        pts = m.fk(qs)[:, :3, 3] if n > 1 else m.fk(qs[0])[None, :3, 3]
        return pts, np.zeros(len(pts), dtype=int), int(n)
    idx = m.actuated_indices
    lo, hi = m.sampling_bounds
    samples = rng.uniform(lo[idx], hi[idx], size=(int(n), len(idx)))
    qs, modes = [], []
    for a in samples:
        for k, q in enumerate(assemble(m, a, numerical=not m.planar)):
            qs.append(q)
            modes.append(k)
    if not qs:
        return np.zeros((0, 3)), np.zeros(0, dtype=int), int(n)
    return np.asarray(m.fk(np.array(qs)))[..., :3, 3].reshape(-1, 3), np.array(modes), int(n)


def workspace(m: Mechanism, n: int = 2000, seed: int | np.random.Generator | None = 0) -> Figure:
    """Scatter plot of sampled reachable end-effector positions within the joint limits.

    See [`workspace_points`][optik.plot.workspace_points] for the sampling. Points are coloured by assembly
    mode, with a legend; the mechanism is drawn in the configuration of
    [`showcase_q`][optik.plot.showcase_q].

    Args:
        m: the mechanism.
        n: number of samples.
        seed: seed or Generator.

    Returns:
        A figure with one axes (2-D for planar mechanisms, 3-D otherwise).

    Raises:
        SolverUnavailableError: a closed chain has neither a closed-form FK nor ``optik.solve_fk``.
    """
    pts, modes, drawn = workspace_points(m, n, seed)
    fig = Figure(figsize=(5.5, 5.8), layout="constrained")
    ax = _new_axes(fig, m, 1, 1, 1)
    what = "actuator samples" if m.is_closed else "samples within the limits"
    ax.set_title(f"workspace of {m.name}\n{len(pts)} end-effector points, {drawn} {what}", fontsize=10)
    colours = colormaps["tab10"]
    for k in np.unique(modes):
        at = pts[modes == k]
        name = f"assembly mode {k + 1}" if m.is_closed else "reachable end-effector points"
        xyz = (at[:, 0], at[:, 1]) if m.planar else (at[:, 0], at[:, 1], at[:, 2])
        ax.scatter(*xyz, s=2 if m.planar else 6, color=colours(int(k) % 10), alpha=0.5, label=name)
    if len(pts):
        ax.legend(loc="upper right", fontsize=8, markerscale=4, framealpha=0.8)
    q_show = showcase_q(m)
    lim = pts
    if q_show is not None:
        g = geometry(m, q_show)
        _render(ax, m, g, {"color": "0.2", "alpha": 0.8})
        lim = np.vstack([pts, _limit_points(m, g)])
    if len(lim):
        _set_limits(ax, lim, m.planar)
    return fig


def showcase_q(m: Mechanism, candidates: int = 24, seed: int = 0) -> np.ndarray | None:
    """A configuration that shows the shape of ``m``: the middle of the limits for an open chain;
    for a closed chain, among the assembly modes of the mid-limit actuated values and of
    ``candidates`` seeded draws around them, the one whose joints lie farthest apart (the largest
    smallest distance between two joint locations), so that no link lies folded along another or
    on the base (a five-bar at ``theta = (0, 0)`` would put its first arm on the base). None
    when no draw assembles."""
    if not m.is_closed:
        return m.mid_q()
    idx = m.actuated_indices
    lo, hi = m.sampling_bounds
    mid = 0.5 * (lo[idx] + hi[idx])
    rng = np.random.default_rng(seed)
    spread = 0.6 * (hi[idx] - lo[idx])
    draws = [mid, *(mid + spread * rng.uniform(-0.5, 0.5, len(idx)) for _ in range(candidates))]
    best, best_gap = None, -1.0
    for a in draws:
        for q in assemble(m, a, numerical=not m.planar):
            at = geometry(m, q).parent_side
            gaps = np.linalg.norm(at[:, None] - at[None, :], axis=-1)[np.triu_indices(len(at), 1)]
            gap = float(gaps.min()) if gaps.size else 0.0
            if gap > best_gap:
                best, best_gap = q, gap
    return best


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomic(path: str | os.PathLike[str], write: Callable[[str], None]) -> Path:
    """Write a file atomically: ``write(tmp)`` into a temporary file next to ``path``, then
    ``os.replace(tmp, path)``; the temporary file is removed when ``write`` fails.

    Args:
        path: destination; its directory is created when missing.
        write: called with the temporary file's path; must create that file.

    Returns:
        The destination path.
    """
    dest = Path(path)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp", dir=dest.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600 files; use the usual mode
        os.replace(tmp, dest)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return dest


def check_writable(path: str | os.PathLike[str], name: str, directory: bool = False) -> Path:
    """Check, before a long computation, that its output can be written: a temporary file is
    created in, and removed from, the folder (``path`` itself when ``directory``, else its
    parent) or, while that folder does not exist, its nearest existing parent. Nothing is left
    behind: the folder is created by the first file written into it (`write_atomic`), so a
    command that fails or has nothing to write leaves no empty folder. A figure file needs an
    image extension matplotlib knows.

    Raises:
        InvalidArgumentError: naming ``name``, with the operating system's reason.
    """
    try:
        dest = Path(path)
    except TypeError:
        raise InvalidArgumentError(name, f"expected a file path, got {path!r}") from None
    folder = dest if directory else dest.parent
    if not directory:
        if dest.is_dir():
            raise InvalidArgumentError(name, f"{str(dest)!r} is a directory; name a file such as plot.png")
        fmt = dest.suffix.lstrip(".").lower()
        known = FigureCanvasBase.get_supported_filetypes()
        if fmt not in known:
            raise InvalidArgumentError(
                name, f"unsupported image format {fmt!r} of {str(dest)!r}; known: {sorted(known)}"
            )
    try:
        existing = folder.absolute()
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        if not existing.is_dir():
            raise NotADirectoryError(f"{str(existing)!r} is not a folder")
        fd, tmp = tempfile.mkstemp(prefix=".optik-write-check.", dir=existing)
        os.close(fd)
        os.unlink(tmp)
    except (OSError, ValueError) as exc:  # ValueError: a NUL character in the path
        reason = getattr(exc, "strerror", None) or str(exc)
        raise InvalidArgumentError(name, f"cannot write into {str(folder)!r}: {reason}") from None
    return dest


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int = 110) -> Path:
    """Save a figure atomically; the format follows the extension of ``path`` (e.g. ``.png``)."""
    fmt = Path(path).suffix.lstrip(".").lower()
    if not fmt:
        raise InvalidArgumentError("path", f"needs an extension such as .png, got {str(path)!r}")
    supported = fig.canvas.get_supported_filetypes()
    if fmt not in supported:
        raise InvalidArgumentError("path", f"unsupported image format {fmt!r}; known: {sorted(supported)}")
    return write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi))
