"""The focused benchmark scripts, shipped inside the package so that every install has them.

Each module ``bench_<name>.py`` has a ``main(argv) -> int``; ``optik benchmark NAME ARGS...``
imports ``optik.benchmarks.bench_NAME`` and calls ``main(ARGS)``, and
``python -m optik.benchmarks.bench_NAME ARGS...`` does the same. Being modules of a package,
they are found by the import system from a wheel, an editable install or a source tree on
``PYTHONPATH`` alike.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Sequence

from optik.errors import InvalidArgumentError

__all__ = ["available", "run"]

PREFIX = "bench_"


def available() -> tuple[str, ...]:
    """The benchmark names, sorted: ``NAME`` of every module ``bench_NAME`` of this package."""
    modules = pkgutil.iter_modules(__path__)
    return tuple(sorted(m.name.removeprefix(PREFIX) for m in modules if m.name.startswith(PREFIX)))


def run(name: str, argv: Sequence[str] = ()) -> int:
    """Import ``optik.benchmarks.bench_<name>`` and return ``main(argv)`` as an exit code.

    Raises:
        InvalidArgumentError: no benchmark of that name (the message lists the available ones).
    """
    if name not in available():
        raise InvalidArgumentError("name", f"unknown benchmark {name!r}; available: {', '.join(available())}")
    module = importlib.import_module(f"{__name__}.{PREFIX}{name}")
    return int(module.main(list(argv)) or 0)
