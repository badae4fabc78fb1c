"""What the prose names exists: read-only checks over the stored chapters (Markdown cells, stored
Markdown outputs, alt text) and the pages (``book/*.md``, ``README.md``), each with a test that
plants its defect in a small synthetic input.

* A cross-reference names something: chapter N a chapter; section / Figure / Table / Exercise /
  equation N.M a heading ``## N.M``, a caption ``*Figure N.M — ...*``, a heading
  ``### Exercise N.M`` or a ``\\tag{N.M}`` of chapter N; a single number (Table 1, section 3,
  equation (5)) is the paper's numbering and must exist in the paper (:data:`QUALIFIER`: exempt).
* A backticked ``danae_lite.x.y`` resolves; a backticked call ``obj.f(...)`` of an exercise
  statement uses a name an earlier code cell of the chapter binds.

Its readers of what a reader sees (:func:`texts`, :func:`blank`) serve ``test_paper_quotes`` and
``test_notebook_rendering`` too.
"""
from __future__ import annotations

import ast
import importlib
import json
import re
from functools import lru_cache, reduce
from pathlib import Path

import pytest

from test_notebook_prose import FIELD, NOTEBOOKS, PAPER, ROOT, markdown_outputs
from tools.execute import toc_chapters

PAGES = [ROOT / "README.md", *sorted((ROOT / "book").glob("*.md"))]
SOURCES = [*NOTEBOOKS, *PAGES]
Text = tuple[str, str]                                   # (where, Markdown)
CODE = re.compile(r"^```.*?^```|`[^`\n]*`", re.S | re.M)
ROLE = re.compile(r"\{[\w:-]+\}`[^`]*`")                 # {glue:text}`..`, {doc}`..`, {cite:p}`..`
HIDDEN = re.compile(r"<!--.*?-->|\]\([^)]*\)", re.S)     # comments, link targets
GENERATED = re.compile(r"<!-- begin ([\w-]+).*?<!-- end \1 -->", re.S)


def blank(text: str, *patterns: re.Pattern) -> str:
    """``text`` with each match of ``patterns`` turned into spaces (line breaks and offsets kept)."""
    for pattern in patterns:
        text = pattern.sub(lambda m: re.sub(r"[^\n]", " ", m.group()), text)
    return text


def _alt(cell: dict) -> list[str]:
    """The alt text of a cell's figure (``metadata.mystnb.image.alt``), if any."""
    return [a for a in [cell.get("metadata", {}).get("mystnb", {}).get("image", {}).get("alt")] if a]


def texts(path: Path, typed: bool = False) -> list[Text]:
    """The Markdown a reader sees: a page; a chapter's Markdown cells, alt text and stored
    Markdown outputs or, ``typed``, what is typed by hand instead: the literal text of every
    string of its code (prose templates, f-strings, captions), fields blanked."""
    if path.suffix == ".md":
        return [(path.name, path.read_text(encoding="utf-8"))]
    made = (lambda c: [blank(t, FIELD) for t in string_literals(c)]) if typed else markdown_outputs
    return [(f"{path.name} cell {i}", t) for i, c in enumerate(json.loads(path.read_text())["cells"])
            for t in (["".join(c["source"])] if c["cell_type"] == "markdown" else []) + made(c) + _alt(c)]


def _literal(node: ast.expr) -> str:
    """The literal text of a string expression: an f-string's fields become a space."""
    if isinstance(node, ast.JoinedStr):
        return "".join(map(_literal, node.values))
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else " "


def string_literals(cell: dict) -> list[str]:
    """The literal text of each string a code cell writes (an f-string's fields a space)."""
    if cell["cell_type"] != "code":
        return []
    source = "\n".join(s for s in "".join(cell["source"]).splitlines() if not s.lstrip().startswith(("%", "!")))
    tree, inner = ast.parse(source), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            inner |= {id(v) for v in ast.walk(node) if v is not node}
    return [_literal(n) for n in ast.walk(tree) if id(n) not in inner
            and (isinstance(n, ast.JoinedStr) or isinstance(n, ast.Constant) and isinstance(n.value, str))]


def at(where: str, text: str, offset: int) -> str:
    """``where``, with the line of ``offset`` on a page."""
    return f"{where}:{text.count(chr(10), 0, offset) + 1}" if where.endswith(".md") else where


# ---- (a) cross-references ----------------------------------------------------------------------

NUM, SEP = r"\(?\d+(?:\.\d+)?\)?", r"\s*(?:–|—|-|to|and|or|,\s*and|,)\s*"
RANGE = ("–", "—", "-", "to")
REF = re.compile(rf"(?<!\w)(?P<word>[Cc]hapter|[Ss]ection|§|[Ff]igure|[Tt]able|[Ee]xercise|[Ee]quation)"
                 rf"(?P<plural>s?)\s*(?P<nums>{NUM}(?:{SEP}{NUM})*)")
QUALIFIER = re.compile(r"(?:paper's|the paper|\(paper,?|authors'|BROAD's|their)\s+"
                       r"(?:(?!(?:as|at|in|of|on|to|by|than|and|or|from|with)\s)[\w-]+\s+){0,2}$", re.I)
"""Another work's reference, exempt: "the paper's §3", "the paper's section 3", "(paper, Table 2)",
"the authors' own Figure 1", "BROAD's Table 2", "their Table 1" (two words at most between, no
preposition: "the paper's KF as chapter 4" is the book's), or followed by "of the paper"."""
LABELS = {"section": r"^##\s+(\d+\.\d+)\b", "exercise": r"^### Exercise (\d+\.\d+)\b",
          "figure": r"^\*Figure (\d+\.\d+) — ", "table": r"^\*Table (\d+\.\d+) — ",
          "equation": r"\\tag\{(\d+\.\d+)\}"}


def refs(text: str) -> list[tuple[int, str, str]]:
    """(offset, kind, number) of each reference not exempt; a list or a range ("sections
    1.5–1.7", "chapters 5 to 8") gives each number it names; a singular word takes ranges only."""
    text, found = blank(text, CODE, ROLE, HIDDEN).replace("’", "'"), []
    for m in REF.finditer(text):
        kind = {"§": "section"}.get(m["word"], m["word"].lower())
        if kind != "chapter" and (QUALIFIER.search(text[max(0, m.start() - 40):m.start()])
                                  or re.match(r"\s+of the paper", text[m.end():])):
            continue
        items = re.split(f"({SEP})", m["nums"])
        nums, seps, keep = [i.strip("()") for i in items[::2]], [s.strip() for s in items[1::2]], []
        for sep, num in zip([""] + seps, nums):
            if keep and (("." in num) != ("." in keep[0]) or not m["plural"] and sep not in RANGE):
                break
            (a, _, x), (b, _, y) = (keep[-1] if keep else num).rpartition("."), num.rpartition(".")
            if sep in RANGE and a == b:
                keep += [f"{a}.{k}".lstrip(".") for k in range(int(x) + 1, int(y))]
            keep.append(num)
        found += [(m.start(), kind, n) for n in keep]
    return found


def book_labels(notebooks: list[Path], toc: list[str]) -> dict[str, set[str]]:
    """Kind -> the labels that chapter N defines as N.M; chapters: files and _toc.yml entries."""
    labels = {kind: set() for kind in LABELS} | {"chapter": {s[:2].lstrip("0") for s in toc}}
    for path in notebooks:
        chapter = path.name[:2].lstrip("0")
        labels["chapter"].add(chapter)
        for _, text in texts(path):
            for kind, pattern in LABELS.items():
                labels[kind] |= {x for x in re.findall(pattern, text, re.M) if x.split(".")[0] == chapter}
    return labels


@lru_cache(maxsize=None)
def paper_counts() -> dict[str, int]:
    """How many sections, figures, tables and equations the paper numbers."""
    tex = PAPER.read_text(encoding="latin-1")
    return {k: len(re.findall(r"\\section\{" if k == "section" else rf"\\begin\{{{k}\}}", tex))
            for k in ("section", "figure", "table", "equation")}


def unresolved(where: str, text: str, labels: dict[str, set[str]], paper: dict[str, int]) -> list[str]:
    """'where: kind N' for each reference to nothing: of the book (chapters, N.M) or of the paper."""
    return [f"{at(where, text, o)}: {k} {n}" for o, k, n in refs(text)
            if (n not in labels[k] if k == "chapter" or "." in n else not 1 <= int(n) <= paper.get(k, 0))]


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_cross_references_name_what_exists(path):
    labels = book_labels(NOTEBOOKS, toc_chapters(ROOT))
    problems = [p for w, t in texts(path) for p in unresolved(w, t, labels, paper_counts())]
    assert not problems, "references to nothing:\n" + "\n".join(problems)


@pytest.mark.parametrize("path", [ROOT / "book" / "intro.md", ROOT / "README.md"], ids=lambda p: p.name)
def test_chapters_named_on_the_front_pages_are_in_the_toc(path):
    toc = book_labels([], toc_chapters(ROOT))["chapter"]
    problems = [f"{at(w, t, o)}: chapter {n}" for w, t in texts(path) for o, k, n in refs(t)
                if k == "chapter" and n not in toc]
    assert not problems, "chapters _toc.yml does not list:\n" + "\n".join(problems)


def test_a_planted_reference_to_nothing_is_found(tmp_path):
    cells = [{"cell_type": "markdown", "source": "## 3.1 Intro\n\n$$ x \\tag{3.1} $$\n### Exercise 3.1"},
             {"cell_type": "code", "source": "",
              "outputs": [{"data": {"text/markdown": "*Figure 3.1 — A.*"}}]}]
    (tmp_path / "03_x.ipynb").write_text(json.dumps({"cells": cells}))
    labels = book_labels([tmp_path / "03_x.ipynb"], ["01_a", "02_b"])
    text = ("Chapters 1–3, section 3.1, equation (3.1), Figure 3.1 and Exercise 3.1; the paper's §4.2,\n"
            "Table 4.1 of the paper, (paper, Table 9), Table 2.\nBut chapters 2 to 4, sections 3.1–3.2, "
            "Figure 3.2, Table 3.1, Exercise 2.1, Table 3, equation (3.3), §4, the paper's KF as chapter 9")
    assert [p.split(": ")[1] for p in unresolved("p.md", text, labels, {"table": 2, "section": 3})] == [
        "chapter 4", "section 3.2", "figure 3.2", "table 3.1", "exercise 2.1", "table 3", "equation 3.3",
        "section 4", "chapter 9"]
    assert paper_counts() == {"section": 7, "figure": 2, "table": 2, "equation": 11}


# ---- (b) code names ----------------------------------------------------------------------------

DOTTED = re.compile(r"`(danae_lite(?:\.\w+)+)(?:\(.*?\))?`")
CALL = re.compile(r"`([A-Za-z_]\w*)\.(\w+(?:\.\w+)*)\(")


def resolves(dotted: str) -> bool:
    """Whether the longest importable module prefix of ``dotted`` has the rest as attributes."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            reduce(getattr, parts[i:], obj)
        except AttributeError:
            return False
        return True
    return False


def bound_names(sources: list[str]) -> dict[str, str | None]:
    """Name -> the module path code imports it from (None: assigned, a loop target, a def)."""
    names: dict[str, str | None] = {}
    for src in sources:
        try:
            tree = ast.parse("\n".join(s for s in src.splitlines() if not s.lstrip().startswith(("%", "!"))))
        except SyntaxError:
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):       # import a.b binds a; import a.b as c binds c
                names |= {a.asname or a.name.split(".")[0]: a.name if a.asname else a.name.split(".")[0]
                          for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                names |= {a.asname or a.name: f"{node.module}.{a.name}" for a in node.names}
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                names[node.id] = None
            elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                names[node.name] = None
    return names


def unresolved_names(where: str, text: str) -> list[str]:
    """'where: name' for each backticked ``danae_lite`` name that does not resolve."""
    return [f"{at(where, text, m.start())}: {m[1]}" for m in DOTTED.finditer(text) if not resolves(m[1])]


def unbound_calls(cells: list[dict], name: str) -> list[str]:
    """'name cell N: call' for each backticked ``obj.f(...)`` of an exercise statement whose
    ``obj`` no earlier code cell binds, or whose ``f`` the ``danae_lite`` module ``obj`` lacks."""
    problems = []
    for i, cell in enumerate(cells):
        text = "".join(cell["source"])
        if cell["cell_type"] == "markdown" and "### Exercise" in text:
            bound = bound_names(["".join(c["source"]) for c in cells[:i] if c["cell_type"] == "code"])
            problems += [f"{name} cell {i}: `{obj}.{attr}(...)` ({bound.get(obj, 'unbound')})"
                         for obj, attr in CALL.findall(text) if obj not in bound or
                         str(bound[obj]).startswith("danae_lite") and not resolves(f"{bound[obj]}.{attr}")]
    return problems


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_code_names_in_the_prose_resolve(path):
    problems = [p for w, t in texts(path) for p in unresolved_names(w, t)]
    if path.suffix == ".ipynb":
        problems += unbound_calls(json.loads(path.read_text())["cells"], path.name)
    assert not problems, "names that do not resolve:\n" + "\n".join(problems)


def test_a_planted_wrong_code_name_is_found():
    text = "`danae_lite.evaluate.metrics.paper_table` and\n`danae_lite.evaluate.metrics.no_such(x)`"
    assert unresolved_names("p.md", text) == ["p.md:2: danae_lite.evaluate.metrics.no_such"]
    cells = [{"cell_type": "code", "source": "from danae_lite.danae import model\nfor cv in x: print(board)"},
             {"cell_type": "markdown", "source": "### Exercise 9.1\n`cv.paired(1)`, `board.run()`, "
                                                 "`model.receptive_field(n)`, `model.no_such()`"}]
    assert unbound_calls(cells, "n") == ["n cell 1: `board.run(...)` (unbound)",
                                         "n cell 1: `model.no_such(...)` (danae_lite.danae.model)"]
