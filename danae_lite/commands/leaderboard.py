"""``python -m danae_lite leaderboard``: every method of :mod:`danae_lite.research.baselines` on the
same split (:func:`danae_lite.research.leaderboard.run_leaderboard`), writing ``leaderboard.csv``,
``leaderboard.json``, ``leaderboard.png`` and the grid searches into ``--out``; with ``--experiment
broad`` (the BROAD benchmark, leaderboard only) also ``broad_trials.csv``, the benchmark's total,
heading and inclination RMSE [deg] per method and test trial. ``--folds`` cross-validates instead
(:func:`folds`)."""
from __future__ import annotations

import argparse
import sys
import time

import pandas as pd

from ..data import oxiod_motions
from ..research import crossval
from ..research.baselines import METHODS
from ..research.leaderboard import run_leaderboard
from .data_flags import UsageError, load_data
from .prepare import prepare


def run(args: argparse.Namespace) -> int:
    """Run ``python -m danae_lite leaderboard`` (:func:`danae_lite.research.leaderboard.run_leaderboard`)."""
    if args.folds:
        return folds(args)
    settings, out_dir, exp, config = prepare(args)
    fast, seeds, device = settings.fast, list(settings.seeds), settings.device
    methods = args.methods or list(METHODS)
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
    if args.experiment == "ucs":
        raise UsageError("--folds: ucs is one recording, there is nothing to hold out; use oxiod or broad")
    if args.estimates:
        raise UsageError("--estimates writes one split's per-sample output; leave it out with --folds")
    if args.train is not None or args.test is not None or args.split != "default":
        raise UsageError("--folds chooses the training and test recordings itself; leave out --train/--test/--split")
    settings, out_dir, _, config = prepare(args)
    methods = args.methods or list(METHODS)
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
