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
from collections.abc import Mapping
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


_OFF = {"off", "none"}


def default_cache_root() -> Path:
    """The user's cache folder for this package (``~/.cache/danae_lite`` on Linux, or
    ``$XDG_CACHE_HOME/danae_lite``), the convention pip and torch follow."""
    import platformdirs

    return Path(platformdirs.user_cache_dir("danae_lite", appauthor=False))


def cache_dir(path: str | os.PathLike[str] | None = None) -> Path | None:
    """Root folder of the network cache: ``path`` if given, else ``DANAE_CACHE``, else
    :func:`default_cache_root`; None when the value is ``off`` or ``none`` (no cache).

    The folder is created when the first network is stored in it.
    """
    raw = str(path).strip() if path is not None else os.environ.get(CACHE_ENV, "").strip()
    if raw.lower() in _OFF:
        return None
    return Path(raw).expanduser().resolve() if raw else default_cache_root().resolve()


def cache_gb(value: float | None = None) -> float:
    """Size cap of each cache sub-folder [GB]: ``value`` if given, else ``DANAE_CACHE_GB``, else
    :data:`DEFAULT_CACHE_GB`. Raises ``ValueError`` for a value that is not a positive number."""
    raw = str(value) if value is not None else os.environ.get(CACHE_GB_ENV, "").strip() or str(DEFAULT_CACHE_GB)
    try:
        gb = float(raw)
    except ValueError:
        gb = 0.0
    if not gb > 0 or gb == float("inf"):
        origin = "cache_gb" if value is not None else f"${CACHE_GB_ENV}"
        raise ValueError(f"{origin}={raw!r}: expected a positive size in GB")
    return gb


def network_cache(root: Path | None, *, fast: bool, max_gb: float = DEFAULT_CACHE_GB) -> "NetworkCache | None":
    """The cache of one mode: ``<root>/fast`` or ``<root>/full``, capped at ``max_gb`` GB; None
    without a root."""
    from .danae.networks import NetworkCache

    if root is None:
        return None
    return NetworkCache(root / ("fast" if fast else "full"), int(max_gb * 1e9))


def jobs(value: int | None = None) -> int:
    """Worker processes: ``value`` if given, else ``DANAE_JOBS``, else 1. Raises ``ValueError``
    for a value that is not a positive integer."""
    raw = str(value) if value is not None else os.environ.get(JOBS_ENV, "").strip() or "1"
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if n < 1:
        origin = "jobs" if value is not None else f"${JOBS_ENV}"
        raise ValueError(f"{origin}={raw!r}: expected a positive number of worker processes")
    return n


def scheduler(value: str | None = None) -> str | None:
    """The Dask scheduler's address: ``value`` if given, else ``DANAE_SCHEDULER``, else None.
    Raises ``ValueError`` for an address without a protocol and a port (``tcp://host:8786``)."""
    raw = (value if value is not None else os.environ.get(SCHEDULER_ENV, "")).strip()
    if not raw:
        return None
    protocol, _, rest = raw.partition("://")
    if not protocol or not rest or not rest.rpartition(":")[2].isdigit():
        origin = "scheduler" if value is not None else f"${SCHEDULER_ENV}"
        raise ValueError(f"{origin}={raw!r}: expected a Dask scheduler address such as tcp://host:8786")
    return raw


def kernel_environment(*, data_dir: Path | None, cache: Path | None, fast: bool, n_jobs: int,
                       max_gb: float = DEFAULT_CACHE_GB, base: Mapping[str, str] | None = None,
                       scheduler_address: str | None = None) -> dict[str, str]:
    """The environment of a child process (a chapter's kernel) that is to run with these settings.

    ``base`` (default: this process's environment) without any ``DANAE_*`` variable, plus ``DANAE_FAST``,
    ``DANAE_JOBS``, ``DANAE_CACHE`` (the cache root, or ``off`` for None), ``DANAE_CACHE_GB`` and,
    when set, ``DANAE_DATA`` and ``DANAE_SCHEDULER``: what the child's :meth:`RunSettings.from_env`
    reads back.
    """
    env = {k: v for k, v in (os.environ if base is None else base).items() if not k.startswith("DANAE_")}
    env.update({FAST_ENV: "1" if fast else "0", JOBS_ENV: str(n_jobs), CACHE_ENV: str(cache) if cache else "off",
                CACHE_GB_ENV: repr(float(max_gb))})
    if data_dir is not None:
        env[DATA_ENV] = str(data_dir)
    if scheduler_address is not None:
        env[SCHEDULER_ENV] = scheduler_address
    return env


FAST_MAX_STEPS = 50
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
        return network_cache(self.cache_root, fast=self.fast, max_gb=self.cache_gb)

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
