"""`Viewer`: a mechanism in a local viser web page, with its IK target, branches and modes.

The page is served by a `viser.ViserServer` (its own threads: the caller is never blocked).
Every interaction of the page has a Python twin on `Viewer`, so that scripts, notebooks and
tests drive the same code paths as a mouse:

| page | Python |
|---|---|
| drag the target gizmo | `Viewer.set_target` (IK from the shown ``q`` as the seed) |
| IK method dropdown | `Viewer.method` |
| "all solutions" box | `Viewer.show_all_solutions` (every branch of ``solve_ik_all``) |
| joint sliders | `Viewer.set_q` (FK) |
| actuator sliders | `Viewer.set_actuated` (closed chains: every assembly mode) |
| "next assembly mode" | `Viewer.show_mode` |
| "track a circle", sample slider | `Viewer.track`, `Viewer.show_path_sample` |
| a planned path, "play" | `Viewer.show_path` (a `JointPath`), `Viewer.play` |
| "capability map" box | `Viewer.show_reach`, `Viewer.set_reach_visible` |
| "collision geometry" box | `Viewer.show_collisions` |
| drag a world object's gizmo | `Viewer.move_object` (the object moves, IK solves again) |

With ``world=`` or ``self_collision=True`` the gizmo's IK is collision-aware (``lm`` or ``nlp``,
`optik.solvers.collision_free`) and the page draws the collision layer
(`optik.view.collisions`): the robot's collision geometry (toggled), the world's objects each
under a gizmo of its own, and the links and objects closer than ``margin`` in red.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import threading
from typing import Any

import numpy as np
from matplotlib import colormaps

from optik import spatial
from optik.checks import as_float, as_vector
from optik.collision import World
from optik.diffik import circle_path, track
from optik.diffik.track import TrackResult
from optik.errors import InvalidArgumentError, SolverUnavailableError, require_extra
from optik.mechanism import Mechanism
from optik.path.result import JointPath
from optik.plot import showcase_q
from optik.reach import ReachMap
from optik.results import IKResult
from optik.solvers import methods, pick_method, solve_ik, solve_ik_all
from optik.solvers.base import Tolerances, joint_distance, positive_int
from optik.solvers.collision_free import METHODS as COLLISION_METHODS
from optik.solvers.fk import solve_fk, solve_fk_all
from optik.targets import target_transform
from optik.view.collisions import CollisionLayer
from optik.view.latest import Latest
from optik.view.scene import RobotDrawing, Style, extent, poses
from optik.view.shapes import rotation, wxyz
from optik.view.visuals import body_visuals

__all__ = ["Viewer", "reach_points"]

PLANAR_TASKS = ("pose2d", "position2d")
RADIUS = 0.03
"""Link radius as a fraction of the mechanism's size."""
REACH_POINT = 0.15
"""Diameter of a capability-map point as a fraction of the voxel edge: small enough that the
robot stays visible between the points of a dense map (the panel's box hides the map)."""
GHOST = Style(link=(120, 170, 230), ground=(120, 120, 120), slide=(230, 150, 120), opacity=0.3, frames=False)


def reach_points(source: Any) -> tuple[np.ndarray, np.ndarray, float]:
    """``(centers (V, 3), index (V,), resolution)`` of a capability map: a `optik.reach.ReachMap`
    or the ``reach.npz`` it is saved as (a file or its folder, read by `optik.ReachMap.load`).

    Raises:
        InvalidArgumentError: not a map, no such file, or a file without those arrays.
    """
    if all(hasattr(source, k) for k in ("centers", "index", "resolution")):
        return np.asarray(source.centers, float), np.asarray(source.index, float), float(source.resolution)
    if not isinstance(source, (str, os.PathLike)):
        raise InvalidArgumentError(
            "source", f"expected a ReachMap or a reach.npz path, got {type(source).__name__}"
        )
    try:
        rmap = ReachMap.load(source)
    except InvalidArgumentError as exc:
        raise InvalidArgumentError("source", str(exc).partition(": ")[2]) from None
    return rmap.centers, rmap.index, rmap.resolution


def _viser() -> Any:
    return require_extra("viser", "view", "the viewer")


def _positive(value: Any, name: str) -> float:
    v = float(as_vector(value, name, 1)[0])
    if not v > 0:
        raise InvalidArgumentError(name, f"must be > 0, got {value!r}")
    return v


def applicable_methods(m: Mechanism, task: str) -> list[str]:
    """IK methods of `optik.solve_ik` that apply to ``m`` with ``task``."""
    return [name for name, info in methods().items() if info.applies(m, task)]


class Viewer:
    """A mechanism in a local web page: links, joint frames, end effector and a draggable target.

    Args:
        m: the mechanism.
        q: first configuration (default: mid-limit; for a closed chain, the configuration of
            `optik.plot.showcase_q` that shows its shape, else the assembly mode of the mid-limit
            actuated values nearest to the mid-limit configuration).
        host: interface to bind (default ``127.0.0.1``: this machine only; ``0.0.0.0`` exposes
            the page to the network).
        port: TCP port (viser takes the next free one when it is busy; see `Viewer.url`).
        task: IK task space (default: the mechanism's).
        method: IK method of the target gizmo (default: `optik.solvers.pick_method`).
        time_limit: seconds per IK solve of a gizmo move.
        tol: success tolerances of the solves.
        all_time_limit: seconds for ``solve_ik_all`` / ``solve_fk_all``.
        max_ghosts: at most this many IK branches are drawn (a redundant arm has a continuum).
        world: obstacles (`optik.World`): drawn, each draggable, and avoided by the gizmo's IK.
        self_collision: the gizmo's IK keeps the robot clear of itself too.
        margin: clearance (m) of the collision-aware IK and of the red colouring.

    The collision layer (`optik.view.collisions`) is drawn whenever ``m`` has collision
    geometry; the IK is collision-aware with a ``world`` or ``self_collision=True``.

    Raises:
        InvalidArgumentError: bad ``q``, ``method``, ``time_limit``, ``world``, ``margin``; a
            ``world`` or ``self_collision`` for a mechanism without collision geometry.
        SolverUnavailableError: ``method`` does not apply to ``m``.
    """

    def __init__(
        self,
        m: Mechanism,
        q: Any = None,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        task: str | None = None,
        method: str | None = None,
        time_limit: float = 0.05,
        tol: float | Tolerances | None = None,
        all_time_limit: float = 1.0,
        max_ghosts: int = 16,
        world: World | None = None,
        self_collision: bool = False,
        margin: float = 0.0,
    ) -> None:
        viser = _viser()
        self.m = m
        self.task = m.task if task is None else task
        self.tol = tol
        self.time_limit = _positive(time_limit, "time_limit")
        self.all_time_limit = _positive(all_time_limit, "all_time_limit")
        self.max_ghosts = positive_int(max_ghosts, "max_ghosts")
        if world is not None and not isinstance(world, World):
            raise InvalidArgumentError(
                "world", f"expected an optik.World or None, got {type(world).__name__}"
            )
        self.world = world
        self.self_collision = bool(self_collision)
        self.margin = as_float(margin, "margin", 0.0)
        self.aware = world is not None or self.self_collision
        """Whether the gizmo's IK is collision-aware."""
        self.methods = applicable_methods(m, self.task)
        if self.aware:
            self.methods = [k for k in self.methods if k in COLLISION_METHODS]
        self._method = ""
        picked = pick_method(m, self.task)
        self.method = (picked if picked in self.methods else "lm") if method is None else method
        self._lock = threading.RLock()
        self.result: IKResult | None = None
        """The last IK answer (None before the first target)."""
        self.solutions: list[IKResult] = []
        """The branches shown by "all solutions" (empty when it is off)."""
        self.modes: list[np.ndarray] = []
        """The assembly modes of the last actuator values (closed chains)."""
        self.path: TrackResult | JointPath | None = None
        """The path shown for playback: the last tracked or planned one."""
        self.notes: list[str] = []
        """URDF visuals that are not drawn, with the reason (their bodies are capsule chains)."""
        self._all = False
        self._reach: Any = None
        self._reach_map: tuple[np.ndarray, np.ndarray, float] | None = None
        self._q = self._first_q(q)
        with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner; `url` tells the address
            self.server = viser.ViserServer(host=host, port=int(port), label=f"optik: {m.name}")
        self.server.gui.configure_theme(show_share_button=False)  # no public share tunnel from the page
        self.size = extent(m, self._q)
        self._draw_scene()
        self._ghosts: list[RobotDrawing] = []
        from optik.view.panel import Panel  # the panel calls back into this object

        self.panel = Panel(self)
        solve = Latest(self.panel.guard(self._solve_target))
        self.gizmo.on_update(lambda _event: solve(self._gizmo_pose()))
        self.set_q(self._q)
        if m.is_closed:
            self.modes = [self._q]

    # ------------------------------------------------------------------ setup
    def _first_q(self, q: Any) -> np.ndarray:
        if q is not None:
            return self.m.check_q(q)
        mid = self.m.mid_q()
        if not self.m.is_closed:
            return mid
        shown = showcase_q(self.m)  # a configuration that shows the chain's shape
        if shown is not None:
            return shown
        modes = solve_fk_all(self.m, mid[self.m.actuated_indices], time_limit=self.all_time_limit)
        if modes:  # the assembly mode nearest to the mid-limit configuration
            return np.asarray(min(modes, key=lambda r: joint_distance(self.m, r.q, mid)).q, dtype=float)
        return np.asarray(solve_fk(self.m, mid[self.m.actuated_indices]).q, dtype=float)

    def _draw_scene(self) -> None:
        scene, size = self.server.scene, self.size
        scene.set_up_direction("+z")
        # No image-based lighting: prefiltering the HDRI costs ~10 s per page load in a software
        # WebGL renderer (headless Chromium); a key light, a fill light and ambient light instead.
        scene.configure_environment_map(None)
        scene.configure_default_lights(False)
        scene.add_light_ambient("/lights/ambient", intensity=1.2)
        scene.add_light_hemisphere("/lights/sky", ground_color=(110, 110, 130), intensity=1.5)
        scene.add_light_directional("/lights/key", intensity=2.0, position=(0.0, 0.0, 0.0))
        center = poses(self.m, self._q).geometry().points().mean(axis=0)
        cell = 10 ** math.floor(math.log10(size / 2))
        scene.add_grid(
            "/ground",
            width=4 * size,
            height=4 * size,
            cell_size=cell,
            section_size=10 * cell,
            position=(center[0], center[1], 0.0),
        )
        visuals, self.notes = body_visuals(self.m)
        self.robot = RobotDrawing(scene, self.m, self._q, "/robot", Style(radius=RADIUS * size), visuals)
        self.collisions: CollisionLayer | None = None
        """The collision layer (None for a mechanism without collision geometry)."""
        if self.aware or self.m.params.get("collisions"):
            self._object_moves = Latest(lambda move: self.move_object(*move))
            self.collisions = CollisionLayer(
                scene,
                self.m,
                self._q,
                self.world,
                self.margin,
                lambda name, pose: self._object_moves((name, pose)),
                0.15 * size,
            )
        planar = self.task in PLANAR_TASKS
        self.gizmo = scene.add_transform_controls(
            "/target",
            scale=0.3 * size,
            active_axes=(True, True, not planar),
            disable_rotations=self.task in ("position", "position2d"),
            disable_axes=self.task == "orientation",
            depth_test=False,
        )
        camera = self.server.initial_camera
        view_dir = np.array([0.0, -0.55, 1.0]) if self.m.planar else np.array([1.3, -1.5, 0.9])
        camera.look_at = tuple(center)
        camera.position = tuple(center + 1.7 * size * view_dir / np.linalg.norm(view_dir))
        camera.up = (0.0, 0.0, 1.0)

    # ------------------------------------------------------------------ properties
    @property
    def url(self) -> str:
        """Address of the page."""
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    @property
    def port(self) -> int:
        """TCP port the page is served on."""
        return int(self.server.get_port())

    @property
    def q(self) -> np.ndarray:
        """The displayed configuration (a copy)."""
        return self._q.copy()

    @property
    def target(self) -> np.ndarray:
        """The target gizmo's pose (4x4; projected on the plane for planar tasks)."""
        return self._gizmo_pose()

    @property
    def method(self) -> str:
        """IK method of the gizmo; assigning checks that it applies."""
        return self._method

    @method.setter
    def method(self, name: str) -> None:
        if name not in methods():
            raise InvalidArgumentError("method", f"unknown IK method {name!r}; known: {sorted(methods())}")
        if name not in self.methods:
            raise SolverUnavailableError(f"method {name!r} does not apply to {self.m.name!r} ({self.task})")
        self._method = name

    # ------------------------------------------------------------------ target and IK
    def _gizmo_pose(self) -> np.ndarray:
        t = spatial.transform(rotation(self.gizmo.wxyz), np.asarray(self.gizmo.position, dtype=float))
        if self.task in PLANAR_TASKS:
            x, y, phi = spatial.planar_pose_of(t)
            return spatial.planar_pose(x, y, phi)
        return t

    def _move_gizmo(self, t: np.ndarray) -> None:
        self.gizmo.position, self.gizmo.wxyz = t[:3, 3], wxyz(t[:3, :3])

    def set_target(self, target: Any) -> IKResult:
        """Move the target gizmo to ``target`` and solve IK from the displayed configuration (what a
        drag of the gizmo does); the arm moves to the answer (the closest configuration found when
        it fails, with the reason in the status line).

        Args:
            target: 4x4 transform, `optik.Pose2D` or `optik.Position`.

        Returns:
            The `optik.IKResult`.
        """
        t = target_transform(target)
        with self._lock:
            self._move_gizmo(t)
            return self._solve_target(self._gizmo_pose())

    def _solve_target(self, t: np.ndarray) -> IKResult:
        with self._lock:
            aware = {"world": self.world, "self_collision": self.self_collision, "margin": self.margin}
            res = solve_ik(
                self.m,
                t,
                self._q,
                self._method,
                task=self.task,
                time_limit=self.time_limit,
                tol=self.tol,
                **(aware if self.aware else {}),
            )
            self.result = res
            q = np.asarray(res.q, dtype=float) if np.all(np.isfinite(res.q)) else self._q
            branches = self._branches(t, q) if self._all else None
            with self.server.atomic():  # the page applies the whole update at once
                self._show_q(q)
                self.panel.show_result(res)
                self._draw_branches(branches)
            return res

    def show_all_solutions(self, on: bool = True) -> list[IKResult]:
        """Draw every branch of `optik.solve_ik_all` for the current target as translucent ghosts
        (and keep doing it on every gizmo move while ``on``); returns the branches."""
        with self._lock:
            self._all = bool(on)
            self.panel.set_all(self._all)
            self._draw_branches(self._branches(self._gizmo_pose(), self._q) if self._all else None)
            return list(self.solutions)

    def _branches(self, t: np.ndarray, q0: np.ndarray) -> list[IKResult]:
        return solve_ik_all(
            self.m,
            t,
            q0,
            task=self.task,
            time_limit=self.all_time_limit,
            tol=self.tol,
            max_solutions=self.max_ghosts,
        )

    def _draw_branches(self, branches: list[IKResult] | None) -> None:
        """Ghosts of the successful ``branches`` (None: "all solutions" is off, no ghosts)."""
        self.solutions = [r for r in branches or () if r.success]
        self._show_ghosts([r.q for r in self.solutions])
        if branches is not None:
            failed = len(branches) - len(self.solutions)
            self.panel.show_branches(len(self.solutions), failed, len(branches) >= self.max_ghosts)

    # ------------------------------------------------------------------ FK
    def _show_q(self, q: np.ndarray) -> None:
        self._q = q
        self.robot.update(q)
        self.panel.sync(q)
        if self.collisions is not None:
            self.panel.show_collisions(self.collisions.update(q))

    def set_q(self, q: Any) -> np.ndarray:
        """Show configuration ``q`` (what the joint sliders do) and put the target on its end
        effector; returns the end-effector pose."""
        q = self.m.check_q(q)
        with self._lock, self.server.atomic():
            self._show_q(q)
            pose = self.m.fk(q)
            self._move_gizmo(pose)
            return pose

    def set_actuated(self, values: Any) -> list[np.ndarray]:
        """Closed chains: every assembly mode of the actuated coordinates ``values`` (what the
        actuator sliders do, through `optik.solve_fk_all`). The mode nearest to the displayed
        configuration is shown, the others are ghosts; an input that does not assemble leaves the
        configuration as it is and says so.

        Raises:
            InvalidArgumentError: open chain (use `set_q`), or wrong number of values.
        """
        if not self.m.is_closed:
            raise InvalidArgumentError("values", f"{self.m.name!r} is an open chain: use set_q")
        a = as_vector(values, "values", len(self.m.actuated_indices))
        with self._lock:
            found = solve_fk_all(self.m, a, time_limit=self.all_time_limit, tol=self.tol)
            self.modes = [np.asarray(r.q, dtype=float) for r in found]
            if self.modes:
                gaps = [joint_distance(self.m, q, self._q) for q in self.modes]
                self.show_mode(int(np.argmin(gaps)))
            else:
                self._show_ghosts([])
                self.panel.show_modes(0, None)
            return [q.copy() for q in self.modes]

    def show_mode(self, index: int, others: bool = True) -> np.ndarray:
        """Show assembly mode ``index`` of `modes` (and the others as ghosts when ``others``);
        returns it."""
        if not 0 <= int(index) < len(self.modes):
            raise InvalidArgumentError("index", f"expected 0 <= index < {len(self.modes)}, got {index!r}")
        with self._lock, self.server.atomic():
            k = int(index)
            self.set_q(self.modes[k])
            self._show_ghosts([q for i, q in enumerate(self.modes) if i != k] if others else [])
            self.panel.show_modes(len(self.modes), k)
            return self.modes[k].copy()

    def _show_ghosts(self, qs: list[np.ndarray]) -> None:
        for k, q in enumerate(qs):
            if k < len(self._ghosts):
                self._ghosts[k].update(q)
                self._ghosts[k].set_visible(True)
            else:
                style = Style(**{**GHOST.__dict__, "radius": RADIUS * self.size})
                self._ghosts.append(RobotDrawing(self.server.scene, self.m, q, f"/ghosts/{k}", style))
        for ghost in self._ghosts[len(qs) :]:
            if ghost.visible:
                ghost.set_visible(False)

    # ------------------------------------------------------------------ collisions
    def show_collisions(self, on: bool = True) -> None:
        """Show the robot's whole collision geometry (what the "collision geometry" box does);
        off, only the colliding links' parts are drawn (red).

        Raises:
            InvalidArgumentError: the mechanism has no collision geometry.
        """
        if self.collisions is None:
            raise InvalidArgumentError("on", f"{self.m.name!r} has no collision geometry to show")
        with self._lock:
            self.collisions.set_shown(on)
            self.panel.set_collisions_shown(bool(on))

    def move_object(self, name: str, pose: Any) -> IKResult:
        """Move world object ``name`` to ``pose`` (what a drag of its gizmo does) and solve IK for
        the current target again from the shown configuration, around the object where it is now.

        Raises:
            InvalidArgumentError: no world, no object of that name, or a bad pose.
        """
        if self.world is None or self.collisions is None:
            raise InvalidArgumentError("name", "the viewer has no world: pass world= to move its objects")
        if name not in self.world:
            raise InvalidArgumentError("name", f"no world object {name!r}; objects: {list(self.world.names)}")
        t = target_transform(pose, "pose")
        with self._lock:
            self.world.move(name, t)
            self.collisions.place(name, t)
            return self._solve_target(self._gizmo_pose())

    # ------------------------------------------------------------------ paths
    def track(self, path: Any = None, dt: float = 0.02, method: str = "qp") -> TrackResult:
        """Follow a path with `optik.diffik.track` from the displayed configuration and keep it for
        playback (`show_path_sample`, the time slider).

        Args:
            path: ``(N, 4, 4)`` poses (default: a circle of 100 poses, one per ``dt``, around the
                end effector, radius a sixth of the mechanism's size, in the horizontal plane, at
                the current tool orientation).
            dt: control period (s).
            method: differential-IK method of `optik.diffik.step`.
        """
        with self._lock:
            if path is None:
                pose = self.m.fk(self._q)
                r = self.size / 6
                center = pose[:3, 3] - np.array([r, 0.0, 0.0])
                speed = 2 * np.pi * r / (99 * dt)  # the circle in 99 steps of dt
                path = circle_path(center, r, speed, dt, rotation=pose[:3, :3])
            result = track(self.m, self._q, path, dt, method, space=self.task)
            targets = np.asarray(path, dtype=float)
            self._load_path(result, np.concatenate([targets[:1], targets]))  # q[0] is the start
            return result

    def show_path(self, path: JointPath) -> JointPath:
        """Keep a planned joint path (`optik.plan_path`, ``optik view PROBLEM --path``) for
        playback: its tool poses drawn as a line, the sample slider and the play button enabled
        (`show_path_sample`, `play`), its first sample shown.

        Raises:
            InvalidArgumentError: ``path`` is not a `JointPath` of this mechanism with samples.
        """
        if (
            not isinstance(path, JointPath)
            or path.q.ndim != 2
            or path.q.shape[1] != self.m.n_q
            or not len(path.q)
        ):
            raise InvalidArgumentError(
                "path", f"expected a JointPath of {self.m.n_q} coordinates with samples, got {path!r:.80}"
            )
        with self._lock:
            self._load_path(path, np.asarray(path.poses, dtype=float))
            self.show_path_sample(0)
            return path

    def _load_path(self, path: TrackResult | JointPath, targets: np.ndarray) -> None:
        """``path`` for playback, ``targets`` its tool pose per configuration (``(N, 4, 4)``)."""
        self.path = path
        self._path_targets = targets
        pts = targets[:, :3, 3]
        segments = np.stack([pts[:-1], pts[1:]], axis=1)
        self.server.scene.add_line_segments("/path", segments, (230, 60, 160), thickness=0.004 * self.size)
        self.panel.show_path(path)

    def show_path_sample(self, k: int) -> np.ndarray:
        """Show configuration ``k`` of the path (for a tracked one 0 is the start) with its
        target; returns it."""
        if self.path is None:
            raise InvalidArgumentError("k", "no path: call track or show_path first")
        n = len(self.path.q)
        if not 0 <= int(k) < n:
            raise InvalidArgumentError("k", f"expected 0 <= k < {n}, got {k!r}")
        with self._lock, self.server.atomic():
            q = self.path.q[int(k)]
            self._show_q(q)
            self._move_gizmo(self._path_targets[int(k)])
            return q.copy()

    def play(self, wait: bool = False) -> None:
        """Play the path back at its own times (the play button): each sample in turn, the
        slider following; ``wait``: return when it has ended.

        Raises:
            InvalidArgumentError: no path (call `track` or `show_path` first).
        """
        if self.path is None:
            raise InvalidArgumentError("path", "no path to play: call track or show_path first")
        self.panel.play_path(wait)

    # ------------------------------------------------------------------ capability map
    def show_reach(self, source: Any, visible: bool = True, z: float | None = None) -> int:
        """Draw a capability map: one horizontal layer of its voxels, as small points coloured
        by the reachability index (viridis: 0 blue, 1 yellow), so that the robot stays visible
        through the map. The panel's box hides the map and its slider moves the layer.

        Args:
            source: a `optik.reach.ReachMap`, or a ``reach.npz`` written by ``optik reach`` /
                ``optik.reach(out=DIR)`` (or its folder).
            visible: show the points (the panel's "capability map" box toggles them).
            z: height of the layer (m; the nearest layer of voxels is drawn). Default: the
                layer of the end effector in the shown configuration. A planar map has one layer.

        Returns:
            The number of points drawn (voxels whose index is not computed yet are left out,
            and the panel says how many).

        Raises:
            InvalidArgumentError: ``source`` is neither a map nor a readable ``reach.npz``.
        """
        centers, index, resolution = reach_points(source)
        done = np.isfinite(index)
        with self._lock:
            self._reach_map = (centers[done], index[done], resolution)
            self.panel.show_reach(
                int(done.sum()), int((~done).sum()), float(np.mean(index[done])) if done.any() else 0.0
            )
            if done.any():
                self.panel.show_reach_layers(
                    float(centers[done, 2].min()), float(centers[done, 2].max()), resolution
                )
            drawn = self.set_reach_layer(self.m.fk(self._q)[2, 3] if z is None else z)
            self.set_reach_visible(visible)
        return drawn

    def set_reach_layer(self, z: float) -> int:
        """Draw the layer of the capability map nearest height ``z`` (m); returns its number of
        points (0 without a map)."""
        height = float(as_vector(z, "z", 1)[0])
        if not math.isfinite(height):
            raise InvalidArgumentError("z", f"expected a finite height, got {z!r}")
        if self._reach_map is None:
            return 0
        centers, index, resolution = self._reach_map
        if not len(centers):
            layer = np.zeros(0, dtype=bool)
        else:
            levels = np.unique(np.round(centers[:, 2] / resolution, 6))
            nearest = levels[np.argmin(np.abs(levels - height / resolution))]
            layer = np.abs(centers[:, 2] / resolution - nearest) < 1e-3
        colors = (255 * colormaps["viridis"](index[layer])[:, :3]).astype(np.uint8)
        with self._lock:
            visible = self._reach.visible if self._reach is not None else True
            if self._reach is not None:
                self._reach.remove()
            self._reach = self.server.scene.add_point_cloud(
                "/reach",
                centers[layer],
                colors,
                point_size=REACH_POINT * resolution,
                point_shape="circle",
                point_shading="flat",
                visible=visible,
            )
            if len(centers):
                self.panel.show_reach_layer(float(nearest * resolution), int(layer.sum()))
        return int(layer.sum())

    def set_reach_visible(self, visible: bool) -> None:
        """Show or hide the capability map drawn by `show_reach`."""
        if self._reach is not None:
            self._reach.visible = bool(visible)

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Stop the server (the page disconnects). viser waits up to 6 s for sockets a browser
        opened but never used (Chromium pre-connects) to time out."""
        self.panel.stop()
        self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Viewer({self.m.name!r}, url={self.url!r})"
