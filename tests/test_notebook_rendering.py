"""What a reader's tools do with a chapter: no tagged display equation that Sphinx wraps in
``split`` (MathJax refuses it), and nothing JupyterLab rewrites when it opens a chapter. Each
check has a test that plants its defect.
"""
from __future__ import annotations

import json
import re

import pytest

from test_book_references import CODE, SOURCES, at, blank, texts
from test_notebook_prose import NOTEBOOKS

# ---- equations and notebook metadata -------------------------------------------------------

KERNELSPEC = {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"}
"""What JupyterLab writes from the kernel it starts (ipykernel 6's kernel.json in .venv)."""


def split_wrapped_tags(where: str, text: str) -> list[str]:
    """'where: \\tag{..}' for each tagged ``$$`` block that Sphinx wraps in ``split`` (a part with
    ``\\\\`` anywhere, even in a matrix or ``aligned``: sphinx.ext.mathjax) or ``aligned``
    (parts split by a blank line); MathJax refuses it: "\\tag not allowed in split environment"."""
    problems = []
    for m in re.finditer(r"\$\$(.*?)\$\$", blank(text, CODE), re.S):
        parts = [p for p in m[1].split("\n\n") if p.strip()]
        problems += [f"{at(where, text, m.start())}: {tag}" for p in parts
                     for tag in re.findall(r"\\tag\{[^}]*\}", p) if "\\\\" in p or len(parts) > 1]
    return problems


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_no_tagged_equation_is_wrapped_in_split(path):
    problems = [p for w, t in texts(path) for p in split_wrapped_tags(w, t)]
    assert not problems, "tagged equations Sphinx wraps in split:\n" + "\n".join(problems)


def test_a_planted_tag_in_a_split_is_found():
    text = ("$$\nx = 1\n\\tag{1.1}\n$$\n\n$$\n\\begin{aligned} a \\\\ b \\end{aligned}\n\\tag{1.2}\n$$\n"
            "$$\nA = \\begin{bmatrix} 1 \\\\ 0 \\end{bmatrix}\n$$\n$$\na\n\nb \\tag{1.3}\n$$\n"
            "`$$ \\\\ \\tag{9} $$`")
    assert split_wrapped_tags("p.md", text) == ["p.md:6: \\tag{1.2}", "p.md:13: \\tag{1.3}"]


def jupyterlab_changes(notebook: dict) -> list[str]:
    """What JupyterLab rewrites on opening (a diff when the reader saves): a kernelspec other than
    :data:`KERNELSPEC`; a cell whose ``collapsed`` and ``jupyter.outputs_hidden`` differ (its cell
    model copies one to the other as it loads the metadata: hidden solution cells)."""
    found = notebook.get("metadata", {}).get("kernelspec", {})
    changes = [f"kernelspec {k}: {found.get(k)!r} (JupyterLab writes {v!r})" for k, v in KERNELSPEC.items()
               if found.get(k) != v]
    for i, cell in enumerate(notebook.get("cells", [])):
        meta = cell.get("metadata", {})
        hidden, collapsed = meta.get("jupyter", {}).get("outputs_hidden"), meta.get("collapsed")
        if hidden != collapsed:
            changes.append(f"cell {i}: collapsed {collapsed} but jupyter.outputs_hidden {hidden}")
    return changes


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_jupyterlab_opens_a_chapter_without_changing_it(path):
    changes = jupyterlab_changes(json.loads(path.read_text()))
    assert not changes, f"{path.name}: JupyterLab would rewrite:\n" + "\n".join(changes)


def test_a_planted_jupyterlab_change_is_found():
    hidden = {"jupyter": {"outputs_hidden": True, "source_hidden": True}}
    cells = [{"metadata": {}}, {"metadata": hidden | {"collapsed": True}}, {"metadata": hidden}]
    assert jupyterlab_changes({"metadata": {"kernelspec": KERNELSPEC}, "cells": cells[:2]}) == []
    spec = {"display_name": "Python 3", "language": "python", "name": "python3"}
    assert jupyterlab_changes({"metadata": {"kernelspec": spec}, "cells": cells}) == [
        "kernelspec display_name: 'Python 3' (JupyterLab writes 'Python 3 (ipykernel)')",
        "cell 2: collapsed None but jupyter.outputs_hidden True"]


def test_the_executor_writes_what_jupyterlab_saves():
    from tools.execute import as_jupyterlab_saves

    hidden = {"jupyter": {"outputs_hidden": True, "source_hidden": True}}
    nb = {"metadata": {"kernelspec": {"display_name": "Python 3", "name": "python3", "language": "python"}},
          "cells": [{"metadata": dict(hidden)}, {"metadata": {"collapsed": False}}, {"metadata": {}}]}
    as_jupyterlab_saves(nb)
    assert jupyterlab_changes(nb) == []
