"""``optik benchmark all`` (benchmarks/bench_all.py): tables found in printed output, the headline
rows, the README section replaced between its markers, and one real quick benchmark written as a page."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from optik.benchmarks import available, bench_all_solutions, peer_arms
from optik.benchmarks.bench_all import (
    END,
    RUNS,
    START,
    Outcome,
    Run,
    headline,
    main,
    markdown_tables,
    page,
    read_pages,
    replace_between_markers,
    spaced_tables,
    summary,
    write_atomic,
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


QUOTED = (
    *("ik", "batch", "all_solutions", "robots", "parallel_fk", "diffik", "first_solve", "closed_form"),
    *("path", "view", "general_6r", "search_1d", "two_hands", "collision", "mjcf_fk", "time_limits"),
)
"""The benchmarks whose figures README and docs quote (docs/benchmarks.md, the solver pages)."""


def test_every_run_is_a_benchmark_and_the_quoted_ones_are_all_there():
    names, keys = {r.name for r in RUNS}, [r.key for r in RUNS]
    assert names <= set(available()) and len(set(keys)) == len(keys)
    assert set(QUOTED) <= names
    assert {"balance_g1", "balance_go2"} <= set(keys)  # one benchmark, two pages


def test_every_option_a_run_passes_is_one_its_script_defines():
    # read from the script's source (importing the scripts changes process-wide state)
    folder = Path(bench_all_solutions.__file__).parent
    for run in RUNS:
        source = (folder / f"bench_{run.name}.py").read_text(encoding="utf-8")
        defined = set(re.findall(r"add_argument\(\s*\"(--[a-z0-9-]+)\"", source))
        passed = {a for a in (*run.full, *run.quick) if a.startswith("--")}
        assert passed <= defined, (run.key, passed - defined)


def _outcome(run: Run, output: str, code: int = 0) -> Outcome:
    return Outcome(
        run, f"optik benchmark {run.name} --n 1", output, code, 3.0, "1.0 2.0 3.0", "4.0 5.0 6.0", "D"
    )


def test_the_index_holds_every_page_of_the_folder_each_with_its_own_run(tmp_path, capsys):
    first, second, absent = RUNS[0], RUNS[2], RUNS[1]
    (tmp_path / f"{first.key}.md").write_text(page(_outcome(first, OUTPUT), "abc1234"), encoding="utf-8")
    (tmp_path / f"{second.key}.md").write_text(page(_outcome(second, OUTPUT, 1), "def5678"), encoding="utf-8")
    (tmp_path / f"{RUNS[3].key}.md").write_text("# hand-made page\n| a |\n|---|\n", encoding="utf-8")
    entries = read_pages(tmp_path)
    assert [e.run.key for e in entries] == [first.key, second.key]  # the order of RUNS
    assert "does not read back" in capsys.readouterr().err  # the hand-made page, left out and said
    assert (entries[0].commit, entries[0].load_before, entries[0].code) == ("abc1234", "1.0 2.0 3.0", 0)
    assert entries[1].code == 1 and entries[0].command == f"optik benchmark {first.name} --n 1"
    text = summary(entries, "optik benchmark all --out x", "measured/")
    assert f"([full output](measured/{first.key}.md)); run D, commit `abc1234`" in text
    assert "load average 1.0 2.0 3.0 before, 4.0 5.0 6.0 after, 3 s; exit code 1" in text
    assert "The 2 runs took 6 s together." in text
    assert text.count("| x | 1 |") == 2 and "| all 3 | 2 |" in text and absent.title not in text


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


def test_a_table_right_under_its_caption_gets_a_blank_line_and_a_message_inside_one_does_not():
    text = "caption\n| a |\n|---|\n| 1 |\na message\n| 2 |\n\n| b |\n|--:|\n"
    assert spaced_tables(text) == "caption\n\n| a |\n|---|\n| 1 |\na message\n| 2 |\n\n| b |\n|--:|"
    assert markdown_tables(spaced_tables(text)) == markdown_tables(text)


def test_the_section_between_the_markers_is_replaced_and_the_rest_kept():
    text = f"head\n{START}\nstale 22.0x\n{END}\ntail\n"
    out = replace_between_markers(text, "fresh\n")
    assert out == f"head\n{START}\nfresh\n{END}\ntail\n"
    assert replace_between_markers(out, "again") == f"head\n{START}\nagain\n{END}\ntail\n"
    with pytest.raises(ValueError, match="markers"):
        replace_between_markers("no markers here", "x")


def test_pages_get_the_mode_of_a_plain_write(tmp_path):
    plain = tmp_path / "plain.md"
    plain.write_text("x", encoding="utf-8")
    page = tmp_path / "sub" / "page.md"
    write_atomic(page, "fresh")
    assert page.read_text(encoding="utf-8") == "fresh"
    assert page.stat().st_mode & 0o777 == plain.stat().st_mode & 0o777  # not mkstemp's 0600
    assert [p.name for p in page.parent.iterdir()] == ["page.md"]


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
    ur = ["ur5", "ur10"] if peer_arms.urdf_path("ur5") is not None else []
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
