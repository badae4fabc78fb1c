"""Command line: ``python -m danae_lite data where|check|fetch`` shows, checks and downloads the
data (:mod:`danae_lite.commands.data`); ``python -m danae_lite reproduce`` runs the paper's
experiment end to end (:mod:`danae_lite.commands.reproduce`, which lists the files it writes);
``python -m danae_lite leaderboard`` runs every method on the same split, or cross-validates with
``--folds`` (:mod:`danae_lite.commands.leaderboard`). This module parses the arguments and runs
the one command asked for; the last two share the data flags
(:mod:`danae_lite.commands.data_flags`). Building the parser imports no torch and no pandas, so
``--help`` answers at once.

Exit status: 0 on success, 2 for a usage or data error (a one-line message on stderr),
1 when ``data check`` finds a problem or ``data fetch`` fails, 130 when interrupted.
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from .runtime import (CACHE_ENV, CACHE_GB_ENV, DATA_ENV, DEFAULT_CACHE_GB, FAST_ENV,
                      FAST_EPOCHS, FAST_MAX_STEPS, FAST_SEEDS, FULL_SEEDS, JOBS_ENV, SCHEDULER_ENV)
from .data.experiments import FAST_DURATION, FAST_SAMPLES, OXIOD_TEST, OXIOD_TRAIN, TRAIN_FRACTION
from .data import broad as broad_data
from .data.oxiod_motions import FAST_MOTION_RECORDINGS
from .data.fetch import BROAD_URL
from .data.inventory import EXPERIMENTS
from ._version import __version__
from .commands.data_flags import PAPER_SPLIT_FOLDER, PAPER_SPLIT_TEST, PAPER_SPLIT_TRAIN, UsageError
from .commands.method_names import METHOD_NAMES, is_method_name
from .commands.prepare import EXPERIMENT_ANGLES, PAPER_EPOCHS, PROG, one_line

__all__ = ["main", "build_parser"]


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
        epilog=("start with: python -m danae_lite data check (is the data folder the book's copy?)\n\n"
                "the book: its chapters are re-executed, and their outputs stored, from the repository\n"
                "root with python -m tools.execute (make execute; --help lists its flags); make book\n"
                "renders them into _build/html."),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s (danae_lite) {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_data(sub)
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
                    help="methods to run (default: all): " + " ".join(METHOD_NAMES)
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
    if not is_method_name(name):
        raise argparse.ArgumentTypeError(
            f"invalid choice: {name!r} (choose from {', '.join(METHOD_NAMES)}, danae-res[<filter>] "
            "or danae-safe[<filter>])")
    return name


def _add_data(sub: Any) -> None:
    """The ``data`` command and its subcommands, on the subparsers ``sub``."""
    data = sub.add_parser(
        "data", help="the data folder: where it is, whether it is the book's copy, download BROAD",
        description="The data folder (--data-dir, else $DANAE_DATA): where each experiment reads, whether "
                    "its files are the book's reference copies, and the public BROAD trials downloaded into it.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    cmds = data.add_subparsers(dest="data_command", metavar="SUBCOMMAND", required=True)
    folder_help = f"the data folder. Default: ${DATA_ENV}"
    where = cmds.add_parser("where", help="the data folder in use and what each experiment would read from it",
                            description="Print the data folder in use and, per dataset, the files the book "
                                        "reads from it and what the chapters do without them.")
    where.add_argument("--data-dir", metavar="DIR", default=None, help=folder_help)
    check = cmds.add_parser(
        "check", help="per dataset: files present, missing, malformed or different from the book's copy",
        description="Check every file the book reads: present or missing; read by the book's loader (wrong "
                    "columns, rows or an unreadable .mat are 'malformed', naming the file and line); SHA-256 "
                    "against the book's reference copies ('differs': the numbers will differ from the book's). "
                    "UCS has no reference copy: its format is checked only.",
        epilog="exit status: 0 when everything present is the book's copy (an optional dataset may be absent);\n"
               "1 when OxIOD handheld is missing, a file is malformed or differs, or a dataset is present in part.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    check.add_argument("--data-dir", metavar="DIR", default=None, help=folder_help)
    check.add_argument("--experiment", nargs="+", choices=tuple(EXPERIMENTS), default=None,
                       help="check only these experiments' datasets. Default: all")
    fetch = cmds.add_parser(
        "fetch", help="download the BROAD trials the book uses (CC BY 4.0), checksums verified",
        description="Download exactly the BROAD trials the book uses, each from a URL pinned to one commit of "
                    "the benchmark's repository, verify each against the book's SHA-256 and move it into "
                    "<data>/broad/data_mat only then (a verified file is kept: a second run resumes). OxIOD "
                    "and UCS are distributed by their authors: it prints where to get them and where they go.")
    fetch.add_argument("--data-dir", metavar="DIR", default=None, help=folder_help + " (created if needed)")
    fetch.add_argument("--url", metavar="URL", default=BROAD_URL,
                       help="base URL of the BROAD repository's files (a mirror). Default: %(default)s")


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
    p.add_argument("--fast", action=argparse.BooleanOptionalAction, default=None,
                     help=f"fast mode: shorter recordings and fewer steps (see below); --no-fast: full mode even "
                          f"when ${FAST_ENV} is set. Default: ${FAST_ENV}, else off")
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

    errors: tuple[type[Exception], ...] = (UsageError, DataError, OSError)
    if args.command == "data":  # only the command asked for is imported (data: no torch)
        from .commands.data import run
    else:
        from .danae.checkpoints import CheckpointError

        errors += (CheckpointError,)
        if args.command == "leaderboard":
            from .commands.leaderboard import run
        else:
            from .commands.reproduce import run
    try:
        return run(args)
    except errors as err:
        print(f"{PROG} {args.command}: error: {one_line(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG} {args.command}: interrupted", file=sys.stderr)
        return 130
