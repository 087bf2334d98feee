"""The documentation site builds in strict mode, and its Python examples run.

Every fenced block opened with ```` ```python ```` in a page of ``docs/`` and in README.md is
executed, the blocks of one page in order in one namespace, from a temporary working directory.
A block fenced as ```` ```{.python .no-run} ```` (the attribute syntax of pymdownx.superfences,
still highlighted as Python) is only shown, e.g. for signatures.

Printed values are checked: a one-line ``print(...)  # TEXT`` whose ``TEXT`` starts with the
first word of what the call prints claims to show that output, and must: the printed text
(whitespace runs counted as one space) is ``TEXT``, or the start of ``TEXT`` before an
annotation (cut at a space or a colon), ``...`` standing for any text. Any other comment is a
description and is not compared.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from optik.errors import MissingExtraError

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
FENCE = re.compile(
    r"^```(?P<info>python[^\n]*|\{[^}\n]*\.python\b[^}\n]*\})\n(?P<code>.*?)^```\s*$",
    re.MULTILINE | re.DOTALL,
)


PRINT_WITH_COMMENT = re.compile(
    r"^(?P<indent>[ \t]*)print\((?P<args>.*)\)[ \t]*#[ \t]*(?P<text>\S.*)$", re.MULTILINE
)


def output_matches(printed: str, text: str) -> bool:
    """``printed`` agrees with the comment ``text`` that claims to show it (module docstring)."""
    out, claim = " ".join(printed.split()), " ".join(text.split())
    # the claim itself, or its start before an annotation (after a space or a colon)
    shown = [claim] + [claim[:i] for i, c in enumerate(claim) if c in " :" and i > 0]
    for part in shown:
        pattern = ".*".join(re.escape(piece) for piece in part.split("..."))
        if re.fullmatch(pattern, out) is not None:
            return True
    return False


def check_print(text: str, *args: object, sep: str = " ", **kwargs: object) -> None:
    """``print(*args)``, and the comparison of its output with ``text`` when ``text`` claims to
    show it (starts with the first word printed)."""
    printed = sep.join(str(a) for a in args)
    print(printed, **kwargs)
    words, claim = printed.split(), text.split()
    if words and claim and claim[0] == words[0]:
        assert output_matches(printed, text), f"printed {printed!r}, the page says {text!r}"


def with_checked_prints(code: str) -> str:
    """``code`` with every one-line ``print(...)  # TEXT`` calling `check_print` instead."""
    return PRINT_WITH_COMMENT.sub(lambda m: f"{m['indent']}__check_print({m['text']!r}, {m['args']})", code)


def runnable_blocks(text: str) -> list[str]:
    """The code of the runnable ```python blocks of a page, in order."""
    return [m["code"] for m in FENCE.finditer(text) if "no-run" not in m["info"]]


PAGES = sorted(
    p for p in [ROOT / "README.md", *DOCS.rglob("*.md")] if runnable_blocks(p.read_text(encoding="utf-8"))
)


def test_fence_parser():
    text = (
        "x\n```python\na = 1\n```\n```{.python .no-run}\nboom()\n```\n"
        "```bash\nls\n```\n```{.python}\nb = 2\n```\n"
    )
    assert runnable_blocks(text) == ["a = 1\n", "b = 2\n"]


def test_printed_values_are_compared_with_the_comment(capsys):
    ns = {"__check_print": check_print}
    exec(with_checked_prints("print(1 + 1, True)   # 2 True\n"), ns)
    exec(with_checked_prints("print([1, 2])  # [1, 2]  both entries\n"), ns)
    exec(with_checked_prints("print('a b c d')  # a ... d\n"), ns)
    exec(with_checked_prints("print(('x', 'y', 'z'))  # ('x', ..., 'z'): the names\n"), ns)
    exec(with_checked_prints("print(3)  # the count of things\n"), ns)  # a description: not compared
    assert capsys.readouterr().out == "2 True\n[1, 2]\na b c d\n('x', 'y', 'z')\n3\n"
    with pytest.raises(AssertionError, match="the page says"):
        exec(with_checked_prints("print(1 + 2, True)   # 3 False\n"), ns)
    with pytest.raises(AssertionError, match="the page says"):
        exec(with_checked_prints("print([1, 3])  # [1, 2]\n"), ns)


def test_strict_build(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    warnings = [line for line in proc.stderr.splitlines() if "WARNING" in line or "ERROR" in line]
    assert proc.returncode == 0, "\n".join(warnings) or proc.stderr[-2000:]
    assert (tmp_path / "site" / "index.html").is_file()
    assert (tmp_path / "site" / "reference" / "plot" / "index.html").is_file()


EXTRAS_MODULES = (
    *("mujoco", "dm_control", "gymnasium", "gymnasium_robotics", "coal", "pinocchio"),
    *("example_robot_data", "viser", "trimesh", "dask", "distributed", "pandas"),
    *("eaik", "pytracik", "pink", "ikpy", "roboticstoolbox"),
)
"""Modules of optik's extras that a docs example may import directly (skipped where absent)."""


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_examples_run(page, tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "__docs__", "__check_print": check_print}
    for i, code in enumerate(runnable_blocks(page.read_text(encoding="utf-8")), 1):
        try:
            exec(
                compile(with_checked_prints(code), f"{page.relative_to(ROOT)} (block {i})", "exec"), namespace
            )
        except MissingExtraError as exc:  # the page shows an extra that this install lacks
            pytest.skip(f"{page.relative_to(ROOT)}, python block {i}: {exc}")
        except ModuleNotFoundError as exc:
            if exc.name not in EXTRAS_MODULES:
                raise
            where = f"{page.relative_to(ROOT)}, python block {i}"
            pytest.skip(f"{where} imports {exc.name} (an extra, not installed)")
        except Exception as exc:
            pytest.fail(f"{page.relative_to(ROOT)}, python block {i} raised {type(exc).__name__}: {exc}")
