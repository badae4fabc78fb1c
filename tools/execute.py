"""The one command that re-executes the chapters: ``python -m tools.execute`` (``make execute``).

The book renders the outputs committed with the notebooks (``execute_notebooks: "off"`` in
``_config.yml``) and never executes them itself; this command produces them. Each executed
notebook carries a record of its run in ``metadata["danae"]["execution"]`` (:func:`stamp`), so
that a test, and this command, can tell when its code changed afterwards (:func:`stale_reason`);
a run with ``--cold`` (every network trained, in a new empty cache) is kept a second time, in
``metadata["danae"]["cold_execution"]`` (:func:`cold_record`), and a run that trained no network
in ``metadata["danae"]["warm_execution"]`` (:func:`warm_record`), each until the next run of its
kind, so that each chapter can state its cold and its warm run time whichever of the two the
stored outputs come from. See :func:`execute_book` for its safety rule and :func:`main` for its flags.
"""
from __future__ import annotations

import argparse
import hashlib
import os
import platform
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Mapping, MutableMapping, Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

from danae_lite.runtime import (CACHE_ENV, CACHE_GB_ENV, DATA_ENV, DEFAULT_CACHE_GB, FAST_ENV,
                                JOBS_ENV, SCHEDULER_ENV, RunSettings)
from tools import conditions as machine

if TYPE_CHECKING:
    import pandas as pd


CELL_SEPARATOR = "\n# -- cell --\n"
"""Joins the code cells' sources before hashing, so that moving text across cells changes the hash."""


INLINE_BACKEND = "module://matplotlib_inline.backend_inline"
"""matplotlib backend of the kernels: figures are stored in the notebook as PNG outputs (an
inherited ``MPLBACKEND=Agg`` would draw them nowhere and leave the book without figures)."""

class BookExecutionError(RuntimeError):
    """A chapter could not be (or must not be) re-executed; the message says which and why."""


def _source(cell: Mapping[str, Any]) -> str:
    """A cell's source as one string (nbformat JSON stores it as a string or a list of lines)."""
    src = cell.get("source", "")
    return src if isinstance(src, str) else "".join(src)


def code_hash(nb: Mapping[str, Any]) -> str:
    """SHA-256 of a notebook's code, as a hex string.

    Parameters
    ----------
    nb
        The notebook, as an ``nbformat.NotebookNode`` or as the plain JSON dictionary.

    Returns
    -------
    str
        The hex digest of the sources of the code cells, in order, joined by
        :data:`CELL_SEPARATOR`. Markdown cells, outputs and metadata do not enter it.
    """
    code = [_source(c) for c in nb.get("cells", []) if c.get("cell_type") == "code"]
    return hashlib.sha256(CELL_SEPARATOR.join(code).encode("utf-8")).hexdigest()


DATA_FOLDERS = ("oxiod", "ucs", "broad")
"""The dataset folders of a data directory that the chapters read (see :mod:`danae_lite.data.experiments`)."""


def data_fingerprint(data_dir: str | os.PathLike[str] | None) -> str:
    """SHA-256 of the data the chapters can read, as a hex string ("" for ``None``: the simulator).

    Every file under the data directory's :data:`DATA_FOLDERS`, in sorted order, enters with its
    path relative to the data directory and its content, so renaming, adding, removing or editing
    a recording changes it; where the directory lives does not. Reading the ~120 MB of the book's
    datasets takes well under a second.
    """
    if data_dir is None:
        return ""
    base = Path(data_dir).expanduser().resolve()
    h = hashlib.sha256()
    for folder in DATA_FOLDERS:
        for f in sorted(p for p in (base / folder).rglob("*") if p.is_file()):
            h.update(f.relative_to(base).as_posix().encode("utf-8") + b"\0")
            with open(f, "rb") as fh:
                h.update(hashlib.file_digest(fh, "sha256").digest())
    return h.hexdigest()


def execution_record(nb: Mapping[str, Any]) -> dict[str, Any] | None:
    """The record of the run that produced a notebook's outputs.

    Parameters
    ----------
    nb
        The notebook, as an ``nbformat.NotebookNode`` or as the plain JSON dictionary.

    Returns
    -------
    dict or None
        ``nb.metadata["danae"]["execution"]`` (see :func:`stamp`), or ``None`` when the
        notebook was never executed by :func:`execute_notebook`.
    """
    record = (nb.get("metadata") or {}).get("danae", {}).get("execution")
    return dict(record) if isinstance(record, Mapping) else None


def stale_reason(nb: Mapping[str, Any], stem: str, data_sha256: str | None = None) -> str | None:
    """Why a chapter's stored outputs cannot be trusted to match its code, or None when they can.

    The book renders the stored outputs without executing anything, so they must come from a
    full-mode, real-data run (:func:`execution_record`) of the code cells as they are now
    (:func:`code_hash`), by this version of danae_lite, with a record of the data it read
    (:func:`data_fingerprint`); given ``data_sha256`` (the fingerprint of the data at hand), also
    of that data. Markdown cells do not enter: editing prose keeps a chapter fresh.
    """
    from danae_lite._version import __version__

    rerun = (f"re-execute it with real data: DANAE_DATA=/path/to/data make execute "
             f"(or: python -m tools.execute --only {stem})")
    record = execution_record(nb)
    if record is None:
        return (f"{stem}: its stored outputs carry no execution record (metadata.danae.execution), so its "
                f"code cells may have changed after they were produced; {rerun}")
    problems = []
    if record.get("code_sha256") != code_hash(nb):
        problems.append("its code cells changed after its stored outputs were produced")
    if record.get("danae_lite_version") != __version__:
        problems.append(f"its outputs come from danae_lite {record.get('danae_lite_version')}, not {__version__}")
    if record.get("data") != "real":
        problems.append(f"its outputs come from {record.get('data')} data, not the real data")
    if record.get("fast") is not False:
        problems.append("its outputs come from a fast-mode run")
    if not record.get("data_sha256"):
        problems.append("its record carries no fingerprint of the data it read (data_sha256)")
    elif data_sha256 and record["data_sha256"] != data_sha256:
        problems.append("the data it read differs from the data at hand (data_sha256)")
    return f"{stem}: {'; '.join(problems)}; {rerun}" if problems else None


def stale_chapters(paths: Sequence[Path], data_sha256: str | None = None) -> list[Path]:
    """The chapters among ``paths`` whose stored outputs are stale (:func:`stale_reason`), in order."""
    import nbformat

    return [p for p in paths if stale_reason(nbformat.read(p, as_version=4), p.stem, data_sha256) is not None]


def chapter_records(paths: Sequence[Path]) -> list[tuple[str, dict[str, Any]]]:
    """(chapter name, :func:`execution_record`) of each notebook in ``paths``, in order; a
    chapter that once ran cold has its :func:`cold_record` under the key ``"cold"``, one that
    once ran warm its :func:`warm_record` under ``"warm"`` (a stored run that trained no network
    and was not the cold one is a warm run, kept or not).

    Raises ValueError naming the notebook when one carries no record."""
    import nbformat

    records = []
    for path in paths:
        nb = nbformat.read(path, as_version=4)
        record = execution_record(nb)
        if record is None:
            raise ValueError(f"{path}: no execution record (metadata.danae.execution); run "
                             "python -m tools.execute first")
        for key, kept in (("cold", cold_record(nb)), ("warm", warm_record(nb))):
            if kept is not None:
                record[key] = kept
        cold = record.get("cold")
        ran_cold = cold is not None and cold.get("executed") == record.get("executed")
        if "warm" not in record and record.get("networks_trained") == 0 and not ran_cold:
            record["warm"] = {k: v for k, v in record.items() if k != "cold"}   # it ran warm
        records.append((Path(path).stem, record))
    return records


def _kept_record(nb: Mapping[str, Any], key: str) -> dict[str, Any] | None:
    record = (nb.get("metadata") or {}).get("danae", {}).get(key)
    return dict(record) if isinstance(record, Mapping) else None


def cold_record(nb: Mapping[str, Any]) -> dict[str, Any] | None:
    """The record of the chapter's last run from an empty network cache (``--cold``), kept in
    ``nb.metadata["danae"]["cold_execution"]`` through later warm runs; ``None`` if it never ran cold."""
    return _kept_record(nb, "cold_execution")


def warm_record(nb: Mapping[str, Any]) -> dict[str, Any] | None:
    """The record of the chapter's last run that trained no network (not ``--cold``: every
    network it needs found in the cache), kept in ``nb.metadata["danae"]["warm_execution"]``
    through later cold runs; ``None`` if it never ran so."""
    return _kept_record(nb, "warm_execution")


SAME_OUTPUTS = ("code_sha256", "data_sha256", "data", "fast")
"""Fields of two execution records that must agree for both runs to have computed the same outputs."""


def keep_run(nb: MutableMapping[str, Any], record: Mapping[str, Any], *, cold: bool) -> None:
    """Keep the run of ``record`` a second time: as the chapter's :func:`cold_record` when it ran
    ``cold``, as its :func:`warm_record` when it trained no network; otherwise keep neither
    (a run that trained some networks and found others is neither cold nor warm). A kept record
    of other code cells or other data (:data:`SAME_OUTPUTS`) is dropped: it timed other outputs."""
    danae = nb["metadata"]["danae"]
    for key in ("cold_execution", "warm_execution"):
        kept = danae.get(key)
        if isinstance(kept, Mapping) and any(kept.get(f) != record.get(f) for f in SAME_OUTPUTS):
            del danae[key]
    if cold:
        nb["metadata"]["danae"]["cold_execution"] = dict(record)
    elif record.get("networks_trained") == 0:
        nb["metadata"]["danae"]["warm_execution"] = dict(record)


def write_pages(root: Path, folder: Path) -> None:
    """Rewrite the blocks of ``README.md``, ``book/performance.md`` and the chapters' opening
    cells that quote the stored chapters of ``_toc.yml`` in ``folder``, the committed benchmark
    run and the committed CI timings (:mod:`tools.pages`); names each page that moved.

    Raises ValueError when a chapter carries no execution record or a page lacks its block."""
    from tools import pages

    if not (root / "book" / "performance.md").is_file():
        return                                  # not the book's repository: nothing to quote
    paths = [folder / f"{c}.ipynb" for c in toc_chapters(root)]
    records = chapter_records(paths)
    for path, (_, record) in zip(paths, records):
        if pages.update_notebook_block(path, "run-time", pages.run_time_markdown(record)):
            print(f"{path.name}: its run time rewritten from its execution record")
    report = pages.read_run(root, pages.BENCHMARK_RUN)
    timings = pages.timings_markdown(pages.read_run(root, pages.COMMANDS_RUN), records, report)
    performance = root / "book" / "performance.md"
    blocks = [(performance, "chapter-times", pages.times_markdown(records)),
              (performance, "benchmark", pages.benchmark_markdown(report)),
              (performance, "timings", timings), (root / "README.md", "timings", timings)]
    for page, name, content in blocks:
        if pages.update_block(page, name, content):
            print(f"{page.relative_to(root)}: block {name!r} rewritten from the stored runs")


def stamp(nb: MutableMapping[str, Any], *, seconds: float, data_dir: str | os.PathLike[str] | None,
          fast: bool, executed: datetime | None = None, networks: tuple[int, int] | None = None,
          data_sha256: str = "", conditions: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Write the record of a run into ``nb.metadata["danae"]["execution"]`` and return it.

    Parameters
    ----------
    nb
        The executed notebook (modified in place).
    seconds
        Wall time of the run [s]; stored rounded to 0.1 s.
    data_dir
        The real-data directory the run used, or ``None`` for the simulator. Only its last
        path component is stored, never the absolute path of the machine that ran it.
    fast
        Whether the run was in fast mode.
    executed
        When the run happened; default now. Stored in UTC, to the second.
    networks
        (networks trained, networks found in the cache) by the run, when known: a run that
        found none in the cache ran cold, one that trained none ran warm.
    data_sha256
        :func:`data_fingerprint` of ``data_dir`` ("" for the simulator).
    conditions
        Under which conditions the run's numbers hold (:func:`tools.conditions.probe`: CPU,
        oneDNN's instruction set, torch threads, jobs; and the machine's load at the start and
        end of the run), when known.

    Returns
    -------
    dict
        The record: ``code_sha256`` (:func:`code_hash`), ``danae_lite_version``, ``data``
        (``"real"`` or ``"simulated"``), ``data_dir``, ``data_sha256``, ``fast``, ``seconds``, ``executed``,
        ``python`` and ``torch`` versions, with ``networks`` given ``networks_trained`` and
        ``networks_cached``, and with ``conditions`` given ``conditions``.
    """
    from importlib.metadata import PackageNotFoundError, version

    from danae_lite._version import __version__

    try:
        torch_version = version("torch")
    except PackageNotFoundError:
        torch_version = ""
    when = (executed or datetime.now(timezone.utc)).astimezone(timezone.utc)
    record: dict[str, Any] = {
        "code_sha256": code_hash(nb),
        "danae_lite_version": __version__,
        "data": "real" if data_dir else "simulated",
        "data_dir": Path(data_dir).name if data_dir else "",
        "data_sha256": data_sha256 if data_dir else "",
        "fast": bool(fast),
        "seconds": round(float(seconds), 1),
        "executed": when.isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "torch": torch_version,
    }
    if networks is not None:
        record["networks_trained"], record["networks_cached"] = (int(n) for n in networks)
    if conditions is not None:
        record["conditions"] = dict(conditions)
    metadata = nb.setdefault("metadata", {})
    metadata.setdefault("danae", {})["execution"] = record
    return record


KERNELSPEC = {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"}
"""The kernelspec JupyterLab writes into a chapter it opens with the project's kernel."""


def as_jupyterlab_saves(nb: MutableMapping[str, Any]) -> None:
    """Set the metadata JupyterLab would rewrite on opening ``nb`` to what it writes, so that
    reading a chapter leaves the tree clean: the kernelspec (:data:`KERNELSPEC`), and each cell's
    ``collapsed``, which JupyterLab copies from ``jupyter.outputs_hidden``."""
    nb.setdefault("metadata", {})["kernelspec"] = dict(KERNELSPEC)
    for cell in nb.get("cells", []):
        meta = cell.setdefault("metadata", {})
        hidden = meta.get("jupyter", {}).get("outputs_hidden")
        if hidden is None:
            meta.pop("collapsed", None)
        else:
            meta["collapsed"] = bool(hidden)


def _write_atomically(nb: Any, target: Path) -> None:
    """Write ``nb`` (nbformat v4) to ``target`` through a temporary file in the same folder,
    its metadata as JupyterLab saves it (:func:`as_jupyterlab_saves`).

    An interruption leaves either the old file or the new one, never half of one.
    """
    import nbformat

    as_jupyterlab_saves(nb)

    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "x", encoding="utf-8") as fh:
            nbformat.write(nb, fh, version=4)
        if target.exists():
            shutil.copymode(target, tmp)
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def execute_notebook(path: str | os.PathLike[str], *, out_path: str | os.PathLike[str],
                     env: Mapping[str, str], data_dir: Path | None, fast: bool, timeout: float | None,
                     networks: Path | None = None, data_sha256: str = "", cold: bool = False,
                     conditions: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Execute one notebook in a fresh ``python3`` kernel and write it, with its record, to ``out_path``.

    The kernel runs in the notebook's own folder (as Jupyter Book runs it) with exactly the
    environment ``env``. Nothing is written unless every cell succeeds, and the write goes
    through a temporary file, so ``out_path`` (possibly ``path`` itself) is never left half
    written.

    Parameters
    ----------
    path
        The notebook to execute.
    out_path
        Where to write the executed notebook (nbformat v4); may be ``path``.
    env
        The whole environment of the kernel (:func:`kernel_environment`).
    data_dir, fast, data_sha256
        The data directory and fast mode that ``env`` gives the kernel, and the data's
        :func:`data_fingerprint`, for the record (:func:`stamp`).
    timeout
        Limit for each cell [s]; ``None`` for no limit.
    networks
        The network cache folder of this mode (``<cache>/full`` or ``/fast``), whose files
        tell the networks the chapter trained and loaded (:func:`_network_counts`); None: not
        counted.
    cold
        The run started from an empty cache (``--cold``): its record is kept a second time,
        as the chapter's :func:`cold_record`, which later warm runs leave in place (a run that
        is not cold and trains no network is kept as its :func:`warm_record`, see :func:`keep_run`).
    conditions
        :func:`tools.conditions.probe` of ``env``, recorded with the machine's load at the
        start and end of the run; None: not recorded.

    Returns
    -------
    dict
        The record stamped into the notebook (:func:`stamp`): ``seconds`` is the wall time of
        the execution, kernel start included.

    Raises
    ------
    BookExecutionError
        When a cell fails or runs past ``timeout``; the message names the notebook and the
        cell (its index among all cells) and ends with the cell's error.
    """
    import nbformat
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError, CellTimeoutError, DeadKernelError

    path = Path(path).resolve()
    out_path = Path(out_path)
    kernel_env = dict(env)
    nb = nbformat.read(path, as_version=4)
    current: dict[str, int] = {"index": -1}

    def on_cell_start(cell: Any, cell_index: int) -> None:
        current["index"] = cell_index

    for cell in nb.cells:  # per-cell timestamps would make every re-execution a diff of every cell
        cell.metadata.pop("execution", None)
    client = NotebookClient(nb, timeout=timeout, kernel_name="python3", allow_errors=False, record_timing=False,
                            resources={"metadata": {"path": str(path.parent)}},
                            on_cell_start=on_cell_start)
    before, started = _network_files(networks), time.time()
    load_start = machine.load()
    start = time.perf_counter()
    try:
        client.execute(cwd=str(path.parent), env=kernel_env)
    except (CellExecutionError, CellTimeoutError, DeadKernelError) as exc:
        where = f"cell {current['index']}" if current["index"] >= 0 else "the kernel start"
        if isinstance(exc, CellExecutionError):
            detail = f"{exc.ename}: {exc.evalue}"
        else:
            lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
            detail = lines[-1] if lines else type(exc).__name__
        raise BookExecutionError(f"{path.name}: {where} failed: {detail}") from exc
    seconds = time.perf_counter() - start
    counts = _network_counts(before, _network_files(networks), started) if networks is not None else None
    held = None if conditions is None else {**conditions, "load_start": load_start, "load_end": machine.load()}
    record = stamp(nb, seconds=seconds, data_dir=data_dir, fast=fast, networks=counts, data_sha256=data_sha256,
                   conditions=held)
    keep_run(nb, record, cold=cold)
    _write_atomically(nb, out_path)
    return record


def _refusal(data_dir: Path | None, fast: bool) -> str | None:
    """Why writing in place is refused for these settings, or ``None`` when it is allowed."""
    reasons = ([] if data_dir else ["without real data (no --data-dir, DANAE_DATA unset)"]) + (
        ["in fast mode"] if fast else [])
    if not reasons:
        return None
    replaced = " and ".join((["simulator"] if not data_dir else []) + (["fast-mode"] if fast else []))
    return (f"refusing to re-execute the chapters in place {' and '.join(reasons)}: the committed notebooks "
            f"hold a full-mode run on real data, and {replaced} outputs would replace them; "
            "pass --out DIR to write executed copies elsewhere, or --data-dir DIR (and no --fast) "
            "to re-execute them in place")


def kernel_environment(*, data_dir: Path | None, cache: Path | None, fast: bool, n_jobs: int,
                       max_gb: float = DEFAULT_CACHE_GB, base: Mapping[str, str] | None = None,
                       scheduler_address: str | None = None) -> dict[str, str]:
    """The environment of a child process (a chapter's kernel) that is to run with these settings.

    ``base`` (default: this process's environment) without any ``DANAE_*`` variable, plus ``DANAE_FAST``,
    ``DANAE_JOBS``, ``DANAE_CACHE`` (the cache root, or ``off`` for None), ``DANAE_CACHE_GB`` and,
    when set, ``DANAE_DATA`` and ``DANAE_SCHEDULER``: what the child's
    :meth:`~danae_lite.runtime.RunSettings.from_env` reads back.
    """
    env = {k: v for k, v in (os.environ if base is None else base).items() if not k.startswith("DANAE_")}
    env.update({FAST_ENV: "1" if fast else "0", JOBS_ENV: str(n_jobs), CACHE_ENV: str(cache) if cache else "off",
                CACHE_GB_ENV: repr(float(max_gb))})
    if data_dir is not None:
        env[DATA_ENV] = str(data_dir)
    if scheduler_address is not None:
        env[SCHEDULER_ENV] = scheduler_address
    return env


def _kernel_setup(data: Path | None, cache: Path | None, *, fast: bool, jobs: int,
                  cache_gb: float, scheduler: str | None = None) -> tuple[dict[str, str], Path | None]:
    """The kernels' environment (:func:`kernel_environment`, inline figures, a
    fixed hash seed) and this mode's network cache folder (created; None without a cache)."""
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
    env = kernel_environment(data_dir=data, cache=cache, fast=fast, n_jobs=jobs, max_gb=cache_gb,
                             scheduler_address=scheduler)
    env.update({"MPLBACKEND": INLINE_BACKEND, "PYTHONHASHSEED": "0"})
    return env, cache / ("fast" if fast else "full") if cache is not None else None


ROW_COLUMNS = ["notebook", "seconds", "networks_trained", "networks_cached", "data", "fast", "written"]
"""Columns of the table :func:`execute_book` returns, one row per notebook."""


def _row(path: Path, target: Path, record: Mapping[str, Any], *, data: Path | None, fast: bool) -> dict[str, Any]:
    """The table row of one executed notebook (see :data:`ROW_COLUMNS`)."""
    return {"notebook": path.name, "seconds": record.get("seconds"), "networks_trained": record.get("networks_trained"),
            "networks_cached": record.get("networks_cached"), "data": "real" if data else "simulated", "fast": fast,
            "written": str(target)}


def _one_line(row: Mapping[str, Any]) -> str:
    """What a run prints for one chapter: its seconds, the networks trained and found, where it went."""
    trained, cached = row["networks_trained"], row["networks_cached"]
    counted = f", {trained} network(s) trained, {cached} found in the cache" if cached is not None else ""
    return f"{Path(row['notebook']).stem}: {row['seconds']:.1f} s{counted} -> {row['written']}"


def execute_book(notebooks: Sequence[str | os.PathLike[str]], *, data_dir: str | os.PathLike[str] | None,
                 cache_dir: str | os.PathLike[str] | None, fast: bool, jobs: int = 1, cache_gb: float = DEFAULT_CACHE_GB,
                 out_dir: str | os.PathLike[str] | None = None, timeout: float | None = 3600,
                 progress: bool = True, cold: bool = False, scheduler: str | None = None) -> pd.DataFrame:
    """Execute chapters one after the other and write them with their outputs.

    The committed notebooks hold a full-mode run on real data. They are therefore rewritten
    in place (``out_dir=None``) only when ``data_dir`` is set and ``fast`` is False; any other
    run must name an ``out_dir``, where executed copies are written under the same file names.

    Parameters
    ----------
    notebooks
        The notebooks, in the order to run them (the order of ``_toc.yml``: a later chapter
        reuses the networks an earlier one cached).
    data_dir
        Real-data directory, given to the kernel as ``DANAE_DATA``; ``None`` removes
        ``DANAE_DATA`` from its environment, and the simulator stands in.
    cache_dir
        Root of the network cache, given as ``DANAE_CACHE``; ``None`` gives ``off`` (no cache).
    cache_gb
        Size cap of each cache sub-folder [GB], given as ``DANAE_CACHE_GB``.
    fast
        Fast mode, given as ``DANAE_FAST`` (``"1"``/``"0"``).
    jobs
        Worker processes of each chapter's trainings and folds, given as ``DANAE_JOBS``.
    out_dir
        Folder for executed copies; ``None`` writes each notebook in place.
    timeout
        Limit for each cell [s]; ``None`` for no limit.
    progress
        Show a progress bar and print each chapter's time as it finishes.
    cold
        ``cache_dir`` was empty when the first chapter started: each chapter's record is kept
        as its cold record too (:func:`cold_record`).
    scheduler
        Address of a Dask scheduler, given as ``DANAE_SCHEDULER`` (the chapters' trainings then
        run on that cluster); None: worker processes on this machine.

    Returns
    -------
    pandas.DataFrame
        One row per notebook: ``notebook`` (file name), ``seconds``, ``networks_trained`` and
        ``networks_cached`` (files the chapter added to, and loaded from, the cache folder of its
        mode; None without a cache; also stored in its record), ``data`` (``"real"`` or ``"simulated"``), ``fast`` and ``written`` (the path written).

    Raises
    ------
    BookExecutionError
        Before anything runs, when an in-place run lacks real data or is in fast mode, or a
        notebook is missing; during the run, when a cell fails (the chapters before it are
        written, the failing one and those after it are left as they were).
    """
    import pandas as pd
    from tqdm.auto import tqdm

    paths = [Path(p).resolve() for p in notebooks]
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise BookExecutionError(f"no such notebook: {', '.join(missing)}")
    data = Path(data_dir).expanduser().resolve() if data_dir else None
    out = Path(out_dir).expanduser().resolve() if out_dir is not None else None
    in_place = out is None or any(p.parent == out for p in paths)  # "copies" into their own folder
    if in_place and (why := _refusal(data, fast)):
        raise BookExecutionError(why)
    cache = Path(cache_dir).expanduser().resolve() if cache_dir is not None else None
    env, networks = _kernel_setup(data, cache, fast=fast, jobs=jobs, cache_gb=cache_gb, scheduler=scheduler)
    if out is not None and not in_place:
        out.mkdir(parents=True, exist_ok=True)
        if progress:
            print(f"writing executed copies to {out}; the notebooks in place are left unchanged")
    fingerprint = data_fingerprint(data)
    held = machine.probe(env)  # once: every kernel of this run gets this environment
    rows: list[dict[str, Any]] = []
    bar = tqdm(paths, desc="chapters", unit="nb", disable=not progress, leave=False)
    for path in bar:
        bar.set_postfix_str(path.stem)
        target = out / path.name if out is not None else path
        record = execute_notebook(path, out_path=target, env=env, data_dir=data, fast=fast, timeout=timeout,
                                  networks=networks, data_sha256=fingerprint, cold=cold, conditions=held)
        rows.append(_row(path, target, record, data=data, fast=fast))
        if progress:
            bar.write(_one_line(rows[-1]))
    bar.close()
    table = pd.DataFrame(rows, columns=ROW_COLUMNS)
    if progress and rows:
        print(f"{len(rows)} notebook(s) executed in {table['seconds'].sum():.1f} s")
    return table


def _network_files(folder: Path | None) -> dict[str, float]:
    """Network key -> modification time [s since the epoch] of the networks in a cache folder
    (the items of its joblib store, :class:`~danae_lite.danae.networks.NetworkCache`)."""
    if folder is None or not folder.is_dir():
        return {}
    found = {}
    for f in folder.glob("networks/*/output.pkl"):
        try:
            found[f.parent.name] = f.stat().st_mtime
        except FileNotFoundError:  # removed meanwhile by the size cap
            continue
    return found


def _network_counts(before: Mapping[str, float], after: Mapping[str, float], start: float) -> tuple[int, int]:
    """(networks trained, networks found in the cache) by a run that started at ``start``: the
    networks it added, and the older ones it loaded (loading marks a network used, see
    :class:`~danae_lite.danae.networks.NetworkCache`)."""
    trained = sum(1 for name in after if name not in before)
    cached = sum(1 for name, mtime in after.items() if name in before and mtime >= start)
    return trained, cached


def find_root(start: str | os.PathLike[str] | None = None) -> Path:
    """The repository root: the first folder holding ``_toc.yml``, from ``start`` (default cwd) upward.

    Raises
    ------
    BookExecutionError
        When no such folder exists.
    """
    here = Path(start or Path.cwd()).resolve()
    for folder in (here, *here.parents):
        if (folder / "_toc.yml").is_file():
            return folder
    raise BookExecutionError(f"no _toc.yml in {here} or above it: run this from inside the book's repository")


def toc_chapters(root: str | os.PathLike[str]) -> list[str]:
    """Stems of the chapters listed in ``<root>/_toc.yml`` under ``notebooks/``, in the book's order."""
    toc = (Path(root) / "_toc.yml").read_text(encoding="utf-8")
    return re.findall(r"^\s*-?\s*file:\s*[\"']?notebooks/([^\s\"'/]+?)(?:\.ipynb)?[\"']?\s*(?:#.*)?$",
                      toc, flags=re.MULTILINE)


_EPILOG = """\
safety rule:
  The committed notebooks hold a full-mode run on real data, and the book renders those
  outputs as they are. The notebooks are therefore rewritten in place only for a full-mode
  run with real data (--data-dir DIR or DANAE_DATA, and no --fast). Without real data, or
  with --fast, the command refuses to start unless --out DIR names a folder for the
  executed copies. A chapter whose cell fails is left untouched.

examples:
  DANAE_DATA=/path/to/data python -m tools.execute                 # the stale chapters, in place
  DANAE_DATA=/path/to/data python -m tools.execute --all --cold    # every chapter, every network trained
  ... --all --cold --cache NEW_DIR      # the same, in a new cache kept for later warm runs
  python -m tools.execute --data-dir /path/to/data --only 03_danae  # one chapter, in place
  python -m tools.execute --fast --out _build/fast_notebooks        # simulator, fast, copies
"""


def _stale_or_say_so(paths: Sequence[Path], data_sha256: str) -> list[Path]:
    """The stale chapters among ``paths`` (``data_sha256``: the data at hand, see
    :func:`stale_reason`); prints which chapters are fresh and left as they are."""
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise BookExecutionError(f"no such notebook: {', '.join(missing)}")
    stale = stale_chapters(paths, data_sha256)
    fresh = [p.stem for p in paths if p not in stale]
    if fresh:
        print(f"up to date, left as they are: {', '.join(fresh)} (--all re-executes them too)")
    if not stale:
        print("every chapter's stored outputs match its code: nothing to re-execute")
    return stale


def _cold_cache(requested: str | None, temporary: Path) -> Path:
    """Cache root of a ``--cold`` run: the ``--cache`` folder ``requested`` (kept afterwards),
    which must be empty or absent, else ``temporary`` (removed afterwards)."""
    if requested is None or requested == "off":
        return temporary
    folder = Path(requested).expanduser().resolve()
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise BookExecutionError(f"--cold --cache {folder}: a cold run needs an empty or absent "
                                 "folder; choose a new one or leave --cache out (a temporary cache)")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _parser() -> argparse.ArgumentParser:
    """The command line of :func:`main`."""
    parser = argparse.ArgumentParser(
        prog="python -m tools.execute", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Re-execute the book's chapters, in the order of _toc.yml, and store their outputs\n"
                    "and a record of the run in the notebooks. The book itself (make book) only renders\n"
                    "the stored outputs; this is the one command that produces them (make execute).",
        epilog=_EPILOG)
    parser.add_argument("--data-dir", metavar="DIR", default=None,
                        help=f"folder holding the real data (oxiod/, ucs/); default ${DATA_ENV}")
    parser.add_argument("--cache", metavar="DIR", default=None,
                        help=f"root of the network cache shared by the chapters and later runs ('off': none); "
                             f"default ${CACHE_ENV}, else the user's cache folder (~/.cache/danae_lite)")
    parser.add_argument("--cold", action="store_true",
                        help="run cold: train every network, in a new empty cache that the chapters of this "
                             "run share and that is removed afterwards (the user's cache is left as it is); "
                             "with --cache DIR, in DIR, which must be empty or absent and is kept for warm runs")
    parser.add_argument("--fast", action=argparse.BooleanOptionalAction, default=None,
                        help=f"fast mode (fewer epochs, shorter recordings); default ${FAST_ENV}")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="write executed copies to DIR instead of rewriting the notebooks in place")
    parser.add_argument("--only", metavar="CHAPTER", action="append", default=None,
                        help="run this chapter, e.g. 03_danae, stale or not (repeatable); default: in place, "
                             "the chapters of _toc.yml whose stored outputs are stale; with --out, every chapter")
    parser.add_argument("--all", action="store_true",
                        help="re-execute every chapter of _toc.yml, stale or not")
    parser.add_argument("--notebooks-dir", metavar="DIR", default=None,
                        help="folder of the chapters; default notebooks/ in the repository root "
                             "(the folder holding _toc.yml, from the current directory upward)")
    parser.add_argument("--jobs", metavar="N", type=int, default=None,
                        help=f"worker processes for the chapters' independent trainings and folds; default "
                             f"${JOBS_ENV}, else 1 (make execute: one per core). The outputs do not depend on it")
    parser.add_argument("--timeout", metavar="S", type=float, default=3600.0,
                        help="limit for each cell in seconds (default 3600)")
    parser.add_argument("--pages", action="store_true",
                        help="execute nothing: rewrite the blocks of README.md and book/performance.md that "
                             "quote the stored chapters (every run in place does it too)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m tools.execute`` (``make execute``). Returns the exit status.

    Parameters
    ----------
    argv
        Arguments (default ``sys.argv[1:]``); ``--help`` lists them.

    Returns
    -------
    int
        0 on success; 2 for a refused run, a missing data folder or notebook, an unknown
        chapter or a failing cell, with one line on stderr.
    """
    args = _parser().parse_args(argv)

    try:
        root = find_root()
        folder = Path(args.notebooks_dir).resolve() if args.notebooks_dir else root / "notebooks"
        if args.pages:
            write_pages(root, folder)
            return 0
        chapters = toc_chapters(root)
        if not chapters:
            raise BookExecutionError(f"{root / '_toc.yml'} lists no chapter under notebooks/")
        if args.only:
            wanted = {Path(name).name.removesuffix(".ipynb") for name in args.only}
            unknown = sorted(wanted - set(chapters))
            if unknown:
                raise BookExecutionError(f"unknown chapter {', '.join(unknown)} for --only: "
                                         f"expected one of {', '.join(chapters)}")
            chapters = [c for c in chapters if c in wanted]
        paths = [folder / f"{c}.ipynb" for c in chapters]
        settings = RunSettings.from_env(fast=args.fast, data=args.data_dir, cache=args.cache, n_jobs=args.jobs)
        if not (args.only or args.all or args.out):
            paths = _stale_or_say_so(paths, data_fingerprint(settings.data_dir))
            if not paths:
                return 0
        with tempfile.TemporaryDirectory(prefix="danae_cold_cache_") as tmp:
            cache = _cold_cache(args.cache, Path(tmp)) if args.cold else settings.cache_root
            execute_book(paths, data_dir=settings.data_dir, cache_dir=cache, cache_gb=settings.cache_gb,
                         fast=settings.fast, jobs=settings.jobs, out_dir=args.out,
                         timeout=args.timeout if args.timeout > 0 else None, cold=args.cold,
                         scheduler=settings.scheduler)
        if args.out is None:
            try:
                write_pages(root, folder)
            except ValueError as exc:           # the run itself succeeded: say why, go on
                print(f"pages not rewritten: {exc}", file=sys.stderr)
    except (BookExecutionError, FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: the chapter that was running is left as it was", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
