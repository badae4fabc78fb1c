"""Reproduce the BROAD authors' published figures: Madgwick and Mahony on every trial.

Runs the benchmark's two filters (:func:`danae_lite.data.broad.madgwick` at beta 0.12 and
:func:`danae_lite.data.broad.mahony` at k_P 0.74, k_I 0.0012: the authors' common best parameters)
on every trial found under ``<data dir>/broad/data_mat``, scores them with the benchmark's own
metric (:func:`danae_lite.research.broad_benchmark.evaluate`: total, heading and inclination RMSE over the movement
phases) and prints, per trial and filter, ours beside the published figure and the relative
difference ``ours / published - 1``; then the largest relative difference per filter, the mean
over the trials present (the published group ``all_trials`` is the mean over all 39) and the
run time.

BROAD: Laidig, Caruso, Cereatti, Seel, "BROAD—A Benchmark for Robust Inertial Orientation
Estimation", Data 6(7):72, 2021 (data under CC BY 4.0).

Usage::

    python benchmarks/broad_published.py --data-dir /path/to/data [--published-dir DIR] [--out table.csv]

``--data-dir`` defaults to ``$DANAE_DATA``; ``--published-dir`` (the folder holding
``results_madgwick_average_rmse.json`` and ``results_mahony_average_rmse.json``) defaults to
``<data dir>/../reference/broad_published``, else ``<data dir>/reference/broad_published``.
"""
from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

try:
    import danae_lite  # noqa: F401
except ImportError:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from danae_lite.data import broad
from danae_lite.research import broad_benchmark
from danae_lite.research.ahrs import broad_reference
from danae_lite.runtime import data_dir as resolve_data_dir

SHORT = {"total_rmse_deg": "total", "heading_rmse_deg": "heading", "inclination_rmse_deg": "incl"}


def default_published_dir(data: Path) -> Path:
    """``<data>/../reference/broad_published`` when it exists, else ``<data>/reference/broad_published``."""
    beside = data.parent / "reference" / "broad_published"
    return beside if beside.is_dir() else data / "reference" / "broad_published"


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data-dir", type=Path, default=None,
                   help="folder holding broad/data_mat (default: $DANAE_DATA)")
    p.add_argument("--published-dir", type=Path, default=None,
                   help="folder of results_<filter>_average_rmse.json (default: beside the data dir, "
                        "reference/broad_published)")
    p.add_argument("--out", type=Path, default=None, help="write the per-trial table to this CSV file")
    p.add_argument("--filters", nargs="+", choices=sorted(broad_reference.BENCHMARK_FILTERS),
                   default=list(broad_reference.BENCHMARK_FILTERS), help="filters to run (default: both)")
    p.add_argument("--trials", nargs="+", default=None,
                   help="only these trials (names or numbers, e.g. 02 10); default: all found")
    p.add_argument("--no-progress", action="store_true", help="no tqdm progress bar")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> pd.DataFrame:
    args = parse_args(argv)
    data = resolve_data_dir(args.data_dir)
    if data is None:
        raise SystemExit("no data directory: pass --data-dir or set DANAE_DATA (a folder holding broad/data_mat)")
    pub_dir = args.published_dir if args.published_dir is not None else default_published_dir(data)
    published = {name: broad_benchmark.published(name, pub_dir) for name in args.filters}
    paths = broad.find_trials(data, args.trials)
    index_path = paths[0].parent / "trials.json"
    index = broad.trial_index(index_path) if index_path.is_file() else None

    rows: list[dict[str, object]] = []
    seconds = {name: 0.0 for name in args.filters}
    samples = 0
    t_load = 0.0
    t0 = time.perf_counter()
    bar = tqdm(total=len(paths) * len(args.filters), desc="BROAD", unit="run", disable=args.no_progress)
    for path in paths:
        t = time.perf_counter()
        rec = broad.load_trial(path, index=index)
        t_load += time.perf_counter() - t
        samples += len(rec)
        for name in args.filters:
            bar.set_postfix_str(f"{rec.name[:24]} {name}")
            t = time.perf_counter()
            q = broad_reference.BENCHMARK_FILTERS[name](rec.gyro, rec.acc, rec.mag, rec.fs, **published[name].params)
            seconds[name] += time.perf_counter() - t
            ours = broad_benchmark.evaluate(rec, q).as_dict()
            pub = published[name].trials.get(rec.name)
            row: dict[str, object] = {"trial": rec.name, "filter": name}
            for metric, short in SHORT.items():
                row[f"{short}_ours"] = ours[metric]
                row[f"{short}_published"] = np.nan if pub is None else pub[metric]
                row[f"{short}_rel_diff"] = np.nan if pub is None else ours[metric] / pub[metric] - 1.0
            rows.append(row)
            bar.update(1)
    bar.close()
    wall = time.perf_counter() - t0
    table = pd.DataFrame(rows)

    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        table.to_csv(args.out, index=False, float_format="%.6g")

    with pd.option_context("display.width", 250, "display.max_rows", 500, "display.max_columns", 20):
        for name in args.filters:
            sub = table[table["filter"] == name].drop(columns="filter").set_index("trial")
            params = ", ".join(f"{k} {v:g}" for k, v in published[name].params.items())
            print(f"\n{name} ({params}): RMSE [deg], ours vs published, rel = ours / published - 1")
            print(sub.to_string(float_format=lambda v: f"{v:.4f}" if abs(v) >= 1e-3 or v == 0 else f"{v:+.1e}"))
    print("\nsummary")
    for name in args.filters:
        sub = table[table["filter"] == name]
        worst = {short: float(np.nanmax(np.abs(sub[f"{short}_rel_diff"]))) for short in SHORT.values()}
        means = {short: (sub[f"{short}_ours"].mean(), sub[f"{short}_published"].mean()) for short in SHORT.values()}
        print(f"  {name:9s} max |rel diff|: " + ", ".join(f"{k} {v:.1e}" for k, v in worst.items())
              + f"; mean over {len(sub)} trials (ours / published): "
              + ", ".join(f"{k} {a:.3f} / {b:.3f}" for k, (a, b) in means.items()))
        print(f"  {name:9s} filter time {seconds[name]:.1f} s, {samples / max(seconds[name], 1e-9):,.0f} samples/s")
    print(f"  loading {len(paths)} trials ({samples:,} samples): {t_load:.1f} s; total wall time {wall:.1f} s")
    if args.out is not None:
        print(f"  table written to {args.out}")
    return table


if __name__ == "__main__":
    main()
