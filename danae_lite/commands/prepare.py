"""What both subcommands share: the experiments' angles and the paper's epochs, the run settings,
output folder, data and training settings of a run (:func:`prepare`), and one-line errors."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .data_flags import UsageError, load_data

if TYPE_CHECKING:
    from ..runtime import RunSettings
    from ..danae.train_types import TrainConfig

PROG = "python -m danae_lite"
EXPERIMENT_ANGLES: dict[str, tuple[str, ...]] = {"oxiod": ("roll", "pitch", "yaw"), "ucs": ("roll", "pitch"),
                                                  "broad": ("roll", "pitch", "yaw")}
"""Angles evaluated per experiment (the paper reports no UCS yaw; it has no BROAD experiment)."""
PAPER_EPOCHS: dict[str, int] = {"oxiod": 1, "ucs": 100, "broad": 1}
"""Training epochs stated in the paper (BROAD: the OxIOD setting)."""
LEADERBOARD_ONLY = ("broad",)
"""Experiments the paper did not run: ``leaderboard`` only, no ``reproduce``."""


def one_line(err: BaseException) -> str:
    """``err`` as one line of text, naming the file of an OSError."""
    text = " ".join(str(err).split())
    if isinstance(err, OSError) and err.filename is not None and str(err.filename) not in text:
        text = f"{err.filename}: {text}"
    return text or type(err).__name__


def _check_device(device: str | None) -> str:
    import torch

    try:
        dev = torch.device(device or "cpu")
    except (RuntimeError, ValueError) as err:
        raise UsageError(f"--device {device}: not a torch device ({one_line(err)})") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise UsageError(f"--device {device}: CUDA is not available on this machine; use --device cpu")
    return str(dev)


def _out_dir(args: argparse.Namespace) -> Path:
    out_dir = Path(args.out if args.out is not None else f"runs/{args.command}-{args.experiment}").expanduser()
    if out_dir.exists() and not out_dir.is_dir():
        raise UsageError(f"--out {out_dir}: exists and is not a folder")
    return out_dir


def _train_config(args: argparse.Namespace, settings: RunSettings) -> TrainConfig:
    """The training settings: the paper's epochs, capped by fast mode (:meth:`RunSettings.train_config`),
    then ``--epochs``/``--max-steps``/``--threads`` as given."""
    from dataclasses import replace

    from ..danae.train_types import TrainConfig

    # the paper's settings, validated on windows that tile the tails as in chapters 3-4
    config = settings.train_config(TrainConfig(epochs=PAPER_EPOCHS[args.experiment], val_stride=20))
    given = {k: v for k, v in (("epochs", args.epochs), ("max_steps", args.max_steps),
                               ("num_threads", args.threads)) if v is not None}
    return replace(config, **given)


def prepare(args: argparse.Namespace) -> tuple[RunSettings, Path, Any, TrainConfig]:
    """Shared start of both subcommands: run settings, output folder, data, training settings."""
    from ..runtime import RunSettings

    seeds = None if args.seeds is None else tuple(int(s) for s in args.seeds)  # None: the mode's default
    if seeds is not None and len(set(seeds)) != len(seeds):
        raise UsageError(f"--seeds {' '.join(map(str, seeds))}: each seed may appear only once")
    device = _check_device(args.device)
    try:
        settings = RunSettings.from_env(fast=args.fast, data=args.data_dir, cache=args.cache, n_jobs=args.jobs,
                                        seeds=seeds, device=device, scheduler_address=args.scheduler)
    except ValueError as err:  # an unrecognised DANAE_FAST, DANAE_JOBS or scheduler value
        raise UsageError(str(err)) from None
    if settings.scheduler is not None:
        from ..danae.networks import use_scheduler

        try:
            use_scheduler(settings.scheduler)
        except OSError as err:  # no scheduler answers at that address
            raise UsageError(f"--scheduler {settings.scheduler}: {one_line(err)}") from None
    out_dir = _out_dir(args)

    import matplotlib

    matplotlib.use("Agg")
    import torch

    from ..paper import pipeline

    exp = load_data(args, settings)
    if args.threads:
        torch.set_num_threads(args.threads)
    config = _train_config(args, settings)
    pipeline.check_lengths(exp, config)
    return settings, out_dir, exp, config
