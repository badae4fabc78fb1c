"""What a JupyterLab reader sees: plain Markdown, never MyST's roles, directives or targets, and
no unfilled field.

JupyterLab renders Markdown cells and Markdown outputs with CommonMark (plus maths and HTML):
``{doc}`x```, ``{glue:text}`x```, ``:::{admonition}`` or ``(label)=`` reach the reader as raw
text. So the chapters write links as ``[title](03_danae.ipynb)``, citations as links to the
references page, equation numbers with ``\\tag``, solutions in ``<details>``, and quote their
results through :func:`danae_lite.book.prose` cells, whose input the book removes
(``remove-input``) and JupyterLab collapses (``jupyter.source_hidden``) and whose stored output
is the filled Markdown. The HTML book renders the same Markdown. A cell the book hides behind a
toggle (``hide-cell``: the computations behind the exercises' solutions) is collapsed in
JupyterLab too, input and output, so that a student does not read a solution before its
exercise.
"""
import json
import re
from pathlib import Path

import pytest

from test_notebook_prose import NOTEBOOKS, fields, markdown_outputs, templates

MYST_ONLY = {
    "a MyST role": re.compile(r"(?<![`\w])\{[a-z][\w:-]*\}`"),
    "a MyST directive": re.compile(r"^\s*(?:`{3,}|~{3,}|:{3,})\s*\{", re.M),
    "a colon fence": re.compile(r"^\s*:{3,}", re.M),
    "a MyST target": re.compile(r"^\([^)\s]+\)=\s*$", re.M),
    "an equation label": re.compile(r"\$\$\s*\([\w-]+\)\s*$", re.M),
}


def raw_markup(path: Path) -> list[str]:
    """'cell N: what' for each piece of MyST-only syntax or unfilled field a reader would see."""
    problems = []
    for i, cell in enumerate(json.loads(path.read_text())["cells"]):
        source = ["".join(cell["source"])] if cell["cell_type"] == "markdown" else []
        for text in source + markdown_outputs(cell):
            problems += [f"cell {i}: {what} {m.group(0).strip()!r}"
                         for what, pattern in MYST_ONLY.items() for m in pattern.finditer(text)]
        for text in markdown_outputs(cell):
            try:
                left = fields(text)
            except ValueError as err:
                left = [f"a stray brace ({err})"]
            problems += [f"cell {i}: an unfilled field {name!r}" for name in left]
    return problems


def prose_cell_problems(path: Path) -> list[str]:
    """'cell N: what' for each prose cell the book would show as code or JupyterLab would not
    collapse, or whose filled Markdown is not stored; and each hidden cell JupyterLab shows."""
    problems = []
    for i, cell in enumerate(json.loads(path.read_text())["cells"]):
        meta = cell.get("metadata", {})
        tags = meta.get("tags", [])
        collapsed = meta.get("jupyter", {}).get("source_hidden", False)
        if templates(cell):
            if "remove-input" not in tags:
                problems.append(f"cell {i}: a prose cell without the remove-input tag")
            if len(markdown_outputs(cell)) != len(templates(cell)):
                problems.append(f"cell {i}: a prose cell without its stored Markdown output")
        if ("remove-input" in tags or "hide-input" in tags) and not collapsed:
            problems.append(f"cell {i}: hidden in the book, shown in JupyterLab "
                            "(set metadata.jupyter.source_hidden)")
        if "hide-cell" in tags and not (collapsed and meta["jupyter"].get("outputs_hidden")):
            problems.append(f"cell {i}: behind a toggle in the book, open in JupyterLab "
                            "(set metadata.jupyter.source_hidden and outputs_hidden)")
    return problems


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_a_jupyterlab_reader_sees_no_myst_markup(path):
    problems = raw_markup(path)
    assert not problems, f"{path.name}: JupyterLab would show raw markup:\n" + "\n".join(problems)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_prose_cells_are_hidden_and_stored(path):
    problems = prose_cell_problems(path)
    assert not problems, f"{path.name}:\n" + "\n".join(problems)


def test_the_checks_catch_each_kind_of_raw_markup(tmp_path):
    md = ("See {doc}`03_danae` and {cite:p}`x`.\n\n(sec-a)=\n## A\n\n:::{admonition} S\n:::\n\n"
          "```{note}\nn\n```\n\n$$\nx\n$$ (eq-x)\n\nFine: $x_{t}$, `{y}`, [a](b.ipynb).")
    prose_cell = {"cell_type": "code", "metadata": {"tags": ["remove-input"]},
                  "source": ['prose(r"""{kept:.1f}""")'],
                  "outputs": [{"output_type": "display_data",
                               "data": {"text/markdown": ["Value {left:.2f} and 1.5"]}}]}
    nb = {"cells": [{"cell_type": "markdown", "metadata": {}, "source": [md]}, prose_cell,
                    {"cell_type": "code", "metadata": {"tags": ["hide-input"]}, "source": ["x = 1"],
                     "outputs": []},
                    {"cell_type": "code", "metadata": {"tags": ["hide-cell"],
                                                       "jupyter": {"source_hidden": True}},
                     "source": ["y = 2"], "outputs": []}]}
    path = tmp_path / "99_probe.ipynb"
    path.write_text(json.dumps(nb))
    found = raw_markup(path)
    assert [p.split(" '")[0].split(" (")[0] for p in found] == [
        "cell 0: a MyST role", "cell 0: a MyST role", "cell 0: a MyST directive",
        "cell 0: a MyST directive", "cell 0: a colon fence", "cell 0: a colon fence",
        "cell 0: a MyST target", "cell 0: an equation label", "cell 1: an unfilled field"], found
    assert prose_cell_problems(path) == [
        "cell 1: hidden in the book, shown in JupyterLab (set metadata.jupyter.source_hidden)",
        "cell 2: hidden in the book, shown in JupyterLab (set metadata.jupyter.source_hidden)",
        "cell 3: behind a toggle in the book, open in JupyterLab (set metadata.jupyter.source_hidden "
        "and outputs_hidden)"]
