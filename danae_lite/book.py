"""The common first cell of every chapter: ``from danae_lite.book import setup; cfg = setup()``.

It fixes the things every chapter relies on, in one place:

* fast mode (``DANAE_FAST``) — fewer epochs and shorter recordings for CI;
* the real-data directory (``DANAE_DATA``) — or the simulator when it is absent;
* the seeds of python and numpy (and of torch when the chapter has loaded it; a chapter that
  trains seeds each network itself, as the library does);
* the plotting style of the book (:mod:`danae_lite.plots`).

It loads no torch: the Kalman-filter chapters run without it. Torch's CPU threads stay torch's
own default (every physical core, or ``OMP_NUM_THREADS``).

It also holds the two functions through which a chapter puts a number from its run into its
prose, so that the number reads the same in the HTML book and in JupyterLab:

* :func:`glue` records a value under a name (through myst-nb's ``glue``, so the stored outputs
  keep a machine-readable record of every quoted number) and remembers it for :func:`prose`;
* :func:`prose` displays Markdown whose ``{name}`` / ``{name:.2f}`` fields are filled with the
  recorded values (Python's format mini-language); a chapter calls it in a cell whose input
  the book removes and JupyterLab collapses, so both show the sentence with its numbers.

and :func:`glue_table`, which glues every value of a table (a verdict table of
:mod:`danae_lite.evaluate.comparison`) by one call, and :func:`show_figure`, which shows a
figure with its numbered caption and the data it is drawn from as outputs of the cell, so
that the HTML book and JupyterLab both show the caption under the figure (its alt text is the
cell's ``mystnb.image.alt`` metadata).

The command that re-executes the chapters and stores their outputs is
:mod:`tools.execute` (``make execute``); the book only renders those outputs.
"""
from __future__ import annotations

import re
import string
from typing import Any

from .danae.seeding import seed_everything
from .runtime import DEFAULT_SEED, RunSettings

# values glued by the running chapter, by name (one chapter per kernel; setup() empties it)
_RECORDED: dict[str, Any] = {}
# the parts of Markdown that prose() leaves as they are: fenced code, inline code, maths (one group,
# so that VERBATIM.split() returns them at the odd positions, between the text to fill)
VERBATIM = re.compile(r"(^```.*?^```[^\n]*$|`[^`\n]*`|\$\$.*?\$\$|\$[^$\n]+\$)", re.S | re.M)


def setup(seed: int = DEFAULT_SEED, *, verbose: bool = True) -> RunSettings:
    """Apply the book's common settings and return them (:class:`~danae_lite.runtime.RunSettings`
    from ``DANAE_FAST``, ``DANAE_DATA``, ``DANAE_CACHE``, ``DANAE_JOBS`` and
    ``DANAE_SCHEDULER``)."""
    from . import plots

    plots.use_style()
    seed_everything(seed)  # torch too once loaded: chapters 1-2 run without it
    _RECORDED.clear()
    cfg = RunSettings.from_env(seed=seed)
    if cfg.scheduler is not None:  # imported only then: chapters 1-2 load no torch
        from .danae.networks import use_scheduler

        use_scheduler(cfg.scheduler)
    if verbose:
        mode = "FAST (DANAE_FAST=1: reduced steps, data and seeds)" if cfg.fast else "full"
        data = "$DANAE_DATA" if cfg.data_dir else "none (DANAE_DATA unset): the simulator stands in"
        workers = f"Dask cluster {cfg.scheduler}" if cfg.scheduler else f"{cfg.jobs} worker process(es)"
        print(f"mode: {mode}\ndata: {data} | seed: {cfg.seed} | device: {cfg.device} ({workers})")
    return cfg


def glue(name: str, value: Any, display: bool = False) -> None:
    """Record ``value`` under ``name`` for :func:`prose` and in the stored outputs (myst-nb's
    ``glue``: an output the book and JupyterLab do not show unless ``display``). A Markdown
    object is remembered as its Markdown text; a NumPy scalar is glued as the Python number it
    holds (so that the record reads ``0.5``, not ``np.float64(0.5)``)."""
    from myst_nb import glue as myst_glue

    if getattr(value, "ndim", None) == 0 and hasattr(value, "item"):
        value = value.item()
    markdown = getattr(value, "_repr_markdown_", None)
    _RECORDED[name] = markdown() if callable(markdown) else value
    myst_glue(name, value, display=display)


def glue_table(prefix: str, table: Any) -> None:
    """Glue every cell of the DataFrame ``table`` under ``{prefix}_{row}_{column}``, or every
    value of the Series ``table`` under ``{prefix}_{label}`` (each run of characters other than
    ASCII letters and digits in a label as one underscore, none at its ends: ``"all (preset)"``
    gives ``all_preset``), so that prose and other pages quote a table's values by one name each,
    all recorded by one call (numbers and text as they are, so that a page quotes either with
    ``{glue:text}``)."""
    items = table.items() if table.ndim == 1 else (
        (f"{row}_{column}", value) for (row, column), value in table.stack(future_stack=True).items())
    for label, value in items:
        name = f"{prefix}_{re.sub(r'[^0-9A-Za-z]+', '_', str(label)).strip('_')}"
        glue(name, value.item() if hasattr(value, "item") else value)


def fill(template: str, values: dict[str, Any]) -> str:
    """``template`` with every ``{name}`` / ``{name:spec}`` field outside code and maths replaced
    by ``format(values[name], spec)``; code spans, fenced code and ``$...$`` / ``$$...$$`` maths
    are kept as written (their braces are LaTeX's or Python's, not fields).

    Raises KeyError naming the field when ``values`` has no such name, ValueError for a brace
    that is not a field."""
    parts = VERBATIM.split(template)
    parts[::2] = [_fill_plain(text, values) for text in parts[::2]]
    return "".join(parts)


class _ReadingFormatter(string.Formatter):
    """Python's format mini-language, with numbers written for reading: no minus sign on a
    value that rounds to zero (``-0.0`` reads as ``0.0``) and powers of ten instead of
    exponent notation (``5e-07`` reads as ``5 × 10⁻⁷``, ``0.0e+00`` as ``0``)."""

    def format_field(self, value: Any, format_spec: str) -> str:
        text = format(value, format_spec)
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            return text
        if re.fullmatch(r"\s*-0(\.0*)?%?\s*", text):
            return text.replace("-", "", 1)
        power = re.fullmatch(r"([+-]?[\d.]+)e([+-]\d+)", text.strip())
        if power and float(power.group(1)) == 0:
            return "0"
        if power:
            mantissa, exponent = power.group(1), int(power.group(2))
            return f"{mantissa} × 10{str(exponent).translate(_SUPERSCRIPT)}"
        return text


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _fill_plain(text: str, values: dict[str, Any]) -> str:
    try:
        return _ReadingFormatter().vformat(text, (), values)
    except KeyError as err:
        raise KeyError(f"prose: no value glued under the name {err.args[0]!r} (glue it in an "
                       f"earlier cell); in {text.strip()[:80]!r}") from None
    except (ValueError, IndexError) as err:
        raise ValueError(f"prose: {err} in {text.strip()[:80]!r}; a field is {{name}} or "
                         "{name:spec} with a glued name") from None


def prose(template: str, **values: Any) -> None:
    """Display ``template`` as Markdown, its fields filled from the values glued so far and from
    ``values``, each of which is glued first under its name (:func:`glue`), so that the stored
    outputs keep every quoted value (see :func:`fill`). The way a chapter writes a paragraph
    that quotes its own results: one call per paragraph, in a cell whose input is hidden."""
    from IPython.display import Markdown, display

    for name, value in values.items():
        glue(name, value)
    display(Markdown(fill(template.strip("\n"), _RECORDED)))


def show_figure(fig: Any, label: str, caption: str, *, data: str) -> None:
    """Display the Matplotlib figure ``fig``, then its caption, ``*label — caption Data: data.*``
    (e.g. ``label="Figure 2.1"``, ``data=exp.source``), as a Markdown output right under it,
    and close the figure so that it is not shown twice. ``data`` names what the figure is drawn
    from, as the run found it (:attr:`danae_lite.data.experiments.Experiment.source`, or e.g.
    ``"the handheld simulator"``), so that the caption stays true without the real data."""
    import matplotlib.pyplot as plt
    from IPython.display import Markdown, display

    if not re.fullmatch(r"Figure \d+\.\d+", label):
        raise ValueError(f"show_figure: label {label!r} is not 'Figure N.K'")
    if not data.strip():
        raise ValueError(f"show_figure: {label} names no data (data='...')")
    display(fig)
    display(Markdown(f"*{label} — {caption.strip()} Data: {data.strip()}.*"))
    plt.close(fig)
