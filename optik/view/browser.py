"""Screenshots of a web page in headless Chromium, over the Chrome DevTools Protocol.

No browser download and no driver binary: the operating system's Chromium (``chromium`` or
``chromium-browser`` on the ``PATH``, Debian's package) is started with
``--headless=new --remote-debugging-port=0`` and software WebGL (SwiftShader), so that it runs
without a display or a GPU; the page is driven through the DevTools websocket (the
``websockets`` package). Used by the viewer's browser tests and by the
documentation screenshots (``docs/figures/view.py``).
"""

from __future__ import annotations

import base64
import io
import json
import shutil
import subprocess
import tempfile
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["BrowserError", "Chromium", "Page", "coloured_pixels", "find_chromium"]

NAMES = ("chromium", "chromium-browser", "google-chrome")
FLAGS = (
    "--headless=new",
    "--remote-debugging-port=0",
    "--remote-debugging-address=127.0.0.1",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--mute-audio",
)
_HIDE_TOASTS = "document.querySelectorAll('.mantine-Notifications-root').forEach(e => e.remove())"


class BrowserError(RuntimeError):
    """Chromium is missing, did not start, or a page did not become ready in time."""


def find_chromium() -> str | None:
    """Path of a Chromium executable on the ``PATH`` (None when there is none)."""
    for name in NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def coloured_pixels(
    png: bytes, box: tuple[int, int, int, int] | None = None, saturation: float = 0.25
) -> int:
    """Number of pixels of a PNG whose saturation ``(max - min) / max`` of RGB exceeds ``saturation``
    inside ``box = (left, top, right, bottom)`` (whole image when None): drawn, coloured geometry,
    as opposed to the white background, the grey grid and black text."""
    from PIL import Image

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
    if box is not None:
        left, top, right, bottom = box
        rgb = rgb[top:bottom, left:right]
    hi, lo = rgb.max(axis=2), rgb.min(axis=2)
    return int(np.count_nonzero((hi - lo) > saturation * np.maximum(hi, 1.0)))


class Chromium:
    """A headless Chromium process; `screenshot` loads a page in a new tab and captures it.

    Args:
        executable: the browser (default: `find_chromium`).
        width, height: viewport in CSS pixels (device scale 1).
        timeout: seconds to wait for the browser to start.

    Raises:
        BrowserError: no Chromium, or it did not start within ``timeout``.
    """

    def __init__(
        self, executable: str | None = None, width: int = 1280, height: int = 800, timeout: float = 20.0
    ) -> None:
        exe = executable or find_chromium()
        if exe is None:
            raise BrowserError(f"no Chromium on the PATH (looked for {', '.join(NAMES)})")
        self.width, self.height = int(width), int(height)
        self._dir = tempfile.mkdtemp(prefix="optik-chromium-")
        args = [exe, *FLAGS, f"--user-data-dir={self._dir}", f"--window-size={width},{height}", "about:blank"]
        self._proc = subprocess.Popen(
            args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        port_file = Path(self._dir) / "DevToolsActivePort"
        deadline = time.monotonic() + timeout
        while True:
            text = port_file.read_text() if port_file.is_file() else ""
            if text.strip():
                self.port = int(text.split()[0])
                break
            if self._proc.poll() is not None or time.monotonic() > deadline:
                self.close()
                raise BrowserError(f"{exe} did not start its DevTools endpoint within {timeout} s")
            time.sleep(0.05)

    def _http(self, path: str, method: str = "GET") -> Any:
        req = urllib.request.Request(f"http://127.0.0.1:{self.port}{path}", method=method)
        with urllib.request.urlopen(req, timeout=10) as reply:
            body = reply.read()
        return json.loads(body) if body.lstrip()[:1] in (b"{", b"[") else body

    def open(self, url: str) -> Page:
        """A new tab showing ``url`` (close it, or use it as a context manager)."""
        return Page(self, url)

    def screenshot(
        self, url: str, ready: Callable[[bytes], bool] | None = None, timeout: float = 20.0
    ) -> bytes:
        """PNG of ``url`` in a new tab once ``ready(png)`` holds (see `Page.screenshot`)."""
        with self.open(url) as page:
            return page.screenshot(ready, timeout)

    def close(self) -> None:
        """End the browser (SIGTERM, then SIGKILL after 5 s) and remove its profile directory."""
        if self._proc.poll() is None:
            self._proc.terminate()
            try:
                self._proc.wait(5)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait(5)
        shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Page:
    """One tab of a `Chromium`, driven over its DevTools websocket.

    Raises:
        BrowserError: the tab did not answer a command within 30 s.
    """

    def __init__(self, browser: Chromium, url: str) -> None:
        from websockets.sync.client import connect

        self._browser = browser
        self._target = browser._http("/json/new?about:blank", method="PUT")
        self._ws = connect(self._target["webSocketDebuggerUrl"], max_size=None, open_timeout=30)
        self._id = 0
        self.call(
            "Emulation.setDeviceMetricsOverride",
            width=browser.width,
            height=browser.height,
            deviceScaleFactor=1,
            mobile=False,
        )
        self.call("Page.navigate", url=url)

    def call(self, method: str, timeout: float = 30.0, **params: Any) -> dict[str, Any]:
        """Send one DevTools command and return its result (events in between are skipped)."""
        self._id += 1
        self._ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BrowserError(f"{method}: no answer within {timeout} s")
            try:
                msg = json.loads(self._ws.recv(timeout=left))
            except TimeoutError:
                continue
            if msg.get("id") == self._id:
                if "error" in msg:
                    raise BrowserError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def screenshot(self, ready: Callable[[bytes], bool] | None = None, timeout: float = 20.0) -> bytes:
        """PNG of the tab once ``ready(png)`` holds (polled every 0.25 s; None: at once), with the
        page's pop-up notifications removed.

        Raises:
            BrowserError: ``ready`` did not hold within ``timeout`` seconds.
        """
        deadline = time.monotonic() + timeout
        while True:
            self.call("Runtime.evaluate", expression=_HIDE_TOASTS)
            png = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
            if ready is None or ready(png):
                return png
            if time.monotonic() > deadline:
                raise BrowserError(f"the page was not ready within {timeout} s")
            time.sleep(0.25)

    def close(self) -> None:
        """Close the tab."""
        self._ws.close()
        self._browser._http(f"/json/close/{self._target['id']}")

    def __enter__(self) -> Page:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
