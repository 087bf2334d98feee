"""Rebuild the Stewart-Gough start instance shipped in optik/data/stewart_gough_start.json.

Draws the generic complex instance of `optik.closed_form.parallel.stewart_parameter.generate`
(seed ``--seed``), solves it with the 128-path total-degree homotopy until 40 distinct
nonsingular solutions are certified, and writes them (atomically) to ``--out``.

    python scripts/make_stewart_start.py [--seed 2026] [--out optik/data/stewart_gough_start.json]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from optik.closed_form.parallel import stewart_parameter


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=stewart_parameter.START_SEED)
    ap.add_argument("--out", type=Path, default=stewart_parameter.START_FILE)
    args = ap.parse_args(argv)
    instance = stewart_parameter.generate(args.seed)
    stewart_parameter.write(instance, args.out)
    print(f"{len(instance.solutions)} solutions, residual {instance.residual():.2e}, written to {args.out}")


if __name__ == "__main__":
    main()
