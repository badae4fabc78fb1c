"""Random seeds and the torch device: the two run-wide choices that training depends on.

* :func:`seed_everything` -- seed python's ``random``, numpy's global generator and torch.
* :func:`seeding_source` -- the source text of :func:`seed_everything`.
* :func:`default_device` -- the requested torch device, else CUDA when available, else the CPU.

It imports neither :mod:`danae_lite.runtime` nor torch, so the chapters that never train
(the book's ``setup()`` seeds through it) load no torch. Its source is part of a trained network's cache
key (:func:`danae_lite.danae.networks.cache_key`).
"""
from __future__ import annotations

import inspect
import random
import sys

import numpy as np

__all__ = ["default_device", "seed_everything", "seeding_source"]


def seed_everything(seed: int = 0) -> None:
    """Seed python's ``random``, numpy's global generator and, once it is loaded, torch (CPU
    and CUDA): training has loaded it; the book's ``setup()`` of a chapter that never loads
    torch seeds the other two.

    Parameters
    ----------
    seed : int
        The seed of all three generators (0 is :data:`danae_lite.runtime.DEFAULT_SEED`).
    """
    random.seed(seed)
    np.random.seed(seed)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.manual_seed(seed)


def seeding_source() -> str:
    """The source text of :func:`seed_everything`."""
    return inspect.getsource(seed_everything)


def default_device(requested: str | None = None) -> str:
    """Return ``requested`` if given, else ``"cuda"`` when available, else ``"cpu"``."""
    if requested:
        return requested
    import torch

    return "cuda" if torch.cuda.is_available() else "cpu"
