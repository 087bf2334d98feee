"""Per-solver tallies of the focused benchmarks: timed calls, the referee's verdicts, summary cells.

Every benchmark table of `benchmarks/` reports its timings the same way: mean, median and p95 of
every timed call (failures included), from one [`Tally`][optik.harness.tally.Tally] per solver.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from optik.harness.peers.rules import Verdict

__all__ = ["Tally", "success_table", "timing_ms"]


def timing_ms(times: Sequence[float]) -> tuple[float, float, float]:
    """``(mean, median, p95)`` of ``times`` (s) in ms; NaN for no times."""
    t = 1e3 * np.asarray(times, dtype=float)
    if t.size == 0:
        return float("nan"), float("nan"), float("nan")
    return float(t.mean()), float(np.median(t)), float(np.percentile(t, 95))


def success_table(results: dict[str, tuple[Sequence[float], int]], n: int, reference: str) -> str:
    """The Markdown table of solvers judged by one referee: per solver ``(times (s), successes)``
    over ``n`` targets, with mean / median / p95 in ms and the ratio of means to ``reference``."""
    ref = timing_ms(results[reference][0])[0]
    lines = ["| solver | success | mean ms | median ms | p95 ms | mean / optik |", "|---" + "|---:" * 5 + "|"]
    for name, (times, ok) in results.items():
        mean, median, p95 = timing_ms(times)
        lines.append(f"| {name} | {ok}/{n} | {mean:.2f} | {median:.2f} | {p95:.2f} | {mean / ref:.2f} |")
    return "\n".join(lines)


@dataclass
class Tally:
    """One solver's calls: wall times (s), the referee's verdicts, the solver's own success flags."""

    name: str
    times: list[float] = field(default_factory=list)
    verdicts: list[Verdict] = field(default_factory=list)
    own: list[bool] = field(default_factory=list)

    def add(self, seconds: float, verdict: Verdict, own: bool) -> None:
        """Record one call."""
        self.times.append(seconds)
        self.verdicts.append(verdict)
        self.own.append(bool(own))

    @property
    def n(self) -> int:
        """Number of calls."""
        return len(self.times)

    def success_pct(self) -> float:
        """Share of calls the referee accepted (%)."""
        return 100.0 * float(np.mean([v.success for v in self.verdicts])) if self.verdicts else float("nan")

    def own_pct(self) -> float:
        """Share of calls the solver itself called a success (%)."""
        return 100.0 * float(np.mean(self.own)) if self.own else float("nan")

    def max_overshoot(self) -> float:
        """Largest raw limit overshoot of the answers (before they were clipped)."""
        return max((v.overshoot for v in self.verdicts), default=float("nan"))

    def timing_ms(self) -> tuple[float, float, float]:
        """``(mean, median, p95)`` call time in ms."""
        return timing_ms(self.times)

    def timing_cells(self) -> str:
        """``mean | median | p95`` (ms) as Markdown table cells."""
        mean, median, p95 = self.timing_ms()
        return f"{mean:.3f} | {median:.3f} | {p95:.3f}"
