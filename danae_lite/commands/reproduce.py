"""``python -m danae_lite reproduce``: the paper's experiment end to end.

The command parses arguments, resolves the data (:mod:`~danae_lite.data.experiments`,
:mod:`~danae_lite.data.oxiod`, :mod:`~danae_lite.data.ucs`) and calls
:func:`danae_lite.paper.pipeline.reproduce`, the same function the book's chapters call: the
paper's KF on every recording -> one DANAE per angle and seed -> the paper's metrics
(:mod:`~danae_lite.evaluate.metrics`) -> the paper's figure (:mod:`~danae_lite.paper.figures`). It writes
into ``--out`` (:func:`write_outputs`, plus ``run.json``):

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
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from .. import plots
from ..evaluate.metrics import METRICS, reduction_pct
from ..evaluate.scoring import plain
from ..paper.figures import PAPER_FIGURES
from .data_flags import UsageError
from .prepare import EXPERIMENT_ANGLES, LEADERBOARD_ONLY, PROG, prepare

if TYPE_CHECKING:
    from ..paper.reproduction import Reproduction

CSV_COLUMNS: tuple[str, ...] = ("method", "angle", "mean_dev", "max_dev", "rmse", "rmse_std",
                                "paper_mean_dev", "paper_max_dev", "paper_rmse")
"""Columns of ``metrics.csv`` (:func:`metrics_table`); metrics in rad."""


def run(args: argparse.Namespace) -> int:
    """Run ``python -m danae_lite reproduce`` (:func:`danae_lite.paper.pipeline.reproduce`); returns the exit status."""
    from ..paper import pipeline

    if args.experiment in LEADERBOARD_ONLY:
        raise UsageError(f"--experiment {args.experiment}: the paper has no such experiment to reproduce; "
                         f"run '{PROG} leaderboard --experiment {args.experiment}'")
    settings, out_dir, exp, config = prepare(args)
    fast, seeds, device = settings.fast, list(settings.seeds), settings.device
    angles = EXPERIMENT_ANGLES[args.experiment]

    print(exp.note)
    print(f"experiment {exp.name} | data: {exp.data} | mode: {'fast' if fast else 'full'} | "
          f"train {', '.join(r.name for r in exp.train)} | test {', '.join(r.name for r in exp.test)}")
    print(f"training: angles {', '.join(angles)} | seeds {' '.join(map(str, seeds))} | epochs {config.epochs} | "
          f"max steps {config.max_steps if config.max_steps is not None else 'none'} | device {device}", flush=True)
    rep = pipeline.reproduce(exp, angles=angles, seeds=seeds, config=config, progress=sys.stdout.isatty(),
                             cache=settings.cache, jobs=settings.jobs, log=_log)
    written = write_outputs(rep, out_dir)
    if args.save_models:
        written += _save_models(rep, out_dir / "models")
    written.append(_write_run_json(args, rep, fast, device, out_dir))

    _print_summary(rep)
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def _log(line: str) -> None:
    print(line, flush=True)


def _save_models(rep: Reproduction, folder: Path) -> list[Path]:
    """One checkpoint per angle and seed (:func:`danae_lite.danae.checkpoints.save`)."""
    from ..danae.checkpoints import save

    exp = rep.experiment
    return [save(res, folder / f"danae_{angle}_seed{seed}.pt",
                 metadata={"experiment": exp.name, "angle": angle, "seed": seed, "train": rep.train})
            for (angle, seed), res in rep.study.results.items()]


def _write_run_json(args: argparse.Namespace, rep: Reproduction, fast: bool, device: str, out_dir: Path) -> Path:
    """``run.json``: the command, data note, mode, settings and the figure shown."""
    import torch

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
    result = metrics_json(rep)
    shown = metrics_table(rep).set_index(["method", "angle"])
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


def metrics_json(rep: Reproduction) -> dict[str, Any]:
    """The content of ``metrics.json``: ``{"experiment", "data", "train", "test", "seeds",
    "kf", "danae", "paper", "seconds"}`` (see the module's docstring)."""
    return {
        "experiment": rep.experiment.name,
        "data": rep.data,
        "train": rep.train,
        "test": rep.test,
        "seeds": list(rep.seeds),
        "kf": plain(rep.kf),
        "danae": plain(rep.danae),
        "paper": plain(rep.paper),
        "seconds": {k: float(rep.seconds[k]) for k in ("kf", "train", "total")},
    }


def metrics_table(rep: Reproduction) -> pd.DataFrame:
    """The table of ``metrics.csv``: one row per method ("kf", "danae") and angle, columns
    :data:`CSV_COLUMNS` [rad]; ``rmse_std`` is NaN for the KF, paper values NaN where absent."""
    rows, paper = [], rep.paper or {}
    for method, block in (("kf", rep.kf), ("danae", rep.danae)):
        for angle, vals in block.items():
            ref = paper.get(method, {}).get(angle, {})
            rows.append({"method": method, "angle": angle, **{m: vals[m] for m in METRICS},
                         "rmse_std": vals.get("rmse_std", np.nan),
                         **{f"paper_{m}": ref.get(m, np.nan) for m in METRICS}})
    return pd.DataFrame(rows, columns=list(CSV_COLUMNS))


def write_outputs(rep: Reproduction, out_dir: Path) -> list[Path]:
    """Write ``metrics.json``, ``metrics.csv``, ``seed_table.csv`` and the paper's figure
    (``figureN_<angle>.csv`` with its samples, ``figureN_<angle>.png``) into ``out_dir``
    (created if needed); return the paths written, ``metrics.json`` first."""
    out_dir.mkdir(parents=True, exist_ok=True)
    spec = PAPER_FIGURES[rep.experiment.name]
    paths = [out_dir / "metrics.json", out_dir / "metrics.csv", out_dir / "seed_table.csv",
             out_dir / f"{spec.filename}.csv", out_dir / f"{spec.filename}.png"]
    paths[0].write_text(json.dumps(metrics_json(rep), indent=2) + "\n")
    metrics_table(rep).to_csv(paths[1], index=False)
    rep.study.table.to_csv(paths[2], index=False)
    rep.figure_series(spec).to_csv(paths[3], index=False)
    plots.use_style()
    fig = rep.plot_figure(spec)
    fig.savefig(paths[4])
    plt.close(fig)
    return paths
