"""``optik view PROBLEM|URDF``: serve a mechanism in the browser until Ctrl-C.

``PROBLEM`` is a problem name or ``.toml`` file, resolved like ``optik solve`` does (its
mechanism, task, tolerances and ``[world]`` obstacles, shown and avoided by the gizmo's IK); a
``.urdf`` file needs ``--base`` and ``--tip``. The page binds to ``127.0.0.1`` (this machine);
``--host 0.0.0.0`` serves it to the network (or keep the default and forward the port: ``ssh -L
8080:localhost:8080 HOST``). Ctrl-C (SIGINT) or SIGTERM stops the
server and exits with code 0. ``--path`` plans the problem's ``[path]`` table as ``optik path
PROBLEM`` does and loads the joint path for playback (the sample slider and the play button).
"""

from __future__ import annotations

import argparse
import signal
import threading
import time
import webbrowser
from types import FrameType
from typing import Any

from optik.problem_files import add_source_arguments, load_source

__all__ = ["add_parser", "run"]

CLOSE_WAIT = 2.0
"""Seconds ``optik view`` waits for the server to stop before it exits anyway."""


def add_parser(sub: Any) -> None:
    """Register ``view`` on the ``optik`` subcommand parsers."""
    p = sub.add_parser(
        "view",
        help="interactive 3-D viewer in the browser (drag the IK target, branches, assembly modes)",
        description=(
            "Serve a mechanism in a local web page (viser): drag the target gizmo and the arm follows "
            "by IK, show every IK branch, move joint or actuator sliders (every assembly mode of a "
            "closed chain), track a path. Binds to 127.0.0.1 unless --host says otherwise; Ctrl-C stops."
        ),
    )
    add_source_arguments(p)
    p.add_argument("--port", type=int, default=8080, help="TCP port (default: %(default)s, or the next free)")
    p.add_argument("--host", default="127.0.0.1", help="interface to bind (default: %(default)s)")
    p.add_argument(
        "--method", help="IK method of the gizmo: closed_form, lm, nlp, dls, qp (default: the best available)"
    )
    p.add_argument(
        "--reach",
        metavar="PATH",
        help="capability map to draw: a reach.npz or its folder, written by optik reach (default: none)",
    )
    p.add_argument(
        "--path",
        action="store_true",
        help="plan the problem's [path] (as optik path PROBLEM does) and load it for playback (default: off)",
    )
    p.add_argument("--no-browser", action="store_true", help="do not open a browser window")
    p.set_defaults(func=run)


def _viewer(args: argparse.Namespace) -> Any:
    from optik.errors import InvalidArgumentError

    if not 0 <= args.port <= 65535:
        raise InvalidArgumentError("--port", f"expected 0..65535, got {args.port}")
    m, problem = load_source(args.source, args.base, args.tip, args.problems_dir)
    # the viewer's extra is needed only once the arguments are known to be right
    from optik.view import Viewer
    from optik.view.viewer import reach_points

    task, tol = (problem.mechanism_task, problem.tolerances) if problem is not None else (None, None)
    if args.reach is not None:  # a bad map is a usage error before the server starts
        try:
            reach_points(args.reach)
        except InvalidArgumentError as exc:
            raise InvalidArgumentError("--reach", str(exc).partition(": ")[2]) from None
    world = problem.world if problem is not None else None  # the file's [world] table
    viewer = Viewer(m, host=args.host, port=args.port, task=task, tol=tol, method=args.method, world=world)
    if args.reach is not None:
        viewer.show_reach(args.reach)
    if args.path:
        viewer.show_path(_planned(problem, m, args.source))
    return viewer


def _planned(problem: Any, m: Any, source: str) -> Any:
    """The joint path of ``problem``'s ``[path]`` table (`optik.plan_path`), its message printed."""
    from optik.errors import InvalidArgumentError
    from optik.path import plan_path

    if problem is None or not problem.path_table:
        raise InvalidArgumentError("--path", f"{source!r} is not a problem with a [path] table")
    poses, times = problem.path_poses()
    path = plan_path(m, poses, times, **problem.path_options())
    print(f"optik view: {problem.name} path: {path.message}", flush=True)
    if not len(path.q):
        raise InvalidArgumentError("--path", f"no path to play: {path.message}")
    return path


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def run(args: argparse.Namespace) -> int:
    """Body of ``optik view``: serve until SIGINT / SIGTERM, then stop the server; exit code 0."""
    viewer = _viewer(args)
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        print(f"optik view: {viewer.m.name} at {viewer.url} (Ctrl-C to stop)", flush=True)
        for note in viewer.notes:
            print(f"note: URDF visual not drawn: {note}", flush=True)
        if not args.no_browser:
            webbrowser.open(viewer.url)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
        # viser's stop may wait seconds for idle browser sockets; the process exit ends them
        closing = threading.Thread(target=viewer.close, name="optik-view-close", daemon=True)
        closing.start()
        closing.join(CLOSE_WAIT)
    print("optik view: stopped", flush=True)
    return 0
