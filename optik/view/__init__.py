"""The browser viewer: a mechanism in a local web page (viser), with a draggable IK target, every
IK branch, joint and actuator sliders, assembly modes and path playback.

``optik.view(m)`` returns a `Viewer` without blocking; ``optik view PROBLEM`` serves one from the
command line. Needs the ``view`` extra (viser).
"""

from optik.view.viewer import Viewer, view

__all__ = ["Viewer", "view"]
