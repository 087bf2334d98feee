"""A plain-text progress bar on stderr (no dependency): one line per problem, redrawn in place."""

from __future__ import annotations

import sys
import time
from typing import TextIO

WIDTH = 30
"""Characters of the bar."""


class Progress:
    """``[3/12] five_bar  |##########..........|  50%  125/250  2.1 s``

    Args:
        problems: number of problems of the run (for the ``[i/N]`` prefix).
        stream: where to write (default ``sys.stderr``).
        interval: minimum seconds between redraws on a terminal; when ``stream`` is not a
            terminal only the finished line of each problem is written.
    """

    def __init__(self, problems: int, stream: TextIO | None = None, interval: float = 0.1) -> None:
        self.problems = problems
        self.stream = sys.stderr if stream is None else stream
        self.interval = interval
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.index = 0
        self.label = ""
        self.total = 0
        self.done = 0
        self.t0 = 0.0
        self.last = 0.0

    def start(self, label: str, total: int) -> None:
        """Begin the next problem with ``total`` steps."""
        self.index += 1
        self.label, self.total, self.done = label, total, 0
        self.t0 = self.last = time.perf_counter()
        self._draw(force=True)

    def step(self, count: int = 1) -> None:
        """``count`` calls done."""
        self.done += count
        self._draw()

    def finish(self) -> None:
        """End the current problem's line."""
        self.done = self.total
        self._draw(force=True, final=True)

    def line(self) -> str:
        """The current text of the bar."""
        frac = self.done / self.total if self.total else 1.0
        filled = round(WIDTH * frac)
        return (
            f"[{self.index}/{self.problems}] {self.label:<14} |{'#' * filled}{'.' * (WIDTH - filled)}| "
            f"{100 * frac:3.0f}%  {self.done}/{self.total}  {time.perf_counter() - self.t0:.1f} s"
        )

    def _draw(self, force: bool = False, final: bool = False) -> None:
        now = time.perf_counter()
        if self.tty and (force or now - self.last >= self.interval):
            self.stream.write("\r" + self.line() + ("\n" if final else ""))
            self.stream.flush()
            self.last = now
        elif not self.tty and final:
            self.stream.write(self.line() + "\n")
            self.stream.flush()
