"""Train DANAE networks: one per head (angle, or all angles jointly) and seed, cached, in parallel.

This is the one place where the book, the command line and every method of the leaderboard
train networks. :func:`train_networks` takes one input/target array per training recording
for each *head* (``"roll"``, ``"pitch"``, ``"yaw"`` for the paper's one-network-per-angle
DANAE; ``"joint"`` for a variant that predicts all angles at once), and returns a
:class:`~danae_lite.danae.train_types.TrainResult` per ``(head, seed)``.

* **Cache** (``cache``: a :class:`NetworkCache`, a plain folder, or None): passed in by the
  entry point, never read from the environment here. A network is an item of joblib's store
  under its key, a hash of everything that determines it (:func:`cache_key`); a network asked
  for under another tag is the same network and is loaded; a damaged item is reported (a
  warning naming it) and the network trained again in its place. A :class:`NetworkCache`
  with a size cap removes its least recently used networks when a new one would exceed the
  cap (a plain folder has no cap).
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
import torch
from numpy.typing import NDArray

from .checkpoints import checkpoint_dict, result_from_checkpoint
from .seeding import default_device
from .train import train
from .train_types import TrainConfig, TrainResult

Array = NDArray[np.float64]
R = TypeVar("R")

NETWORK_CODE: tuple[str, ...] = (
    "danae_lite.danae.base",  # what every network shares: initialisation, standardisation
    "danae_lite.danae.model",  # the authors' two networks, layer by layer
    "danae_lite.danae.causal",  # the causal network
    "danae_lite.danae.train_types",  # TrainConfig: the network's constructor arguments
    "danae_lite.danae.train",  # the split, the windows' standardisation, the loop, Adam, model selection
    "danae_lite.danae.windows",  # how recordings are cut into windows
    "danae_lite.danae.seeding",  # how the random generators are seeded
)
"""The modules whose source decides a trained network, hashed into its :func:`cache_key`.
Left out: the checkpoints (:mod:`danae_lite.danae.checkpoints`: writing and reading a network
changes no network) and this module (caching and worker processes change no network either),
so editing them keeps the cache."""


@dataclass(frozen=True)
class NetworkCache:
    """Trained networks kept in joblib's store (the storage of a :class:`joblib.Memory` in
    ``folder``), optionally capped in size.

    A network is the item ``networks/<key>`` (:func:`cache_key`), its
    :func:`~danae_lite.danae.checkpoints.checkpoint_dict` with the weights as NumPy arrays:
    plain data. joblib writes an item whole under a temporary name and then renames it, so
    processes sharing the folder never read half of one. Loading a network marks it used;
    storing one past ``max_bytes`` removes the least recently used first (joblib's
    ``reduce_size``). It is a path (``os.fspath(cache)`` is the folder), so it goes wherever a
    cache folder is accepted.
    """

    folder: Path
    """The folder of the :class:`joblib.Memory`."""
    max_bytes: int | None = None
    """Cap on the total size of the stored networks [bytes]; None: no cap."""

    def __fspath__(self) -> str:
        return str(self.folder)

    @functools.cached_property
    def memory(self) -> joblib.Memory:
        """The :class:`joblib.Memory` whose storage holds the networks (it prints nothing)."""
        return joblib.Memory(self.folder, verbose=0)

    def load(self, key: str) -> TrainResult | None:
        """The network stored under ``key``, or None. A damaged item is reported (a warning
        naming it) and removed: the network is trained again in its place."""
        item, backend = ["networks", key], self.memory.store_backend
        where = os.path.join(backend.location, *item, "output.pkl")
        if not backend.contains_item(item):
            return None
        try:
            ckpt = backend.load_item(item, verbose=0)
            os.utime(where)  # used now: the last to go
            ckpt["state_dict"] = {k: torch.from_numpy(v) for k, v in ckpt["state_dict"].items()}
            return result_from_checkpoint(ckpt, where)
        except FileNotFoundError:  # removed meanwhile by another process sharing the folder
            return None
        except Exception as err:  # damaged: trained again, and the item replaced
            warnings.warn(f"{where}: not a readable network ({type(err).__name__}: {err}); it is trained "
                          "again and replaced", stacklevel=3)
            backend.clear_item(item)
            return None

    def save(self, key: str, result: TrainResult, metadata: Mapping[str, Any]) -> None:
        """Store ``result`` under ``key`` with ``metadata``, then keep the store within ``max_bytes``."""
        ckpt = checkpoint_dict(result, metadata=dict(metadata))
        ckpt["state_dict"] = {k: v.numpy() for k, v in ckpt["state_dict"].items()}
        self.memory.store_backend.dump_item(["networks", key], ckpt, verbose=0)
        if self.max_bytes is not None:
            self.memory.reduce_size(bytes_limit=self.max_bytes)


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
    """32 hex digits of a SHA-256 over what decides a trained network: the code of
    :data:`NETWORK_CODE`, torch's and NumPy's versions, the instruction set torch's CPU kernels
    use, the device (:func:`device_name`), the settings (not the thread count, which changes
    only float rounding) and the data."""
    h = hashlib.sha256()
    for name in NETWORK_CODE:
        h.update(module_code(name))
    h.update(f"torch {torch.__version__}; numpy {np.__version__}; {torch.backends.cpu.get_cpu_capability()}; "
             f"{device_name(job.config.device)}".encode())
    settings = {k: v for k, v in job.config.to_dict().items() if k not in ("device", "num_threads")}
    h.update(repr(sorted(settings.items())).encode())
    for a in (*job.inputs, *(job.masks or ()), *job.targets):
        h.update(str(a.shape).encode())
        h.update(np.asarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()[:32]


def device_name(device: str | None) -> str:
    """What a network's key names of the device it trains on: ``cpu``, or ``cuda`` and the
    GPU's model (the GPU's number does not change a network: ``cuda:0`` and ``cuda:1`` of
    one model give the same key)."""
    dev = torch.device(default_device(device))
    if dev.type != "cuda":
        return dev.type
    return f"cuda {torch.cuda.get_device_name(dev.index or 0)}"


def _cached(job: NetworkJob, cache: NetworkCache | None) -> TrainResult | None:
    return None if cache is None else cache.load(cache_key(job))


def _store(job: NetworkJob, res: TrainResult, cache: NetworkCache | None) -> None:
    if cache is not None:
        cache.save(cache_key(job), res, {**job.metadata, "tag": job.tag})


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
        # loky replaces a worker whose memory grew by more than its leak threshold (ours keep
        # what they computed, by design: research.memo) and warns from its manager thread, at
        # any later time; the results do not change, and a chapter would store the warning
        warnings.filterwarnings("ignore", message="A worker stopped while some jobs were given",
                                category=UserWarning, module="joblib.externals.loky.process_executor")
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
    :func:`threads_per_process` torch threads unless the configuration fixes them, and with
    several GPUs one GPU each in turn (:func:`worker_devices`); this process looks the networks
    up in the cache and stores what comes back.
    """
    store = as_cache(cache)
    results: list[TrainResult | None] = [_cached(j, store) for j in jobs_]
    todo = [i for i, r in enumerate(results) if r is None]
    if (jobs > 1 or _scheduler is not None) and len(todo) > 1:
        threads = threads_per_process(jobs)
        devices = worker_devices(jobs_[todo[0]].config.device, len(todo))
        calls = [(replace(jobs_[i], config=replace(_threads(jobs_[i].config, threads), device=device)), False)
                 for i, device in zip(todo, devices)]
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


def worker_devices(device: str | None, calls: int) -> list[str | None]:
    """The device of each of ``calls`` trainings that run side by side: with ``"cuda"`` (no
    number) and several GPUs, the GPUs in turn (``cuda:0``, ``cuda:1``, ...), so that workers
    do not all crowd the first one; otherwise ``device`` for every call. The GPU's number is
    not part of a network's key (:func:`device_name`)."""
    count = torch.cuda.device_count() if device is not None and device.strip().lower() == "cuda" else 0
    if count < 2:
        return [device] * calls
    return [f"cuda:{k % count}" for k in range(calls)]


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
