"""The long fuzz run of the public API: every entry point of the harness `tests/fuzz/harness.py`, valid
and corrupted arguments mixed, each outcome classified (ok, OptikError, leak, false success,
overtime), with the counts per class and entry and the peak memory.

Method: hypothesis draws the calls (``--seed``: the same seed gives the same calls) in chunks of
``--chunk`` examples, each chunk a fresh hypothesis run seeded ``seed * 100003 + chunk`` (no
shrinking; a chunk's choice tree stays small, so the fuzzer's own memory stays bounded). The mix
is `WEIGHTS`; ``--subprocess-calls`` calls of the ``optik`` command through a subprocess run
after the in-process calls. The address space is capped at ``--max-memory-gb`` (``RLIMIT_AS``),
so that a runaway allocation is a ``MemoryError`` (a leak) instead of exhausting the machine.

Run: ``python tests/fuzz/long_run.py --calls 100000`` (about 20 minutes on two loaded cores). Exit code 1
when any call broke the promise (leak, false success, overtime).
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import seed as hypothesis_seed
from hypothesis import strategies as st

if __package__ in (None, ""):  # run as a script: make the package `fuzz` (this folder) importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fuzz.harness import ENTRIES, Call, Tally, classify, mixed, peak_rss_mib, warm_up


def run_chunk(strategy: st.SearchStrategy, n: int, seed: int, tally: Tally) -> None:
    """``n`` calls drawn from ``strategy`` by one seeded hypothesis run, classified into ``tally``."""

    @hypothesis_seed(seed)
    @settings(
        max_examples=n,
        database=None,
        deadline=None,
        derandomize=False,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
        report_multiple_bugs=False,
    )
    @given(call=strategy)
    def chunk(call: Call) -> None:
        tally.add(classify(call))

    chunk()


def _cap_memory(gib: float) -> None:
    limit = int(gib * 2**30)
    _soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python tests/fuzz/long_run.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=100_000, help="in-process calls (default: %(default)s)")
    ap.add_argument("--subprocess-calls", type=int, default=100, help="CLI calls through a subprocess")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunk", type=int, default=2_000, help="calls per hypothesis run")
    ap.add_argument("--max-memory-gb", type=float, default=8.0, help="address-space cap (RLIMIT_AS)")
    args = ap.parse_args(argv)
    _cap_memory(args.max_memory_gb)
    start = time.perf_counter()
    warm_up()
    print(f"warm-up {time.perf_counter() - start:.1f} s, peak RSS {peak_rss_mib():.0f} MiB", flush=True)
    tally = Tally()
    strategy = mixed()
    chunk = 0
    while tally.calls < args.calls:
        n = min(args.chunk, args.calls - tally.calls)
        before = tally.calls
        run_chunk(strategy, n, args.seed * 100_003 + chunk, tally)
        chunk += 1
        print(
            f"{tally.calls} calls, {time.perf_counter() - start:.0f} s, failures {tally.n_failures}, "
            f"peak RSS {peak_rss_mib():.0f} MiB",
            flush=True,
        )
        if tally.calls == before:  # hypothesis found nothing new to draw (never for this mix)
            break
    if args.subprocess_calls:
        done = tally.calls
        while tally.calls - done < args.subprocess_calls:
            run_chunk(
                ENTRIES["cli (subprocess)"](),
                args.subprocess_calls - (tally.calls - done),
                args.seed * 100_003 + chunk,
                tally,
            )
            chunk += 1
    elapsed = time.perf_counter() - start
    print(tally.report())
    print(
        f"wall time {elapsed:.0f} s ({1e3 * elapsed / max(tally.calls, 1):.1f} ms per call), "
        f"peak RSS {peak_rss_mib():.0f} MiB (getrusage ru_maxrss), address space capped at "
        f"{args.max_memory_gb:g} GiB"
    )
    return 1 if tally.n_failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
