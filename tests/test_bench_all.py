"""``optik benchmark all`` (benchmarks/bench_all.py): tables found in printed output, the headline
rows, the README section replaced between its markers, and one real quick benchmark written as a page."""

from __future__ import annotations

import pytest

from optik.benchmarks import available, bench_all_solutions
from optik.benchmarks.bench_all import (
    END,
    RUNS,
    START,
    Run,
    headline,
    main,
    markdown_tables,
    replace_between_markers,
)

OUTPUT = """intro line
| a | b |
|---|--:|
| x | 1 |
a library's message printed between two rows
| all 3 | 2 |

| not a table |

text
| c |
|:-:|
| y |
"""


def test_every_run_is_a_benchmark_and_the_quoted_ones_are_all_there():
    names = [r.name for r in RUNS]
    assert set(names) <= set(available()) and len(set(names)) == len(names)
    for quoted in ("ik", "batch", "all_solutions", "robots", "parallel_fk", "diffik", "first_solve"):
        assert quoted in names


def test_tables_and_headline_rows_are_read_from_the_output():
    tables = markdown_tables(OUTPUT)
    assert tables == [["| a | b |", "|---|--:|", "| x | 1 |", "| all 3 | 2 |"], ["| c |", "|:-:|", "| y |"]]
    assert headline(Run("t", "T", (), (), rows=("| all ",)), OUTPUT) == [
        "| a | b |",
        "|---|--:|",
        "| all 3 | 2 |",
    ]
    assert headline(Run("t", "T", (), (), table=1), OUTPUT) == ["| c |", "|:-:|", "| y |"]
    assert "no table 5" in headline(Run("t", "T", (), (), table=5), OUTPUT)[0]


def test_the_section_between_the_markers_is_replaced_and_the_rest_kept():
    text = f"head\n{START}\nstale 22.0x\n{END}\ntail\n"
    out = replace_between_markers(text, "fresh\n")
    assert out == f"head\n{START}\nfresh\n{END}\ntail\n"
    assert replace_between_markers(out, "again") == f"head\n{START}\nagain\n{END}\ntail\n"
    with pytest.raises(ValueError, match="markers"):
        replace_between_markers("no markers here", "x")


def test_a_quick_sitting_writes_the_page_the_index_and_the_readme(tmp_path, monkeypatch):
    pytest.importorskip("eaik", reason="the all_solutions page compares with EAIK (extra 'peers')")
    monkeypatch.setenv("OPTIK_NO_CODEGEN", "1")  # no C compiler runs in the test suite
    readme = tmp_path / "README.md"
    readme.write_text(f"# x\n{START}\nold figure\n{END}\nend\n", encoding="utf-8")
    out = tmp_path / "measured"
    assert main(["--out", str(out), "--quick", "--only", "all_solutions", "--readme", str(readme)]) == 0
    page = (out / "all_solutions.md").read_text(encoding="utf-8")
    assert "Command: `optik benchmark all_solutions --n 30`" in page and "load average" in page
    assert "commit `" in page and "CPUs" in page
    rows = markdown_tables(page)[0][2:]
    ur = ["ur5", "ur10"] if bench_all_solutions._urdf_path("ur5") is not None else []
    assert [r.split("|")[1].strip() for r in rows] == [*ur, "puma560", "seed_6r_arm"]
    assert all("| 0 | 0 | 0 |" in r for r in rows)  # no duplicates, no failed check, nothing extra
    text = readme.read_text(encoding="utf-8")
    assert "old figure" not in text and text.startswith("# x\n") and text.endswith(f"{END}\nend\n")
    assert "(measured/all_solutions.md)" in text and "| puma560 |" in text
    index = (out / "index.md").read_text(encoding="utf-8")
    assert "(all_solutions.md)" in index and "| seed_6r_arm |" in index


def test_unknown_names_are_refused(tmp_path):
    with pytest.raises(SystemExit):
        main(["--out", str(tmp_path), "--only", "nope"])
