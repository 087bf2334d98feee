"""The viewer in a real browser: headless Chromium (software WebGL) loads the page served by
``optik view`` and by ``optik.view(...)``; screenshots must show a drawn scene, a target moved
from Python must move the arm in the page, and Ctrl-C must stop the command cleanly.

The documentation screenshots are taken here too, on request (each page costs seconds of
software rendering): ``OPTIK_VIEW_SHOTS=docs/img python3 -m pytest tests/test_view_browser.py -k
screenshots`` writes them into docs/img.

Each test starts its own browser and closes it before the viewer's server: the server's stop
waits for the sockets a browser keeps open.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser", reason="the view extra (viser) is not installed")
pytest.importorskip("websockets", reason="the view extra (websockets) is not installed")

from test_view import free_port

import optik
from optik import catalog, closed_form, spatial
from optik.plot import write_atomic
from optik.view.browser import Chromium, coloured_pixels, find_chromium

CHROMIUM = find_chromium()
pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="no Chromium on the PATH: .ci/run installs Debian's chromium package"
)

WIDTH, HEIGHT = 1280, 800
CANVAS = (80, 0, WIDTH - 360, HEIGHT - 80)
"""The 3-D view without the control panel (right) and the orientation widget (bottom left)."""
PANEL = (WIDTH - 330, 60, WIDTH - 20, 400)
"""The control panel (its sliders and buttons are blue)."""
DRAWN = 2000
"""Coloured pixels in `CANVAS` that make a drawn scene (the white page, the grey grid and the
panel's text have none; the Panda alone has about 10,000)."""


def drawn(png: bytes) -> bool:
    return coloured_pixels(png, CANVAS) > DRAWN


def complete(png: bytes) -> bool:
    """A drawn scene and a populated control panel."""
    return drawn(png) and coloured_pixels(png, PANEL) > 300


def settled() -> Callable[[bytes], bool]:
    """A `complete` page that looks the same in two captures in a row (meshes still arriving
    change it)."""
    last: list[bytes] = []

    def ready(png: bytes) -> bool:
        same = bool(last) and last[-1] == png
        last[:] = [png]
        return same and complete(png)

    return ready


@pytest.fixture
def browser():
    chromium = Chromium(CHROMIUM, WIDTH, HEIGHT)
    yield chromium
    chromium.close()


def test_a_blank_page_is_not_a_drawn_scene(browser):
    png = browser.screenshot("data:text/html,<html><body><h1>optik</h1></body></html>")
    assert coloured_pixels(png) == 0 and not drawn(png)


@pytest.fixture
def served():
    """``optik view panda --no-browser`` in a subprocess on a free port; killed if still running."""
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "optik.cli", "view", "panda", "--no-browser", "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
    )
    lines: queue.Queue[str] = queue.Queue()
    reader = threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True)
    reader.start()
    yield proc, lines, reader
    if proc.poll() is None:
        proc.kill()
    proc.wait(10)


def test_optik_view_serves_a_drawn_page_and_stops_on_ctrl_c(browser, served):
    proc, lines, reader = served
    first = lines.get(timeout=60)  # "optik view: panda at http://127.0.0.1:PORT (Ctrl-C to stop)"
    assert "http://127.0.0.1:" in first, first
    url = first.split(" at ")[1].split()[0]
    png = browser.screenshot(url, ready=complete, timeout=30)
    assert drawn(png)
    assert len(np.unique(np.frombuffer(png, dtype=np.uint8))) > 100  # a rendered image, not a flat fill
    proc.send_signal(signal.SIGINT)
    proc.wait(20)
    err = proc.stderr.read()
    assert proc.returncode in (0, 130), err
    assert "Traceback" not in err, err
    reader.join(5)
    assert "optik view: stopped" in "".join(lines.queue)


def test_a_target_set_from_python_moves_the_arm_in_the_page(browser):
    m = catalog.panda()
    with optik.view(m, port=free_port()) as v, browser, browser.open(v.url) as page:
        before = page.screenshot(drawn, timeout=30)
        assert len(v.server.get_clients()) == 1  # the page is connected to this viewer
        target = m.fk(np.array([1.2, 0.5, 0.3, -1.2, 0.4, 2.0, 0.0]))
        res = v.set_target(target)
        assert res.success
        shown = m.fk(v.q)  # the configuration sent to the page solves the target
        assert np.linalg.norm(shown[:3, 3] - target[:3, 3]) < 1e-6
        assert np.linalg.norm(shown[:3, :3] - target[:3, :3]) < 1e-6

        def moved(png: bytes) -> bool:
            return drawn(png) and _changed(before, png) > 3000

        after = page.screenshot(moved, timeout=20)
        assert _changed(before, after) > 3000


def _pixel(client, point: np.ndarray) -> tuple[float, float]:
    """Where the page's camera (viser: OpenCV axes, vertical field of view ``fov``) shows a point."""
    from optik.view.shapes import rotation

    cam = client.camera
    p = rotation(cam.wxyz).T @ (point - np.asarray(cam.position))
    f = (HEIGHT / 2) / np.tan(cam.fov / 2)
    return WIDTH / 2 + f * p[0] / p[2], HEIGHT / 2 + f * p[1] / p[2]


def test_a_mouse_drag_of_the_gizmo_in_the_page_re_solves_ik(browser):
    m = catalog.panda()
    with optik.view(m, port=free_port()) as v, browser, browser.open(v.url) as page:
        v.set_q([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
        page.screenshot(complete, timeout=30)
        (client,) = v.server.get_clients().values()
        start, axis = v.target[:3, 3].copy(), v.target[:3, 0]
        moved = False
        for frac in (0.75, 0.6, 0.9):  # press on the gizmo's x arrow, drag 40 px, release
            x, y = _pixel(client, start + frac * 0.3 * v.size * axis)
            page.call("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y)
            page.call(
                "Input.dispatchMouseEvent",
                type="mousePressed",
                x=x,
                y=y,
                button="left",
                buttons=1,
                clickCount=1,
            )
            for k in range(1, 11):
                page.call(
                    "Input.dispatchMouseEvent",
                    type="mouseMoved",
                    x=x - 4 * k,
                    y=y + k,
                    button="left",
                    buttons=1,
                )
                time.sleep(0.05)
            page.call(
                "Input.dispatchMouseEvent",
                type="mouseReleased",
                x=x - 40,
                y=y + 10,
                button="left",
                clickCount=1,
            )
            deadline = time.monotonic() + 10
            while v.result is None and time.monotonic() < deadline:
                time.sleep(0.1)
            if v.result is not None:
                moved = True
                break
        assert moved, "no gizmo event reached the viewer"
        time.sleep(0.5)  # the last events of the drag
        assert np.linalg.norm(v.target[:3, 3] - start) > 0.005  # the drag moved the target
        assert v.result.success
        shown = m.fk(v.q)  # the arm followed: FK of the displayed q is the dragged target
        assert np.linalg.norm(shown[:3, 3] - v.target[:3, 3]) < 1e-6
        assert spatial.angle_between(shown[:3, :3], v.target[:3, :3]) < 1e-6


def _changed(a: bytes, b: bytes) -> int:
    """Pixels of `CANVAS` that differ between two screenshots."""
    import io

    from PIL import Image

    left, top, right, bottom = CANVAS
    x, y = (np.asarray(Image.open(io.BytesIO(p)).convert("RGB"), dtype=int) for p in (a, b))
    x, y = x[top:bottom, left:right], y[top:bottom, left:right]
    return int(np.count_nonzero(np.abs(x - y).sum(axis=2) > 60))


def _panda(v):
    q = np.array([0.3, -0.4, 0.2, -2.2, 0.1, 1.9, 0.8])
    target = v.m.fk(q)
    target[:3, 3] += (0.08, 0.1, 0.05)
    assert v.set_target(target).success


def _five_bar(mode):
    def setup(v):
        modes = v.set_actuated([2.0, 1.2])
        assert len(modes) == 2 == len(closed_form.fk(v.m, [2.0, 1.2]))
        v.show_mode(mode)

    return setup


def _stewart(v):
    modes = v.set_actuated([1.2, 1.1, 1.15, 1.25, 1.2, 1.1])
    assert len(modes) >= 2
    upright = int(np.argmax([v.m.fk(q)[2, 3] for q in modes]))  # the highest platform
    v.show_mode(upright, others=False)


def _branches(v):
    target = v.m.fk(v.m.random_q(seed=193))  # a target with all 8 branches within the limits
    v.set_target(target)
    assert len(v.show_all_solutions(True)) == len(closed_form.ik(v.m, target)) == 8


def _erd_panda():
    """The Panda of example-robot-data, with its visual meshes (the robots extra)."""
    from test_urdf_ros import _robots_dir

    return optik.Mechanism.from_urdf(
        _robots_dir() / "panda_description/urdf/panda.urdf", "panda_link0", "panda_hand"
    )


def _reach(v):
    rmap = optik.reach(v.m, resolution=0.1, orientations=8, samples=20000)
    assert v.show_reach(rmap) == len(rmap.centers)
    v.set_target(optik.Pose2D(1.2, 0.8, 0.5))


def _panda_reach(v):
    _panda(v)
    rmap = optik.reach(v.m, resolution=0.1, orientations=8, samples=20000)
    assert 0 < v.show_reach(rmap) < len(rmap.centers)  # one layer


SHOTS = {
    "view_panda": (_erd_panda, _panda),
    "view_panda_reach": (_erd_panda, _panda_reach),
    "view_panda_capsules": (catalog.panda, _panda),
    "view_five_bar_mode1": (catalog.five_bar, _five_bar(0)),
    "view_five_bar_mode2": (catalog.five_bar, _five_bar(1)),
    "view_stewart_gough": (catalog.stewart_gough, _stewart),
    "view_puma560_branches": (catalog.puma560, _branches),
    "view_planar_3r_reach": (lambda: catalog.planar_3r(lengths=(1.0, 0.8, 0.5)), _reach),
}


@pytest.mark.skipif(
    not os.environ.get("OPTIK_VIEW_SHOTS"),
    reason="set OPTIK_VIEW_SHOTS=DIR to take the documentation screenshots",
)
@pytest.mark.parametrize("name", SHOTS)
def test_documentation_screenshots(name):
    build, setup = SHOTS[name]
    with optik.view(build(), port=free_port()) as v:
        setup(v)
        with Chromium(CHROMIUM, WIDTH, HEIGHT) as browser:
            png = browser.screenshot(v.url, ready=settled(), timeout=60)
    assert drawn(png)
    write_atomic(Path(os.environ["OPTIK_VIEW_SHOTS"]) / f"{name}.png", lambda tmp: Path(tmp).write_bytes(png))


def _capture(page, changed_since: bytes | None = None) -> bytes:
    """A screenshot equal to the one before it (nothing still arriving); after a change made
    from Python, one that differs from ``changed_since``; the first one a drawn scene."""
    last: list[bytes] = []

    def ready(png: bytes) -> bool:
        same = bool(last) and last[-1] == png
        last[:] = [png]
        if changed_since is None:
            return same and complete(png)
        return same and _changed(changed_since, png) > 200

    return page.screenshot(ready, timeout=60)


def test_the_robot_stays_visible_through_its_capability_map(browser):
    m = catalog.panda()
    rmap = optik.reach(m, resolution=0.2, orientations=2, samples=3000, workers=1, time_limit=0.002)
    with optik.view(m, port=free_port()) as v, browser, browser.open(v.url) as page:
        _panda(v)
        v.show_reach(rmap)
        both = _capture(page)
        v.robot.set_visible(False)
        map_only = _capture(page, both)
        v.set_reach_visible(False)
        v.robot.set_visible(True)
        robot_only = _capture(page, map_only)
        v.robot.set_visible(False)
        nothing = _capture(page, robot_only)
    robot = _changed(robot_only, nothing)  # the robot's pixels without the map
    seen = _changed(both, map_only)  # the robot's pixels that the map leaves visible
    assert robot > 3000
    assert seen >= 0.8 * robot, (seen, robot)


def test_a_catalog_robot_opens_with_its_meshes(browser):
    try:
        m = catalog.robot("ur5")
    except optik.MissingExtraError as exc:
        pytest.skip(str(exc))
    with optik.view(m, port=free_port()) as v, browser, browser.open(v.url) as page:
        assert v.notes == []  # every visual mesh of the URDF resolved
        meshes = _capture(page)  # settled: the meshes have streamed in
        v.robot.set_visible(False)
        bare = _capture(page, meshes)
    assert _changed(meshes, bare) > 8000, _changed(meshes, bare)  # the arm's meshes, not joint spheres


@pytest.mark.parametrize(
    "source",
    [
        ["five_bar"],  # a closed chain (problem file)
        [str(catalog.urdf_path("panda")), "--base", "panda_link0", "--tip", "panda_link8"],  # a URDF arm
    ],
)
def test_the_newcomer_sources_open_as_drawn_scenes(source, browser):
    from optik.problem_files import load_source

    m, _ = load_source(source[0], *(source[2::2] if len(source) > 1 else (None, None)))
    with optik.view(m, port=free_port()) as v, browser, browser.open(v.url) as page:
        png = _capture(page)
    assert drawn(png) and complete(png)


def test_a_planned_path_plays_back_in_the_page(browser):
    """The PUMA's weld line of ``problems/puma560_weld.toml`` planned by ``plan_path`` and played
    back (the play button's `Viewer.play`): the arm drawn in the page moves from the first sample
    to the last, and the page shows the last configuration."""
    from optik.problem_files import find_problem

    problem = find_problem("puma560_weld", None)
    m = problem.mechanism()
    poses, times = problem.path_poses()
    path = optik.plan_path(m, poses[::4], times[::4], **problem.path_options())
    assert path.success, path.message
    with optik.view(m, port=free_port()) as v, browser, browser.open(v.url) as page:
        v.show_path(path)
        first = page.screenshot(settled(), timeout=30)
        v.play(wait=True)
        np.testing.assert_allclose(v.q, path.q[-1])

        def moved(png: bytes) -> bool:
            return drawn(png) and _changed(first, png) > 1500

        last = page.screenshot(moved, timeout=20)
        assert _changed(first, last) > 1500
