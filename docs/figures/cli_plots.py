"""Figures of the CLI page: ``optik plot`` of the five-bar and the Stewart-Gough platform.

Run from the repository root: ``python docs/figures/cli_plots.py``. Writes
``docs/img/cli/<problem>_{config,branches,assembly,workspace}.png`` exactly as the command
``optik plot <problem> --mode all --out docs/img/cli`` does (same seed, same sampling).
"""

from __future__ import annotations

import sys
from pathlib import Path

from optik.cli import main

OUT = Path(__file__).resolve().parent.parent / "img" / "cli"
PROBLEMS = ("five_bar", "stewart_gough")


def run() -> int:
    """``optik plot PROBLEM --mode all`` for every problem of ``PROBLEMS``."""
    codes = [main(["plot", name, "--mode", "all", "--out", str(OUT)]) for name in PROBLEMS]
    return max(codes)


if __name__ == "__main__":
    sys.exit(run())
