"""House rules for what a chapter says on the page: numbers from a run are glued, not typed;
code fits the page; every chapter ends with exercises (solutions behind a toggle) and a summary.

The number rule: a figure in a chapter's prose that equals, at the precision it is written with,
a number its stored outputs print must come from the run through myst-nb ``glue``
(``{glue:text}`name:.3f```), so the prose cannot drift from the outputs and reads correctly
on the simulator too. A number that is a setting or a published value is not a result: it is
allowed when it is written literally in the chapter's code, in ``danae_lite`` or in the paper.
"""
import json
import re
from functools import lru_cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
PAPER = ROOT.parent / "shared" / "reference" / "danae_metrosea2020.tex"
MAX_CODE_LINE = 88

GLUE_ROLE = re.compile(r"\{glue(?::\w+)?\}`[^`]*`")
INLINE_CODE = re.compile(r"`[^`]*`")
MATH = re.compile(r"\$\$.*?\$\$|\$[^$]+\$", re.S)
# section numbers: "## 1.7 Title", "section 6.3", "sections 1.5–1.7", "§2.6"
SECTION = re.compile(r"^#+\s+[\d.]+|(?:[Ss]ections?|[Cc]hapters?|§)\s*\d+(?:\.\d+)*(?:\s*(?:[–-]|and|,)\s*\d+(?:\.\d+)*)*", re.M)
LINK_TARGET = re.compile(r"\]\([^)]*\)|<https?://[^>]*>|https?://\S+")
# a decimal (0.622, 1.3e-3 is written 0.0013 in prose) or an integer carrying a % or ° sign
PROSE_NUMBER = re.compile(r"(?<![\w.])[-+−]?(\d+\.\d+|\d+(?=\s?(?:%|°)))(?![\w.]*\d)")
OUTPUT_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def _cells(path: Path) -> list[dict]:
    return json.loads(path.read_text())["cells"]


def _prose(cell: dict) -> str:
    text = "".join(cell["source"])
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)  # fenced code shown as code
    for pattern in (GLUE_ROLE, INLINE_CODE, MATH, LINK_TARGET, SECTION):
        text = pattern.sub(" ", text)
    return text


def _output_text(cell: dict) -> str:
    parts = []
    for out in cell.get("outputs", []):
        if out.get("output_type") == "stream":
            parts.append("".join(out.get("text", "")))
        for mime in ("text/plain", "text/html", "text/markdown"):
            value = out.get("data", {}).get(mime)
            if value:
                parts.append("".join(value))
    return "\n".join(parts)


def _numbers(text: str) -> set[float]:
    found = set()
    for token in OUTPUT_NUMBER.findall(text):
        try:
            found.add(abs(float(token)))
        except ValueError:
            pass
    return found


@lru_cache(maxsize=None)
def _allowed_literals(path: Path) -> frozenset[str]:
    """Numbers written as literals in the chapter's code, the package or the paper: settings and
    published values, which prose may quote without glue."""
    texts = ["".join(c["source"]) for c in _cells(path) if c["cell_type"] == "code"]
    texts += [p.read_text() for p in sorted((ROOT / "danae_lite").rglob("*.py"))]
    if PAPER.exists():
        texts.append(PAPER.read_text())
    return frozenset(re.findall(r"\d+(?:\.\d+)?", "\n".join(texts)))


def _matches(value: str, computed: set[float]) -> float | None:
    """The computed number that ``value`` is a rounding of, if any."""
    decimals = len(value.split(".")[1]) if "." in value else 0
    target = abs(float(value))
    half = 0.5 * 10.0 ** -decimals
    for v in computed:
        if abs(v - target) <= half * (1 + 1e-9) and v != 0:
            return v
    return None


def unglued_numbers(path: Path) -> list[str]:
    """'cell N: "number" (computed NUMBER) in "...context..."' for each typed number that a
    stored output of the chapter prints."""
    cells = _cells(path)
    computed: set[float] = set()
    for c in cells:
        if c["cell_type"] == "code":
            computed |= _numbers(_output_text(c))
    allowed = _allowed_literals(path)
    problems = []
    for i, c in enumerate(cells):
        if c["cell_type"] != "markdown":
            continue
        prose = _prose(c)
        for m in PROSE_NUMBER.finditer(prose):
            value = m.group(1)
            if value in allowed:
                continue
            hit = _matches(value, computed)
            if hit is not None:
                context = " ".join(prose[max(0, m.start() - 40): m.end() + 20].split())
                problems.append(f'cell {i}: "{value}" (an output prints {hit:g}) in "...{context}..."')
    return problems


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_numbers_from_the_run_are_glued(path):
    problems = unglued_numbers(path)
    assert not problems, (f"{path.name}: numbers typed into the prose that the run computes; insert them "
                          "with myst-nb glue instead:\n" + "\n".join(problems))


def test_the_glue_rule_catches_a_typed_result_and_accepts_a_glued_one(tmp_path):
    nb = {"cells": [
        {"cell_type": "code", "source": ["gain = 0.6221\nprint(f'{gain:.3f} {100 * gain:.1f} %')\nwindow = 0.25"],
         "outputs": [{"output_type": "stream", "name": "stdout", "text": ["0.622 62.2 %\n"]}]},
        {"cell_type": "markdown", "source": ["The gain settles near 0.62, a window of 0.25 s."]},
        {"cell_type": "markdown", "source": ["The gain settles near {glue:text}`gain:.2f`."]},
        {"cell_type": "markdown", "source": ["A 62 % share; $x = 0.62$ in maths, `0.62` as code."]},
        {"cell_type": "markdown", "source": ["Near 0.7, 0.6 or 63 %: none of them is printed."]},
    ]}
    path = tmp_path / "99_probe.ipynb"
    path.write_text(json.dumps(nb))
    problems = unglued_numbers(path)
    # 0.25 is a literal of the code (a setting), the glued and the maths/code values are fine
    assert [p.split(" (")[0] for p in problems] == ['cell 1: "0.62"', 'cell 3: "62"'], problems


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_code_lines_fit_the_page(path):
    long = [(i, n + 1, len(line)) for i, c in enumerate(_cells(path)) if c["cell_type"] == "code"
            for n, line in enumerate("".join(c["source"]).splitlines()) if len(line) > MAX_CODE_LINE]
    assert not long, (f"{path.name}: code lines longer than {MAX_CODE_LINE} characters scroll sideways "
                      f"in the HTML (cell, line, length): {long}")


EXERCISE = re.compile(r"^### Exercise (\d+)\.(\d+)\b", re.M)
SOLUTION = re.compile(r"^:::+\{admonition\} Solution.*?\n:class: dropdown", re.M)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_chapter_ends_with_a_summary_and_exercises_with_solutions(path):
    chapter = int(path.name[:2])
    md = ["".join(c["source"]) for c in _cells(path) if c["cell_type"] == "markdown"]
    heads = [line for text in md for line in text.splitlines() if line.startswith("## ")]
    assert heads[-2:] == ["## Summary", "## Exercises"], f"{path.name}: last sections are {heads[-2:]}"
    text = "\n".join(md[next(i for i, t in enumerate(md) if "## Exercises" in t):])
    found = EXERCISE.findall(text)
    assert 3 <= len(found) <= 5, f"{path.name}: {len(found)} exercises (3 to 5 expected)"
    assert [int(a) for a, _ in found] == [chapter] * len(found), found
    assert [int(b) for _, b in found] == list(range(1, len(found) + 1)), found
    pieces = EXERCISE.split(text)[1:]
    bodies = pieces[2::3]
    for (a, b), body in zip(found, bodies):
        assert SOLUTION.search(body), f"{path.name}: exercise {a}.{b} has no solution behind a toggle"


GLUE_KEY = re.compile(r"\{glue(?::\w+)?\}`([A-Za-z_][A-Za-z0-9_]*)")


def missing_glue_keys(path: Path) -> list[str]:
    """'cell N: key' for each ``{glue...}`key``` in the prose that no stored output glued (the
    book would render it as a warning, and ``-W`` fails the build)."""
    cells = _cells(path)
    glued = {o.get("metadata", {}).get("scrapbook", {}).get("name")
             for c in cells if c["cell_type"] == "code" for o in c.get("outputs", [])}
    return [f"cell {i}: {key}" for i, c in enumerate(cells) if c["cell_type"] == "markdown"
            for key in GLUE_KEY.findall("".join(c["source"])) if key not in glued]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_glued_name_in_the_prose_is_in_the_stored_outputs(path):
    missing = missing_glue_keys(path)
    assert not missing, f"{path.name}: glue references without a stored glue output:\n" + "\n".join(missing)


def test_the_glue_key_check_finds_a_reference_without_output(tmp_path):
    glued = {"output_type": "display_data", "data": {"text/plain": ["1"]},
             "metadata": {"scrapbook": {"name": "ch9_kept", "mime_prefix": ""}}}
    nb = {"cells": [
        {"cell_type": "code", "source": ["glue('ch9_kept', 1)"], "outputs": [glued]},
        {"cell_type": "markdown", "source": ["{glue:text}`ch9_kept:.1f` and {glue:md}`ch9_gone`."]},
    ]}
    path = tmp_path / "99_probe.ipynb"
    path.write_text(json.dumps(nb))
    assert missing_glue_keys(path) == ["cell 1: ch9_gone"]
