"""The focused benchmark scripts, shipped inside the package so that every install has them.

Each module ``bench_<name>.py`` has a ``main(argv) -> int``; ``optik benchmark NAME ARGS...``
imports ``optik.benchmarks.bench_NAME`` and calls ``main(ARGS)``, and
``python -m optik.benchmarks.bench_NAME ARGS...`` does the same. Being modules of a package,
they are found by the import system from a wheel, an editable install or a source tree on
``PYTHONPATH`` alike. Each script builds its options with `benchmark_parser`, so that
``optik benchmark NAME --help`` is titled with its command and shows every default;
`summaries` gives the one-line description of each (its docstring's first paragraph, read
without importing it).
"""

from __future__ import annotations

import argparse
import ast
import importlib
import pkgutil
from collections.abc import Sequence
from pathlib import Path

from optik.errors import InvalidArgumentError

__all__ = ["available", "benchmark_parser", "run", "summaries", "summary"]

PREFIX = "bench_"


class _DefaultsFormatter(argparse.HelpFormatter):
    """Appends ``(default: X)`` to every option's help that does not state its default (and
    whose default is not None or False)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        quiet = action.default in (None, False, argparse.SUPPRESS) or not action.option_strings
        if quiet or "default" in text:
            return text
        return f"{text} (default: %(default)s)".lstrip()


def summary(doc: str | None) -> str:
    """The first paragraph of a docstring, on one line."""
    first = (doc or "").strip().split("\n\n")[0]
    return " ".join(first.split())


def benchmark_parser(name: str, doc: str | None) -> argparse.ArgumentParser:
    """The argument parser of the script ``bench_<name>``: titled ``optik benchmark <name>``,
    described by the first paragraph of ``doc`` (the script's docstring), every default shown."""
    return argparse.ArgumentParser(
        prog=f"optik benchmark {name}", description=summary(doc), formatter_class=_DefaultsFormatter
    )


def summaries() -> dict[str, str]:
    """``{name: one-line description}`` of every benchmark, from the scripts' docstrings
    (parsed, not imported: listing them costs no import of numpy, CasADi or a peer)."""
    folder = Path(__path__[0])
    texts = {name: (folder / f"{PREFIX}{name}.py").read_text(encoding="utf-8") for name in available()}
    return {name: summary(ast.get_docstring(ast.parse(text))) for name, text in texts.items()}


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
