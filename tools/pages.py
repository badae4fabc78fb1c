"""Blocks of the README and the book's pages written from the stored chapters, never by hand.

Three places quote what the stored chapters hold:

* ``book/performance.md``, the chapters' run times: :func:`times_markdown` of each chapter's
  execution record (:func:`tools.execute.execution_record`);
* each chapter's opening Markdown cell, its own run time (:func:`run_time_markdown`; a Markdown
  cell, so writing it leaves the chapter's record valid);
* ``book/performance.md``, the benchmark: :func:`benchmark_markdown` of the committed benchmark
  run (:data:`BENCHMARK_RUN`, written by ``make bench``);
* ``README.md`` and ``book/performance.md``, the timings of the project's commands:
  :func:`timings_markdown` of the committed fresh-clone CI run (:data:`COMMANDS_RUN`, written by
  ``benchmarks/ci_times.py``), the chapters' records and the benchmark run.

Each sits between two marker lines, ``<!-- begin NAME: ... -->`` and ``<!-- end NAME -->``
(invisible on GitHub, in the book and in JupyterLab). ``python -m tools.execute`` rewrites them
after every run in place (and ``--pages`` alone), and ``tests/test_pages.py`` fails when a page
differs from what they quote.
"""
from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any


BENCHMARK_RUN = Path("benchmarks") / "results" / "reference.json"
"""The committed run of ``benchmarks/run.py`` that the Performance page quotes (repository-relative)."""
COMMANDS_RUN = Path("benchmarks") / "results" / "commands.json"
"""The committed fresh-clone run of ``.ci/run`` whose times the README and the Performance page
quote (repository-relative; written by ``benchmarks/ci_times.py``)."""


def marker_lines(name: str) -> tuple[str, str]:
    """The two lines that enclose the block ``name``."""
    return (f"<!-- begin {name}: written by `python -m tools.execute` from the stored "
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
    :func:`tools.execute.chapter_records`)."""
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


def read_run(root: Path, relative: Path) -> dict[str, Any]:
    """The committed JSON record ``root / relative`` (a benchmark or command-timing run)."""
    path = root / relative
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: expected the committed JSON record of a run ({exc})") from exc


# (key of the benchmark's summary, label, format of the value)
BENCHMARK_ROWS: tuple[tuple[str, str, str], ...] = (
    ("kf_samples_per_s", "KF (`run_kf`, authors' setting) [samples/s]", "{:,.0f}"),
    ("kf_general_samples_per_s", "KF, general 6×3-gain path [samples/s]", "{:,.0f}"),
    ("fusion_samples_per_s", "Fusion (imufusion, C) [samples/s]", "{:,.0f}"),
    ("vqf_samples_per_s", "VQF (C++) [samples/s]", "{:,.0f}"),
    ("madgwick_samples_per_s", "Madgwick (ahrs, pure Python) [samples/s]", "{:,.0f}"),
    ("mahony_samples_per_s", "Mahony (ahrs, pure Python) [samples/s]", "{:,.0f}"),
    ("danae_train_steps_per_s", "DANAE training, batch 16 [steps/s]", "{:,.1f}"),
    ("danae_train_steps_per_s_b256", "DANAE training, batch 256 [steps/s]", "{:,.1f}"),
    ("train_bare_windows_per_s", "bare training step, batch 16 [windows/s]", "{:,.0f}"),
    ("train_loop_windows_per_s", "`train.train`, paper settings, validation included [windows/s]", "{:,.0f}"),
    ("train_loop_over_bare", "loop / bare step", "{:.2f}"),
    ("train_gflops", "training arithmetic rate [GFLOP/s]", "{:,.1f}"),
    ("matmul_gflops", "float32 matmul peak, same threads [GFLOP/s]", "{:,.0f}"),
    ("train_over_matmul_peak", "training rate / matmul peak", "{:.2f}"),
    ("paper_epoch_50k_s", "one paper epoch over 50,000 windows [s]", "{:.1f}"),
    ("predict_100k_s", "`predict` over 100,000 samples [s]", "{:.2f}"),
    ("danae_infer_ms_per_sample", "paper network streaming, one window per sample [ms/sample]", "{:.2f}"),
    ("causal_h128_stream_ms_per_sample", "causal network streaming, hidden 128 [ms/sample]", "{:.3f}"),
    ("denoiser_stream_ms_per_sample", "DANAE-res behind VQF, streaming, median [ms/sample]", "{:.3f}"),
    ("denoiser_stream_p99_ms", "DANAE-res behind VQF, streaming, p99 [ms/sample]", "{:.3f}"),
)
"""The rows of the Performance page's benchmark table."""


def _path_name(machine: Mapping[str, Any]) -> str:
    """'AVX2 (forced)', or the instruction set torch's kernels use, e.g. 'AVX-512 (native)'."""
    isa = machine["isa"]
    native = {"AVX512": "AVX-512"}.get(isa["torch_capability"], isa["torch_capability"])
    return "AVX2 (forced)" if isa.get("avx2_forced") else f"{native} (native)"


def benchmark_markdown(report: Mapping[str, Any]) -> str:
    """One sentence on the machine and the run, then a table of the benchmark's figures, one
    column per instruction-set path (the native one, and AVX2 forced where the run has it)."""
    mach = report["machine"]
    paths = {_path_name(mach): report}
    if "avx2_path" in report:
        paths[_path_name(report["avx2_path"]["machine"])] = report["avx2_path"]
    libs = ", ".join(f"{name} {version}" for name, version in mach["libraries"].items())
    threads = mach["torch_threads_default"]
    lines = [f"Measured on {str(report['date'])[:10]} by one run of `make bench` "
             f"({report['total_wall_s']:.0f} s in all) on an {mach['cpu_model']} with "
             f"{mach['usable_cores']} cores and {mach['ram_gib']:.0f} GiB (the CPU has "
             f"{mach['isa']['cpu']}), Python {mach['python']}, torch {mach['torch']} on "
             f"{threads} thread{'' if threads == 1 else 's'}, {libs}; the simulated recording has "
             f"{report['recording']['samples']:,} samples at {report['recording']['fs_hz']:g} Hz. "
             f"Committed as `{BENCHMARK_RUN.as_posix()}`.", "",
             "| figure | " + " | ".join(paths) + " |", "|---|" + "---:|" * len(paths)]
    for key, label, fmt in BENCHMARK_ROWS:
        cells = [fmt.format(p[key]) if p.get(key) is not None else "—" for p in paths.values()]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _minutes(seconds: float) -> str:
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest} s" if minutes else f"{rest} s"


def timings_markdown(commands: Mapping[str, Any], records: Sequence[tuple[str, Mapping[str, Any]]],
                     report: Mapping[str, Any]) -> str:
    """The table of how long the project's commands take: the fresh-clone CI run
    (``commands``, see :data:`COMMANDS_RUN`), the book's last cold and warm runs (the chapters'
    execution ``records``) and the benchmark run (``report``)."""
    def total(key: str) -> str:
        kept = [r.get(key) for _, r in records]
        if not kept or any(k is None for k in kept):
            return "not recorded"
        return _minutes(sum(float(k["seconds"]) for k in kept))

    ci = (f"{commands['date']}, commit {commands['commit']}, {commands['machine']}")
    tests = f"{commands['tests_passed']} passed, {commands['tests_skipped']} skipped"
    return "\n".join([
        "| command | wall time | what it does |",
        "|---|---:|---|",
        f"| `.ci/run` from a fresh clone | {_minutes(commands['ci_run_s'])} | `make test`, then "
        f"`make book` ({ci}) |",
        f"| `make test` (first run: creates `.venv`) | {_minutes(commands['make_test_s'])} | unit "
        f"tests and every chapter in fast mode, on the real data and again without it ({tests}) |",
        f"| `make book` | {_minutes(commands['make_book_s'])} | renders the stored chapters; "
        "executes and trains nothing |",
        f"| `make execute ARGS=\"--all --cold\"` | {total('cold')} | every chapter, every network "
        "trained anew (the chapters' last cold run) |",
        f"| `make execute ARGS=--all` | {total('warm')} | every chapter with every network in the "
        "cache (the chapters' last warm run) |",
        f"| one paper epoch over 50,000 windows | {_minutes(report['paper_epoch_50k_s'])} | "
        f"`make bench`, {_path_name(report['machine'])} |",
        f"| `make bench` | {_minutes(report['total_wall_s'])} | both instruction-set paths where "
        "the CPU has AVX-512 |",
    ])
