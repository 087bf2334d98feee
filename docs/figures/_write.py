"""The command line shared by the figure scripts: ``--out DIR`` (default ``docs/img``)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from matplotlib.figure import Figure

from optik.plot import save_figure

IMG = Path(__file__).resolve().parents[1] / "img"


def write_figures(
    prefix: str, figures: Callable[[], dict[str, Figure]], description: str, argv: list[str] | None
) -> list[Path]:
    """Save every figure of ``figures()`` as ``<out>/<prefix>_<name>.png`` (atomically), print and
    return the paths."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--out", default=str(IMG), help="output directory (default: docs/img)")
    args = parser.parse_args(argv)
    written = [save_figure(fig, Path(args.out) / f"{prefix}_{name}.png") for name, fig in figures().items()]
    for path in written:
        print(path)
    return written
