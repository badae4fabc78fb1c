"""README.md and the Performance page quote the stored chapters through generated blocks
(danae_lite.pages): the blocks must equal what the stored notebooks give."""
import json
from pathlib import Path

import nbformat
import pytest

from danae_lite import pages
from danae_lite.execute import chapter_records, toc_chapters

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"
REWRITE = "rewrite it with: python -m danae_lite.execute --pages"


def test_the_performance_page_shows_the_stored_execution_records():
    chapters = [NOTEBOOKS / f"{c}.ipynb" for c in toc_chapters(ROOT)]
    expected = pages.times_markdown(chapter_records(chapters))
    assert pages.block(ROOT / "book" / "performance.md", "chapter-times") == expected, (
        f"book/performance.md: the chapter times differ from the execution records; {REWRITE}")


def _quoted_chapters():
    return [nbformat.read(NOTEBOOKS / f"{c}.ipynb", as_version=4) for c in pages.RESULTS_CHAPTERS]


def test_the_readme_quotes_chapters_9_and_10_as_stored():
    assert pages.block(ROOT / "README.md", "results") == pages.results_markdown(_quoted_chapters()), (
        f"README.md: the DANAE-res results differ from the stored chapters 9 and 10; {REWRITE}")


def test_every_field_of_the_readme_template_is_glued_by_chapters_9_and_10():
    from danae_lite.book import fields
    glued = {k for nb in _quoted_chapters() for k in pages.glued_values(nb)}
    missing = set(fields(pages.RESULTS)) - glued
    assert not missing, f"fields of pages.RESULTS that chapters 9 and 10 do not glue: {sorted(missing)}"


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


def test_glued_values_reads_numbers_text_and_markdown(tmp_path):
    path = _notebook(tmp_path / "06_x.ipynb", 1.0, 0, 0, glued=[
        ("ch9_rmse", "text/plain", "0.0232"), ("ch9_wins", "text/plain", "'3 of 4'"),
        ("ch9_n", "text/plain", "11"), ("ch9_name", "text/markdown", "`vqf`")])
    values = pages.glued_values(nbformat.read(path, as_version=4))
    assert values == {"ch9_rmse": 0.0232, "ch9_wins": "3 of 4", "ch9_n": 11, "ch9_name": "`vqf`"}


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
