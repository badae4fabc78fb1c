"""Blocks of the README and the book's pages written from the stored chapters, never by hand.

Three places quote what the stored chapters hold:

* ``book/performance.md``, the chapters' run times: :func:`times_markdown` of each chapter's
  execution record (:func:`danae_lite.execute.execution_record`);
* each chapter's opening Markdown cell, its own run time (:func:`run_time_markdown`; a Markdown
  cell, so writing it leaves the chapter's record valid);
* ``README.md``, the measured case for the recommended denoiser: :data:`RESULTS` filled with the
  values chapters 9 and 10 glued (:func:`glued_values`, :func:`danae_lite.book.fill`).

Each sits between two marker lines, ``<!-- begin NAME: ... -->`` and ``<!-- end NAME -->``
(invisible on GitHub, in the book and in JupyterLab). ``python -m danae_lite.execute`` rewrites both after
every run in place (and ``--pages`` alone), and ``tests/test_pages.py`` fails when a page differs
from the stored chapters.
"""
from __future__ import annotations

import ast
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from .book import fill

_RECORD = "application/papermill.record/"

# The README's paragraph on DANAE-res; its fields are names chapters 9 and 10 glue.
RESULTS_CHAPTERS: tuple[str, ...] = ("09_danae_res", "10_no_harm", "11_fallback")
"""The chapters whose glued values :data:`RESULTS` quotes, in order (a later one's value wins)."""
RESULTS = """\
Measured in chapter 9 on real OxIOD, holding out one handheld recording at a time (the methods
fitted on the other handheld recordings, three seeds): on roll, {ch6_cmp_roll_res} has an RMSE
of {ch6_cmp_roll_res_rmse:.4f} rad against {ch6_cmp_roll_lib_rmse:.4f} rad for
{ch6_cmp_roll_lib}, the best library filter on roll (a reduction of {ch6_cmp_roll_red:+.1f} %,
better on {ch6_cmp_roll_wins} held-out recordings); on pitch, {ch6_cmp_pitch_res} has
{ch6_cmp_pitch_res_rmse:.4f} rad against {ch6_cmp_pitch_lib_rmse:.4f} rad for
{ch6_cmp_pitch_lib}, the best on pitch (a reduction of {ch6_cmp_pitch_red:+.1f} %, better on
{ch6_cmp_pitch_wins}). Fitted on BROAD's undisturbed trials and tested on its {ch6_cmpb_ntrials}
disturbed ones, DANAE-res behind VQF has a mean total error of {ch6_cmpb_res_vqf:.2f}° against
VQF's {ch6_cmpb_vqf:.2f}°, and its roll is worse than its filter's on {ch6_nhb_vqf_roll_worse}
trials behind VQF and on {ch6_nhb_riann_roll_worse} behind RIANN (chapter 10).

DANAE-safe (chapter 11) adds a per-sample fallback and an error bar. Within a motion, its 68 %
and 95 % intervals covered {ch11_cov68_in:.0f} % and {ch11_cov95_in:.0f} % of the held-out
samples on average; from one motion to another {ch11_cov68_each:.0f} % and
{ch11_cov95_each:.0f} %, on BROAD's disturbed trials {ch11_cov68_broad:.0f} % and
{ch11_cov95_broad:.0f} %. Pooled over the protocols (behind VQF with three seeds, the paper's KF
and Fusion with one, and on BROAD VQF and RIANN with three), it was worse than its filter by more
than 2 % in {ch11_abl_both_worse2} held-out recording × filter × angle cases, against
{ch11_abl_gate_worse2} for DANAE-res; {ch11_n_met} targets set for it are met in full, and it
costs {ch11_lat_median:.2f} ms per sample on one CPU thread."""


def marker_lines(name: str) -> tuple[str, str]:
    """The two lines that enclose the block ``name``."""
    return (f"<!-- begin {name}: written by `python -m danae_lite.execute` from the stored "
            f"chapters; do not edit by hand -->", f"<!-- end {name} -->")


def _split(text: str, name: str, where: Path) -> tuple[str, str]:
    """The text before the block's first marker and after its second; ValueError without them."""
    begin, end = marker_lines(name)
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        raise ValueError(f"{where}: expected one block between the lines {begin!r} and {end!r}")
    head, rest = text.split(begin)
    return head, rest.split(end)[1]


def block(page: Path, name: str) -> str:
    """The content of the block ``name`` of ``page`` as it stands."""
    text = page.read_text(encoding="utf-8")
    head, tail = _split(text, name, page)
    begin, end = marker_lines(name)
    return text[len(head) + len(begin):len(text) - len(tail) - len(end)].strip("\n")


def _replaced(text: str, name: str, content: str, where: Path) -> str:
    head, tail = _split(text, name, where)
    begin, end = marker_lines(name)
    return f"{head}{begin}\n{content}\n{end}{tail}"


def update_block(page: Path, name: str, content: str) -> bool:
    """Put ``content`` in the block ``name`` of ``page``; True when the page changed."""
    text = page.read_text(encoding="utf-8")
    new = _replaced(text, name, content, page)
    if new == text:
        return False
    page.write_text(new, encoding="utf-8")
    return True


def _block_cell(nb: Any, name: str, path: Path) -> Any:
    """The one Markdown cell of a notebook that holds the block ``name``."""
    begin = marker_lines(name)[0]
    cells = [c for c in nb.cells if c.cell_type == "markdown" and begin in c.source]
    if len(cells) != 1:
        raise ValueError(f"{path}: expected one Markdown cell holding the line {begin!r}, "
                         f"found {len(cells)}")
    return cells[0]


def notebook_block(path: Path, name: str) -> str:
    """The content of the block ``name`` in the Markdown cells of the notebook ``path``."""
    import nbformat

    cell = _block_cell(nbformat.read(path, as_version=4), name, path)
    begin, end = marker_lines(name)
    return cell.source.split(begin)[1].split(end)[0].strip("\n")


def update_notebook_block(path: Path, name: str, content: str) -> bool:
    """Put ``content`` in the block ``name`` of a Markdown cell of the notebook ``path`` (the
    code cells, outputs and execution record stay as they are); True when it changed."""
    import nbformat

    nb = nbformat.read(path, as_version=4)
    cell = _block_cell(nb, name, path)
    new = _replaced(cell.source, name, content, path)
    if new == cell.source:
        return False
    cell.source = new
    tmp = path.with_name(f".{path.name}.pages.tmp")
    nbformat.write(nb, tmp, version=4)
    tmp.replace(path)
    return True


def _networks(record: Mapping[str, Any]) -> str:
    trained, cached = record.get("networks_trained"), record.get("networks_cached")
    if trained is None or cached is None:
        return "not recorded"
    if trained + cached == 0:
        return "none"
    return f"{trained} trained, {cached} found in the cache"


def _when(record: Mapping[str, Any]) -> str:
    return str(record["executed"]).replace("T", " ").removesuffix("+00:00")


def _total(seconds: float) -> str:
    minutes, rest = divmod(seconds, 60.0)
    return f"**{seconds:,.1f}** ({minutes:.0f} min {rest:.0f} s)"


def _same_run(a: Mapping[str, Any], b: Mapping[str, Any] | None) -> bool:
    return b is not None and str(a.get("executed")) == str(b.get("executed"))


def _counts(record: Mapping[str, Any]) -> str:
    trained, cached = record.get("networks_trained"), record.get("networks_cached")
    return "not recorded" if trained is None or cached is None else f"{trained} / {cached}"


def times_markdown(records: Sequence[tuple[str, Mapping[str, Any]]]) -> str:
    """A Markdown table of each chapter's last run from an empty cache ("cold": its cold record)
    and its last run with every network it needs in the cache ("warm": its warm record), where
    it has them, with their totals; the seconds of the run the stored outputs come from are in
    bold (a stored run that is neither is named beside the chapter).

    ``records`` holds (chapter name, execution record) pairs in the book's order (see
    :func:`danae_lite.execute.chapter_records`)."""
    lines = ["| chapter | cold [s] | networks trained / found | cold run (UTC) | "
             "warm [s] | networks trained / found | warm run (UTC) |",
             "|---|---:|---|---|---:|---|---|"]
    totals = {"cold": 0.0, "warm": 0.0}
    for chapter, record in records:
        cells, stored = [], False
        for key in totals:
            kept = record.get(key)
            if kept is None:
                cells.append("— | |")
                continue
            totals[key] += float(kept["seconds"])
            seconds = f"{kept['seconds']:,.1f}"
            if _same_run(record, kept) and not stored:
                seconds, stored = f"**{seconds}**", True
            cells.append(f"{seconds} | {_counts(kept)} | {_when(kept)[:16]}")
        if not stored:
            chapter += f" (stored: {record['seconds']:,.1f} s, {_counts(record)}, {_when(record)[:16]})"
        lines.append(f"| {chapter} | {cells[0]} | {cells[1]} |")
    every = {k: all(r.get(k) is not None for _, r in records) for k in totals}
    cold, warm = ((_total(totals[k]) if every[k] else "—") for k in totals)
    lines.append(f"| **all chapters** | {cold} | | | {warm} | | |")
    return "\n".join(lines)


def _trained_clause(record: Mapping[str, Any]) -> str:
    trained, cached = record.get("networks_trained") or 0, record.get("networks_cached") or 0
    if trained + cached == 0:
        return ""
    found = f" and finding {cached} that earlier chapters trained" if cached else ""
    return f", training {trained} networks{found}"


def run_time_markdown(record: Mapping[str, Any]) -> str:
    """One sentence on a chapter's stored run, its wall time and networks (its execution
    record), on its last run from an empty cache where it has a cold record (``"cold"``) and on
    its last run with every network cached where it has a warm record (``"warm"``) that
    used networks."""
    seconds = f"{record['seconds']:,.1f} s"
    trained, cached = record.get("networks_trained"), record.get("networks_cached")
    where = "on the reference machine (2 CPU cores, no GPU)"
    perf = " (see [Performance](../book/performance.md))"
    cold, warm = record.get("cold"), record.get("warm")
    warm_used = warm is not None and (warm.get("networks_cached") or 0) > 0
    warm_part = (f"; with every network in the cache ({str(warm['executed'])[:10]}) it took "
                 f"{warm['seconds']:,.1f} s" if warm_used and not _same_run(record, warm) else "")
    if cold is not None and _same_run(record, cold):
        return (f"*Run time*: the stored outputs of this chapter come from its last run from an empty "
                f"network cache ({str(cold['executed'])[:10]}): {seconds} {where}"
                f"{_trained_clause(cold)}{warm_part}{perf}.")
    if cold is not None:
        nets = cold.get("networks_trained") or 0
        what = f", training {nets} networks" if nets else ""
        day = str(cold["executed"])[:10]
        after = (f"; from an empty network cache, in its last run from scratch ({day}), it took "
                 f"{cold['seconds']:,.1f} s{what}{perf}")
    elif trained is None or cached is None or trained + cached == 0:
        after = ""
    else:
        after = f"; from an empty cache it trains them all and takes longer{perf}"
    if trained is None or cached is None or trained + cached == 0:
        return f"*Run time*: the stored run of this chapter took {seconds} {where}{after}."
    return (f"*Run time*: the stored run of this chapter took {seconds} {where}, with "
            f"{cached} of its {trained + cached} trained networks found in the cache{after}.")


def glued_values(nb: Mapping[str, Any]) -> dict[str, Any]:
    """Name -> value of every glued output of a stored notebook: Markdown values as their text,
    others as the Python literal their text shows (its text where it is no literal)."""
    values: dict[str, Any] = {}
    for cell in nb.get("cells", []):
        for out in cell.get("outputs", []):
            name = out.get("metadata", {}).get("scrapbook", {}).get("name")
            if not name:
                continue
            data = out.get("data", {})
            if _RECORD + "text/markdown" in data:
                values[name] = "".join(data[_RECORD + "text/markdown"])
                continue
            text = "".join(data.get(_RECORD + "text/plain", ""))
            try:
                values[name] = ast.literal_eval(text)
            except (ValueError, SyntaxError):
                values[name] = text
    return values


def results_markdown(chapters: Sequence[Mapping[str, Any]]) -> str:
    """The README's paragraph on DANAE-res (:data:`RESULTS`) from the glued values of
    ``chapters`` (the notebooks of :data:`RESULTS_CHAPTERS`, in order)."""
    values: dict[str, Any] = {}
    for nb in chapters:
        values.update(glued_values(nb))
    return fill(RESULTS, values)
