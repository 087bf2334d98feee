"""Latency of the browser viewer's interactions: IK re-solve per gizmo move, and FK per actuator
slider move of the closed chains.

Method: a `optik.view.Viewer` serves the mechanism on a free local port (the real viser server;
with ``--browser`` a headless Chromium keeps the page open, so every update is also sent over
the websocket). A drag is a sequence of small target moves: the end-effector poses of a smooth
joint-space path (``q0 + a sin(2 pi k / n)`` per joint, phases seeded), about 2-5 mm apart. Each
move calls what a gizmo event calls (`optik.view.Viewer.set_target`: IK from the last answer,
then the scene update: link poses, joint frames, sliders, status line); its wall time is the
latency. The solve time reported by the solver is printed next to it, so that the scene's
share is visible. With "all solutions" on, every move also runs ``solve_ik_all`` and redraws
the ghosts. Actuator moves (five-bar, Stewart-Gough) call `optik.view.Viewer.set_actuated`:
every assembly mode, the nearest one shown, the others as ghosts.

Run: ``optik benchmark view [--moves 200] [--method lm] [--browser]``.
"""

from __future__ import annotations

import contextlib
import socket
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING

import numpy as np

import optik
from optik import catalog
from optik.benchmarks import benchmark_parser
from optik.harness.tally import timing_ms

if TYPE_CHECKING:  # the view extra is imported where the benchmark runs, so --help works without it
    from optik.view import Viewer


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def drag(m: optik.Mechanism, n: int, seed: int = 0, amplitude: float = 0.15) -> np.ndarray:
    """``(n, n_q)`` joint path of a smooth drag around the mid-limit posture (within the limits)."""
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi, m.n_q)
    k = np.arange(n)[:, None]
    q = m.mid_q() + amplitude * np.sin(2 * np.pi * k / n + phase)
    return np.clip(q, m.lower, m.upper)


def _timed(calls: Iterator[Callable[[], object]]) -> tuple[np.ndarray, list[object]]:
    times, answers = [], []
    for call in calls:
        t0 = time.perf_counter()
        answers.append(call())
        times.append(time.perf_counter() - t0)
    return np.array(times), answers


def _ms(x: np.ndarray) -> str:
    mean, median, p95 = timing_ms(x)
    return f"{mean:.3f} / {median:.3f} / {p95:.3f}"


HEADER = (
    "| case | handler | moves | per move ms: mean / median / p95 | solve ms: mean / median / p95 | result |\n"
    "|---|---|--:|--:|--:|---|"
)


@contextlib.contextmanager
def _page(v: Viewer, browser: bool) -> Iterator[None]:
    if not browser:
        yield
        return
    from optik.view.browser import Chromium

    with Chromium() as chromium, chromium.open(v.url) as page:
        page.screenshot(lambda _png: len(v.server.get_clients()) > 0, timeout=30)
        yield


def gizmo_moves(name: str, method: str | None, moves: int, all_solutions: bool, browser: bool) -> str:
    """The table row of the latency of ``moves`` gizmo moves on catalog mechanism ``name``."""
    m = getattr(catalog, name)()
    targets = [m.fk(q) for q in drag(m, moves + 1)]
    from optik.view import Viewer

    with Viewer(m, port=_port(), method=method) as v, _page(v, browser):
        v.set_target(targets[0])  # warm up: compiled solvers, first scene messages
        if all_solutions:
            v.show_all_solutions(True)
        times, results = _timed(lambda t=t: v.set_target(t) for t in targets[1:])
        solve = np.array([r.solve_time for r in results])
        ok = sum(r.success for r in results)
        what = " + all solutions" if all_solutions else ""
        branches = f", {len(v.solutions)} branches drawn at the end" if all_solutions else ""
        return (
            f"| {name} | {v.method}{what} | {len(results)} | {_ms(times)} | {_ms(solve)} "
            f"| solved {ok}/{len(results)}{branches} |"
        )


def actuator_moves(name: str, values: Sequence[float], moves: int, browser: bool) -> str:
    """The table row of the latency of ``moves`` actuator-slider moves around ``values``."""
    m = getattr(catalog, name)()
    a = np.asarray(values, dtype=float)
    path = a + 0.05 * np.sin(2 * np.pi * np.arange(moves)[:, None] / moves + np.arange(len(a)))
    from optik.view import Viewer

    with Viewer(m, port=_port()) as v, _page(v, browser):
        v.set_actuated(a)
        times, modes = _timed(lambda x=x: v.set_actuated(x) for x in path)
        counts = [len(x) for x in modes]
        modes_drawn = f"{min(counts)}-{max(counts)} modes drawn"
        return f"| {name} | actuators | {len(path)} | {_ms(times)} | - | {modes_drawn} |"


def main(argv: Sequence[str] | None = None) -> int:
    parser = benchmark_parser("view", __doc__)
    parser.add_argument("--moves", type=int, default=200, help="gizmo moves per case (default: %(default)s)")
    parser.add_argument("--method", help="IK method of the gizmo (default: the viewer's choice)")
    parser.add_argument("--browser", action="store_true", help="keep a headless Chromium page connected")
    args = parser.parse_args(argv)
    print(
        f"optik view latency: {args.moves} moves per case, handler wall time (solve + scene update)"
        f"{', page connected' if args.browser else ''}\n"
    )
    rows = [
        gizmo_moves("panda", args.method, args.moves, False, args.browser),
        gizmo_moves("seed_6r_arm", args.method, args.moves, False, args.browser),
        gizmo_moves("puma560", args.method, max(args.moves // 4, 1), True, args.browser),
        actuator_moves("five_bar", (1.5, 1.0), args.moves, args.browser),
        actuator_moves(
            "stewart_gough", (1.2, 1.1, 1.15, 1.25, 1.2, 1.1), max(args.moves // 20, 1), args.browser
        ),
    ]
    print("\n".join([HEADER, *rows]))  # after the servers' own messages, as one table
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
