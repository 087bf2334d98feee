"""The focused benchmark scripts, shipped inside the package so that every install has them.

Each module ``bench_<name>.py`` has a ``main(argv) -> int``; ``optik benchmark NAME ARGS...``
imports ``optik.benchmarks.bench_NAME`` and calls ``main(ARGS)``, and
``python -m optik.benchmarks.bench_NAME ARGS...`` does the same. Being modules of a package,
they are found by the import system from a wheel, an editable install or a source tree on
``PYTHONPATH`` alike. Each script builds its options with `benchmark_parser`, so that
``optik benchmark NAME --help`` is titled with its command and shows every default;
`summaries` gives the one-line description of each (its docstring's first paragraph, read
without importing it).

BLAS and OpenMP thread pools are pinned to one thread for every measured run (`PINNED`): a
library reads ``OMP_NUM_THREADS`` and the like once, when it loads, and ``import optik`` has
loaded numpy (and its OpenBLAS) before any script could set them. So `run` starts the script in
a child process (``python -m optik.benchmarks.bench_NAME``) with the pinned environment, its
output passed through line by line, exactly as ``optik benchmark all`` does; it runs it in the
calling process only where that process is pinned already (`is_pinned`) or the arguments only
ask for the help text (nothing is measured then).
"""

from __future__ import annotations

import argparse
import ast
import importlib
import os
import pkgutil
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from optik.errors import InvalidArgumentError

__all__ = [
    "PINNED",
    "available",
    "benchmark_parser",
    "command",
    "is_pinned",
    "pinned_environment",
    "run",
    "summaries",
    "summary",
]

PREFIX = "bench_"

PINNED: Mapping[str, str] = {
    name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
}
"""Thread pools of a benchmark process: one thread each (the benchmarks' own threads and
processes are their ``--workers``)."""


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


def pinned_environment(base: Mapping[str, str] | None = None) -> dict[str, str]:
    """``base`` (default: ``os.environ``) with every thread pool of `PINNED` set to one thread."""
    return {**(os.environ if base is None else base), **PINNED}


def is_pinned(env: Mapping[str, str] | None = None) -> bool:
    """Whether ``env`` (default: ``os.environ``) pins every thread pool of `PINNED` as it does."""
    env = os.environ if env is None else env
    return all(env.get(k) == v for k, v in PINNED.items())


def command(name: str, argv: Sequence[str] = ()) -> list[str]:
    """The child-process command line of one benchmark: ``python -m optik.benchmarks.bench_NAME ARGV``.

    Raises:
        InvalidArgumentError: no benchmark of that name (the message lists the available ones).
    """
    if name not in available():
        raise InvalidArgumentError("name", f"unknown benchmark {name!r}; available: {', '.join(available())}")
    return [sys.executable, "-m", f"{__name__}.{PREFIX}{name}", *argv]


def run(name: str, argv: Sequence[str] = ()) -> int:
    """Run the benchmark ``bench_<name>`` with ``argv`` and return its exit code.

    In a child process with `pinned_environment` (its standard output copied line by line to
    ``sys.stdout``, its standard error inherited), unless this process `is_pinned` or ``argv``
    asks for ``--help`` / ``-h``: then ``main(argv)`` of the imported module.

    Raises:
        InvalidArgumentError: no benchmark of that name (the message lists the available ones).
    """
    cmd = command(name, argv)
    if is_pinned() or {"-h", "--help"} & set(argv):
        module = importlib.import_module(f"{__name__}.{PREFIX}{name}")
        return int(module.main(list(argv)) or 0)
    sys.stdout.flush()
    with subprocess.Popen(
        cmd, stdout=subprocess.PIPE, text=True, bufsize=1, env=pinned_environment()
    ) as child:
        assert child.stdout is not None  # stdout=PIPE
        for line in child.stdout:
            sys.stdout.write(line)
    return child.returncode
