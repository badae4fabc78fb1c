"""Command line: ``python -m danae_lite reproduce`` runs the paper's experiment end to end;
``python -m danae_lite leaderboard`` runs every method of :mod:`danae_lite.research.baselines` on the
same split (:func:`danae_lite.research.leaderboard.run_leaderboard`) and writes ``leaderboard.csv``,
``leaderboard.json``, ``leaderboard.png`` and the grid searches into ``--out``; with
``--experiment broad`` (the BROAD benchmark, leaderboard only) also ``broad_trials.csv``, the
benchmark's total, heading and inclination RMSE [deg] per method and test trial. Both share the
data flags below.

The command parses arguments, resolves the data (:mod:`~danae_lite.data.experiments`,
:mod:`~danae_lite.data.oxiod`, :mod:`~danae_lite.data.ucs`) and calls
:func:`danae_lite.paper.pipeline.reproduce`, the same function the book's chapters call: the
paper's KF on every recording -> one DANAE per angle and seed -> the paper's metrics
(:mod:`~danae_lite.evaluate.metrics`) -> the paper's figure (:mod:`~danae_lite.paper.figures`). It writes
into ``--out`` (:meth:`danae_lite.paper.reproduction.Reproduction.write`, plus ``run.json``):

``metrics.json``
    ``{"experiment", "data", "train", "test", "seeds", "kf", "danae", "paper", "seconds"}``;
    ``kf[angle]`` and ``danae[angle]`` hold ``mean_dev``, ``max_dev``, ``rmse`` [rad]
    (``danae`` also ``rmse_std``), ``paper`` the paper's Table 1 or 2 in the same layout (or
    null), ``seconds`` the wall time of the KF, of training + inference, and of the whole
    pipeline (data loading excluded).
``metrics.csv``
    The same numbers, one row per method and angle, with the paper's values beside them.
``seed_table.csv``
    Per test recording, angle, seed and method: the metrics behind the means.
``figureN_<angle>.png`` / ``figureN_<angle>.csv``
    The paper's figure recreated (Figure 1 roll for OxIOD, Figure 2 pitch for UCS) and the
    plotted samples (``time_s``, ``ground_truth``, ``kf``, ``danae``).
``run.json``
    How the run was made: the command, the data note, fast mode, training settings, device.
``models/`` (only with ``--save-models``)
    One checkpoint per angle and seed (:func:`danae_lite.danae.checkpoints.save`).

Metrics are computed on all samples of all test recordings taken together, with errors
wrapped to [-pi, pi). DANAE numbers use the overlap-average reconstruction (every sample is
covered) and are means over seeds; ``rmse_std`` is the sample standard deviation of the RMSE
over seeds (NaN in the CSV and null in the JSON with one seed).

Exit status: 0 on success, 2 for a usage or data error (a one-line message on stderr),
130 when interrupted.
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .runtime import (CACHE_ENV, CACHE_GB_ENV, DATA_ENV, DEFAULT_CACHE_GB, FAST_ENV,
                      FAST_EPOCHS, FAST_MAX_STEPS, FAST_SEEDS, FULL_SEEDS, JOBS_ENV, SCHEDULER_ENV)
from .data.experiments import (FAST_DURATION, FAST_SAMPLES, OXIOD_TEST, OXIOD_TRAIN,
                               PAPER_SPLIT_FOLDER, PAPER_SPLIT_TEST, PAPER_SPLIT_TRAIN,
                               TRAIN_FRACTION)
from .cli_data import UsageError, load_data
from .data import broad as broad_data
from .data import oxiod_motions
from .data.oxiod_motions import FAST_MOTION_RECORDINGS

if TYPE_CHECKING:
    from .runtime import RunSettings
    from .paper.reproduction import Reproduction
    from .danae.train_types import TrainConfig

__all__ = ["main", "build_parser"]

PROG = "python -m danae_lite"
EXPERIMENT_ANGLES: dict[str, tuple[str, ...]] = {"oxiod": ("roll", "pitch", "yaw"), "ucs": ("roll", "pitch"),
                                                  "broad": ("roll", "pitch", "yaw")}
"""Angles evaluated per experiment (the paper reports no UCS yaw; it has no BROAD experiment)."""
PAPER_EPOCHS: dict[str, int] = {"oxiod": 1, "ucs": 100, "broad": 1}
"""Training epochs stated in the paper (BROAD: the OxIOD setting)."""
LEADERBOARD_ONLY = ("broad",)
"""Experiments the paper did not run: ``leaderboard`` only, no ``reproduce``."""


def __getattr__(name: str) -> Any:
    """``CSV_COLUMNS`` is :data:`danae_lite.paper.reproduction.CSV_COLUMNS`, imported on first use (the
    pipeline imports torch, which ``--help`` does not need)."""
    if name == "CSV_COLUMNS":
        from .paper.reproduction import CSV_COLUMNS

        return CSV_COLUMNS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ---------------------------------------------------------------------------------------
# argument parsing
# ---------------------------------------------------------------------------------------
def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {value}")
    return value


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer seed, got {text!r}") from None
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError(f"seeds must be between 0 and {2**32 - 1}, got {value}")
    return value


REPRODUCE_EPILOG = f"""\
data selection:
  Without --train/--test the experiment's recordings are taken from the data directory
  (--data-dir, else ${DATA_ENV}) in their original layout:
    oxiod: <dir>/oxiod/handheld/data1/syn/imuK.csv + viK.csv; train {", ".join(f"imu{k}" for k in OXIOD_TRAIN)}; test {", ".join(f"imu{k}" for k in OXIOD_TEST)}
    ucs:   <dir>/ucs/full_dataset/imu_adis.txt; first {TRAIN_FRACTION:.0%} train, last {1 - TRAIN_FRACTION:.0%} test
    broad: <dir>/broad/data_mat/NN_<name>.mat + trials.json (leaderboard only); train the
           "{broad_data.TRAIN_GROUP}" trials, test the "{broad_data.TEST_GROUP}" ones
  With neither --data-dir nor ${DATA_ENV}, the deterministic simulator stands in (the output
  and metrics.json say "simulated"). A --data-dir without the experiment's folder is an
  error; a ${DATA_ENV} without it lets the simulator stand in, as in the notebooks.

  --split paper (oxiod): the paper's own split, for readers who have OxIOD's slow-walking
    set: <dir>/oxiod/{"/".join(PAPER_SPLIT_FOLDER)}/syn/imuK.csv + viK.csv; train {", ".join(f"imu{k}" for k in PAPER_SPLIT_TRAIN)}; test {", ".join(f"imu{k}" for k in PAPER_SPLIT_TEST)}.
    A missing file is an error naming it. Not with --train/--test or --folds.

  --train/--test name files instead (loaded as "real" data):
    oxiod: imuK.csv files (the Vicon viK.csv beside each is read too) or folders holding
           them (all imuK.csv inside, by K). A side left out takes its default recordings
           from the data directory.
    ucs:   imu_adis.txt files. With --train and --test both given (different files), each
           file is used whole. With a single file (only --train, only --test, or the same
           file for both) that file is split: first {TRAIN_FRACTION:.0%} train, last {1 - TRAIN_FRACTION:.0%} test.
    broad: NN_<name>.mat trial files or folders holding them (all trials inside). A side
           left out takes its default trials from the data directory.

fast mode (--fast or {FAST_ENV}=1):
  OxIOD recordings are cut to their first {FAST_SAMPLES} samples (at most {FAST_MOTION_RECORDINGS} per motion with --folds);
  BROAD trials to their first {broad_data.FAST_SAMPLES} samples (by default the first {broad_data.FAST_TRIALS} of each group);
  simulated ones to {FAST_DURATION["handheld"]:g} s (handheld) or {FAST_DURATION["underwater"]:g} s (underwater).
  The default epochs are capped at {FAST_EPOCHS} and each network at {FAST_MAX_STEPS} optimiser steps (--max-steps overrides).

environment:
  {DATA_ENV}   data directory used when --data-dir is not given
  {FAST_ENV}   1/true/yes/on switches fast mode on (same as --fast)
  {CACHE_ENV}  root of the trained-network cache when --cache is not given (unset: ~/.cache/danae_lite;
               off: no cache); networks go to its full/ or fast/ sub-folder
  {CACHE_GB_ENV}  size cap of each of those sub-folders in GB (default {DEFAULT_CACHE_GB:g}; least recently used removed first)
  {JOBS_ENV}   worker processes used when --jobs is not given (default 1)
  {SCHEDULER_ENV}  Dask scheduler address used when --scheduler is not given (unset: this machine)

example:
  {DATA_ENV}=/data {PROG} reproduce --experiment oxiod --seeds 0 1 2 --out runs/oxiod
"""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``python -m danae_lite``."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Reproduce the DANAE paper (KF -> DANAE -> metrics -> figure) from the command line.",
        epilog=("the book: re-executing its chapters and storing their outputs is book maintenance, not\n"
                "part of this package: from the repository root, python -m tools.execute (make execute;\n"
                "--help lists its flags)."),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    rep = sub.add_parser(
        "reproduce",
        help="run the paper's experiment on one dataset and write metrics, figure and data",
        description=("Run the paper's KF on every recording, train one DANAE per angle and seed on the "
                     "training recordings, evaluate KF and DANAE on the test recordings with the paper's "
                     "metrics (rad, errors wrapped to [-pi, pi)), and recreate the paper's figure."),
        epilog=REPRODUCE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_common(rep, "reproduce")
    rep.add_argument("--save-models", action="store_true",
                     help="also write one checkpoint per angle and seed to OUT/models/. Default: off")
    _add_leaderboard(sub)
    return parser


def _add_leaderboard(sub: Any) -> None:
    """The ``leaderboard`` command and its flags, on the subparsers ``sub``."""
    lb = sub.add_parser(
        "leaderboard",
        help="run every baseline, library filter and DANAE on the same split and write one table",
        description=("Fit every method (a constant at the training mean, the paper's KF, a tuned KF and its "
                     "RTS smoother, Butterworth and moving-average low-pass filters of the KF, a linear window "
                     "map, Fusion, VQF, Madgwick, Mahony, RIANN and DANAE) on the training recordings, evaluate "
                     "each on the test recordings (mean dev, max dev, RMSE [rad] per angle, errors wrapped to "
                     "[-pi, pi), on all and on clean ground-truth samples; a causal column says which use only "
                     "past samples) and write leaderboard.csv, leaderboard.json, leaderboard.png and each grid "
                     "search; for --experiment broad also broad_trials.csv (the benchmark's total, heading and "
                     "inclination RMSE [deg] per method and test trial)."),
        epilog=REPRODUCE_EPILOG.replace("reproduce --experiment oxiod", "leaderboard --experiment oxiod"),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_common(lb, "leaderboard")
    lb.add_argument("--methods", metavar="NAME", nargs="+", default=None, type=_method_name,
                    help="methods to run (default: all): " + " ".join(_method_names())
                    + "; danae-res[FILTER], the recommended denoiser on FILTER's output (e.g. danae-res[vqf]); "
                    "danae-safe[FILTER], DANAE-res with a per-sample fallback and an error bar")
    lb.add_argument("--estimates", action="store_true",
                    help="also write estimates_<method>.csv per method: its roll, pitch, yaw [rad] per test "
                         "recording, seed and sample and, for danae-safe[FILTER], the half-widths of its 68 %% "
                         "(<angle>_sd_rad) and 95 %% (<angle>_hw95_rad) intervals. Not with --folds. Default: off")
    lb.add_argument("--folds", action="store_true",
                    help="cross-validate instead of one split: oxiod -> leave one recording out within each "
                         "motion found (handheld, trolley, multi users) and handheld -> the other motions; broad -> "
                         "undisturbed -> disturbed trials, grouped by disturbance. Every method is refitted per "
                         "split; writes folds.csv (one row per held-out recording), folds_summary.csv (mean and std "
                         "over recordings), folds_params.csv, folds.json (and folds_broad.csv; no_harm.csv when a "
                         "danae-res[FILTER] runs beside its FILTER; coverage.csv for danae-safe[FILTER]). Not with "
                         "--train/--test or ucs")


def _method_name(name: str) -> str:
    """``--methods`` value check: a leaderboard method, ``danae-res[<filter>]`` or ``danae-safe[<filter>]``."""
    from .research.baselines import is_method_name

    if not is_method_name(name):
        raise argparse.ArgumentTypeError(
            f"invalid choice: {name!r} (choose from {', '.join(_method_names())}, danae-res[<filter>] "
            "or danae-safe[<filter>])")
    return name


def _method_names() -> list[str]:
    from .research.baselines import METHODS

    return list(METHODS)


def _add_common(p: argparse.ArgumentParser, command: str) -> None:
    """Arguments shared by ``reproduce`` and ``leaderboard``."""
    p.add_argument("--experiment", choices=tuple(EXPERIMENT_ANGLES), default="oxiod",
                     help="dataset of the experiment: oxiod (roll, pitch, yaw; Table 1, Figure 1), "
                          "ucs (roll, pitch; Table 2, Figure 2) or broad (the BROAD benchmark; leaderboard "
                          "only). Default: oxiod")
    p.add_argument("--data-dir", metavar="DIR", default=None,
                     help=f"folder holding oxiod/, ucs/ and/or broad/ in their original layout. Default: ${DATA_ENV}; "
                          "without either the simulator stands in")
    p.add_argument("--train", metavar="FILE", nargs="+", default=None,
                     help="training recordings (see 'data selection' below). Default: the experiment's "
                          "training recordings in the data directory")
    p.add_argument("--test", metavar="FILE", nargs="+", default=None,
                     help="test recordings (see 'data selection' below). Default: the experiment's test "
                          "recordings in the data directory")
    p.add_argument("--split", choices=("default", "paper"), default="default",
                   help="oxiod only: 'paper' takes the paper's own split from the slow-walking set (see 'data "
                        "selection' below). Default: the book's handheld split")
    p.add_argument("--seeds", metavar="SEED", nargs="+", type=_seed, default=None,
                     help=f"training seeds; one network per angle and seed. Default: {' '.join(map(str, FULL_SEEDS))}, "
                          f"in fast mode {' '.join(map(str, FAST_SEEDS))}")
    p.add_argument("--epochs", metavar="N", type=_positive_int, default=None,
                     help=f"training epochs per network. Default: the paper's ({PAPER_EPOCHS['oxiod']} for oxiod, "
                          f"{PAPER_EPOCHS['ucs']} for ucs), at most {FAST_EPOCHS} in fast mode")
    p.add_argument("--max-steps", metavar="N", type=_positive_int, default=None,
                     help=f"cap on optimiser steps per network. Default: {FAST_MAX_STEPS} in fast mode, "
                          "no cap otherwise")
    p.add_argument("--fast", action="store_true", default=None,
                     help=f"fast mode: shorter recordings and fewer steps (see below). Default: ${FAST_ENV}, else off")
    p.add_argument("--device", metavar="DEV", default=None,
                     help="torch device for training, e.g. cpu, cuda, cuda:1. Default: cpu")
    p.add_argument("--threads", metavar="N", type=_positive_int, default=None,
                     help="torch CPU threads. Default: torch's own (every physical core, or OMP_NUM_THREADS)")
    p.add_argument("--jobs", metavar="N", type=_positive_int, default=None,
                     help=f"worker processes for independent trainings (angles x seeds, and folds with --folds), "
                          f"each with cores/N torch threads; the results do not depend on it. Default: ${JOBS_ENV}, "
                          "else 1")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                     help=f"send the trainings (and filter runs) that would go to worker processes to the Dask "
                          f"cluster whose scheduler is at ADDRESS, e.g. tcp://host:8786; this process keeps "
                          f"the cache. Default: ${SCHEDULER_ENV}, else worker processes on this machine")
    p.add_argument("--cache", metavar="DIR", default=None,
                     help=f"keep trained networks under DIR (its full/ or fast/ sub-folder) and reuse them when "
                          f"the data, settings and code are the same; 'off': cache nothing. Default: ${CACHE_ENV}, "
                          "else the user's cache folder (~/.cache/danae_lite)")
    p.add_argument("--out", metavar="DIR", default=None,
                     help="output folder (created if needed; files in it are overwritten). "
                          f"Default: runs/{command}-<experiment>")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m danae_lite``; returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # --help, or an argparse usage error (already printed)
        return stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 2)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    args.argv = list(sys.argv[1:] if argv is None else argv)
    from .data.recording import DataError
    from .danae.checkpoints import CheckpointError

    try:
        return leaderboard(args) if args.command == "leaderboard" else reproduce(args)
    except (UsageError, DataError, CheckpointError, OSError) as err:
        print(f"{PROG} {args.command}: error: {_one_line(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG} {args.command}: interrupted", file=sys.stderr)
        return 130


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    if isinstance(err, OSError) and err.filename is not None and str(err.filename) not in text:
        text = f"{err.filename}: {text}"
    return text or type(err).__name__


def _check_device(device: str | None) -> str:
    import torch

    try:
        dev = torch.device(device or "cpu")
    except (RuntimeError, ValueError) as err:
        raise UsageError(f"--device {device}: not a torch device ({_one_line(err)})") from None
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

    from .danae.train_types import TrainConfig

    # the paper's settings, validated on windows that tile the tails as in chapters 3-4
    config = settings.train_config(TrainConfig(epochs=PAPER_EPOCHS[args.experiment], val_stride=20))
    given = {k: v for k, v in (("epochs", args.epochs), ("max_steps", args.max_steps),
                               ("num_threads", args.threads)) if v is not None}
    return replace(config, **given)


def _log(line: str) -> None:
    print(line, flush=True)


def _prepare(args: argparse.Namespace) -> tuple[RunSettings, Path, Any, TrainConfig]:
    """Shared start of both subcommands: run settings, output folder, data, training settings."""
    from .runtime import RunSettings

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
        from .danae.networks import use_scheduler

        try:
            use_scheduler(settings.scheduler)
        except OSError as err:  # no scheduler answers at that address
            raise UsageError(f"--scheduler {settings.scheduler}: {_one_line(err)}") from None
    out_dir = _out_dir(args)

    import matplotlib

    matplotlib.use("Agg")
    import torch

    from .paper import pipeline

    exp = load_data(args, settings)
    if args.threads:
        torch.set_num_threads(args.threads)
    config = _train_config(args, settings)
    pipeline.check_lengths(exp, config)
    return settings, out_dir, exp, config


def reproduce(args: argparse.Namespace) -> int:
    """Run the ``reproduce`` subcommand (:func:`danae_lite.paper.pipeline.reproduce`); returns the exit status."""
    from .paper import pipeline

    if args.experiment in LEADERBOARD_ONLY:
        raise UsageError(f"--experiment {args.experiment}: the paper has no such experiment to reproduce; "
                         f"run '{PROG} leaderboard --experiment {args.experiment}'")
    settings, out_dir, exp, config = _prepare(args)
    fast, seeds, device = settings.fast, list(settings.seeds), settings.device
    angles = EXPERIMENT_ANGLES[args.experiment]

    print(exp.note)
    print(f"experiment {exp.name} | data: {exp.data} | mode: {'fast' if fast else 'full'} | "
          f"train {', '.join(r.name for r in exp.train)} | test {', '.join(r.name for r in exp.test)}")
    print(f"training: angles {', '.join(angles)} | seeds {' '.join(map(str, seeds))} | epochs {config.epochs} | "
          f"max steps {config.max_steps if config.max_steps is not None else 'none'} | device {device}", flush=True)
    rep = pipeline.reproduce(exp, angles=angles, seeds=seeds, config=config, progress=sys.stdout.isatty(),
                             cache=settings.cache, jobs=settings.jobs, log=_log)
    written = rep.write(out_dir)
    if args.save_models:
        written += _save_models(rep, out_dir / "models")
    written.append(_write_run_json(args, rep, fast, device, out_dir))

    _print_summary(rep)
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def leaderboard(args: argparse.Namespace) -> int:
    """Run the ``leaderboard`` subcommand (:func:`danae_lite.research.leaderboard.run_leaderboard`)."""
    import time

    import pandas as pd

    from .research.leaderboard import run_leaderboard

    if args.folds:
        return folds(args)
    settings, out_dir, exp, config = _prepare(args)
    fast, seeds, device = settings.fast, list(settings.seeds), settings.device
    methods = args.methods or _method_names()
    print(exp.note)
    print(f"leaderboard {exp.name} | data: {exp.data} | mode: {'fast' if fast else 'full'} | "
          f"train {', '.join(r.name for r in exp.train)} | test {', '.join(r.name for r in exp.test)} | "
          f"methods {' '.join(methods)} | DANAE seeds {' '.join(map(str, seeds))} | device {device}", flush=True)
    t0 = time.perf_counter()
    board = run_leaderboard(exp, methods=methods, seeds=seeds, train_config=config, progress=sys.stdout.isatty(),
                            cache=settings.cache, jobs=settings.jobs)
    written = board.write(out_dir)
    if args.estimates:
        written.update(board.write_estimates(out_dir, list(board.methods)))
    with pd.option_context("display.float_format", "{:.4f}".format, "display.width", 140):
        for subset in ("all", "clean"):
            print(f"\nRMSE [rad] on {subset} test samples (errors wrapped; DANAE: mean over seeds):")
            print(board.wide("rmse", subset).to_string(na_rep="-"))
    if exp.name == "broad":
        trials = board.trial_metrics()
        means = trials.groupby("method", sort=False)[["causal", "total_rmse_deg", "heading_rmse_deg",
                                                     "inclination_rmse_deg"]].agg(
            {"causal": "first", "total_rmse_deg": "mean", "heading_rmse_deg": "mean", "inclination_rmse_deg": "mean"})
        with pd.option_context("display.float_format", "{:.2f}".format, "display.width", 140):
            print(f"\nBROAD metric [deg], mean over the {len(exp.test)} test trials (per trial: broad_trials.csv):")
            print(means.to_string(na_rep="-"))
    print(f"\nalignment: {board.alignment.summary()}")
    print(f"time: {time.perf_counter() - t0:.1f} s; " + ", ".join(f"{k} {v:.1f} s" for k, v in board.seconds.items()))
    print("wrote " + ", ".join(str(p) for p in written.values()))
    return 0


def folds(args: argparse.Namespace) -> int:
    """``leaderboard --folds``: :func:`danae_lite.research.crossval.run_splits` on the experiment's protocol."""
    import time

    import pandas as pd

    from .research import crossval

    if args.experiment == "ucs":
        raise UsageError("--folds: ucs is one recording, there is nothing to hold out; use oxiod or broad")
    if args.estimates:
        raise UsageError("--estimates writes one split's per-sample output; leave it out with --folds")
    if args.train is not None or args.test is not None or args.split != "default":
        raise UsageError("--folds chooses the training and test recordings itself; leave out --train/--test/--split")
    settings, out_dir, _, config = _prepare(args)
    methods = args.methods or _method_names()
    if args.experiment == "oxiod":
        motions = oxiod_motions.load(settings.data_dir, fast=settings.fast, verbose=False)
        recs = motions.recordings
        splits = [s for m, r in recs.items() if len(r) > 1 for s in crossval.leave_one_out(r, m)]
        others = {m: r for m, r in recs.items() if m != "handheld"}
        if others:
            splits.append(crossval.transfer(recs["handheld"], others, "handheld"))
        note, data, aligned = motions.note, motions.data, False
    else:
        exp = load_data(args, settings)
        splits, note, data, aligned = [crossval.broad_transfer(exp.train, exp.test)], exp.note, exp.data, True
    print(note)
    print(f"folds {args.experiment} | data: {data} | mode: {'fast' if settings.fast else 'full'} | {len(splits)} "
          f"splits | methods {' '.join(methods)} | seeds {' '.join(map(str, settings.seeds))} | jobs {settings.jobs}",
          flush=True)
    t0 = time.perf_counter()
    cv = crossval.run_splits(splits, name=args.experiment, data=data, aligned=aligned, methods=methods,
                             seeds=settings.seeds, train_config=config, cache=settings.cache, jobs=settings.jobs,
                             progress=sys.stdout.isatty())
    written = cv.write(out_dir)
    with pd.option_context("display.float_format", "{:.4f}".format, "display.width", 160):
        for protocol in dict.fromkeys(cv.rows.protocol):
            print(f"\nRMSE [rad] on clean samples, {protocol}: mean and std over held-out recordings")
            print(cv.summary("clean", protocol, by_group=True).to_string(na_rep="-"))
    if not cv.trials.empty:
        with pd.option_context("display.float_format", "{:.2f}".format, "display.width", 160):
            print("\nBROAD metric [deg], mean and std over the held-out trials:")
            print(cv.trial_summary().to_string(na_rep="-"))
    if cv.corrections():
        with pd.option_context("display.float_format", "{:.1f}".format, "display.width", 160):
            print("\nNo harm? Each correction against the filter it corrects, per held-out recording "
                  "(change: error reduction [%], negative = worse than the filter):")
            print(cv.no_harm_summary().to_string())
    print(f"time: {time.perf_counter() - t0:.1f} s")
    print("wrote " + ", ".join(str(p) for p in written.values()))
    return 0


def _save_models(rep: Reproduction, folder: Path) -> list[Path]:
    """One checkpoint per angle and seed (:func:`danae_lite.danae.checkpoints.save`)."""
    from .danae.checkpoints import save

    exp = rep.experiment
    return [save(res, folder / f"danae_{angle}_seed{seed}.pt",
                 metadata={"experiment": exp.name, "angle": angle, "seed": seed, "train": rep.train})
            for (angle, seed), res in rep.study.results.items()]


def _write_run_json(args: argparse.Namespace, rep: Reproduction, fast: bool, device: str, out_dir: Path) -> Path:
    """``run.json``: the command, data note, mode, settings and the figure shown."""
    import torch

    from .paper.figures import PAPER_FIGURES

    exp = rep.experiment
    spec = PAPER_FIGURES[exp.name]
    series = rep.figure_series(spec)
    run = {
        "command": " ".join(shlex.quote(a) for a in [PROG, *getattr(args, "argv", [])]),
        "note": exp.note, "fast": fast, "device": device, "threads": torch.get_num_threads(),
        "kf_config": repr(rep.kf_config), "train_config": rep.config.to_dict(),
        "samples": {r.name: len(r) for r in [*exp.train, *exp.test]},
        "figure": {"file": f"{spec.filename}.png", "test": rep.test[0],
                   "samples": [int(series.index[0]), int(series.index[-1]) + 1], "seed": rep.seeds[0]},
    }
    path = out_dir / "run.json"
    path.write_text(json.dumps(run, indent=2) + "\n")
    return path


def _print_summary(rep: Reproduction) -> None:
    """Print the metric table [rad] and the RMSE reductions [%] next to the paper's."""
    import pandas as pd

    from .evaluate.metrics import reduction_pct

    result = rep.to_json()
    shown = rep.metrics_frame().set_index(["method", "angle"])
    with pd.option_context("display.float_format", "{:.4f}".format, "display.width", 140):
        print(f"\nmetrics [rad] on the test recordings ({result['data']} data; DANAE: mean over seeds "
              f"{' '.join(map(str, result['seeds']))}):")
        print(shown.to_string(na_rep="-"))
    red = []
    for angle, kf in result["kf"].items():
        ours = reduction_pct(result["danae"][angle]["rmse"], kf["rmse"])
        paper = result["paper"] or {}
        p_kf, p_dn = paper.get("kf", {}).get(angle), paper.get("danae", {}).get(angle)
        theirs = f"{reduction_pct(p_dn['rmse'], p_kf['rmse']):.1f} %" if p_kf and p_dn else "-"
        red.append(f"{angle} {ours:.1f} % (paper {theirs})")
    print("RMSE reduction by DANAE: " + "; ".join(red))
    s = result["seconds"]
    print(f"time: KF {s['kf']:.1f} s, DANAE {s['train']:.1f} s, total {s['total']:.1f} s")
