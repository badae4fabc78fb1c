"""Run-time settings: read from the environment by the entry points only, then passed along.

The entry points (the command line, the book's ``setup()``, ``python -m tools.execute``)
build one :class:`RunSettings` from their flags and these variables; everything below them
takes its settings as arguments and never reads the environment.

``DANAE_FAST``
    ``1``/``true``/``yes`` switches every notebook and the CLI to a reduced run (fewer epochs,
    shorter recordings) so that the whole notebook suite runs in minutes. Default: off.
``DANAE_CACHE``
    Folder where trained networks are kept between chapters and runs (keyed by a hash of their
    data, settings and training code), so a later chapter, or a later run, reuses a network
    an earlier one trained. Unset: the user's cache folder (``~/.cache/danae_lite`` on Linux,
    from :func:`platformdirs.user_cache_dir`, as pip and torch keep theirs), so it survives a
    fresh clone. ``off`` (or ``none``): nothing is cached. Full-mode and fast-mode networks
    go to its sub-folders ``full/`` and ``fast/``, capped separately, so that fast runs
    never push out full-mode networks. The research chapters (5-8) also keep there, in
    ``runs/full/`` and ``runs/fast/``, what library filters and trained networks computed on
    recordings (:func:`danae_lite.research.memo.keep_runs`, keyed by the code that computes
    them): a re-execution finds what an earlier one computed with the same code.
``DANAE_CACHE_GB``
    Size cap of each of those sub-folders [GB] (default :data:`DEFAULT_CACHE_GB`): storing a
    network (or run) past it removes the least recently used ones first.
``DANAE_JOBS``
    Worker processes for independent trainings and folds (the book's setting; the command
    line has ``--jobs``). Default 1.
``DANAE_SCHEDULER``
    Address of a Dask scheduler (e.g. ``tcp://host:8786``; the command line has
    ``--scheduler``): the trainings and filter runs that would go to worker processes go to
    that cluster's workers instead (:func:`danae_lite.danae.networks.use_scheduler`). Unset:
    worker processes on this machine.
``DANAE_DATA``
    Directory that holds the real datasets in their original layout, as sub-folders
    ``oxiod/`` (``<setting>/<dataN>/syn/imuK.csv`` + ``viK.csv``), ``broad/``
    (``data_mat/NN_<name>.mat``) and ``ucs/``
    (``full_dataset/imu_adis.txt``). Unset or missing: the simulator stands in.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .data.experiments import existing_dir

if TYPE_CHECKING:  # imported where used: the settings of the KF chapters load no torch
    from .danae.networks import NetworkCache
    from .danae.train_types import TrainConfig


FAST_ENV = "DANAE_FAST"
DATA_ENV = "DANAE_DATA"
CACHE_ENV = "DANAE_CACHE"
CACHE_GB_ENV = "DANAE_CACHE_GB"
DEFAULT_CACHE_GB = 4.0
"""Default cap of each cache sub-folder (``full/``, ``fast/``) [GB]; a full-mode run of the
whole book stores about 1 GB of networks."""
JOBS_ENV = "DANAE_JOBS"
SCHEDULER_ENV = "DANAE_SCHEDULER"
DEFAULT_SEED = 0

_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"", "0", "false", "no", "off"}
_OFF = {"off", "none"}


def _given(value: object, name: str, env: str, default: str = "") -> tuple[str, str]:
    """A setting's text and where it came from: ``value`` if given (``name``), else the variable
    ``env``, else ``default`` (``$env``); stripped."""
    if value is not None:
        return str(value).strip(), name
    return os.environ.get(env, "").strip() or default, f"${env}"


def _positive(value: float | None, name: str, env: str, default: str, kind: type, expected: str) -> Any:
    """A positive finite number of type ``kind`` from :func:`_given`; ValueError naming its origin."""
    raw, origin = _given(value, name, env, default)
    try:
        number = kind(raw)
    except ValueError:
        number = 0
    if not 0 < number < float("inf"):
        raise ValueError(f"{origin}={raw!r}: expected {expected}")
    return number


def fast_mode(value: bool | None = None) -> bool:
    """Return whether fast mode is on: ``value`` if given, else the ``DANAE_FAST`` variable.

    Raises ``ValueError`` for an unrecognised value of ``DANAE_FAST``.
    """
    if value is not None:
        return bool(value)
    raw = os.environ.get(FAST_ENV, "").strip().lower()
    if raw not in _TRUE | _FALSE:
        raise ValueError(f"{FAST_ENV}={raw!r}: expected one of 1/0, true/false, yes/no, on/off")
    return raw in _TRUE


def data_env() -> str | None:
    """The ``DANAE_DATA`` variable as set (None when unset or empty); unlike :func:`data_dir` it
    need not name an existing folder (``data fetch`` creates it)."""
    return os.environ.get(DATA_ENV, "").strip() or None


def data_dir(path: str | os.PathLike[str] | None = None) -> Path | None:
    """Resolve the real-data directory.

    Order: the explicit ``path`` argument, then ``DANAE_DATA``. An explicit path that does
    not exist raises ``FileNotFoundError`` (a user who names a directory means it); an
    environment variable that points nowhere also raises. Returns ``None`` when neither is set.
    """
    if path is not None:
        return existing_dir(path)
    env = data_env()
    if env is None:
        return None
    p = Path(env).expanduser().resolve()
    if not p.is_dir():
        raise FileNotFoundError(f"${DATA_ENV} points to {p}, which is not a directory")
    return p


def cache_dir(path: str | os.PathLike[str] | None = None) -> Path | None:
    """Root folder of the network cache: ``path`` if given, else ``DANAE_CACHE``, else the user's
    cache folder for this package (``~/.cache/danae_lite`` on Linux, or ``$XDG_CACHE_HOME/danae_lite``:
    :func:`platformdirs.user_cache_dir`, the convention pip and torch follow); None when the
    value is ``off`` or ``none`` (no cache).

    The folder is created when the first network is stored in it.
    """
    import platformdirs

    raw, _ = _given(path, "cache", CACHE_ENV)
    if raw.lower() in _OFF:
        return None
    return Path(raw or platformdirs.user_cache_dir("danae_lite", appauthor=False)).expanduser().resolve()


def cache_gb(value: float | None = None) -> float:
    """Size cap of each cache sub-folder [GB]: ``value`` if given, else ``DANAE_CACHE_GB``, else
    :data:`DEFAULT_CACHE_GB`. Raises ``ValueError`` for a value that is not a positive number."""
    return _positive(value, "cache_gb", CACHE_GB_ENV, str(DEFAULT_CACHE_GB), float, "a positive size in GB")


def jobs(value: int | None = None) -> int:
    """Worker processes: ``value`` if given, else ``DANAE_JOBS``, else 1. Raises ``ValueError``
    for a value that is not a positive integer."""
    return _positive(value, "jobs", JOBS_ENV, "1", int, "a positive number of worker processes")


def scheduler(value: str | None = None) -> str | None:
    """The Dask scheduler's address: ``value`` if given, else ``DANAE_SCHEDULER``, else None.
    Raises ``ValueError`` for an address without a protocol and a port (``tcp://host:8786``)."""
    raw, origin = _given(value, "scheduler", SCHEDULER_ENV)
    if not raw:
        return None
    protocol, _, rest = raw.partition("://")
    if not protocol or not rest or not rest.rpartition(":")[2].isdigit():
        raise ValueError(f"{origin}={raw!r}: expected a Dask scheduler address such as tcp://host:8786")
    return raw


FAST_MAX_STEPS = 10
"""Fast mode: cap on optimiser steps per network."""
FAST_EPOCHS = 2
"""Fast mode: cap on the epochs per network."""
FAST_SEEDS: tuple[int, ...] = (0,)
"""Fast mode: training seeds (one network per angle)."""
FULL_SEEDS: tuple[int, ...] = (0, 1, 2)
"""Full mode: training seeds of a single train/test split."""


@dataclass(frozen=True)
class RunSettings:
    """The one settings object of a run (command line, chapter or script).

    Fast mode shrinks the run in one place: :meth:`train_config` caps every network at
    :data:`FAST_MAX_STEPS` optimiser steps and :data:`FAST_EPOCHS` epochs, the default seeds
    become :data:`FAST_SEEDS`, and :func:`danae_lite.data.experiments.load_experiment` shortens the
    recordings (its ``FAST_*`` constants).
    """

    fast: bool = False
    """Fast mode (CI, quick looks): shorter recordings, capped training, one seed."""
    data_dir: Path | None = None
    """Real-data directory (``oxiod/``, ``broad/``, ``ucs/``); None: the simulator stands in."""
    seed: int = DEFAULT_SEED
    """Seed given to python, numpy and torch at the start."""
    seeds: tuple[int, ...] = field(default=FULL_SEEDS)
    """Training seeds of the networks (one network per angle/head and seed)."""
    cache_root: Path | None = None
    """Root of the network cache (holding ``full/`` and ``fast/``), or None for no cache."""
    cache_gb: float = DEFAULT_CACHE_GB
    """Size cap of each cache sub-folder [GB]."""
    jobs: int = 1
    """Worker processes for independent trainings and folds."""
    device: str = "cpu"
    """Torch device of the trainings: the CPU unless asked (``device=`` of :meth:`from_env`)."""
    scheduler: str | None = None
    """Address of the Dask scheduler that takes the parallel work, or None (this machine)."""

    @property
    def cache(self) -> "NetworkCache | None":
        """This mode's network cache (``<cache_root>/full`` or ``/fast``, capped at ``cache_gb``),
        what the library calls take as ``cache=``; None for no cache."""
        from .danae.networks import NetworkCache

        if self.cache_root is None:
            return None
        return NetworkCache(self.cache_root / ("fast" if self.fast else "full"), int(self.cache_gb * 1e9))

    @classmethod
    def from_env(cls, *, fast: bool | None = None, data: str | os.PathLike[str] | None = None,
                 cache: str | os.PathLike[str] | None = None, n_jobs: int | None = None,
                 seeds: tuple[int, ...] | None = None, seed: int = DEFAULT_SEED,
                 device: str | None = None, scheduler_address: str | None = None) -> "RunSettings":
        """Settings from explicit values, falling back to ``DANAE_FAST``, ``DANAE_DATA``,
        ``DANAE_CACHE``, ``DANAE_CACHE_GB``, ``DANAE_JOBS`` and ``DANAE_SCHEDULER``: what an
        entry point calls once. The device is ``device`` if given, else the CPU (a GPU is used
        only when asked for)."""
        is_fast = fast_mode(fast)
        default_seeds = FAST_SEEDS if is_fast else FULL_SEEDS
        return cls(fast=is_fast, data_dir=data_dir(data), seed=seed,
                   seeds=tuple(int(s) for s in (seeds if seeds is not None else default_seeds)),
                   cache_root=cache_dir(cache), cache_gb=cache_gb(), jobs=jobs(n_jobs),
                   device=device or "cpu", scheduler=scheduler(scheduler_address))

    def pick(self, full: Any, fast: Any) -> Any:
        """``fast`` in fast mode, else ``full`` (e.g. ``cfg.pick(full=20, fast=2)`` epochs)."""
        return fast if self.fast else full

    def train_config(self, base: "TrainConfig | None" = None, **overrides: Any) -> "TrainConfig":
        """``base`` (default the paper's :class:`~danae_lite.danae.train_types.TrainConfig`) with
        ``overrides``, this run's device, and in fast mode at most :data:`FAST_EPOCHS` epochs
        and :data:`FAST_MAX_STEPS` steps per network."""
        from .danae.train_types import TrainConfig

        cfg = replace(base or TrainConfig(), **overrides)
        if cfg.device is None:
            cfg = replace(cfg, device=self.device)
        if self.fast:
            steps = FAST_MAX_STEPS if cfg.max_steps is None else min(cfg.max_steps, FAST_MAX_STEPS)
            cfg = replace(cfg, epochs=min(cfg.epochs, FAST_EPOCHS), max_steps=steps)
        return cfg
