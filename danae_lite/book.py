"""The common first cell of every chapter: ``from danae_lite.book import setup; cfg = setup()``.

It fixes the things every chapter relies on, in one place:

* fast mode (``DANAE_FAST``) — fewer epochs and shorter recordings for CI;
* the real-data directory (``DANAE_DATA``) — or the simulator when it is absent;
* the seeds of python, numpy and torch;
* the plotting style of the book (:mod:`danae_lite.plots`);
* a sensible number of torch CPU threads.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from .config import DEFAULT_SEED, data_dir, default_device, fast_mode, seed_everything


@dataclass(frozen=True)
class BookConfig:
    """What a chapter needs to know about the run it is part of."""

    fast: bool
    """Fast mode: shrink epochs and data so the whole book runs in minutes."""
    data_dir: Path | None
    """Directory holding ``oxiod/`` and/or ``ucs/``; ``None`` means the simulator stands in."""
    seed: int
    """Seed given to python, numpy and torch."""
    device: str
    """Torch device used for training (``"cuda"`` when available, else ``"cpu"``)."""

    def pick(self, full: int, fast: int) -> int:
        """Return ``fast`` in fast mode, else ``full`` (e.g. ``cfg.pick(full=20, fast=2)`` epochs)."""
        return fast if self.fast else full


def setup(seed: int = DEFAULT_SEED, *, verbose: bool = True) -> BookConfig:
    """Apply the book's common settings and return them as a :class:`BookConfig`."""
    from . import plots

    plots.use_style()
    seed_everything(seed)
    import torch

    torch.set_num_threads(max(1, min(4, os.cpu_count() or 1)))
    cfg = BookConfig(fast=fast_mode(), data_dir=data_dir(), seed=seed, device=default_device())
    if verbose:
        mode = "FAST (DANAE_FAST=1: reduced epochs and data)" if cfg.fast else "full"
        data = f"{cfg.data_dir}" if cfg.data_dir else "not set (DANAE_DATA unset): the simulator stands in"
        print(f"mode: {mode} | data: {data} | seed: {cfg.seed} | device: {cfg.device}")
    return cfg
