"""danae_lite.book.glue / prose / fill: how a chapter's sentences quote its results."""
import math

import numpy as np

import pytest
from IPython.display import Markdown

from danae_lite import book

from test_notebook_prose import fields


def test_fill_formats_fields_with_python_format_specs():
    values = {"gain": 0.62213, "n": 1234, "change": -3.25, "name": "VQF"}
    text = "gain {gain:.3f}, {n:,} samples, {change:+.1f} %, {name}; {{literal}}"
    assert book.fill(text, values) == "gain 0.622, 1,234 samples, -3.2 %, VQF; {literal}"
    # the same as Python's own str.format where the number reads well as it is
    assert book.fill(text, values) == text.format(**values)


def test_fill_writes_numbers_for_reading():
    # no sign on a value that rounds to zero, powers of ten instead of exponent notation
    values = {"tiny": -0.004, "pct": -1e-5, "small": 5e-07, "big": 3.2e12, "word": "-0", "zero": 0.0}
    text = "{tiny:.2f}, {pct:.1%}, {small:.0e}, {small:.2g}, {big:.1e}, {tiny:+.3f}, {word}, {zero:.1e}"
    assert book.fill(text, values) == "0.00, 0.0%, 5 × 10⁻⁷, 5 × 10⁻⁷, 3.2 × 10¹², -0.004, -0, 0"


def test_fill_keeps_maths_and_code_as_written():
    text = ("$\\hat{x}_{t|t-1}$ and $$\nP_{t} = A P A^\\top\n$$ stay; `f\"{x}\"` stays;\n"
            "```python\nd = {'a': 1}\n```\nbut {x:.1f} is filled")
    filled = book.fill(text, {"x": math.pi})
    assert filled == text.replace("{x:.1f} is", "3.1 is")


def test_fill_names_the_missing_field_and_the_sentence():
    with pytest.raises(KeyError, match="'ch9_missing'.*the gain is"):
        book.fill("the gain is {ch9_missing:.2f}", {})
    with pytest.raises(ValueError, match="a field is"):
        book.fill("an open { brace", {})


def test_fields_lists_the_names_outside_maths_and_code():
    # the prose tests' reading of a template, with book.VERBATIM
    assert fields("{a:.1f} $x_{b}$ `{c}` {d} {{e}}") == ["a", "d"]


def test_glue_records_numbers_and_markdown_for_prose(capsys, monkeypatch):
    shown = []
    monkeypatch.setattr("IPython.display.display", lambda obj, **kw: shown.append(obj))
    book._RECORDED.clear()
    book.glue("ch9_gain", 0.125)
    book.glue("ch9_verdict", Markdown("**better** on roll"))
    book.prose("\nThe gain is {ch9_gain:.2f}; {ch9_verdict}.\n")
    shown = [s for s in shown if isinstance(s, Markdown)]      # glue's records are dicts
    assert len(shown) == 1
    assert shown[0].data == "The gain is 0.12; **better** on roll."   # round half to even
    book._RECORDED.clear()


def test_show_figure_displays_the_figure_then_its_caption_and_closes_it(monkeypatch):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = []
    monkeypatch.setattr("IPython.display.display", lambda obj, **kw: shown.append(obj))
    fig, ax = plt.subplots()
    book.show_figure(fig, "Figure 2.3", " The KF's roll against the truth. ", data="real OxIOD data")
    assert shown[0] is fig and isinstance(shown[1], Markdown)
    assert shown[1].data == "*Figure 2.3 — The KF's roll against the truth. Data: real OxIOD data.*"
    assert not plt.fignum_exists(fig.number)
    with pytest.raises(ValueError, match="'Fig. 2' is not 'Figure N.K'"):
        book.show_figure(plt.figure(), "Fig. 2", "x", data="y")
    with pytest.raises(ValueError, match="Figure 2.4 names no data"):
        book.show_figure(plt.figure(), "Figure 2.4", "x", data=" ")
    plt.close("all")


def test_prose_glues_the_values_it_is_given_and_fills_them(monkeypatch):
    shown, glued = [], []
    monkeypatch.setattr("IPython.display.display", lambda obj, **kw: shown.append(obj))
    monkeypatch.setattr("myst_nb.glue", lambda name, value, display=True: glued.append((name, value, display)))
    book._RECORDED.clear()
    book.glue("ch9_earlier", 2)
    book.prose("{ch9_earlier} then {ch9_new:.1f} and {ch9_word}", ch9_new=0.25, ch9_word=Markdown("*x*"))
    assert [g[0] for g in glued] == ["ch9_earlier", "ch9_new", "ch9_word"] and not any(g[2] for g in glued)
    assert shown[-1].data == "2 then 0.2 and *x*"                      # round half to even
    assert book._RECORDED["ch9_new"] == 0.25
    book.glue("ch9_numpy", np.float64(0.5))                  # a NumPy scalar: its Python number
    assert type(glued[-1][1]) is float and type(book._RECORDED["ch9_numpy"]) is float
    book._RECORDED.clear()
