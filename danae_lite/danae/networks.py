"""Train DANAE networks: one per head (angle, or all angles jointly) and seed, cached, in parallel.

This is the one place where the book, the command line and every method of the leaderboard
train networks. :func:`train_networks` takes one input/target array per training recording
for each *head* (``"roll"``, ``"pitch"``, ``"yaw"`` for the paper's one-network-per-angle
DANAE; ``"joint"`` for a variant that predicts all angles at once), and returns a
:class:`~danae_lite.danae.train.TrainResult` per ``(head, seed)``.

* **Cache** (``cache``: a :class:`NetworkCache`, a plain folder, or None): passed in by the
  entry point, never read from the environment here. A network is stored as
  ``<cache>/<tag>-seed<seed>-<key>.pt``, ``key`` hashing everything that determines it
  (:func:`cache_key`); a network with the same key under another tag is the same network and
  is loaded; a damaged file is reported (a warning naming it) and the network trained again
  in its place. A :class:`NetworkCache` with a size cap removes its least recently used files
  when a new one would exceed the cap (a plain folder has no cap).
* **Parallel** (``jobs``): the trainings that the cache does not hold run in ``jobs`` worker
  processes (:func:`in_processes`: :class:`joblib.Parallel`, also used by
  :mod:`danae_lite.research.crossval`), each with ``max(1, cores // jobs)`` torch threads
  (:func:`threads_per_process`) unless the configuration fixes ``num_threads``. With a Dask
  scheduler (:func:`use_scheduler`) the trainings go to the cluster's workers instead, with
  their arrays; this process still looks them up in the cache and stores them.
  A network does not depend on the number of threads beyond float rounding
  (``tests/test_train.py``), so ``jobs`` changes the wall time, not the results.
"""
from __future__ import annotations

import ast
import functools
import hashlib
import importlib
import os
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypeVar

import joblib
import numpy as np
from numpy.typing import NDArray

from .checkpoints import CheckpointError, load_result, save
from .train import train
from .train_types import TrainConfig, TrainResult

Array = NDArray[np.float64]
R = TypeVar("R")

NETWORK_CODE: tuple[str, ...] = (
    "danae_lite.danae.model",  # the layers and their initialisation
    "danae_lite.danae.gemm_conv",  # the convolutions as matrix products
    "danae_lite.danae.train_types",  # TrainConfig: the network's constructor arguments
    "danae_lite.danae.train",  # the split, the windows' standardisation, the loop, Adam, model selection
    "danae_lite.danae.windows",  # how recordings are cut into windows
    "danae_lite.danae.seeding",  # how the random generators are seeded
)
"""The modules whose source decides a trained network, hashed into its :func:`cache_key`.
Left out: the checkpoint files (:mod:`danae_lite.danae.checkpoints`: writing and reading a network
changes no network) and this module (caching and worker processes change no network either),
so editing them keeps the cache."""


@dataclass(frozen=True)
class NetworkCache:
    """A folder of trained networks, optionally capped in size.

    Loading a network marks it used (its modification time is set to now); storing one that
    takes the folder past ``max_bytes`` removes the least recently used files first, never
    the one just stored. It is a path (``os.fspath(cache)`` is the folder), so it goes
    wherever a cache folder is accepted.
    """

    folder: Path
    """Where the ``.pt`` files are."""
    max_bytes: int | None = None
    """Cap on the total size of the folder's ``.pt`` files [bytes]; None: no cap."""

    def __fspath__(self) -> str:
        return str(self.folder)

    def prune(self, keep: Path | None = None) -> list[Path]:
        """Remove the least recently used files until the folder is within ``max_bytes``;
        ``keep`` is never removed. Returns the files removed (oldest first)."""
        return prune_folder(self.folder, "*.pt", self.max_bytes, keep)


def prune_folder(folder: Path, pattern: str, max_bytes: int | None, keep: Path | None = None) -> list[Path]:
    """Remove the least recently used (oldest modification time) files of ``folder`` matching
    ``pattern`` until they total at most ``max_bytes``; ``keep`` is never removed, nor is
    anything when ``max_bytes`` is None. Returns the files removed (oldest first)."""
    if max_bytes is None or not folder.is_dir():
        return []
    files = []
    for f in folder.glob(pattern):
        try:
            st = f.stat()
        except FileNotFoundError:  # removed meanwhile by another process sharing the folder
            continue
        files.append((st.st_mtime, f, st.st_size))
    total = sum(size for _, _, size in files)
    removed = []
    for _, f, size in sorted(files):
        if total <= max_bytes:
            break
        if f == keep:
            continue
        f.unlink(missing_ok=True)
        total -= size
        removed.append(f)
    return removed


def as_cache(cache: str | os.PathLike[str] | None) -> NetworkCache | None:
    """``cache`` as a :class:`NetworkCache` (a plain folder: no size cap), or None."""
    if cache is None or isinstance(cache, NetworkCache):
        return cache
    return NetworkCache(Path(cache).expanduser().resolve())


@dataclass(frozen=True)
class NetworkJob:
    """Everything one training needs: data per training recording, settings, cache name."""

    inputs: tuple[Array, ...]
    """Input per training recording, (N,) or (N, C)."""
    targets: tuple[Array, ...]
    """Target per training recording, (N,) or (N, D), same N."""
    masks: tuple[NDArray[np.bool_], ...] | None
    """Target samples allowed in the loss, per recording; None: all."""
    config: TrainConfig
    tag: str
    metadata: Mapping[str, Any]


def module_code(name: str) -> bytes:
    """The code of module ``name`` without its docstrings and comments (``ast.unparse``), as
    bytes: editing the documentation, or moving the file, keeps the networks."""
    return _code_only(Path(importlib.import_module(name).__file__ or "").read_bytes())


@functools.lru_cache(maxsize=32)
def _code_only(source: bytes) -> bytes:
    """``source`` parsed and unparsed without its docstrings and comments; remembered per source
    text, since every network of a run hashes the same few files (parsing them is slow)."""
    tree = ast.parse(source)
    for node in ast.walk(tree):  # a bare string statement (a docstring) does nothing
        body = getattr(node, "body", None)
        if isinstance(body, list):
            kept = [st for st in body if not (isinstance(st, ast.Expr) and isinstance(st.value, ast.Constant)
                                              and isinstance(st.value.value, str))]
            node.body = kept or [ast.Pass()]
    return ast.unparse(tree).encode()


def cache_key(job: NetworkJob) -> str:
    """16 hex digits of a SHA-256 over the code of :data:`NETWORK_CODE`, the settings
    (not the device or thread count, which change only float rounding) and the data."""
    h = hashlib.sha256()
    for name in NETWORK_CODE:
        h.update(module_code(name))
    settings = {k: v for k, v in job.config.to_dict().items() if k not in ("device", "num_threads")}
    h.update(repr(sorted(settings.items())).encode())
    for a in (*job.inputs, *(job.masks or ()), *job.targets):
        h.update(str(a.shape).encode())
        h.update(np.asarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


def _cached(job: NetworkJob, cache: NetworkCache | None) -> TrainResult | None:
    if cache is None:
        return None
    for found in sorted(cache.folder.glob(f"*-seed{job.config.seed}-{cache_key(job)}.pt")):
        try:
            os.utime(found)  # used now: the last to be removed by the size cap
            return load_result(found)
        except FileNotFoundError:  # removed meanwhile by another process sharing the folder
            continue
        except CheckpointError as err:  # damaged: trained again, and the file replaced
            warnings.warn(f"{err}; the network is trained again and the file replaced", stacklevel=2)
            continue
    return None


def _store(job: NetworkJob, res: TrainResult, cache: NetworkCache | None) -> None:
    if cache is not None:
        cache.folder.mkdir(parents=True, exist_ok=True)
        path = save(res, cache.folder / f"{job.tag}-seed{job.config.seed}-{cache_key(job)}.pt",
                    metadata=dict(job.metadata))
        cache.prune(keep=path)


def _run(job: NetworkJob, progress: bool) -> TrainResult:
    return train(list(job.inputs), list(job.targets), job.config, progress=progress,
                 target_masks=None if job.masks is None else list(job.masks))


def threads_per_process(processes: int) -> int:
    """CPU threads for each of ``processes`` concurrent workers: their share of the CPU cores
    (at least 1), so that together they do not oversubscribe the machine."""
    return max(1, (os.cpu_count() or 1) // processes)


_scheduler: str | None = None
"""The Dask scheduler that :func:`in_processes` sends its calls to (:func:`use_scheduler`);
None: worker processes on this machine."""


def use_scheduler(address: str | None) -> None:
    """Send the calls of :func:`in_processes` (trainings, filter runs) to the Dask cluster whose
    scheduler is at ``address`` (e.g. ``tcp://host:8786``), through joblib's ``dask`` backend;
    None: worker processes on this machine. Set by an entry point (``--scheduler``,
    ``DANAE_SCHEDULER``); dask is imported only here, when an address is given."""
    global _scheduler
    if address is not None:
        _dask_client(address)  # connect now: a wrong address fails at the entry point
    _scheduler = address


@functools.lru_cache(maxsize=None)
def _dask_client(address: str) -> Any:
    """One :class:`distributed.Client` per scheduler address for the life of the process."""
    from distributed import Client

    return Client(address, set_as_default=False)


def in_processes(fn: Callable[..., R], calls: Sequence[tuple[Any, ...]], *, processes: int,
                 threads: int, local: bool = False) -> Iterator[R]:
    """``fn(*args)`` for each ``args`` of ``calls`` with :class:`joblib.Parallel`, results in order.

    On this machine (no :func:`use_scheduler` address, or ``local``): ``processes`` worker
    processes of joblib's ``loky`` backend, kept between calls with the same settings, so a
    worker imports the package once and keeps what it remembered from one call to the next
    (:mod:`danae_lite.research.memo`); each runs ``threads`` CPU threads (joblib's
    ``inner_max_num_threads``: torch's and the BLAS thread pools). Arrays reach the workers as
    copies (no memory-mapping: a network trained on them must not see read-only arrays).
    With a scheduler: every worker of the Dask cluster (joblib's ``dask`` backend), each
    running the calls with the threads the cluster gives it; the calls and their arrays travel
    to the workers and the results come back, so the workers need no shared disk or data.

    Parameters
    ----------
    fn : a module-level function (it is pickled to the workers, as are its arguments).
    calls : one tuple of positional arguments per call.
    processes : worker processes on this machine.
    threads : CPU threads in each of them (e.g. :func:`threads_per_process`).
    local : on this machine even when a scheduler is set (calls that read files by path).

    Yields
    ------
    The result of each call, in the order of ``calls``, as soon as it and those before it are
    done. If a call raises, the calls not yet started are cancelled and the error is raised.
    """
    if _scheduler is None or local:
        config = joblib.parallel_config(backend="loky", inner_max_num_threads=threads)
        n_jobs = processes
    else:
        config = joblib.parallel_config(backend="dask", client=_dask_client(_scheduler))
        n_jobs = -1
    with config:
        run = joblib.Parallel(n_jobs=n_jobs, return_as="generator", max_nbytes=None, verbose=0)
        yield from run(joblib.delayed(_leaving_ctrl_c)(fn, *args) for args in calls)


def _leaving_ctrl_c(fn: Callable[..., R], *args: Any) -> R:
    """``fn(*args)`` in a worker that leaves Ctrl-C (SIGINT) to the parent process, which stops
    the calls not yet started; the worker finishes the call it is running. (A notebook's kernel
    sends SIGINT to its whole process group when it is interrupted or shut down: each worker
    would otherwise print a ``KeyboardInterrupt`` traceback.) A Dask worker runs calls in
    threads of its own, which receive no signal: nothing to do there."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    return fn(*args)


def run_jobs(jobs_: Sequence[NetworkJob], *, cache: str | os.PathLike[str] | None = None, jobs: int = 1,
             progress: bool = False) -> list[TrainResult]:
    """Train every job (or load it from ``cache``); results in the order of ``jobs_``.

    ``jobs`` > 1 trains the missing networks in that many worker processes, or on the Dask
    cluster of :func:`use_scheduler` (see the module docstring), each with
    :func:`threads_per_process` torch threads unless the configuration fixes them; this process
    looks the networks up in the cache and stores what comes back.
    """
    store = as_cache(cache)
    results: list[TrainResult | None] = [_cached(j, store) for j in jobs_]
    todo = [i for i, r in enumerate(results) if r is None]
    if (jobs > 1 or _scheduler is not None) and len(todo) > 1:
        threads = threads_per_process(jobs)
        calls = [(replace(jobs_[i], config=_threads(jobs_[i].config, threads)), False) for i in todo]
        for res, i in zip(in_processes(_run, calls, processes=jobs, threads=threads), todo):
            results[i] = res
            _store(jobs_[i], res, store)
    else:
        for i in todo:
            results[i] = _run(jobs_[i], progress)
            _store(jobs_[i], results[i], store)
    return [r for r in results if r is not None]


def pretrain(jobs_: Sequence[NetworkJob], *, cache: str | os.PathLike[str] | None, jobs: int) -> int:
    """Train the networks of ``jobs_`` that ``cache`` lacks, all in one pool of ``jobs`` worker
    processes, and store them there: what a caller does before fitting several methods or
    splits one after the other, so that every worker stays busy (three seeds on two workers
    would leave one idle a third of the time). The fits then find their networks in the cache.
    The largest trainings start first (:func:`_work`); the same network asked for twice (one
    :func:`cache_key`) is trained once. Nothing is trained without a cache, or with one
    process and no Dask scheduler. Returns the number of networks trained."""
    store = as_cache(cache)
    if store is None or (jobs <= 1 and _scheduler is None):
        return 0
    missing = {cache_key(j): j for j in jobs_ if _cached(j, store) is None}
    run_jobs(sorted(missing.values(), key=_work, reverse=True), cache=store, jobs=jobs)
    return len(missing)


def _work(job: NetworkJob) -> float:
    """A rough measure of a training's work, to start the largest first (the last to finish
    then keeps a worker idle for less): optimiser steps times window length."""
    c = job.config
    windows = sum(max(0, len(x) - c.window + 1) for x in job.inputs)
    steps = c.epochs * windows / c.batch_size
    return min(steps, c.max_steps or steps) * c.window


def _threads(config: TrainConfig, threads: int) -> TrainConfig:
    return config if config.num_threads is not None else replace(config, num_threads=threads)


def train_networks(
    inputs: Mapping[str, Sequence[Array]],
    targets: Mapping[str, Sequence[Array]],
    config: TrainConfig,
    seeds: Sequence[int] | Mapping[str, Sequence[int]],
    *,
    masks: Sequence[NDArray[np.bool_]] | Mapping[str, Sequence[NDArray[np.bool_]]] | None = None,
    tag: str = "danae",
    metadata: Mapping[str, Any] | None = None,
    cache: str | os.PathLike[str] | None = None,
    jobs: int = 1,
    progress: bool = False,
) -> dict[tuple[str, int], TrainResult]:
    """One network per head and seed: DANAE's training, for every caller.

    Parameters
    ----------
    inputs, targets : ``{head: [array per training recording]}``, the same heads in both;
        arrays (N,) or (N, C) in the units of the signal (rad for angles).
    config : training settings; its ``seed`` is replaced by each of ``seeds``.
    seeds : training seeds (distinct): one list for every head, or ``{head: list}``.
    masks : per training recording, the target samples allowed in the loss: one list shared by
        the heads, or ``{head: list}`` when the heads train on different recordings.
    tag : file-name prefix in the cache (``<tag>-<head>``).
    metadata : stored with each cached network (plus ``head`` and ``seed``).
    cache, jobs, progress : see :func:`run_jobs`.

    Returns
    -------
    dict
        ``{(head, seed): TrainResult}``.
    """
    keys, work = network_jobs(inputs, targets, config, seeds, masks=masks, tag=tag, metadata=metadata)
    return dict(zip(keys, run_jobs(work, cache=cache, jobs=jobs, progress=progress)))


def network_jobs(
    inputs: Mapping[str, Sequence[Array]],
    targets: Mapping[str, Sequence[Array]],
    config: TrainConfig,
    seeds: Sequence[int] | Mapping[str, Sequence[int]],
    *,
    masks: Sequence[NDArray[np.bool_]] | Mapping[str, Sequence[NDArray[np.bool_]]] | None = None,
    tag: str = "danae",
    metadata: Mapping[str, Any] | None = None,
) -> tuple[list[tuple[str, int]], list[NetworkJob]]:
    """The ``(head, seed)`` keys and the jobs that :func:`train_networks` trains, in the same
    order, for the same arguments; without training (e.g. for :func:`pretrain`)."""
    if set(inputs) != set(targets):
        raise ValueError(f"inputs and targets must have the same heads, got {sorted(inputs)} and {sorted(targets)}")
    per_head = seeds if isinstance(seeds, Mapping) else {head: seeds for head in inputs}
    if set(per_head) != set(inputs):
        raise ValueError(f"seeds must have the heads of the inputs, got {sorted(per_head)} and {sorted(inputs)}")
    per_head = {head: [int(s) for s in per_head[head]] for head in inputs}
    for head, ss in per_head.items():
        if not ss or len(set(ss)) != len(ss):
            raise ValueError(f"seeds of head {head!r} must be distinct and non-empty, got {ss}")
    if isinstance(masks, Mapping) and set(masks) != set(inputs):
        raise ValueError(f"masks must have the heads of the inputs, got {sorted(masks)} and {sorted(inputs)}")
    keys, work = [], []
    for head in inputs:
        mh = masks[head] if isinstance(masks, Mapping) else masks
        m = None if mh is None else tuple(np.ascontiguousarray(x, dtype=bool) for x in mh)
        xs = tuple(np.ascontiguousarray(a) for a in inputs[head])
        ys = tuple(np.ascontiguousarray(a) for a in targets[head])
        for seed in per_head[head]:
            keys.append((head, seed))
            work.append(NetworkJob(xs, ys, m, replace(config, seed=seed), f"{tag}-{head}",
                                   {**(metadata or {}), "head": head, "seed": seed}))
    return keys, work
