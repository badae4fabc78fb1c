"""House rules for what a chapter says on the page: numbers from a run are glued, not typed;
code fits the page; every chapter ends with exercises (solutions behind a toggle) and a summary.

A chapter's prose is its Markdown cells and the templates of its ``prose(...)`` cells
(:func:`danae_lite.book.prose`: Markdown whose ``{name:.3f}`` fields are filled with values
glued earlier in the run; the book removes the cell's input and JupyterLab collapses it, so
both show the filled Markdown).

The number rule: a figure in a chapter's prose that equals, at the precision it is written with,
a number its stored outputs print must come from the run through a glued field, so the prose
cannot drift from the outputs and reads correctly on the simulator too. A number that is a
setting or a published value is not a result: it is allowed when it is written literally in the
chapter's code, in ``danae_lite`` or in the paper.
"""
import ast
import io
import json
import re
import string
import tokenize
from functools import lru_cache
from pathlib import Path

import pytest

from danae_lite.book import VERBATIM

ROOT = Path(__file__).resolve().parents[1]


def fields(template: str) -> list[str]:
    """The names of the fields of a prose() template outside code and maths, in order."""
    return [name for text in VERBATIM.split(template)[::2] for _, name, _, _ in string.Formatter().parse(text)
            if name]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
PAPER = ROOT.parent / "shared" / "reference" / "danae_metrosea2020.tex"
MAX_CODE_LINE = 88

FIELD = re.compile(r"\{[A-Za-z_]\w*(?:![rsa])?(?::[^{}]*)?\}")
INLINE_CODE = re.compile(r"`[^`]*`")
MATH = re.compile(r"\$\$.*?\$\$|\$[^$]+\$", re.S)
# section and exercise numbers: "## 1.7 Title", "section 6.3", "sections 1.5–1.7", "§2.6",
# "Exercise 9.3"
SECTION = re.compile(r"^#+\s+[\d.]+|(?:[Ss]ections?|[Cc]hapters?|[Ee]xercises?|§)\s*\d+(?:\.\d+)*(?:\s*(?:[–-]|and|,)\s*\d+(?:\.\d+)*)*", re.M)
LINK_TARGET = re.compile(r"\]\([^)]*\)|<https?://[^>]*>|https?://\S+")
# a decimal (0.622, 1.3e-3 is written 0.0013 in prose) or an integer carrying a % or ° sign
PROSE_NUMBER = re.compile(r"(?<![\w.])[-+−]?(\d+\.\d+|\d+(?=\s?(?:%|°)))(?![\w.]*\d)")
OUTPUT_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def _cells(path: Path) -> list[dict]:
    return json.loads(path.read_text())["cells"]


def templates(cell: dict) -> list[str]:
    """The Markdown templates of the ``prose(...)`` calls of a code cell (none for other cells)."""
    if cell["cell_type"] != "code" or "prose(" not in "".join(cell["source"]):
        return []
    tree = ast.parse("".join(cell["source"]))
    return [node.args[0].value for node in ast.walk(tree)
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "prose"
            and node.args and isinstance(node.args[0], ast.Constant)]


def prose_keywords(cell: dict) -> set[str]:
    """The names a code cell's ``prose(template, name=value, ...)`` calls glue themselves."""
    if cell["cell_type"] != "code" or "prose(" not in "".join(cell["source"]):
        return set()
    return {kw.arg for node in ast.walk(ast.parse("".join(cell["source"])))
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "prose"
            for kw in node.keywords if kw.arg}


def markdown_outputs(cell: dict) -> list[str]:
    """The Markdown outputs a reader sees (glue's records carry another MIME type)."""
    return ["".join(o["data"]["text/markdown"]) for o in cell.get("outputs", [])
            if "text/markdown" in o.get("data", {})]


def markdown_of(cell: dict) -> str:
    """The Markdown a reader sees of a cell as written: a Markdown cell's source, the templates
    of a prose cell, nothing for other cells."""
    if cell["cell_type"] == "markdown":
        return "".join(cell["source"])
    return "\n\n".join(templates(cell))


GENERATED_BLOCK = re.compile(r"<!-- begin ([\w-]+):.*?<!-- end \1 -->", re.S)


def _prose(cell: dict) -> str:
    text = markdown_of(cell)
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)  # fenced code shown as code
    text = GENERATED_BLOCK.sub(" ", text)  # written from the execution record (tools.pages)
    for pattern in (FIELD, INLINE_CODE, MATH, LINK_TARGET, SECTION):
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
    texts = ["".join(c["source"]) for c in _cells(path)
             if c["cell_type"] == "code" and not templates(c)]
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
        if c["cell_type"] == "code" and not templates(c):   # a prose cell prints its template
            computed |= _numbers(_output_text(c))
    allowed = _allowed_literals(path)
    problems = []
    for i, c in enumerate(cells):
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
                          "with a glued field of prose() instead:\n" + "\n".join(problems))


def test_the_glue_rule_catches_a_typed_result_and_accepts_a_glued_one(tmp_path):
    nb = {"cells": [
        {"cell_type": "code", "source": ["gain = 0.6221\nprint(f'{gain:.3f} {100 * gain:.1f} %')\nwindow = 0.25"],
         "outputs": [{"output_type": "stream", "name": "stdout", "text": ["0.622 62.2 %\n"]}]},
        {"cell_type": "markdown", "source": ["The gain settles near 0.62, a window of 0.25 s."]},
        {"cell_type": "code", "source": ['prose(r"""The gain settles near {gain:.2f}.""")'],
         "outputs": [{"output_type": "display_data",
                      "data": {"text/markdown": ["The gain settles near 0.62."]}}]},
        {"cell_type": "markdown", "source": ["A 62 % share; $x = 0.62$ in maths, `0.62` as code."]},
        {"cell_type": "markdown", "source": ["Near 0.7, 0.6 or 63 %: none of them is printed."]},
        {"cell_type": "code", "source": ['prose(r"""Typed: 0.622, glued: {gain:.3f}.""")'],
         "outputs": [{"output_type": "display_data",
                      "data": {"text/markdown": ["Typed: 0.622, glued: 0.622."]}}]},
    ]}
    path = tmp_path / "99_probe.ipynb"
    path.write_text(json.dumps(nb))
    problems = unglued_numbers(path)
    # 0.25 is a literal of the code (a setting), the glued and the maths/code values are fine
    assert [p.split(" (")[0] for p in problems] == ['cell 1: "0.62"', 'cell 3: "62"',
                                                     'cell 5: "0.622"'], problems


def shown_code(cell: dict) -> str:
    """The code a reader sees: a code cell's input unless the book removes it, and the fenced
    code blocks of the cell's Markdown (solutions, command lines)."""
    shown = "\n".join(re.findall(r"^```.*?^```", markdown_of(cell), flags=re.S | re.M))
    removed = "remove-input" in cell.get("metadata", {}).get("tags", [])
    if cell["cell_type"] == "code" and not removed:
        shown = "".join(cell["source"]) + "\n" + shown
    return shown


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_code_lines_fit_the_page(path):
    long = [(i, n + 1, len(line)) for i, c in enumerate(_cells(path))
            for n, line in enumerate(shown_code(c).splitlines()) if len(line) > MAX_CODE_LINE]
    assert not long, (f"{path.name}: code lines longer than {MAX_CODE_LINE} characters scroll sideways "
                      f"in the HTML (cell, line, length): {long}")


EXERCISE = re.compile(r"^### Exercise (\d+)\.(\d+)\b", re.M)
SOLUTION = re.compile(r"^<details>\n<summary>Solution</summary>", re.M)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_chapter_ends_with_a_summary_and_exercises_with_solutions(path):
    chapter = int(path.name[:2])
    md = [markdown_of(c) for c in _cells(path) if markdown_of(c)]
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


def missing_glue_keys(path: Path) -> list[str]:
    """'cell N: name' for each field of a prose template that no earlier stored output glued (the
    cell would have failed; a stored chapter with it is stale)."""
    glued: set[str] = set()
    missing = []
    for i, c in enumerate(_cells(path)):
        own = {o.get("metadata", {}).get("scrapbook", {}).get("name") for o in c.get("outputs", [])}
        # a prose cell may glue its values itself: prose(template, name=value), or glue() calls
        # above it in the same cell (its stored outputs hold them, the run having succeeded)
        given = glued | own | prose_keywords(c)
        missing += [f"cell {i}: {name}" for t in templates(c) for name in fields(t)
                    if name not in given]
        glued |= own
    return missing


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_field_of_the_prose_was_glued_before_it(path):
    missing = missing_glue_keys(path)
    assert not missing, f"{path.name}: prose fields without an earlier glue output:\n" + "\n".join(missing)


def test_the_glue_key_check_finds_a_field_without_output(tmp_path):
    glued = {"output_type": "display_data", "data": {"text/plain": ["1"]},
             "metadata": {"scrapbook": {"name": "ch9_kept", "mime_prefix": ""}}}
    nb = {"cells": [
        {"cell_type": "code", "source": ["glue('ch9_kept', 1)"], "outputs": [glued]},
        {"cell_type": "code", "source": ['prose(r"""{ch9_kept:.1f} and {ch9_gone}, $x_{t}$.""")'],
         "outputs": []},
        {"cell_type": "code", "source": ['prose(r"""{ch9_kept} {ch9_own:.2f} {ch9_none}""", ch9_own=1.0)'],
         "outputs": []},
    ]}
    path = tmp_path / "99_probe.ipynb"
    path.write_text(json.dumps(nb))
    assert missing_glue_keys(path) == ["cell 1: ch9_gone", "cell 2: ch9_none"]


def _shows(cell: dict) -> list[str]:
    """'figure' / 'table' for each figure or table a reader sees among a code cell's outputs."""
    tags = cell.get("metadata", {}).get("tags", [])
    if cell["cell_type"] != "code" or templates(cell) or {"hide-cell", "hide-output",
                                                          "remove-output"} & set(tags):
        return []
    kinds = []
    for out in cell.get("outputs", []):
        data = out.get("data", {})
        if "image/png" in data or "image/svg+xml" in data:
            kinds.append("figure")
        elif "text/html" in data:
            kinds.append("table")
    return kinds


def unexplained_outputs(path: Path) -> list[str]:
    """'cell N: figure' for each figure or table that no prose follows before the next heading:
    every table and figure is followed by what it shows."""
    cells = _cells(path)
    problems = []
    for i, cell in enumerate(cells):
        kinds = _shows(cell)
        if not kinds:
            continue
        for later in cells[i + 1:]:
            text = markdown_of(later).strip()
            if text.startswith("#"):
                break                                   # the next section begins
            if text:
                break
        else:
            text = ""
        if not text or text.startswith("#"):
            problems.append(f"cell {i}: {' and '.join(sorted(set(kinds)))}")
    return problems


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_table_and_figure_is_followed_by_what_it_shows(path):
    problems = unexplained_outputs(path)
    assert not problems, (f"{path.name}: tables or figures with no prose after them before the "
                          "next heading:\n" + "\n".join(problems))


def test_the_explanation_check_finds_a_figure_left_alone(tmp_path):
    png = {"output_type": "display_data", "data": {"image/png": "iVBOR"}}
    html = {"output_type": "execute_result", "data": {"text/html": ["<table></table>"]}}
    nb = {"cells": [
        {"cell_type": "code", "metadata": {}, "source": ["plot()"], "outputs": [png]},
        {"cell_type": "markdown", "metadata": {}, "source": ["## Next section"]},
        {"cell_type": "code", "metadata": {}, "source": ["table()"], "outputs": [html]},
        {"cell_type": "code", "metadata": {}, "source": ["x = 1"], "outputs": []},
        {"cell_type": "markdown", "metadata": {}, "source": ["The table shows it."]},
        {"cell_type": "code", "metadata": {"tags": ["hide-cell"]}, "source": ["plot()"],
         "outputs": [png]},
    ]}
    path = tmp_path / "99_probe.ipynb"
    path.write_text(json.dumps(nb))
    assert unexplained_outputs(path) == ["cell 0: figure"]



# ---- chapter size: every chapter stays readable in one sitting ------------------------------

MARKDOWN_TABLE = re.compile(r"^\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)+\|?\s*$", re.M)
PARTS = {"I": range(1, 5), "II": range(5, 7), "III": range(7, 9)}
"""The book's three parts by chapter number: the tutorial, checking the paper, beyond the paper."""
PART_LIMITS = {"I": (4000, 10), "II": (2500, 8), "III": (2500, 8)}
"""Words and tables (before the exercises) a chapter of each part may show its reader."""


def part_of(path: Path) -> str:
    """The part ('I', 'II' or 'III') a chapter belongs to, from its number."""
    number = int(path.name[:2])
    return next(part for part, numbers in PARTS.items() if number in numbers)


def reader_size(path: Path) -> tuple[int, int]:
    """The size of a chapter as its reader meets it: words of its Markdown cells and stored
    Markdown outputs, split on whitespace, without fenced code, HTML tags and comments; tables:
    every Markdown table and every DataFrame or HTML table shown before the exercises."""
    words = tables = 0
    in_exercises = False
    for cell in _cells(path):
        texts = (["".join(cell["source"])] if cell["cell_type"] == "markdown" else []) + markdown_outputs(cell)
        for text in texts:
            in_exercises = in_exercises or text.lstrip().startswith("## Exercises")
            text = re.sub(r"^```.*?^```", " ", text, flags=re.S | re.M)
            text = re.sub(r"<!--.*?-->|<[^>]+>", " ", text, flags=re.S)
            words += len(text.split())
            if not in_exercises:
                tables += len(MARKDOWN_TABLE.findall(text))
        if not in_exercises and cell["cell_type"] == "code" and not (
                {"hide-cell", "hide-output", "remove-output", "remove-cell"} & _tags(cell)):
            tables += sum("<table" in "".join(o.get("data", {}).get("text/html", ""))
                          for o in cell.get("outputs", []))
    return words, tables


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_a_chapter_fits_the_size_of_its_part(path):
    words, tables = reader_size(path)
    max_words, max_tables = PART_LIMITS[part_of(path)]
    assert words <= max_words and tables <= max_tables, (
        f"{path.name} (part {part_of(path)}): {words} words and {tables} tables "
        f"(at most {max_words} and {max_tables})")


def test_every_chapter_belongs_to_a_part():
    assert [part_of(p) for p in NOTEBOOKS] == sorted(part_of(p) for p in NOTEBOOKS)


def test_the_reader_size_counts_markdown_outputs_and_tables_but_not_code(tmp_path):
    html = {"output_type": "execute_result", "data": {"text/html": ["<table><tr><td>1</td></tr></table>"]}}
    md_out = {"output_type": "display_data", "data": {"text/markdown": ["Four *words* here <b>now</b>."]}}
    nb = {"cells": [
        {"cell_type": "markdown", "metadata": {}, "source": ["# Title\n\n| a | b |\n|---|---:|\n| 1 | 2 |\n"
                                                             "```python\nx = 1 + 2\n```\n<!-- not counted -->"]},
        {"cell_type": "code", "metadata": {}, "source": ["df"], "outputs": [html, md_out]},
        {"cell_type": "code", "metadata": {"tags": ["hide-cell"]}, "source": ["df"], "outputs": [html]},
        {"cell_type": "markdown", "metadata": {}, "source": ["## Exercises\n\n| x | y |\n|---|---|\n"]},
    ]}
    path = tmp_path / "01_probe.ipynb"
    path.write_text(json.dumps(nb))
    # words: "# Title" 2 + table 10 ("|" counts) + 5 from the output + exercises 2 + 8
    assert reader_size(path) == (len("# Title | a | b | |---|---:| | 1 | 2 |".split()) + 5
                                 + len("## Exercises | x | y | |---|---|".split()), 2)


PYTHON_FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def shown_code_problems(text: str) -> list[str]:
    """For each ``from danae_lite... import NAME`` or ``import danae_lite...`` in the Python code
    that Markdown ``text`` shows (fenced ``python`` blocks, which the reader copies but nothing
    runs), what fails to import: the module or the name."""
    import importlib

    problems = []
    for block in PYTHON_FENCE.findall(text):
        for node in ast.walk(ast.parse(block)):
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "danae_lite":
                targets = [(node.module, alias.name) for alias in node.names]
            elif isinstance(node, ast.Import):
                targets = [(alias.name, None) for alias in node.names if alias.name.startswith("danae_lite")]
            else:
                continue
            for module, name in targets:
                try:
                    found = importlib.import_module(module)
                except ImportError:
                    problems.append(f"no module {module}")
                    continue
                if name is not None and not hasattr(found, name):
                    try:
                        importlib.import_module(f"{module}.{name}")
                    except ImportError:
                        problems.append(f"{module} has no {name}")
    return problems


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_code_shown_in_the_prose_imports_what_exists(path):
    problems = [f"cell {i}: {p}" for i, cell in enumerate(_cells(path))
                for p in shown_code_problems(markdown_of(cell))]
    assert not problems, f"{path.name}: code shown to the reader imports what does not exist:\n" + "\n".join(problems)


def test_the_shown_code_check_finds_a_wrong_import():
    text = ("```python\nfrom danae_lite.danae.train import predict\nfrom danae_lite import alignment\n"
            "from danae_lite.danae.predict import predict\nimport numpy as np\n```\n"
            "```bash\nfrom danae_lite import nothing\n```")
    assert shown_code_problems(text) == ["danae_lite.danae.train has no predict",
                                         "danae_lite has no alignment"]


# ---- exercises a student does, figures with captions ------------------------------------------

CAPTION = re.compile(r"\*Figure (\d+)\.(\d+) — \S.*\*", re.S)
MIN_ALT = 40       # characters of alt text: a sentence, not a word


def _tags(cell: dict) -> set[str]:
    return set(cell.get("metadata", {}).get("tags", []))


def figure_problems(path: Path) -> list[str]:
    """What is wrong with the figures of a chapter: each image output must be followed, in the
    same cell, by its caption ``*Figure N.K — ...*`` (numbered in order within the chapter), the
    cell must carry alt text (``metadata.mystnb.image.alt``), and the chapter's prose must refer
    to each figure by its label."""
    chapter, number, problems, labels = int(path.name[:2]), 0, [], []
    cells = _cells(path)
    for i, cell in enumerate(cells):
        outputs = cell.get("outputs", [])
        for k, out in enumerate(outputs):
            if "image/png" not in out.get("data", {}):
                continue
            number += 1
            label = f"Figure {chapter}.{number}"
            labels.append(label)
            following = outputs[k + 1].get("data", {}).get("text/markdown", "") if k + 1 < len(outputs) else ""
            m = CAPTION.fullmatch("".join(following).strip())
            if not m or (int(m.group(1)), int(m.group(2))) != (chapter, number):
                problems.append(f"cell {i}: the figure is not followed by the caption '*{label} — ...*'")
            alt = cell.get("metadata", {}).get("mystnb", {}).get("image", {}).get("alt", "")
            if len(alt.strip()) < MIN_ALT:
                problems.append(f"cell {i}: {label} has no alt text (metadata.mystnb.image.alt)")
    prose_text = "\n".join(markdown_of(c) + "\n".join(markdown_outputs(c)) for c in cells
                           if not (c["cell_type"] == "code" and "image/png" in json.dumps(c.get("outputs", []))))
    problems += [f"{label} is never referred to in the prose" for label in labels
                 if not re.search(rf"\b{re.escape(label)}\b", prose_text)]
    return problems


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_every_figure_has_a_numbered_caption_alt_text_and_a_reference(path):
    problems = figure_problems(path)
    assert not problems, f"{path.name}:\n" + "\n".join(problems)


def exercise_problems(path: Path) -> list[str]:
    """What is wrong with a chapter's exercises: after ``## Exercises`` come only statements and
    what follows each: ``### Exercise N.K`` → an empty code cell for the student → the solution's
    code in cells behind a toggle (``hide-cell``) with a visible output → the answer behind a
    ``<details>`` Solution toggle, with numbers; no code shown in Markdown that nothing runs."""
    cells = _cells(path)
    start = next(i for i, c in enumerate(cells) if markdown_of(c).lstrip().startswith("## Exercises"))
    heads = [i for i, c in enumerate(cells) if c["cell_type"] == "markdown"
             and EXERCISE.match("".join(c["source"]).lstrip())]
    problems = [f"cell {i}: code before the first exercise" for i in range(start, heads[0])
                if cells[i]["cell_type"] == "code"]
    for n, h in enumerate(heads):
        name = EXERCISE.match("".join(cells[h]["source"]).lstrip()).group(0).lstrip("# ")
        body = cells[h + 1:heads[n + 1] if n + 1 < len(heads) else len(cells)]
        if not body or body[0]["cell_type"] != "code" or "".join(body[0]["source"]).strip():
            problems.append(f"{name}: not followed by an empty code cell for the student")
            continue
        solution = [c for c in body[1:] if c["cell_type"] == "code" and "hide-cell" in _tags(c)]
        shown = [o for c in solution for o in c.get("outputs", [])
                 if not o.get("metadata", {}).get("scrapbook")]
        if not solution or not shown:
            problems.append(f"{name}: no solution code behind a toggle (hide-cell) with a visible output")
        answers = ["\n".join(markdown_outputs(c)) for c in body[1:] if SOLUTION.search(markdown_of(c))]
        if not answers or not re.search(r"\d", answers[-1]):
            problems.append(f"{name}: no answer with numbers behind a <details> Solution toggle")
        if any(PYTHON_FENCE.search(markdown_of(c)) for c in body):
            problems.append(f"{name}: shows code in Markdown; put it in the solution's code cell")
        if any(c["cell_type"] == "code" and not ({"hide-cell", "remove-input"} & _tags(c))
               for c in body[1:]):
            problems.append(f"{name}: a solution cell the reader sees unfolded")
    return problems


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_each_exercise_leaves_the_student_a_cell_and_solves_after_it(path):
    problems = exercise_problems(path)
    assert not problems, f"{path.name}:\n" + "\n".join(problems)


# ---- bookkeeping out of sight ---------------------------------------------------------------------

HIDING = {"remove-input", "hide-input", "hide-cell", "remove-cell"}
SENTENCE_CALL = re.compile(r"(?<![\w.])(glue|prose|Markdown)\(")
MAX_LOGIC_LINES = 200          # in all chapters together
LOGIC_TAGS = {"remove-input", "hide-input", "remove-cell"}


def visible_bookkeeping(path: Path) -> list[str]:
    """'cell N' for each code cell the reader sees (no hiding tag) that builds sentences: it
    calls ``glue``, ``prose`` or ``Markdown``."""
    return [f"cell {i}" for i, c in enumerate(_cells(path)) if c["cell_type"] == "code"
            and not (HIDING & _tags(c)) and SENTENCE_CALL.search("".join(c["source"]))]


def without_long_strings(source: str) -> str:
    """``source`` with each string literal that spans several lines replaced by ``""`` (its
    opening and closing lines join: ``prose(r\"\"\"...\"\"\", a=v)`` becomes ``prose("", a=v)``)."""
    starts = [0]
    for line in source.splitlines(keepends=True):
        starts.append(starts[-1] + len(line))
    spans = [(starts[t.start[0] - 1] + t.start[1], starts[t.end[0] - 1] + t.end[1])
             for t in tokenize.generate_tokens(io.StringIO(source).readline)
             if t.type == tokenize.STRING and t.start[0] != t.end[0]]
    for begin, end in reversed(spans):
        source = source[:begin] + '""' + source[end:]
    return source


def logic_lines(path: Path) -> int:
    """The chapter's hidden logic: non-blank, non-comment lines outside multi-line string
    literals, in the code cells tagged remove-input, hide-input or remove-cell."""
    return sum(1 for c in _cells(path) if c["cell_type"] == "code" and LOGIC_TAGS & _tags(c)
               for line in without_long_strings("".join(c["source"])).splitlines()
               if line.strip() and not line.strip().startswith("#"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_no_cell_the_reader_sees_builds_sentences(path):
    cells = visible_bookkeeping(path)
    assert not cells, (f"{path.name}: cells without a hiding tag call glue, prose or Markdown (move "
                       f"the sentence into the section's input-removed cell): {cells}")


def test_the_hidden_logic_of_all_chapters_stays_short():
    lines = {p.stem: logic_lines(p) for p in NOTEBOOKS}
    assert sum(lines.values()) <= MAX_LOGIC_LINES, (
        f"{sum(lines.values())} lines of logic in hidden cells in all chapters together (at most "
        f"{MAX_LOGIC_LINES}): {lines}")


def test_the_bookkeeping_check_sees_calls_not_names(tmp_path):
    nb = {"cells": [
        {"cell_type": "code", "metadata": {}, "source": ["x = 1\nglue('a', x)"], "outputs": []},
        {"cell_type": "code", "metadata": {}, "source": ["from danae_lite.book import glue, prose\nplots.glue_x(1)"], "outputs": []},
        {"cell_type": "code", "metadata": {"tags": ["remove-input"]},
         "source": ['# a comment\nv = 2\n\nprose(r"""\nline {a}\nline two\n""", a=v)'], "outputs": []},
    ]}
    path = tmp_path / "01_probe.ipynb"
    path.write_text(json.dumps(nb))
    assert visible_bookkeeping(path) == ["cell 0"]
    assert logic_lines(path) == 2          # "v = 2" and the prose call around its template
    nb["cells"].append({"cell_type": "code", "metadata": {"tags": ["remove-cell"]}, "outputs": [],
                        "source": ['text = """\nnot code\n"""\nglue("b",\n     text)']})
    nb["cells"].append({"cell_type": "code", "metadata": {"tags": ["hide-cell"]}, "outputs": [],
                        "source": ["y = 3"]})             # folded, not hidden: the reader opens it
    path.write_text(json.dumps(nb))
    assert logic_lines(path) == 2 + 3
