"""The control panel of the page: IK method and status, joint or actuator sliders, assembly
modes, path tracking and playback. Every widget calls the `optik.view.Viewer` method of the same
name; answers come back through the ``show_*`` methods. Library errors raised by a widget's
action are shown in the status line instead of stopping the server."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from optik.diffik.track import TrackResult
from optik.errors import OptikError
from optik.path.result import JointPath
from optik.results import IKResult
from optik.view.latest import Latest

__all__ = ["Panel"]

FRAME = 0.02
"""Shortest time (s) a sample stays on the page during playback (a dense path's samples are
milliseconds apart: the page cannot draw faster)."""


def _range(lo: float, hi: float, revolute: bool, size: float) -> tuple[float, float]:
    """Slider range of one coordinate: its limits, or +-2 pi / +-size when a limit is infinite."""
    span = 2 * np.pi if revolute else size
    return (lo if np.isfinite(lo) else -span), (hi if np.isfinite(hi) else span)


class Panel:
    """The GUI of an `optik.view.Viewer` (built by it; ``viewer`` is that object)."""

    def __init__(self, viewer: Any) -> None:
        self.v = viewer
        m = viewer.m
        gui = viewer.server.gui
        self._stop = threading.Event()  # of the latest playback (each has its own)
        self._player: threading.Thread | None = None
        self._playing = threading.Lock()  # one playback starts at a time
        with gui.add_folder("Target: IK"):
            self.method = gui.add_dropdown("method", viewer.methods, initial_value=viewer.method)
            self.method.on_update(self._user(lambda: setattr(viewer, "method", self.method.value)))
            hint = "every branch of solve_ik_all, as ghosts"
            self.all = gui.add_checkbox("all solutions", False, hint=hint)
            self.all.on_update(self._user(lambda: viewer.show_all_solutions(self.all.value)))
            self.status = gui.add_markdown("Drag the target gizmo: IK follows.")
            self.branches = gui.add_markdown("")
        self.notes = None
        if viewer.notes:
            shown = "; ".join(viewer.notes[:3]) + ("; ..." if len(viewer.notes) > 3 else "")
            self.notes = gui.add_markdown(
                f"**{len(viewer.notes)} URDF visuals not drawn** (capsules instead): {shown}"
            )
        self.collisions = self.collision_text = None
        if viewer.collisions is not None:
            with gui.add_folder("Collisions: exact check"):
                hint = "every collision part of the robot (the colliding links are red either way)"
                self.collisions = gui.add_checkbox("collision geometry", False, hint=hint)
                self.collisions.on_update(self._user(lambda: viewer.show_collisions(self.collisions.value)))
                self.collision_text = gui.add_markdown("")
        self.index = m.actuated_indices if m.is_closed else np.arange(m.n_q)
        title = "Actuators: every assembly mode" if m.is_closed else "Joints: FK"
        with gui.add_folder(title):
            self.sliders = []
            for i in self.index:
                lo, hi = _range(m.lower[i], m.upper[i], bool(m.revolute_mask[i]), viewer.size)
                s = gui.add_slider(m.coordinate_names[i], lo, hi, (hi - lo) / 1000, float(np.clip(0, lo, hi)))
                self.sliders.append(s)
            move = Latest(self._guarded(self._slid))
            for s in self.sliders:
                s.on_update(lambda event: None if event.client is None else move(None))
            if m.is_closed:
                self.next_mode = gui.add_button("next assembly mode")
                self.next_mode.on_click(self._user(self._next_mode))
                self.modes = gui.add_markdown("")
        with gui.add_folder("Path: diffik.track, plan_path"):
            self.track_button = gui.add_button("track a circle")
            self.track_button.on_click(self._user(viewer.track))
            self.sample = gui.add_slider("sample", 0, 1, 1, 0, disabled=True)
            self.sample.on_update(self._user(lambda: viewer.show_path_sample(int(self.sample.value))))
            self.play = gui.add_button("play", disabled=True)
            self.play.on_click(self._user(self._play))
            self.path_text = gui.add_markdown("")
        with gui.add_folder("Capability map: optik.reach", expand_by_default=False):
            self.reach = gui.add_checkbox("capability map", True, disabled=True)
            self.reach.on_update(self._user(lambda: viewer.set_reach_visible(self.reach.value)))
            self.reach_layer = gui.add_slider("height (m)", 0.0, 1.0, 0.1, 0.0, disabled=True)
            self.reach_layer.on_update(self._user(lambda: viewer.set_reach_layer(self.reach_layer.value)))
            self.reach_text = gui.add_markdown("Load one with `--reach DIR` or `Viewer.show_reach`.")
            self.layer_text = gui.add_markdown("")

    # ------------------------------------------------------------------ callbacks
    def _guarded(self, action: Callable[..., Any]) -> Callable[..., None]:
        def run(*args: Any) -> None:
            try:
                action(*args)
            except OptikError as exc:
                self.status.content = f"**error**: {exc}"

        return run

    def guard(self, action: Callable[..., Any]) -> Callable[..., None]:
        """``action`` with library errors shown in the status line (for the viewer's callbacks)."""
        return self._guarded(action)

    def _user(self, action: Callable[[], Any]) -> Callable[[Any], None]:
        """A widget callback running ``action`` for the browser's events only (assignments made
        from Python, e.g. `sync`, run viser's callbacks too, with no client)."""
        run = self._guarded(action)
        return lambda event: None if event.client is None else run()

    def _slid(self, _: Any) -> None:
        values = np.array([s.value for s in self.sliders], dtype=float)
        if self.v.m.is_closed:
            self.v.set_actuated(values)
        else:
            self.v.set_q(values)

    def _next_mode(self) -> None:
        if self.v.modes:
            shown = next((i for i, q in enumerate(self.v.modes) if np.array_equal(q, self.v.q)), -1)
            self.v.show_mode((shown + 1) % len(self.v.modes))

    def _play(self) -> None:
        self.play_path(False)

    def play_path(self, wait: bool) -> None:
        """Play the viewer's path at its own times (each sample shown until the next one's time,
        at least `FRAME` s), unless a playback runs; ``wait``: until it ends. A playback that
        `stop` ended does not keep the next one from playing."""
        with self._playing:
            if self._player is None or not self._player.is_alive():
                path = self.v.path
                if path is None:
                    return
                t = np.asarray(path.t, dtype=float)
                steps = np.maximum(np.diff(t), FRAME) if len(t) > 1 else np.zeros(0)
                stop = self._stop = threading.Event()

                def run() -> None:
                    for k in range(len(path.q)):
                        if stop.is_set():
                            return
                        self.v.show_path_sample(k)
                        self.sample.value = k
                        if k < len(steps):
                            stop.wait(steps[k])

                self._player = threading.Thread(target=run, name="optik-view-play", daemon=True)
                self._player.start()
            player = self._player
        if wait:
            player.join()

    def stop(self) -> None:
        """End a running playback (at once: its wait for the next sample's time ends too)."""
        with self._playing:
            self._stop.set()
            player = self._player
        if player is not None:
            player.join(timeout=5)

    # ------------------------------------------------------------------ answers
    def sync(self, q: np.ndarray) -> None:
        """Put the sliders on configuration ``q``."""
        for s, i in zip(self.sliders, self.index, strict=True):
            s.value = float(np.clip(q[i], s.min, s.max))

    def set_all(self, on: bool) -> None:
        """Tick or clear "all solutions"."""
        self.all.value = on
        if not on:
            self.branches.content = ""

    def set_collisions_shown(self, on: bool) -> None:
        """Tick or untick the "collision geometry" box (a call from Python)."""
        if self.collisions is not None:
            self.collisions.value = on

    def show_collisions(self, report: Any) -> None:
        """The exact check of the shown configuration: clear, or the pairs closer than the margin."""
        if self.collision_text is None:
            return
        if not report.in_collision:
            self.collision_text.content = (
                f"clear by {report.margin:g} m (closest {report.min_distance:.4g} m)"
            )
            return
        pairs = ", ".join(f"{p.a} / {p.b} {p.distance:.3g} m" for p in report.close_pairs[:3])
        more = f" and {len(report.close_pairs) - 3} more" if len(report.close_pairs) > 3 else ""
        self.collision_text.content = f"**closer than {report.margin:g} m** (red): {pairs}{more}"

    def show_result(self, res: IKResult) -> None:
        """The status line of an IK answer: method, success, errors, solve time."""
        verdict = "solved" if res.success else "**not solved**"
        lines = [
            f"**{res.method}**: {verdict} in {1e3 * res.solve_time:.2f} ms",
            f"position error {res.position_error:.1e} m, orientation error {res.orientation_error:.1e} rad",
        ]
        if self.v.m.is_closed:
            lines.append(f"closure error {res.closure_error:.1e}")
        if not res.success and res.message:
            lines.append(res.message)
        self.status.content = "  \n".join(lines)

    def show_branches(self, found: int, failed: int, capped: bool) -> None:
        """How many branches "all solutions" draws (``capped``: the search stopped at the limit)."""
        text = f"all solutions: **{found}** branch{'es' if found != 1 else ''} (ghosts)"
        text += f"; {failed} unconverged not drawn" if failed else ""
        self.branches.content = text + ("; capped (redundant arm: a continuum)" if capped else "")

    def show_modes(self, count: int, shown: int | None) -> None:
        """How many assembly modes the actuator values have, and which is shown."""
        if shown is None:
            self.modes.content = "**does not assemble** for these actuator values"
        else:
            self.modes.content = f"**{count}** assembly mode{'s' if count != 1 else ''}; showing {shown + 1}"

    def show_reach(self, drawn: int, pending: int, mean: float) -> None:
        """Enable the capability-map box and summarize the map."""
        self.reach.disabled = False
        self.reach.value = True
        text = f"{drawn} voxels, mean reachability index {mean:.2f} (viridis: 0 blue, 1 yellow)"
        self.reach_text.content = text + (
            f"; {pending} voxels not computed yet, not drawn" if pending else ""
        )

    def show_reach_layers(self, low: float, high: float, step: float) -> None:
        """Range the layer slider over the map's voxel heights."""
        self.reach_layer.min, self.reach_layer.max = low, max(high, low + step)
        self.reach_layer.step = step
        self.reach_layer.disabled = high <= low

    def show_reach_layer(self, z: float, count: int) -> None:
        """Say which layer of the map is drawn."""
        self.reach_layer.value = z
        self.layer_text.content = f"layer z = {z:.3f} m: {count} voxels drawn"

    def show_path(self, result: TrackResult | JointPath) -> None:
        """Enable playback of a tracked or planned path and summarize it."""
        n = len(result.q) - 1
        self.sample.max = max(n, 1)
        self.sample.value = 0
        self.sample.disabled = n < 1
        self.play.disabled = False
        if isinstance(result, JointPath):
            failed = [k for k, ok in result.checks.items() if not ok]
            checks = "all passed" if not failed else "failed " + ", ".join(failed)
            self.path_text.content = (
                f"planned: {n + 1} samples over {result.t[-1]:.2f} s, joint-space length {result.cost:.4g}, "
                f"{result.flips} branch changes; checks: {checks}"
            )
            return
        self.path_text.content = (
            f"{n} steps of {1e3 * (result.t[1] - result.t[0]):.0f} ms: max position error "
            f"{np.max(result.position_error):.1e} m, within limits: {'yes' if result.within_limits else 'no'}"
        )
