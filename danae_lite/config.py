"""Run-time settings read from the environment: fast mode, data directory, seeds, device.

``DANAE_FAST``
    ``1``/``true``/``yes`` switches every notebook and the CLI to a reduced run (fewer epochs,
    shorter recordings) so that the whole notebook suite runs in minutes. Default: off.
``DANAE_CACHE``
    Directory where trained networks are kept between chapters (keyed by a hash of their
    data and settings), so a later chapter reuses a network an earlier one trained. Unset:
    no cache. ``make book`` and ``make test`` set it to ``_build/danae_cache``.
``DANAE_DATA``
    Directory that holds the real datasets in their original layout, as sub-folders
    ``oxiod/`` (``<setting>/<dataN>/syn/imuK.csv`` + ``viK.csv``), ``broad/``
    (``data_mat/NN_<name>.mat``) and ``ucs/``
    (``full_dataset/imu_adis.txt``). Unset or missing: the simulator stands in.
"""
from __future__ import annotations

import os
import random
from pathlib import Path

import numpy as np

FAST_ENV = "DANAE_FAST"
DATA_ENV = "DANAE_DATA"
CACHE_ENV = "DANAE_CACHE"
DEFAULT_SEED = 0

_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"", "0", "false", "no", "off"}


def fast_mode(value: bool | None = None) -> bool:
    """Return whether fast mode is on: ``value`` if given, else the ``DANAE_FAST`` variable.

    Raises ``ValueError`` for an unrecognised value of ``DANAE_FAST``.
    """
    if value is not None:
        return bool(value)
    raw = os.environ.get(FAST_ENV, "").strip().lower()
    if raw in _TRUE:
        return True
    if raw in _FALSE:
        return False
    raise ValueError(f"{FAST_ENV}={raw!r}: expected one of 1/0, true/false, yes/no, on/off")


def data_dir(path: str | os.PathLike[str] | None = None) -> Path | None:
    """Resolve the real-data directory.

    Order: the explicit ``path`` argument, then ``DANAE_DATA``. An explicit path that does
    not exist raises ``FileNotFoundError`` (a user who names a directory means it); an
    environment variable that points nowhere also raises. Returns ``None`` when neither is set.
    """
    if path is None:
        env = os.environ.get(DATA_ENV, "").strip()
        if not env:
            return None
        path, origin = env, f"${DATA_ENV}"
    else:
        origin = "data directory argument"
    p = Path(path).expanduser().resolve()
    if not p.is_dir():
        raise FileNotFoundError(f"{origin} points to {p}, which is not a directory")
    return p


def cache_dir(path: str | os.PathLike[str] | None = None) -> Path | None:
    """Directory for cached trained networks: ``path`` if given, else ``DANAE_CACHE``, else None.

    The directory is created when needed.
    """
    raw = str(path) if path is not None else os.environ.get(CACHE_ENV, "").strip()
    if not raw:
        return None
    p = Path(raw).expanduser().resolve()
    p.mkdir(parents=True, exist_ok=True)
    return p


def seed_everything(seed: int = DEFAULT_SEED) -> None:
    """Seed python's ``random``, numpy's global generator and torch (CPU and CUDA)."""
    random.seed(seed)
    np.random.seed(seed)
    try:
        import torch
    except ImportError:  # torch is a dependency, but keep the data layer importable without it
        return
    torch.manual_seed(seed)


def default_device(requested: str | None = None) -> str:
    """Return ``requested`` if given, else ``"cuda"`` when available, else ``"cpu"``."""
    if requested:
        return requested
    import torch

    return "cuda" if torch.cuda.is_available() else "cpu"
