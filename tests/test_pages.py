"""README.md and the Performance page quote the stored chapters, the committed benchmark run and
the committed CI timings through generated blocks (tools.pages): the blocks must equal what
those records give, and the pages keep to their size budgets."""
import json
import re
import runpy
from pathlib import Path

import nbformat
import pytest

from tools import pages
from tools.execute import chapter_records, toc_chapters

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"
REWRITE = "rewrite it with: python -m tools.execute --pages"
README_LINES = 130          # the README's budget (150 lines, with room for what comes next)
PERFORMANCE_WORDS = 1500


def _records():
    return chapter_records([NOTEBOOKS / f"{c}.ipynb" for c in toc_chapters(ROOT)])


def test_the_performance_page_shows_the_stored_execution_records():
    chapters = [NOTEBOOKS / f"{c}.ipynb" for c in toc_chapters(ROOT)]
    expected = pages.times_markdown(chapter_records(chapters))
    assert pages.block(ROOT / "book" / "performance.md", "chapter-times") == expected, (
        f"book/performance.md: the chapter times differ from the execution records; {REWRITE}")


def _notebook(path: Path, seconds: float, trained: int, cached: int, glued=()) -> Path:
    record = {"seconds": seconds, "networks_trained": trained, "networks_cached": cached,
              "executed": "2026-11-27T14:00:00+00:00"}
    outputs = [{"output_type": "display_data", "metadata": {"scrapbook": {"name": n}},
                "data": {f"application/papermill.record/{mime}": text}} for n, mime, text in glued]
    cells = [{"cell_type": "code", "execution_count": 1, "id": "a", "metadata": {},
              "outputs": outputs, "source": ""}]
    path.write_text(json.dumps({"cells": cells, "metadata": {"danae": {"execution": record}},
                                "nbformat": 4, "nbformat_minor": 5}))
    return path


def test_update_block_writes_once_and_the_times_add_up(tmp_path):
    nbs = [_notebook(tmp_path / "01_a.ipynb", 8.25, 0, 0),
           _notebook(tmp_path / "02_b.ipynb", 70.0, 0, 4)]
    page = tmp_path / "page.md"
    begin, end = pages.marker_lines("chapter-times")
    page.write_text(f"# P\n\nbefore\n\n{begin}\nold\n{end}\n\nafter\n")
    table = pages.times_markdown(chapter_records(nbs))
    assert pages.update_block(page, "chapter-times", table) is True
    assert pages.update_block(page, "chapter-times", table) is False   # nothing left to change
    text = page.read_text()
    assert text.startswith("# P\n\nbefore\n\n") and text.endswith("\n\nafter\n")
    rows = pages.block(page, "chapter-times").splitlines()
    # a stored run that trained no network is the chapter's warm run, with or without a kept record
    assert rows[2] == "| 01_a | — | | | **8.2** | 0 / 0 | 2026-11-27 14:00 |"   # round half to even
    assert rows[3] == "| 02_b | — | | | **70.0** | 0 / 4 | 2026-11-27 14:00 |"
    assert rows[4] == "| **all chapters** | — | | | **78.2** (1 min 18 s) | | |"
    # a run that trained some networks and found others is neither: the row names it
    partial = chapter_records([_notebook(tmp_path / "03_c.ipynb", 70.0, 2, 4)])
    assert pages.times_markdown(partial).splitlines()[2] == (
        "| 03_c (stored: 70.0 s, 2 / 4, 2026-11-27 14:00) | — | | | — | | |")


def test_a_page_without_its_markers_or_a_chapter_without_a_record_is_refused(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# no markers\n")
    with pytest.raises(ValueError, match="expected one block"):
        pages.block(page, "results")
    bare = tmp_path / "03_c.ipynb"
    bare.write_text(json.dumps({"cells": [], "metadata": {}, "nbformat": 4, "nbformat_minor": 5}))
    with pytest.raises(ValueError, match="03_c.ipynb: no execution record"):
        chapter_records([bare])


def test_each_chapter_states_its_stored_run_time():
    chapters = [NOTEBOOKS / f"{c}.ipynb" for c in toc_chapters(ROOT)]
    for path, (_, record) in zip(chapters, chapter_records(chapters)):
        assert pages.notebook_block(path, "run-time") == pages.run_time_markdown(record), (
            f"{path.name}: its stated run time differs from its execution record; {REWRITE}")


def test_a_notebook_block_is_rewritten_without_touching_code_or_record(tmp_path):
    begin, end = pages.marker_lines("run-time")
    path = _notebook(tmp_path / "05_x.ipynb", 12.0, 1, 2)
    nb = json.loads(path.read_text())
    nb["cells"].insert(0, {"cell_type": "markdown", "id": "m", "metadata": {},
                           "source": f"# 5. X\n\nIntro.\n\n{begin}\nold\n{end}"})
    path.write_text(json.dumps(nb))
    (_, record), = chapter_records([path])
    assert pages.update_notebook_block(path, "run-time", pages.run_time_markdown(record))
    after = nbformat.read(path, as_version=4)
    assert after.cells[1] == nbformat.from_dict(nb["cells"][1])       # the code cell as it was
    assert after.metadata["danae"]["execution"]["seconds"] == 12.0
    assert pages.notebook_block(path, "run-time") == (
        "*Run time*: the stored run of this chapter took 12.0 s on the reference machine "
        "(2 CPU cores, no GPU), with 2 of its 3 trained networks found in the cache; from an "
        "empty cache it trains them all and takes longer (see "
        "[Performance](../book/performance.md)).")
    assert not pages.update_notebook_block(path, "run-time", pages.run_time_markdown(record))


def test_a_cold_record_adds_the_run_from_an_empty_cache_to_the_sentence_and_the_table(tmp_path):
    warm = _notebook(tmp_path / "01_a.ipynb", 20.0, 0, 6)
    nb = json.loads(warm.read_text())
    nb["metadata"]["danae"]["cold_execution"] = {"seconds": 180.0, "networks_trained": 6, "networks_cached": 0,
                                                 "executed": "2026-11-28T00:10:00+00:00"}
    warm.write_text(json.dumps(nb))
    plain = _notebook(tmp_path / "02_b.ipynb", 10.0, 0, 0)
    (_, with_cold), (_, without) = chapter_records([warm, plain])
    assert with_cold["cold"]["seconds"] == 180.0 and "cold" not in without
    assert pages.run_time_markdown(with_cold) == (
        "*Run time*: the stored run of this chapter took 20.0 s on the reference machine (2 CPU cores, "
        "no GPU), with 6 of its 6 trained networks found in the cache; from an empty network cache, "
        "in its last run from scratch (2026-11-28), it took 180.0 s, training 6 networks (see "
        "[Performance](../book/performance.md)).")
    rows = pages.times_markdown([("01_a", with_cold), ("02_b", without)]).splitlines()
    assert rows[2] == "| 01_a | 180.0 | 6 / 0 | 2026-11-28 00:10 | **20.0** | 0 / 6 | 2026-11-27 14:00 |"
    assert rows[3] == "| 02_b | — | | | **10.0** | 0 / 0 | 2026-11-27 14:00 |"
    assert rows[4] == "| **all chapters** | — | | | **30.0** (0 min 30 s) | | |"   # one chapter never ran cold
    both = pages.times_markdown([("01_a", with_cold), ("02_b", {**without, "cold": with_cold["cold"]})])
    assert both.splitlines()[-1] == "| **all chapters** | **360.0** (6 min 0 s) | | | **30.0** (0 min 30 s) | | |"


def test_stored_outputs_from_the_cold_run_still_state_the_warm_run(tmp_path):
    path = _notebook(tmp_path / "03_c.ipynb", 200.0, 6, 2)
    nb = json.loads(path.read_text())
    danae = nb["metadata"]["danae"]
    danae["cold_execution"] = dict(danae["execution"])                    # the stored run ran cold
    danae["warm_execution"] = {"seconds": 50.0, "networks_trained": 0, "networks_cached": 8,
                               "executed": "2026-11-26T10:00:00+00:00"}
    path.write_text(json.dumps(nb))
    (_, record), = chapter_records([path])
    assert pages.run_time_markdown(record) == (
        "*Run time*: the stored outputs of this chapter come from its last run from an "
        "empty network cache (2026-11-27): 200.0 s on the reference machine (2 CPU cores, no GPU), training 6 "
        "networks and finding 2 that earlier chapters trained; with every network in the cache "
        "(2026-11-26) it took 50.0 s (see [Performance](../book/performance.md)).")
    assert pages.times_markdown([("03_c", record)]).splitlines()[2] == (
        "| 03_c | **200.0** | 6 / 2 | 2026-11-27 14:00 | 50.0 | 0 / 8 | 2026-11-26 10:00 |")
    # a chapter without networks says nothing of a warm run: cold and warm do the same work
    plain = _notebook(tmp_path / "01_a.ipynb", 11.0, 0, 0)
    nb = json.loads(plain.read_text())
    nb["metadata"]["danae"]["cold_execution"] = dict(nb["metadata"]["danae"]["execution"])
    plain.write_text(json.dumps(nb))
    (_, record), = chapter_records([plain])
    assert "warm" not in record
    assert pages.run_time_markdown(record) == (
        "*Run time*: the stored outputs of this chapter come from its last run from an "
        "empty network cache (2026-11-27): 11.0 s on the reference machine (2 CPU cores, no GPU) (see "
        "[Performance](../book/performance.md)).")


def test_the_benchmark_table_is_the_committed_benchmark_run():
    report = pages.read_run(ROOT, pages.BENCHMARK_RUN)
    assert pages.block(ROOT / "book" / "performance.md", "benchmark") == pages.benchmark_markdown(report), (
        f"book/performance.md: the benchmark table differs from {pages.BENCHMARK_RUN}; {REWRITE}")
    assert not report["quick"], "the committed benchmark run must be a full run, not --quick"


def test_the_readme_and_the_performance_page_show_the_same_timings_from_the_records():
    expected = pages.timings_markdown(pages.read_run(ROOT, pages.COMMANDS_RUN), _records(),
                                      pages.read_run(ROOT, pages.BENCHMARK_RUN))
    for page in (ROOT / "README.md", ROOT / "book" / "performance.md"):
        assert pages.block(page, "timings") == expected, (
            f"{page.name}: the timings differ from the committed runs; {REWRITE}")


def _report(**overrides):
    machine = {"cpu_model": "Test CPU", "usable_cores": 2, "ram_gib": 23.5, "python": "3.11.7",
               "torch": "2.13.0+cpu", "torch_threads_default": 2,
               "isa": {"cpu": "AVX-512", "torch_capability": "AVX512", "avx2_forced": False},
               "libraries": {"imufusion": "1.3.3", "vqf": "2.1.2"}}
    report = {"date": "2026-11-29T06:00:00+00:00", "quick": False, "total_wall_s": 95.4,
              "machine": machine, "recording": {"samples": 100000, "fs_hz": 100.0},
              "kf_samples_per_s": 987654.3, "paper_epoch_50k_s": 19.66, "predict_100k_s": 4.789}
    return report | overrides


def test_the_benchmark_table_has_a_column_per_instruction_set_path():
    native = pages.benchmark_markdown(_report()).splitlines()
    assert native[0].startswith("Measured on 2026-11-29 by one run of `make bench` (95 s in all) on an "
                                "Test CPU with 2 cores and 24 GiB (the CPU has AVX-512)")
    assert "torch 2.13.0+cpu on 2 threads, imufusion 1.3.3, vqf 2.1.2;" in native[0]
    assert native[2] == "| figure | AVX-512 (native) |"
    assert native[4] == "| KF (`run_kf`, authors' setting) [samples/s] | 987,654 |"
    assert "| one paper epoch over 50,000 windows [s] | 19.7 |" in native
    assert "| Fusion (imufusion, C) [samples/s] | — |" in native           # not measured: a dash
    avx2_machine = {**_report()["machine"], "isa": {"cpu": "AVX-512", "torch_capability": "AVX2",
                                                    "avx2_forced": True}}
    both = pages.benchmark_markdown(_report(avx2_path={"machine": avx2_machine, "kf_samples_per_s": 5.0e5,
                                                       "paper_epoch_50k_s": 30.04})).splitlines()
    assert both[2] == "| figure | AVX-512 (native) | AVX2 (forced) |"
    assert both[3] == "|---|---:|---:|"
    assert "| one paper epoch over 50,000 windows [s] | 19.7 | 30.0 |" in both
    assert len(both) == 4 + len(pages.BENCHMARK_ROWS)


def test_the_timings_table_adds_up_the_chapters_and_says_what_is_not_recorded():
    commands = {"date": "2026-11-29", "commit": "abc1234", "machine": "Test CPU, 2 cores, AVX-512",
                "ci_run_s": 250, "make_test_s": 244, "make_book_s": 5, "tests_passed": 900,
                "tests_skipped": 1}
    cold = {"seconds": 100.0, "executed": "2026-11-29T00:00:00+00:00"}
    records = [("01_a", {"cold": cold, "warm": {"seconds": 20.4}}),
               ("02_b", {"cold": {**cold, "seconds": 30.0}, "warm": {"seconds": 10.0}})]
    rows = pages.timings_markdown(commands, records, _report()).splitlines()
    assert rows[2] == ("| `.ci/run` from a fresh clone | 4 min 10 s | `make test`, then `make book` "
                       "(2026-11-29, commit abc1234, Test CPU, 2 cores, AVX-512) |")
    assert rows[3].startswith("| `make test` (first run: creates `.venv`) | 4 min 4 s |")
    assert rows[3].endswith("(900 passed, 1 skipped) |")
    assert rows[4].startswith("| `make book` | 5 s |")
    assert rows[5].startswith('| `make execute ARGS="--all --cold"` | 2 min 10 s |')
    assert rows[6].startswith("| `make execute ARGS=--all` | 30 s |")
    assert rows[7].startswith("| one paper epoch over 50,000 windows | 20 s |")
    assert rows[8].startswith("| `make bench` | 1 min 35 s |")
    no_warm = pages.timings_markdown(commands, [("01_a", {"cold": cold})], _report()).splitlines()
    assert no_warm[6].startswith("| `make execute ARGS=--all` | not recorded |")


def test_the_ci_log_gives_the_times_and_counts_or_names_what_it_lacks():
    parse_log = runpy.run_path(str(ROOT / "benchmarks" / "ci_times.py"))["parse_log"]
    log = ("real data: DANAE_DATA=/x\n== 12 passed in 3s ==\n"
           "===== 901 passed, 1 skipped, 3 warnings in 240.1s =====\nmake test: 244 s\n"
           "build succeeded.\nmake book: 6 s\n")
    assert parse_log(log) == {"make_test_s": 244, "make_book_s": 6, "tests_passed": 901, "tests_skipped": 1}
    assert parse_log(log.replace(", 1 skipped", ""))["tests_skipped"] == 0
    with pytest.raises(ValueError, match="make book"):
        parse_log(log.replace("make book: 6 s", "make book failed"))


def test_the_readme_and_the_performance_page_keep_to_their_budgets():
    lines = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    assert lines <= README_LINES, f"README.md has {lines} lines, over its budget of {README_LINES}"
    # every whitespace-separated token, as `wc -w` counts: generated tables and commands included
    words = len((ROOT / "book" / "performance.md").read_text(encoding="utf-8").split())
    assert words <= PERFORMANCE_WORDS, (
        f"book/performance.md has {words} words, over its budget of {PERFORMANCE_WORDS}")


# ---- the Verdicts page: one table, its values read from the chapters' stored outputs --------

CROSS_GLUE = re.compile(r"\{glue:text\}`\.\./notebooks/([\w]+)\.ipynb::(\w+)(?::[^`]*)?`")


def glued_names(path: Path) -> set[str]:
    """The names a chapter's stored outputs glue (myst-nb's records)."""
    nb = nbformat.read(path, as_version=4)
    return {o.get("metadata", {}).get("scrapbook", {}).get("name") for c in nb.cells
            if c.cell_type == "code" for o in c.get("outputs", [])} - {None}


def missing_verdict_values(page: Path) -> list[str]:
    """'CHAPTER::KEY' for each value the page quotes that the chapter's stored outputs lack."""
    refs = CROSS_GLUE.findall(page.read_text(encoding="utf-8"))
    chapters = {stem: glued_names(ROOT / "notebooks" / f"{stem}.ipynb") for stem, _ in refs
                if (ROOT / "notebooks" / f"{stem}.ipynb").exists()}
    return [f"{stem}::{key}" for stem, key in refs if key not in chapters.get(stem, set())]


def test_the_verdicts_page_quotes_values_the_chapters_store():
    page = ROOT / "book" / "verdicts.md"
    assert len(CROSS_GLUE.findall(page.read_text(encoding="utf-8"))) >= 20
    assert missing_verdict_values(page) == []


def test_the_verdicts_check_finds_a_value_no_chapter_stores(tmp_path):
    page = tmp_path / "verdicts.md"
    page.write_text("| a | {glue:text}`../notebooks/04_reproduce_paper.ipynb::ch4_red_roll:.1f` % |\n"
                    "| b | {glue:text}`../notebooks/04_reproduce_paper.ipynb::no_such_value:.1f` |\n"
                    "| c | {glue:text}`../notebooks/06_cross_validation.ipynb::no_such_verdict` |\n")
    assert missing_verdict_values(page) == ["04_reproduce_paper::no_such_value",
                                            "06_cross_validation::no_such_verdict"]


def test_the_verdicts_page_is_in_the_table_of_contents():
    assert "file: book/verdicts" in (ROOT / "_toc.yml").read_text()
