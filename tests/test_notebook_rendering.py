"""What a reader's tools do with a chapter: no tagged display equation that Sphinx wraps in
``split`` (MathJax refuses it), and nothing JupyterLab rewrites when it opens a chapter. Each
check has a test that plants its defect.
"""
from __future__ import annotations

import json
import re

import pytest

from test_book_references import CODE, SOURCES, at, blank, texts
from test_notebook_prose import NOTEBOOKS, ROOT

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


# ---- what the HTML page shows of a cell ----------------------------------------------------
def output_text(output: dict) -> str:
    """The text an output shows: a stream's, or its ``text/*`` representations joined."""
    parts = [output.get("text", "")] + [v for k, v in output.get("data", {}).items() if k.startswith("text/")]
    return "".join("".join(p) if isinstance(p, list) else p for p in parts)


def empty_toggles(notebook: dict) -> list[str]:
    """'cell N' for each cell whose input the book folds behind a "Show code cell source"
    toggle (``hide-input``) but that shows no output: the reader opens a toggle beside nothing.
    Glue records are not shown, so they do not count as output."""
    return [f"cell {i}" for i, c in enumerate(notebook["cells"])
            if c["cell_type"] == "code" and "hide-input" in c.get("metadata", {}).get("tags", [])
            and not any(not any(k.startswith("application/papermill.record/") for k in o.get("data", {}))
                        for o in c.get("outputs", []))]


def test_a_planted_empty_toggle_is_found():
    glue_only = {"output_type": "display_data", "metadata": {},
                 "data": {"application/papermill.record/text/plain": "0.5"}}
    shown = {"output_type": "stream", "name": "stdout", "text": "0.5\n"}
    cells = [{"cell_type": "code", "metadata": {"tags": ["hide-input"]}, "source": "", "outputs": o}
             for o in ([glue_only], [glue_only, shown], [])]
    assert empty_toggles({"cells": cells}) == ["cell 0", "cell 2"]


MAX_OUTPUT_LINE = 88
"""Characters of a printed line that fit a code block of the HTML page, as code lines do."""


def long_output_lines(notebook: dict) -> list[str]:
    """'cell N: length' for each printed line (a stream, or a plain-text result shown as such)
    longer than :data:`MAX_OUTPUT_LINE`: the page scrolls it sideways and the reader misses its
    end. Tables, figures and Markdown have their own layout and are not counted."""
    found = []
    for i, c in enumerate(notebook["cells"]):
        if c["cell_type"] != "code" or {"remove-output", "remove-cell"} & set(c.get("metadata", {}).get("tags", [])):
            continue
        for o in c.get("outputs", []):
            if o.get("output_type") == "stream" or set(o.get("data", {})) == {"text/plain"}:
                found += [f"cell {i}: {len(line)}" for line in output_text(o).splitlines()
                          if len(line) > MAX_OUTPUT_LINE]
    return found


def test_a_planted_long_output_line_is_found():
    long, short = "x" * (MAX_OUTPUT_LINE + 1), "y" * MAX_OUTPUT_LINE
    cells = [{"cell_type": "code", "metadata": {}, "source": "", "outputs": [
        {"output_type": "stream", "name": "stdout", "text": [short + "\n", long + "\n"]},
        {"output_type": "execute_result", "metadata": {}, "data": {"text/plain": long}},
        {"output_type": "execute_result", "metadata": {}, "data": {"text/plain": long, "text/html": "<table/>"}}]},
        {"cell_type": "code", "metadata": {"tags": ["remove-output"]}, "source": "", "outputs": [
            {"output_type": "stream", "name": "stdout", "text": long}]}]
    assert long_output_lines({"cells": cells}) == [f"cell 0: {MAX_OUTPUT_LINE + 1}"] * 2


ABSOLUTE_PATH = re.compile(r"(?<![\w.:/])/(?:[\w.-]+/)+[\w.-]*")
"""A folder of the machine that ran a chapter (``/home/me/data/oxiod``), not a URL or a unit."""


def absolute_paths(notebook: dict) -> list[str]:
    """The absolute paths the stored outputs print: the data folder is named ``<data dir>``
    (``$DANAE_DATA``), whatever machine executed the chapter."""
    return [path for c in notebook["cells"] for o in c.get("outputs", [])
            for path in ABSOLUTE_PATH.findall(output_text(o))]


def test_a_planted_absolute_path_is_found():
    out = {"output_type": "stream", "name": "stdout",
           "text": "Real OxIOD from /home/me/data/oxiod: see https://x.org/a/b, 3 rad/s/√s, <data dir>/ucs"}
    assert absolute_paths({"cells": [{"cell_type": "code", "outputs": [out]}]}) == ["/home/me/data/oxiod"]


# ---- captions name their data, as the run found it ------------------------------------------

CAPTION_DATA = re.compile(r"^\*Figure \d+\.\d+ — .* Data: (?P<data>[^*]+)\.\*$", re.S)
TYPED_REAL = re.compile(r"\breal\b", re.I)


def caption_problems(notebook: dict) -> list[str]:
    """What is wrong with the data a chapter's figures name: each caption (``show_figure``'s
    ``*Figure N.K — ... Data: ....*``) names its data, a run without the real data
    (``metadata.danae.execution.data`` not ``"real"``) names none as real, and neither the
    typed caption nor the alt text says "real" (that is the run's to say, through ``data=``)."""
    record = notebook.get("metadata", {}).get("danae", {}).get("execution", {})
    problems = []
    for i, c in enumerate(notebook["cells"]):
        if c["cell_type"] != "code":
            continue
        for o in c.get("outputs", []):
            text = "".join(o.get("data", {}).get("text/markdown", "")).strip()
            if not text.startswith("*Figure "):
                continue
            m = CAPTION_DATA.match(text)
            if not m:
                problems.append(f"cell {i}: a caption without 'Data: ...': {text[:60]!r}")
            elif record.get("data") != "real" and m["data"].startswith("real"):
                problems.append(f"cell {i}: names real data on a {record.get('data')} run: {m['data']!r}")
        source = "".join(c["source"])
        typed = [call.split("data=")[0] for call in re.findall(r"show_figure\(.*?\)\s*$", source, re.S | re.M)]
        alt = c.get("metadata", {}).get("mystnb", {}).get("image", {}).get("alt", "")
        if any(TYPED_REAL.search(t) for t in typed + [alt]):
            problems.append(f"cell {i}: its typed caption or alt text says 'real'")
    return problems


def test_planted_caption_defects_are_found():
    def figure(caption: str, alt: str = "a plot of the roll error over one minute") -> dict:
        return {"cell_type": "code", "metadata": {"mystnb": {"image": {"alt": alt}}},
                "source": 'show_figure(fig, "Figure 1.1", "roll", data=exp.source)',
                "outputs": [{"output_type": "display_data", "data": {"text/markdown": caption}}]}
    run = {"danae": {"execution": {"data": "simulated"}}}
    cells = [figure("*Figure 1.1 — Roll. Data: the simulator standing in for OxIOD.*"),
             figure("*Figure 1.2 — Roll.*"),
             figure("*Figure 1.3 — Roll. Data: real OxIOD data.*"),
             figure("*Figure 1.4 — Roll. Data: the handheld simulator.*", alt="roll on a real walk")]
    assert caption_problems({"metadata": run, "cells": cells}) == [
        "cell 1: a caption without 'Data: ...': '*Figure 1.2 — Roll.*'",
        "cell 2: names real data on a simulated run: 'real OxIOD data'",
        "cell 3: its typed caption or alt text says 'real'"]


def unclosed_toggles(notebook: dict) -> list[str]:
    """'cell N' for each cell whose source (Markdown, or a ``prose`` template in code) opens a
    ``<details>`` toggle it does not close: the page would fold everything after it."""
    return [f"cell {i}" for i, c in enumerate(notebook["cells"])
            if "".join(c["source"]).count("<details>") != "".join(c["source"]).count("</details>")]


def test_a_planted_unclosed_toggle_is_found():
    cells = [{"cell_type": "markdown", "source": "<details>\n<summary>Solution</summary>\n\nx\n\n</details>"},
             {"cell_type": "code", "source": 'prose(r"""\n<details>\n<summary>Solution</summary>\n\n{x}\n""")'}]
    assert unclosed_toggles({"cells": cells}) == ["cell 1"]


# ---- figure labels at phone width -------------------------------------------------------------

FIGURE_CSS = ROOT / "book" / "_static" / "figures.css"
MIN_LABEL_PX = 9.0
"""Smallest height [CSS px] of a figure's axis and tick labels on a phone, below which they
cannot be read (a 10 pt label on a 990 px figure shrunk to a 350 px column is about 5 px)."""


def figure_min_width_px(css: str) -> float:
    """The width [CSS px] below which the book's stylesheet does not shrink a chapter's figure."""
    m = re.search(r"div\.cell_output img\s*\{[^}]*min-width:\s*(\d+)px", css)
    if not m:
        raise AssertionError(f"{FIGURE_CSS.name}: no 'div.cell_output img {{ min-width: ...px }}' rule")
    return float(m[1])


def text_px() -> float:
    """Height [px] of text at the book's font size in a stored figure (``plots.use_style``:
    ``font.size`` points at ``figure.dpi``), at the figure's own width."""
    import matplotlib as mpl

    from danae_lite import plots

    with mpl.rc_context():
        plots.use_style()
        return float(mpl.rcParams["font.size"]) * float(mpl.rcParams["figure.dpi"]) / 72


def small_figure_labels(notebook: dict, *, min_width: float | None = None) -> list[str]:
    """'cell N: <px>' for each stored figure whose labels would be under :data:`MIN_LABEL_PX` on
    a phone, where the stylesheet shows it ``min_width`` px wide (read from ``figures.css``)."""
    import base64
    import struct

    width = figure_min_width_px(FIGURE_CSS.read_text()) if min_width is None else min_width
    natural = text_px()
    found = []
    for i, c in enumerate(notebook["cells"]):
        for o in c.get("outputs", []):
            png = o.get("data", {}).get("image/png")
            if png:
                (png_width,) = struct.unpack(">I", base64.b64decode(png)[16:20])
                if (px := natural * width / png_width) < MIN_LABEL_PX:
                    found.append(f"cell {i}: {png_width} px wide, labels {px:.1f} px")
    return found


def test_a_planted_wide_figure_is_found():
    import base64
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def figure(width_in: float) -> dict:
        fig = plt.figure(figsize=(width_in, 2), dpi=100)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100)
        plt.close(fig)
        png = base64.b64encode(buf.getvalue()).decode()
        return {"cell_type": "code", "outputs": [{"output_type": "display_data", "data": {"image/png": png}}]}

    assert small_figure_labels({"cells": [figure(9), figure(13)]}, min_width=720) == [
        "cell 1: 1300 px wide, labels 7.7 px"]


def test_the_book_loads_the_figure_stylesheet():
    import yaml

    sphinx = yaml.safe_load((ROOT / "_config.yml").read_text())["sphinx"]["config"]
    assert FIGURE_CSS.name in sphinx["html_css_files"]
    assert any((ROOT / d / FIGURE_CSS.name) == FIGURE_CSS for d in sphinx["html_static_path"])
    assert figure_min_width_px(FIGURE_CSS.read_text()) >= 600


PAGE_CHECKS = {
    "hide-input cells with no visible output (an empty toggle; tag them remove-input)": empty_toggles,
    f"printed lines longer than {MAX_OUTPUT_LINE} characters (wrap them)": long_output_lines,
    "outputs that print absolute paths": absolute_paths,
    "captions that do not name the data their run found": caption_problems,
    "<details> without </details>": unclosed_toggles,
    f"figures whose labels are under {MIN_LABEL_PX:g} px on a phone (narrow the figure)": small_figure_labels,
}
"""What a reader would meet on a chapter's page, each found by its function above."""


@pytest.mark.parametrize("what", PAGE_CHECKS)
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_a_chapter_page_has_none_of_these_defects(path, what):
    found = PAGE_CHECKS[what](json.loads(path.read_text()))
    assert not found, f"{path.name}: {what}:\n" + "\n".join(found)
