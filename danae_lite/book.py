"""The common first cell of every chapter: ``from danae_lite.book import setup; cfg = setup()``.

It fixes the things every chapter relies on, in one place:

* fast mode (``DANAE_FAST``) — fewer epochs and shorter recordings for CI;
* the real-data directory (``DANAE_DATA``) — or the simulator when it is absent;
* the seeds of python, numpy and torch;
* the plotting style of the book (:mod:`danae_lite.core.plots`);
* torch's CPU threads: torch's own default (every physical core, or ``OMP_NUM_THREADS``).

The command that re-executes the chapters and stores their outputs is
:mod:`danae_lite.execute` (``make execute``); the book only renders those outputs.
"""
from __future__ import annotations

from .config import DEFAULT_SEED, RunSettings
from .core.seeding import seed_everything


def setup(seed: int = DEFAULT_SEED, *, verbose: bool = True) -> RunSettings:
    """Apply the book's common settings and return them (:class:`~danae_lite.config.RunSettings`
    from ``DANAE_FAST``, ``DANAE_DATA``, ``DANAE_CACHE`` and ``DANAE_JOBS``)."""
    from .core import plots

    plots.use_style()
    seed_everything(seed)
    import torch

    # torch's own thread count stands: every physical core, or OMP_NUM_THREADS when set (make
    # test sets 1 per pytest worker so that two workers never oversubscribe two cores)
    cfg = RunSettings.from_env(seed=seed)
    if verbose:
        mode = "FAST (DANAE_FAST=1: reduced steps, data and seeds)" if cfg.fast else "full"
        data = f"{cfg.data_dir}" if cfg.data_dir else "not set (DANAE_DATA unset): the simulator stands in"
        print(f"mode: {mode} | data: {data} | seed: {cfg.seed} | device: {cfg.device} "
              f"({torch.get_num_threads()} CPU threads, {cfg.jobs} worker process(es))")
    return cfg
