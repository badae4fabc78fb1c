"""Results quoted on the book's pages and in the README come from a stored chapter.

A number with a unit of a result (%, °, rad, deg) written in ``README.md`` or a page of ``book/``
must be printed, at the precision it is written with, by a stored output of some chapter, or be
a published value (the paper) or a setting (a literal of ``danae_lite``). Text between the
``<!-- begin NAME -->`` markers is written from the stored chapters by ``tools.pages`` and
checked by ``tests/test_pages.py``. ``book/performance.md`` is left out: its numbers are
measurements of the machine (seconds, steps per second), each beside the command that gives it,
not results of the chapters; its chapter times are such a generated block.
"""
import json
import re
from functools import lru_cache
from pathlib import Path

import pytest

from test_notebook_prose import NOTEBOOKS, PAPER, ROOT, _matches, _numbers, _output_text

PAGES = [ROOT / "README.md"] + sorted(p for p in (ROOT / "book").glob("*.md")
                                      if p.name != "performance.md")
QUOTED = re.compile(r"(?<![\w.])[-+−]?(\d+(?:\.\d+)?)\s?(?:%|°|rad\b|deg\b)")


@lru_cache(maxsize=None)
def _printed() -> frozenset[float]:
    found: set[float] = set()
    for path in NOTEBOOKS:
        for cell in json.loads(path.read_text())["cells"]:
            found |= _numbers(_output_text(cell))
    return frozenset(found)


@lru_cache(maxsize=None)
def _allowed() -> frozenset[str]:
    texts = [p.read_text() for p in sorted((ROOT / "danae_lite").rglob("*.py"))]
    if PAPER.exists():
        texts.append(PAPER.read_text())
    return frozenset(re.findall(r"\d+(?:\.\d+)?", "\n".join(texts)))


def unbacked_numbers(text: str) -> list[str]:
    """'NUMBER in "...context..."' for each quoted result that no stored output prints and that
    is no published value or setting."""
    text = re.sub(r"^```.*?^```", " ", text, flags=re.S | re.M)            # code blocks
    text = re.sub(r"<!-- begin ([\w-]+).*?<!-- end \1 -->", " ", text, flags=re.S)
    text = re.sub(r"`[^`]*`", " ", text)
    problems = []
    for m in QUOTED.finditer(text):
        value = m.group(1)
        if value in _allowed() or _matches(value, set(_printed())) is not None:
            continue
        problems.append(f'{value} in "...{" ".join(text[max(0, m.start() - 50):m.end() + 10].split())}..."')
    return problems


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_results_quoted_on_a_page_come_from_a_stored_chapter(page):
    problems = unbacked_numbers(page.read_text(encoding="utf-8"))
    assert not problems, (f"{page.name}: numbers that no stored chapter prints and that are neither "
                          "published nor settings (quote them from a chapter, or generate the "
                          "sentence with tools.pages):\n" + "\n".join(problems))


def test_the_check_flags_a_typed_result_and_accepts_a_generated_one():
    begin, end = "<!-- begin results: x -->", "<!-- end results -->"
    text = f"DANAE lowers roll by 97.13 %.\n{begin}\nby 97.13 %\n{end}\n`12.5 %` in code."
    assert [p.split(" in ")[0] for p in unbacked_numbers(text)] == ["97.13"]
