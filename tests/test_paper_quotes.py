"""The paper, quoted and not retyped: a quote attributed to the paper (:func:`paper_quotes`)
occurs in the paper's TeX, and no value of the paper's tables (3+ significant digits) or text
claims is typed into the prose (a verbatim quote, checked by the first test, is exempt; a
paraphrase is not, even in verdicts.md's claim column). Each check has a test that plants its
defect.
"""
from __future__ import annotations

import re
from functools import lru_cache

import pytest

from test_book_references import CODE, GENERATED, HIDDEN, ROLE, SOURCES, at, blank, string_literals, texts
from test_notebook_prose import PAPER

# ---- quotes of the paper -------------------------------------------------------------------

PAPER_FIGURE_TEXT = ("Time [0.01s]",)
"""Text inside the paper's figures (images, not in the TeX): the time-axis label of Figures 1 and
2, from the authors' plotting code (shared/reference/authors_code_notes.md)."""
QUOTE = re.compile(r'"((?:[^"\n]|\n(?!\s*\n))+)"|“([^”]+)”')
CUE = re.compile(r"(?i:\bthe paper\b(?!')|\(paper\b|\bthe authors\b(?!'))|\b(?:Abstract|Introduction|"
                 r"Method|Results|Conclusions)\b|(?i:paper's|authors')\s+(?:\S+\s+){0,5}$")
"""Attribution in the quote's sentence or table cell: the paper or its authors as subject ("The
paper splits OxIOD", "the authors write"), one of its sections ("(Method: "), or a possessive at
most five words before the quote ("the paper's axis label"; not "the paper's KF ... reads")."""
BOUNDARY = re.compile(r"[.!?]\s|\n\s*\n|\||\n\s*(?:[-*]|\d+\.)\s")


def normal(text: str) -> str:
    """TeX or Markdown reduced for comparison: ``\\%`` → %, no ``\\cite``/``\\ref``, no other
    command names, braces, ``$`` or TeX quotes, ``~`` a space, one dash, whitespace collapsed
    (none before %), case folded."""
    text = re.sub(r"\\(?:cite|ref|label|eqref)\{[^}]*\}", "", text.replace("\\%", "%"))
    text = re.sub(r"\\[A-Za-z]+\*?|\\[,;! ]|[{}$]|``|''", " ", text.replace("~", " ").replace("’", "'"))
    text = re.sub(r"\s*(?:---|--|[—–‐-])\s*", "-", text)
    return re.sub(r"\s*%", "%", re.sub(r"\s+", " ", text)).strip().casefold()


@lru_cache(maxsize=None)
def paper_text() -> str:
    """The paper's TeX without comments, :func:`normal`."""
    return normal(re.sub(r"(?<!\\)%.*", "", PAPER.read_text(encoding="latin-1")))


def in_paper(quote: str, paper: str) -> bool:
    """Whether ``quote`` is text of the paper's figures, or its fragments (split at an ellipsis)
    occur in ``paper`` in order."""
    if normal(quote) in {normal(t) for t in PAPER_FIGURE_TEXT}:
        return True
    pos = 0
    for fragment in [normal(f).strip(" .,;:") for f in re.split(r"…|\.\.\.", quote)]:
        if fragment and (pos := paper.find(fragment, pos)) < 0:
            return False
        pos += len(fragment)
    return True


def _paper_column(text: str, offset: int) -> bool:
    """Whether ``offset`` lies in a Markdown table column whose header names the paper."""
    lines = text[:offset].split("\n")
    head = len(lines) - 1
    while head > 0 and lines[head - 1].lstrip().startswith("|"):
        head -= 1
    header, column = text.split("\n")[head].strip().strip("|").split("|"), lines[-1].count("|") - 1
    return lines[-1].lstrip().startswith("|") and 0 <= column < len(header) and "paper" in header[column]


def paper_quotes(text: str) -> list[tuple[int, int, str]]:
    """(start, end, quote) of each double-quoted phrase attributed to the paper: :data:`CUE` in
    its sentence before it, or in a table column headed by the paper ("the paper's claim")."""
    text, found = blank(text, CODE, ROLE, HIDDEN).replace("’", "'"), []
    for m in QUOTE.finditer(text):
        head = text[:m.start()]
        head = head[max((b.end() for b in BOUNDARY.finditer(head)), default=0):]
        if CUE.search(head) or _paper_column(text, m.start()):
            found.append((m.start(), m.end(), m[1] or m[2]))
    return found


def misquotes(where: str, text: str, paper: str) -> list[str]:
    """'where: "quote"' for each quote attributed to the paper that the paper does not hold."""
    return [f'{at(where, text, s)}: "{" ".join(q.split())}"' for s, _, q in paper_quotes(text)
            if not in_paper(q, paper)]


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_quotes_of_the_paper_are_in_the_paper(path):
    problems = [p for w, t in texts(path) for p in misquotes(w, t, paper_text())]
    assert not problems, "quotes the paper does not hold:\n" + "\n".join(problems)


def test_a_planted_misquote_is_found():
    paper = normal(r"In the case of OxIOD, DANAE provides a mean reduction of the RMSE equal to 63\%;"
                   r" see Table~\ref{t}. It is ``filter agnostic'' -- and robust.")
    text = ('The paper claims "a mean reduction of the RMSE equal to 63 %" and "filter agnostic — and '
            'robust", "DANAE provides … 63 %" (Results: "a reduction of 70 %").\nThe column says "zero".'
            ' The authors\' axis reads "Time [0.01s]"; the paper says "robust … DANAE". The paper\'s KF,'
            ' tuned by hand on one recording, reads "two".\n\n'
            '| # | the paper says | ours |\n|---|---|---|\n| 1 | “equal to 64 %” | "not a quote" |\n')
    assert [p.split(": ", 1)[1] for p in misquotes("p.md", text, paper)] == [
        '"a reduction of 70 %"', '"robust … DANAE"', '"equal to 64 %"']


# ---- no paper value typed by hand ----------------------------------------------------------

NUMBER = re.compile(r"(?<![\w.])(\d+(?:\.\d+)?)(?![\w.]*\d)")


@lru_cache(maxsize=None)
def paper_values() -> tuple[tuple[float, ...], re.Pattern]:
    """The values of the paper's tables and the RMSE reductions they imply (per angle, mean, mean
    of roll and pitch); a pattern of the reductions its text claims ("63 %")."""
    from danae_lite.evaluate import metrics

    values = []
    for dataset in metrics.PAPER:
        for method in metrics.PAPER[dataset]:
            values += metrics.paper_table(dataset, method).stack().dropna().tolist()
        red = metrics.paper_rmse_reduction(dataset)
        values += [*red.dropna(), red.mean(), red[["roll", "pitch"]].mean()]
    claims = "|".join(f"{v:.0f}" for v in metrics.PAPER_CLAIMED_RMSE_REDUCTION.values())
    return tuple(values), re.compile(rf"(?<![\w.])(?:{claims})\s?%")


def _is_paper_value(number: str, values: tuple[float, ...]) -> bool:
    """Whether ``number`` has 3+ significant digits and is a rounding of one of ``values``."""
    half = 0.5 * 10.0 ** -len((number + ".").split(".")[1]) * (1 + 1e-9)
    significant = len(number.replace(".", "").lstrip("0"))
    return significant >= 3 and any(abs(v - float(number)) <= half for v in values)


def typed_values(where: str, text: str, paper: str = "") -> list[str]:
    """'where: value' for each paper value typed outside code, roles, generated blocks and the
    quotes of the paper that ``paper`` holds (a verbatim quote is checked by (c) instead)."""
    text = blank(text, GENERATED)
    for s, e, q in paper_quotes(text):
        if paper and in_paper(q, paper):
            text = text[:s] + blank(text[s:e], re.compile(".+")) + text[e:]
    text = blank(text, CODE, ROLE, HIDDEN)
    values, claims = paper_values()
    hits = [m for m in NUMBER.finditer(text) if _is_paper_value(m[1], values)] + [*claims.finditer(text)]
    return [f"{at(where, text, m.start())}: {m[0]}" for m in sorted(hits, key=lambda m: m.start())]


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_no_value_of_the_paper_is_typed_into_the_prose(path):
    problems = [p for w, t in texts(path, typed=True) for p in typed_values(w, t, paper_text())]
    assert not problems, "paper values typed by hand (glue them):\n" + "\n".join(problems)


def test_a_planted_typed_paper_value_is_found():
    text = ('Table 1 gives 65.4 % and a max of 9.01 rad, RMSE 2.40 and 0.0815, mean 59.25; the text'
            ' says 63 % and 55%.\nFine: 65 %, 0.06, 2.4, 163 %, `59.25`, {glue:text}`x::y`, 1.2345.\n'
            'The paper says "a reduction equal to 63 %".\n<!-- begin b: x -->\n67.3\n<!-- end b -->\n')
    found = [p.split(": ")[1] for p in typed_values("p.md", text, normal("a reduction equal to 63\\%"))]
    assert found == ["65.4", "9.01", "2.40", "0.0815", "59.25", "63 %", "55%"]
    cell = {"cell_type": "code", "source": 'show_figure(fig, "Figure 1.1", f"KF {x:.2f} vs 9.01 rad")\n'
                                           'glue("w", words(f"""the paper: {a:.1f} and 67.3 %"""))'}
    assert [p.split(": ")[1] for t in string_literals(cell) for p in typed_values("c", t)] == ["9.01", "67.3"]
