"""Cross-validation by recording: every method refitted per split, scored per held-out recording.

A :class:`Split` is one training set and the recordings held out from it. The protocols:

* :func:`leave_one_out` — within one motion, each recording is held out once and the methods
  are fitted on the others (leave-one-recording-out);
* :func:`transfer` — fitted on every recording of one motion (or BROAD's undisturbed trials),
  tested on the recordings of other motions (or the disturbed trials), each test recording
  tagged with its group (the motion, or the BROAD disturbance).

:func:`run_splits` fits every method on each split's training recordings only, through
:func:`danae_lite.research.leaderboard.run_leaderboard` (grid searches, early stopping and frame
alignment all see the training recordings only), and scores every held-out recording on its
own: one row per split, test recording, method, sample subset and angle. Splits are
independent, so ``jobs`` > 1 runs them in worker processes
(:func:`danae_lite.danae.networks.in_processes`: joblib's workers, ``cores // jobs`` torch
threads each, kept between calls, so that a worker's filter runs and network outputs,
:mod:`danae_lite.research.memo`, serve later splits too), after the workers have
trained the networks of all splits together, into the cache (:func:`_pretrain`: on the Dask
cluster when one is named, :func:`danae_lite.danae.networks.use_scheduler`); with a single
split the workers train its networks instead.

Aggregation (:class:`CrossValidation`): per recording the mean over seeds, then the mean and
sample standard deviation over held-out recordings (:func:`danae_lite.evaluate.metrics.spread`), and
:meth:`CrossValidation.paired` compares two methods recording by recording.
"""
from __future__ import annotations

import copy
import json
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from . import broad_benchmark
from ..evaluate import metrics
from ..angles import ANGLES, wrap
from ..data.experiments import Experiment
from .leaderboard import Leaderboard, network_jobs, run_leaderboard, trial_figures
from .memo import carrying_store
from .methods import Method
from ..danae.networks import in_processes, pretrain, threads_per_process
from ..data.recording import Recording
from .baselines import METHODS
from ..evaluate.scoring import plain, score_rows
from ..danae.train_types import TrainConfig

ROW_COLUMNS: tuple[str, ...] = ("split", "protocol", "group", "test", "method", "causal", "samples", "angle",
                                "mean_dev", "max_dev", "rmse", "rmse_seed_std", "n", "seeds")
"""Columns of :attr:`CrossValidation.rows` (``folds.csv``): metrics [rad] of one held-out
recording, mean over seeds (``rmse_seed_std``: their sample std, NaN with one seed)."""
TRIAL_COLUMNS: tuple[str, ...] = ("split", "protocol", "group", "test", "method", "causal", *broad_benchmark.METRICS, "seeds")
"""Columns of :attr:`CrossValidation.trials` (``folds_broad.csv``): the BROAD benchmark's figures [deg]."""

COVERAGE_COLUMNS: tuple[str, ...] = ("split", "protocol", "group", "test", "method", "angle", "cover68", "cover95",
                                     "sd_rmse", "n", "seeds")
"""Columns of :attr:`CrossValidation.coverage` (``coverage.csv``): for a method with an error bar
(``predict_bars``), on one held-out recording's clean samples, the fraction of samples whose
error lies within the 68 % and the 95 % interval, and the root mean square of the 68 % half-width
(the stated standard deviation) [rad]; means over seeds."""
NO_HARM_COLUMNS: tuple[str, ...] = ("split", "protocol", "group", "test", "quantity", "filter", "corrector",
                                    "filter_value", "corrector_value", "change_pct")
"""Columns of :meth:`CrossValidation.no_harm` (``no_harm.csv``): a corrector against the filter
it corrects on one held-out recording; values in the unit the ``quantity`` names."""


@dataclass(frozen=True)
class Split:
    """One training set and the recordings held out from it."""

    name: str
    """Label, e.g. ``"handheld: hold out handheld/data1/imu2"``."""
    protocol: str
    """``"in-motion"`` (leave one recording out) or ``"transfer"`` (another motion or group)."""
    train: tuple[Recording, ...]
    test: tuple[Recording, ...]
    groups: Mapping[str, str]
    """Test recording name -> its group (motion, or BROAD disturbance)."""

    def __post_init__(self) -> None:
        overlap = {r.name for r in self.train} & {r.name for r in self.test}
        if overlap:
            raise ValueError(f"split {self.name!r}: recordings both trained on and tested: {sorted(overlap)}")
        if not self.train or not self.test:
            raise ValueError(f"split {self.name!r}: needs training and test recordings")


def leave_one_out(recordings: Sequence[Recording], motion: str) -> list[Split]:
    """One split per recording of ``motion``: fitted on the others, tested on it."""
    if len(recordings) < 2:
        raise ValueError(f"{motion}: leave-one-recording-out needs at least 2 recordings, got {len(recordings)}")
    return [Split(f"{motion}: hold out {r.name}", "in-motion", tuple(x for x in recordings if x is not r), (r,),
                  {r.name: motion}) for r in recordings]


def transfer(train: Sequence[Recording], tests: Mapping[str, Sequence[Recording]], label: str) -> Split:
    """One split: fitted on ``train`` (e.g. every handheld recording), tested on every
    recording of ``tests`` (group -> recordings, e.g. ``{"trolley": [...], "multi users": [...]}``)."""
    groups = {r.name: g for g, recs in tests.items() for r in recs}
    test = tuple(r for recs in tests.values() for r in recs)
    return Split(f"{label} -> {', '.join(tests)}", "transfer", tuple(train), test, groups)


def broad_transfer(train: Sequence[Recording], test: Sequence[Recording]) -> Split:
    """BROAD: fitted on ``train`` (the undisturbed trials), tested on each disturbed trial,
    grouped by its disturbance (tapping, vibration, stationary / attached magnet)."""
    kinds = ("tapping", "vibration", "stationary_magnet", "attached_magnet", "office_environment", "mixed")
    groups = {}
    for r in test:
        g = [k for k in kinds if k in r.meta.get("groups", ())]
        groups[r.name] = g[0] if g else "disturbed"
    return Split(f"undisturbed -> disturbed ({len(test)} trials)", "transfer", tuple(train), tuple(test), groups)


@dataclass
class CrossValidation:
    """Result of :func:`run_splits`."""

    name: str
    """Experiment name (``"oxiod"``, ``"broad"``)."""
    data: str
    rows: pd.DataFrame
    """:data:`ROW_COLUMNS`: one row per split, held-out recording, method, subset and angle."""
    trials: pd.DataFrame
    """:data:`TRIAL_COLUMNS` (experiment ``"broad"`` only, real or simulated; empty otherwise)."""
    params: pd.DataFrame
    """Parameters each method chose on each split's training recordings (``split``, ``method``, ``params``)."""
    seconds: dict[str, float]
    """Wall time per split and ``total`` [s]."""
    seeds: tuple[int, ...] = (0,)
    methods: list[str] = field(default_factory=list)
    coverage: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=list(COVERAGE_COLUMNS)))
    """:data:`COVERAGE_COLUMNS`, for the methods with an error bar (empty without one)."""

    def per_recording(self, angle: str, samples: str = "clean", protocol: str | None = None) -> pd.DataFrame:
        """RMSE [rad] per held-out recording (rows: ``(group, test)``) and method (columns)."""
        t = self._select(samples, protocol)
        t = t[t.angle == angle]
        out = t.pivot_table(index=["group", "test"], columns="method", values="rmse", aggfunc="first", sort=False)
        return out[[m for m in self.methods if m in out.columns]]

    def summary(self, samples: str = "clean", protocol: str | None = None, by_group: bool = False) -> pd.DataFrame:
        """Mean ± std over held-out recordings (:func:`danae_lite.evaluate.metrics.spread`) of the RMSE
        [rad]: rows methods (with ``causal``), columns ``(angle, "mean" | "std")`` and the number
        of recordings ``n``; with ``by_group`` one block of rows per group."""
        t = self._select(samples, protocol)
        keys = ["group", "method"] if by_group else ["method"]
        rows = []
        for key, g in t.groupby(keys, sort=False):
            key = key if isinstance(key, tuple) else (key,)
            row: dict[str, Any] = dict(zip(keys, key))
            row["causal"] = bool(g.causal.iloc[0])
            for a in ANGLES:
                v = g[g.angle == a].rmse.to_numpy(float)
                row[(a, "mean")], row[(a, "std")] = metrics.spread(v) if len(v) and np.isfinite(v).all() else (
                    np.nan, np.nan)
            row["n"] = int(g.test.nunique())
            rows.append(row)
        out = pd.DataFrame(rows).set_index(keys)
        order = [m for m in self.methods if m in out.index.get_level_values("method")]
        if by_group:
            groups = list(dict.fromkeys(t.group))
            out = out.loc[[(g, m) for g in groups for m in order if (g, m) in out.index]]
        else:
            out = out.loc[order]
        cols = ["causal", *[(a, s) for a in ANGLES for s in ("mean", "std")], "n"]
        out = out[cols]
        out.columns = pd.MultiIndex.from_tuples([c if isinstance(c, tuple) else (c, "") for c in cols])
        return out

    def paired(self, a: str, b: str, angle: str, samples: str = "clean", protocol: str | None = None) -> pd.DataFrame:
        """``a`` against ``b`` recording by recording: their RMSE [rad], the difference ``a - b``
        [rad] and the reduction of ``a`` over ``b`` [%] (:func:`danae_lite.evaluate.metrics.reduction_pct`;
        positive: ``a`` has the smaller error). The frame's ``attrs`` hold the summary:
        ``mean_diff``, ``std_diff`` (spread over recordings), ``mean_reduction_pct``,
        ``wins`` (recordings where ``a`` is better) and ``n``."""
        per = self.per_recording(angle, samples, protocol)
        for m in (a, b):
            if m not in per.columns:
                raise KeyError(f"method {m!r} is not in this cross-validation ({', '.join(per.columns)})")
        out = pd.DataFrame({a: per[a], b: per[b]})
        out["diff"] = out[a] - out[b]
        out["reduction_pct"] = metrics.reduction_pct(out[a], out[b])
        mean, std = metrics.spread(out["diff"])
        out.attrs = {"a": a, "b": b, "angle": angle, "mean_diff": mean, "std_diff": std,
                     "mean_reduction_pct": float(out["reduction_pct"].mean()),
                     "wins": int((out["diff"] < 0).sum()), "n": len(out)}
        return out

    def trial_summary(self) -> pd.DataFrame:
        """BROAD: per method, mean ± std over the held-out trials of the benchmark's figures [deg]."""
        rows = []
        for m, g in self.trials.groupby("method", sort=False):
            row: dict[str, Any] = {"method": m, "causal": bool(g.causal.iloc[0])}
            for k in broad_benchmark.METRICS:
                v = g[k].to_numpy(float)
                row[f"{k}"], row[f"{k}_std"] = metrics.spread(v) if np.isfinite(v).all() else (np.nan, np.nan)
            row["n"] = len(g)
            rows.append(row)
        return pd.DataFrame(rows).set_index("method")

    def corrections(self) -> dict[str, str]:
        """Each method that corrects another method of this cross-validation's output, mapped
        to that method: ``"danae-res[vqf]" -> "vqf"`` (leaderboard names ``<family>[<filter>]``
        whose filter ran too)."""
        out = {}
        for m in self.methods:
            if m.endswith("]") and "[" in m:
                source = m[m.index("[") + 1:-1]
                if source in self.methods:
                    out[m] = source
        return out

    def no_harm(self, pairs: Mapping[str, str] | None = None, samples: str = "clean") -> pd.DataFrame:
        """Does a correction do harm? Per pair ``corrector -> filter`` (default
        :meth:`corrections`), split and held-out recording, :data:`NO_HARM_COLUMNS`: the filter's
        and the corrector's value of each ``quantity`` on the same recording — the RMSE [rad] of
        roll, pitch and yaw on ``samples`` and, for BROAD, the benchmark's figures [deg] — and the
        ``change_pct`` (:func:`danae_lite.evaluate.metrics.reduction_pct`; negative: the correction made
        that recording worse). Values are means over seeds; an angle the filter does not
        estimate (NaN) has no row."""
        pairs = dict(self.corrections() if pairs is None else pairs)
        missing = [m for pair in pairs.items() for m in pair if m not in self.methods]
        if missing:
            raise KeyError(f"not in this cross-validation: {', '.join(missing)} (methods: {', '.join(self.methods)})")
        rows: list[dict[str, Any]] = []
        keys = ["split", "protocol", "group", "test"]
        t = self._select(samples, None)
        tables = [(t.assign(quantity=t.angle + " RMSE [rad]"), "rmse")]
        if not self.trials.empty:
            for k in broad_benchmark.METRICS:
                name = k.replace("_rmse_deg", "") + " RMSE [deg]"
                tables.append((self.trials.assign(quantity=name, value=self.trials[k]), "value"))
        for table, col in tables:
            for corrector, source in pairs.items():
                f = table[table.method == source].set_index([*keys, "quantity"])[col]
                c = table[table.method == corrector].set_index([*keys, "quantity"])[col]
                both = pd.DataFrame({"filter_value": f, "corrector_value": c}).dropna()
                for idx, r in both.iterrows():
                    rows.append({**dict(zip([*keys, "quantity"], idx)), "filter": source, "corrector": corrector,
                                 "filter_value": float(r.filter_value), "corrector_value": float(r.corrector_value),
                                 "change_pct": float(metrics.reduction_pct(r.corrector_value, r.filter_value))})
        return pd.DataFrame(rows, columns=list(NO_HARM_COLUMNS))

    def no_harm_summary(self, pairs: Mapping[str, str] | None = None, samples: str = "clean") -> pd.DataFrame:
        """:meth:`no_harm` per corrector and quantity: the number of held-out recordings, on how
        many the correction is worse than its filter (``worse_on``), the mean and the worst
        (lowest) ``change_pct``; rows ``(corrector, filter, quantity)``."""
        nh = self.no_harm(pairs, samples)
        return nh.groupby(["corrector", "filter", "quantity"], sort=False).agg(
            recordings=("change_pct", "size"), worse_on=("change_pct", lambda c: int((c < 0).sum())),
            mean_change_pct=("change_pct", "mean"), worst_change_pct=("change_pct", "min"))

    def _select(self, samples: str, protocol: str | None) -> pd.DataFrame:
        t = self.rows[self.rows.samples == samples]
        if protocol is not None:
            t = t[t.protocol == protocol]
        if t.empty:
            raise ValueError(f"no rows for samples={samples!r}, protocol={protocol!r}")
        return t

    def write(self, out_dir: str | os.PathLike[str]) -> dict[str, Path]:
        """``folds.csv`` (every row), ``folds_summary.csv`` (:meth:`summary` per protocol and
        group, clean samples), ``folds_params.csv``, ``folds.json``, for BROAD
        ``folds_broad.csv`` and, when a method corrects another (:meth:`corrections`),
        ``no_harm.csv`` (:meth:`no_harm`), and ``coverage.csv`` (:attr:`coverage`) when a method
        has an error bar; returns the paths."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"rows": out / "folds.csv", "summary": out / "folds_summary.csv", "params": out / "folds_params.csv",
                 "json": out / "folds.json"}
        self.rows.to_csv(paths["rows"], index=False, float_format="%.6g")
        blocks = []
        for protocol in dict.fromkeys(self.rows.protocol):
            s = self.summary("clean", protocol, by_group=True)
            s.columns = [c if not s2 else f"{c}_{s2}" for c, s2 in s.columns]
            blocks.append(s.reset_index().assign(protocol=protocol))
        pd.concat(blocks).to_csv(paths["summary"], index=False, float_format="%.6g")
        self.params.to_csv(paths["params"], index=False)
        if not self.trials.empty:
            paths["broad"] = out / "folds_broad.csv"
            self.trials.to_csv(paths["broad"], index=False, float_format="%.6g")
        if not self.coverage.empty:
            paths["coverage"] = out / "coverage.csv"
            self.coverage.to_csv(paths["coverage"], index=False, float_format="%.6g")
        if self.corrections():
            paths["no_harm"] = out / "no_harm.csv"
            self.no_harm().to_csv(paths["no_harm"], index=False, float_format="%.6g")
        paths["json"].write_text(json.dumps({"experiment": self.name, "data": self.data, "seeds": list(self.seeds),
                                             "methods": self.methods, "splits": sorted(set(self.rows.split)),
                                             "seconds": self.seconds}, indent=2) + "\n")
        return paths


def _recording_rows(split: Split, board: Leaderboard,
                    benchmark: bool) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Per held-out recording: the paper's metrics per subset and angle and, with ``benchmark``
    (BROAD), the benchmark's figures over ``meta["movement"]`` and ``meta["gt_valid"]`` (every
    sample when a recording has neither, e.g. a simulated stand-in)."""
    rows, trials = [], []
    for name, per_test in board.predictions.items():
        causal = bool(board.methods[name].causal)
        for rec in split.test:
            base = {"split": split.name, "protocol": split.protocol, "group": split.groups[rec.name],
                    "test": rec.name, "method": name, "causal": causal}
            preds = per_test[rec.name]
            for row in score_rows(preds, rec.euler, board.clean[rec.name]):
                row["rmse_seed_std"] = row.pop("rmse_std")
                rows.append({**base, **row, "seeds": len(preds)})
            if benchmark:
                figures, _ = trial_figures(rec, preds)
                trials.append({**base, **{m: mean for m, (mean, _) in figures.items()}, "seeds": len(preds)})
    return rows, trials


def _coverage_rows(split: Split, board: Leaderboard) -> list[dict[str, Any]]:
    """:data:`COVERAGE_COLUMNS` rows of the methods of ``board`` with an error bar."""
    rows = []
    for name, m in board.methods.items():
        if not hasattr(m, "predict_bars"):
            continue
        for rec in split.test:
            aligned = board.alignment.apply(rec)
            ok = board.clean[rec.name]
            per_seed = [interval_coverage(out[ok], sd[ok], hw[ok], aligned.euler[ok])
                        for out, sd, hw in m.predict_bars(aligned)]
            for k, angle in enumerate(ANGLES):
                vals = np.array([c[k] for c in per_seed])
                if np.isnan(vals).all():
                    continue
                rows.append({"split": split.name, "protocol": split.protocol, "group": split.groups[rec.name],
                             "test": rec.name, "method": name, "angle": angle, "cover68": float(vals[:, 0].mean()),
                             "cover95": float(vals[:, 1].mean()), "sd_rmse": float(vals[:, 2].mean()),
                             "n": int(ok.sum()), "seeds": len(per_seed)})
    return rows


def interval_coverage(out: NDArray[np.float64], sd: NDArray[np.float64], hw95: NDArray[np.float64],
                      truth: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3): per angle, the fraction of samples whose wrapped error ``truth - out`` [rad] lies
    within ``sd`` and within ``hw95``, and the root mean square of ``sd`` [rad]; NaN for an angle
    without a bar."""
    err = np.abs(wrap(np.asarray(truth, dtype=float) - np.asarray(out, dtype=float)))
    res = np.full((3, 3), np.nan)
    for k in range(3):
        if np.isfinite(sd[:, k]).all() and len(err):
            res[k] = [np.mean(err[:, k] <= sd[:, k]), np.mean(err[:, k] <= hw95[:, k]), np.sqrt(np.mean(sd[:, k] ** 2))]
    return res


def _run_one(split: Split, name: str, data: str, aligned: bool, methods: Sequence[str], extra: Sequence[Method],
             seeds: Sequence[int], train_config: TrainConfig, cache: str | os.PathLike[str] | None,
             jobs: int) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[dict[str, Any]], float,
                                 list[dict[str, Any]]]:
    """Fit and score every method on one split: its rows, BROAD trials and chosen parameters
    (:func:`_recording_rows`), its wall time [s] and the coverage of its error bars."""
    t0 = time.perf_counter()
    exp = Experiment(name, data, list(split.train), list(split.test), split.name, aligned=aligned)
    board = run_leaderboard(exp, methods=methods, extra=[copy.deepcopy(m) for m in extra], seeds=seeds,
                            train_config=train_config, cache=cache, progress=False, jobs=jobs)
    rows, trials = _recording_rows(split, board, benchmark=name == "broad")
    params = [{"split": split.name, "method": n, "params": json.dumps(plain(m.params), sort_keys=True)}
              for n, m in board.methods.items()]
    return rows, trials, params, time.perf_counter() - t0, _coverage_rows(split, board)


def _pretrain(splits: Sequence[Split], name: str, data: str, aligned: bool, methods: Sequence[str],
              extra: Sequence[Method], seeds: Sequence[int], train_config: TrainConfig,
              cache: str | os.PathLike[str] | None, jobs: int) -> None:
    """Train the networks of every split together (:func:`~danae_lite.danae.networks.pretrain`):
    the splits then run in parallel and find them in the cache, instead of each training its
    own while the other workers may be idle."""
    pretrain([j for s in splits for j in network_jobs(
        Experiment(name, data, list(s.train), list(s.test), s.name, aligned=aligned), methods=methods,
        extra=[copy.deepcopy(m) for m in extra], seeds=seeds, train_config=train_config)], cache=cache, jobs=jobs)


def _each_split(splits: Sequence[Split], common: tuple[Any, ...], cfg: TrainConfig,
                cache: str | os.PathLike[str] | None, jobs: int, progress: bool) -> list[Any]:
    """:func:`_run_one` of every split, in order: with ``jobs`` > 1 in worker processes on this
    machine (a split reads its recordings by path) after the networks of every split were
    trained together (:func:`_pretrain`), else one after the other."""
    if progress:  # the notebook widget when available
        from tqdm.auto import tqdm
    else:
        from tqdm import tqdm

    bar = tqdm(total=len(splits), desc=f"{common[0]} splits", unit="split", disable=not progress)
    if jobs > 1 and len(splits) > 1:
        _pretrain(splits, *common, cfg, cache, jobs)
        threads = threads_per_process(jobs)
        worker_cfg = cfg if cfg.num_threads is not None else _with_threads(cfg, threads)
        calls = [(s, *common, worker_cfg, cache, 1) for s in splits]
        runs = in_processes(carrying_store(_run_one), calls, processes=jobs, threads=threads, local=True)
    else:
        runs = (_run_one(s, *common, cfg, cache, jobs) for s in splits)
    results = []
    for res in runs:
        results.append(res)
        bar.update()
    bar.close()
    return results


def run_splits(
    splits: Sequence[Split],
    *,
    name: str,
    data: str,
    aligned: bool = False,
    methods: Sequence[str] = METHODS,
    extra: Sequence[Method] = (),
    seeds: Sequence[int] = (0,),
    train_config: TrainConfig | None = None,
    cache: str | os.PathLike[str] | None = None,
    jobs: int = 1,
    progress: bool = True,
) -> CrossValidation:
    """Fit and score every method on every split (see the module docstring).

    Parameters
    ----------
    splits : from :func:`leave_one_out`, :func:`transfer`, :func:`broad_transfer`.
    name, data : experiment name (``"oxiod"``, ``"broad"``) and ``"real"``/``"simulated"``.
    aligned : the recordings' frames are already the ground truth's (BROAD): no alignment.
    methods, extra : leaderboard methods by name and further unfitted methods (copied per split).
    seeds : training seeds of the learned methods.
    train_config : their training settings (default the paper's).
    cache : trained-network cache folder (None: none).
    jobs : worker processes: over splits, or over one split's networks when there is one split.
    progress : progress bar over the splits.
    """
    if not splits:
        raise ValueError("no splits to run")
    t0 = time.perf_counter()
    cfg = train_config or TrainConfig()
    common = (name, data, aligned, tuple(methods), tuple(extra), tuple(int(s) for s in seeds))
    results = _each_split(splits, common, cfg, cache, jobs, progress)
    rows = [r for res in results for r in res[0]]
    trials = [r for res in results for r in res[1]]
    params = [r for res in results for r in res[2]]
    seconds = {s.name: float(res[3]) for s, res in zip(splits, results)}
    seconds["total"] = time.perf_counter() - t0
    table = pd.DataFrame(rows, columns=list(ROW_COLUMNS))
    coverage = pd.DataFrame([r for res in results for r in res[4]], columns=list(COVERAGE_COLUMNS))
    return CrossValidation(name=name, data=data, rows=table, trials=pd.DataFrame(trials, columns=list(TRIAL_COLUMNS)),
                           params=pd.DataFrame(params), seconds=seconds, seeds=common[-1],
                           methods=list(dict.fromkeys(table.method)), coverage=coverage)


def combine(parts: Sequence[CrossValidation]) -> CrossValidation:
    """One cross-validation from several runs of :func:`run_splits` on the same experiment with
    different methods (for instance three seeds behind one filter and one seed behind the
    others): rows, trials, parameters and coverage concatenated, each row keeping its own
    ``seeds`` count; wall times added per split. ValueError when the parts are of different
    experiments or data, or run a method twice."""
    if not parts:
        raise ValueError("nothing to combine")
    first = parts[0]
    other = [p.name for p in parts if (p.name, p.data) != (first.name, first.data)]
    if other:
        raise ValueError(f"cannot combine cross-validations of different experiments: {first.name} and {other}")
    methods = [m for p in parts for m in p.methods]
    twice = sorted({m for m in methods if methods.count(m) > 1})
    if twice:
        raise ValueError(f"methods run in more than one part: {', '.join(twice)}")
    seconds: dict[str, float] = {}
    for p in parts:
        for k, v in p.seconds.items():
            seconds[k] = seconds.get(k, 0.0) + v
    frames = {f: pd.concat([getattr(p, f) for p in parts], ignore_index=True)
              for f in ("rows", "trials", "params", "coverage")}
    return CrossValidation(name=first.name, data=first.data, seconds=seconds, methods=methods,
                           seeds=tuple(sorted({s for p in parts for s in p.seeds})), **frames)


def _with_threads(cfg: TrainConfig, threads: int) -> TrainConfig:
    return replace(cfg, num_threads=threads)
