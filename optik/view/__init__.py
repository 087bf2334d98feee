"""The browser viewer: a mechanism in a local web page (viser), with a draggable IK target, every
IK branch, joint and actuator sliders, assembly modes and path playback.

``optik.view(m)`` returns a `Viewer` without blocking; ``optik view PROBLEM`` serves one from the
command line. Needs the ``view`` extra (viser). The viewer's modules (viser, trimesh, matplotlib)
are imported on the first call, so that ``import optik`` stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from optik.errors import require_extra

if TYPE_CHECKING:
    from optik.mechanism import Mechanism
    from optik.view.viewer import Viewer


def view(m: Mechanism, q: Any = None, **options: Any) -> Viewer:
    """Show ``m`` in a local web page and return the `Viewer` without blocking (scripts,
    notebooks): ``v = optik.view(m); v.set_target(T); v.q; v.close()``. ``options`` are those of
    `Viewer` (``port``, ``host``, ``method``...). Open `Viewer.url` in a browser.

    Raises:
        MissingExtraError: viser or trimesh is not installed (``pip install "optik[view]"``).
    """
    return _viewer_class()(m, q, **options)


def _viewer_class() -> type[Viewer]:
    """`Viewer`, after checking that the ``view`` extra's packages import."""
    for module in ("viser", "trimesh"):
        require_extra(module, "view", "the viewer")
    from optik.view.viewer import Viewer

    return Viewer


def __getattr__(name: str) -> Any:
    """`Viewer` on first use (PEP 562), without importing the viewer at ``import optik``."""
    if name == "Viewer":
        return _viewer_class()
    raise AttributeError(f"module 'optik.view' has no attribute {name!r}")


__all__ = ["Viewer", "view"]
