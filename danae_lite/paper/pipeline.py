"""The paper's experiment end to end: KF, one DANAE per angle and seed, Table 1 or 2, Figure 1 or 2.

:func:`reproduce` runs the paper's KF (:func:`filter_all`) on every recording and the paper's
DANAE (raw targets, every target sample, no frame alignment) on its output
(:func:`seed_study`, i.e. :class:`danae_lite.paper.danae.PaperDanae`, the estimator behind the
leaderboard's ``danae`` too), and scores both on the test recordings with the leaderboard's
rule (:func:`danae_lite.evaluate.scoring.score_rows`: all test samples taken together, mean over
seeds), on all samples and on the clean ones. It returns a :class:`Reproduction` (Table 1 or 2
and Figure 1 or 2) that can write ``metrics.json``, ``metrics.csv``, the per-seed table and
the figure. :func:`seed_study` is also the step-by-step view of chapter 3: the networks
evaluated recording by recording, with both of the paper's reconstructions (overlap average
and tiles).

Angles are (roll, pitch, yaw) [rad] as everywhere in the package. As in the paper, one network
is trained per angle, on the KF estimate of that angle as input and the ground truth of the
same angle as target.
"""
from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from numpy.typing import NDArray

from . import figures
from ..kalman.filter import run_kf
from ..kalman.model import KFConfig
from ..evaluate import metrics
from .. import plots
from ..angles import ANGLES, wrap
from ..data.experiments import Experiment
from .figures import PAPER_FIGURES, PaperFigure
from ..data.groundtruth import clean_mask
from .danae import PaperDanae
from ..data.recording import DataError, Recording
from ..evaluate.scoring import SUBSETS, plain, score_rows, seed_metrics
from ..danae.train import validation_tail
from ..danae.train_types import TrainConfig, TrainResult

CSV_COLUMNS: tuple[str, ...] = ("method", "angle", "mean_dev", "max_dev", "rmse", "rmse_std",
                                "paper_mean_dev", "paper_max_dev", "paper_rmse")
"""Columns of :meth:`Reproduction.metrics_frame` (``metrics.csv``); metrics in rad."""


def filter_all(recordings: Iterable[Recording], config: KFConfig | None = None) -> dict[str, NDArray[np.float64]]:
    """Run the paper's KF on every recording; return ``{name: euler (N, 3) [rad]}``."""
    return {r.name: run_kf(r, config).euler for r in recordings}


@dataclass
class SeedStudy:
    """DANAE trained per angle and per seed, evaluated on the test recordings."""

    results: dict[tuple[str, int], TrainResult]
    """Trained networks, keyed by ``(angle, seed)``."""
    predictions: dict[tuple[str, int, str], dict[str, NDArray[np.float64]]]
    """``(angle, seed, stitch) -> {test name: denoised angle (N,) [rad]}``."""
    table: pd.DataFrame
    """Long table: one row per test recording, angle, seed and method with the paper's metrics."""

    def rmse(self) -> pd.DataFrame:
        """RMSE [rad] per method (rows) and angle (columns), mean over seeds and test recordings."""
        return self.table.pivot_table(index="method", columns="angle", values="rmse", aggfunc="mean")

    def reduction(self, method: str = "danae (overlap)") -> pd.DataFrame:
        """RMSE reduction of ``method`` over the KF [%] per angle and seed (rows), with mean and std."""
        t = self.table
        kf = t[t.method == "kf"].set_index(["test", "angle", "seed"])["rmse"]
        dn = t[t.method == method].set_index(["test", "angle", "seed"])["rmse"]
        red = metrics.reduction_pct(dn, kf).rename("reduction [%]").reset_index()
        out = red.pivot_table(index="seed", columns="angle", values="reduction [%]", aggfunc="mean")
        agg = {a: metrics.spread(out[a]) for a in out.columns}
        out.loc["mean"] = {a: m for a, (m, _) in agg.items()}
        out.loc["std"] = {a: sd for a, (_, sd) in agg.items()}
        return out


def seed_study(
    train_recs: Sequence[Recording],
    test_recs: Sequence[Recording],
    estimates: dict[str, NDArray[np.float64]],
    *,
    angles: Sequence[str] = ("roll", "pitch"),
    seeds: Sequence[int] = (0, 1, 2),
    config: TrainConfig | None = None,
    stitches: Sequence[str] = ("overlap", "tiles"),
    progress: bool = True,
    cache: str | os.PathLike[str] | None = None,
    jobs: int = 1,
) -> SeedStudy:
    """Train one DANAE per angle and seed; evaluate KF and DANAE on every test recording.

    Metrics follow :func:`danae_lite.evaluate.metrics.metric_table` (errors wrapped to [-pi, pi)). The
    ``"overlap"`` reconstruction covers every sample. The ``"tiles"`` reconstruction (the
    paper's non-overlapping windows) leaves the last ``N mod window`` samples uncovered; its
    rows are computed on the covered samples only and the ``samples`` column says how many.
    The KF rows always use every sample. Inputs are ``estimates[name][:, k]`` (the filter's
    angle, rad), targets the ground truth of the same angle (rad), one array per recording so
    that no window crosses two recordings; ``cache`` and ``jobs`` are passed to
    :func:`danae_lite.danae.networks.train_networks`.
    """
    model = PaperDanae(angles, targets="raw", config=config, seeds=seeds, tag="danae",
                       metadata={"train": [r.name for r in train_recs]}, cache=cache, jobs=jobs, progress=progress)
    model.fit([estimates[r.name] for r in train_recs], [r.euler for r in train_recs])
    out = {(rec.name, stitch): model.predict(estimates[rec.name], stitch=stitch)
           for rec in test_recs for stitch in stitches}
    preds: dict[tuple[str, int, str], dict[str, NDArray[np.float64]]] = {}
    rows = []
    for angle, seed in model.results_:
        k, i = ANGLES.index(angle), model.seeds.index(seed)
        for rec in test_recs:
            est, truth = estimates[rec.name][:, k], rec.euler[:, k]
            rows.append(_row(rec.name, angle, seed, "kf", est, truth))
            for stitch in stitches:
                pred = out[(rec.name, stitch)][i][:, k]
                preds.setdefault((angle, seed, stitch), {})[rec.name] = pred
                rows.append(_row(rec.name, angle, seed, f"danae ({stitch})", pred, truth))
    return SeedStudy(results=model.results_, predictions=preds, table=pd.DataFrame(rows))


def _row(test: str, angle: str, seed: int, method: str, est: NDArray[np.float64],
         truth: NDArray[np.float64]) -> dict[str, Any]:
    """One row of :attr:`SeedStudy.table`: the paper's metrics [rad] of one angle and seed on
    the samples the estimate covers (the tiles reconstruction leaves the tail as NaN)."""
    ok = np.isfinite(est)
    (m,) = seed_metrics([est], truth, angle, ok)
    return {"test": test, "angle": angle, "seed": int(seed), "method": method, "samples": int(ok.sum()), **m.to_dict()}


# ---------------------------------------------------------------------------------------
# the paper's experiment end to end
# ---------------------------------------------------------------------------------------
MetricDict = dict[str, float]
"""``{"mean_dev", "max_dev", "rmse"}`` [rad] (DANAE: also ``"rmse_std"``)."""


def check_lengths(exp: Experiment, config: TrainConfig) -> None:
    """Raise :class:`~danae_lite.data.recording.DataError`, naming the recording, when one is too
    short to train on (a window plus a validation block) or to test (one window)."""
    w = config.window
    for rec in exp.train:
        n_val = validation_tail(len(rec), w, config.val_fraction)
        if len(rec) - n_val < w:
            raise DataError(f"training recording {rec.name} has {len(rec)} samples; at least {2 * w} are needed "
                            f"(a {w}-sample window to train on plus a validation block)")
    for rec in exp.test:
        if len(rec) < w:
            raise DataError(f"test recording {rec.name} has {len(rec)} samples; at least one {w}-sample window "
                            "is needed")


def _joined(arrays: Iterable[NDArray[np.float64]]) -> NDArray[np.float64]:
    return np.concatenate([np.asarray(a, dtype=float) for a in arrays])


def paper_values(experiment: str, angles: Sequence[str]) -> dict[str, dict[str, MetricDict]] | None:
    """The paper's Table 1 (``"oxiod"``) or 2 (``"ucs"``) as ``{method: {angle: metrics}}`` [rad].

    Angles the paper does not report are left out; None when it reports none of ``angles``.
    """
    if experiment not in metrics.PAPER:
        return None
    out: dict[str, dict[str, MetricDict]] = {}
    for method, rows in metrics.PAPER[experiment].items():
        per_angle = {a: {m: rows[m][a] for m in metrics.METRICS} for a in angles}
        out[method] = {a: {m: float(v) for m, v in vals.items()}  # type: ignore[arg-type]
                       for a, vals in per_angle.items() if all(v is not None for v in vals.values())}
    return out if any(out.values()) else None


SCORE_COLUMNS: tuple[str, ...] = ("method", "samples", "angle", "mean_dev", "max_dev", "rmse", "rmse_std", "n")
"""Columns of :attr:`Scores.table`: method "kf" or "danae", samples "all" or "clean", metrics
[rad] (mean over seeds; ``rmse_std`` their sample std, NaN with one seed and for the KF), ``n``
the sample count."""


@dataclass
class Scores:
    """The paper's metrics of a reproduction, by the leaderboard's rule
    (:func:`danae_lite.evaluate.scoring.score_rows`: all test samples taken together, errors wrapped,
    mean over seeds), on all samples and on the clean ones."""

    table: pd.DataFrame
    """:data:`SCORE_COLUMNS`, one row per method, subset and angle."""
    clean: dict[str, NDArray[np.bool_]]
    """Clean ground-truth mask (:func:`danae_lite.data.groundtruth.clean_mask`) per recording name,
    training and test."""
    predictions: dict[str, dict[str, list[NDArray[np.float64]]]]
    """``{"kf" | "danae": {test recording: [(N, 3) roll, pitch, yaw [rad], one per seed]}}`` as
    scored: the KF's yaw wrapped to [-π, π), DANAE's NaN for an angle without a network."""

    def blocks(self, samples: str, angles: Sequence[str]) -> tuple[dict[str, MetricDict], dict[str, MetricDict]]:
        """``(kf, danae)``: ``{angle: {mean_dev, max_dev, rmse}}`` [rad] on ``samples`` ("all" or
        "clean"), DANAE's also with ``rmse_std``."""
        rows = self.table[self.table.samples == samples].set_index(["method", "angle"])
        out = {m: {a: {k: float(rows.loc[(m, a), k]) for k in metrics.METRICS} for a in angles}
               for m in ("kf", "danae")}
        for a in angles:
            out["danae"][a]["rmse_std"] = float(rows.loc[("danae", a), "rmse_std"])
        return out["kf"], out["danae"]


def score(exp: Experiment, estimates: dict[str, NDArray[np.float64]], study: SeedStudy,
          angles: Sequence[str], seeds: Sequence[int]) -> Scores:
    """Score the paper's KF (``estimates``, its yaw wrapped) and DANAE (the overlap predictions
    of ``study``, one per seed) on ``exp.test``, on all and on the clean samples."""
    clean = {r.name: clean_mask(r) for r in [*exp.train, *exp.test]}
    preds: dict[str, dict[str, list[NDArray[np.float64]]]] = {"kf": {}, "danae": {}}
    for r in exp.test:
        kf = estimates[r.name].copy()
        kf[:, 2] = wrap(kf[:, 2])
        preds["kf"][r.name] = [kf]
        preds["danae"][r.name] = []
        for seed in seeds:
            e = np.full((len(r), 3), np.nan)
            for a in angles:
                e[:, ANGLES.index(a)] = study.predictions[(a, seed, "overlap")][r.name]
            preds["danae"][r.name].append(e)
    truth = np.concatenate([r.euler for r in exp.test])
    ok = np.concatenate([clean[r.name] for r in exp.test])
    rows = []
    for method, per_test in preds.items():
        n_seeds = len(per_test[exp.test[0].name])
        joined = [np.concatenate([per_test[r.name][s] for r in exp.test]) for s in range(n_seeds)]
        rows += [{"method": method, **row} for row in score_rows(joined, truth, ok, angles)]
    return Scores(table=pd.DataFrame(rows, columns=list(SCORE_COLUMNS)), clean=clean, predictions=preds)


@dataclass
class Reproduction:
    """The paper's experiment on one dataset: KF, DANAE per angle and seed, metrics, figure.

    Made by :func:`reproduce`. All metrics are in rad, computed on all samples of all test
    recordings taken together with errors wrapped to [-pi, pi); DANAE uses the overlap-average
    reconstruction (every sample covered).
    """

    experiment: Experiment
    """The recordings used (``experiment.name``, ``.data``, ``.train``, ``.test``, ``.note``)."""
    angles: tuple[str, ...]
    """Angles evaluated, e.g. ("roll", "pitch", "yaw")."""
    seeds: list[int]
    """Training seeds; one network per angle and seed."""
    estimates: dict[str, NDArray[np.float64]]
    """KF estimates ``{recording name: (N, 3) roll, pitch, yaw [rad]}`` (yaw unbounded)."""
    study: SeedStudy
    """All networks, their test predictions (stitch ``"overlap"``) and the per-recording table."""
    kf: dict[str, MetricDict]
    """``{angle: {mean_dev, max_dev, rmse}}`` of the KF [rad]."""
    danae: dict[str, MetricDict]
    """``{angle: {mean_dev, max_dev, rmse, rmse_std}}`` of DANAE, mean (and RMSE std) over seeds [rad];
    ``rmse_std`` is NaN with one seed (:func:`danae_lite.evaluate.metrics.spread`)."""
    paper: dict[str, dict[str, MetricDict]] | None
    """The paper's values in the layout of ``kf``/``danae`` under keys "kf" and "danae", or None."""
    seconds: dict[str, float]
    """Wall time [s]: ``kf`` (filter on every recording), ``train`` (training and inference),
    ``total`` (the whole :func:`reproduce` call)."""
    config: TrainConfig
    """Training settings shared by every network (the seed is replaced per network)."""
    kf_config: KFConfig
    """Filter settings."""
    scores: Scores
    """The metrics on all and on clean test samples, the clean masks and the test predictions."""

    @property
    def leaderboard(self) -> Scores:
        """:attr:`scores`, under the name of the engine that once produced them (chapter 4 reads
        ``rep.leaderboard.clean``)."""
        return self.scores

    def metrics_on(self, samples: str = "all") -> tuple[dict[str, MetricDict], dict[str, MetricDict]]:
        """``(kf, danae)`` as :attr:`kf` / :attr:`danae`, on ``"all"`` test samples (those
        attributes) or on the ``"clean"`` ones (ground-truth glitches of
        :mod:`danae_lite.data.groundtruth` left out)."""
        if samples not in SUBSETS:
            raise ValueError(f"samples={samples!r}: choose 'all' or 'clean'")
        if samples == "all":
            return self.kf, self.danae
        return self.scores.blocks("clean", self.angles)

    @property
    def data(self) -> str:
        """``"real"`` or ``"simulated"``."""
        return self.experiment.data

    @property
    def train(self) -> list[str]:
        """Names of the training recordings."""
        return [r.name for r in self.experiment.train]

    @property
    def test(self) -> list[str]:
        """Names of the test recordings."""
        return [r.name for r in self.experiment.test]

    def to_json(self) -> dict[str, Any]:
        """The content of ``metrics.json``: ``{"experiment", "data", "train", "test", "seeds",
        "kf", "danae", "paper", "seconds"}`` (see :mod:`danae_lite.cli`)."""
        return {
            "experiment": self.experiment.name,
            "data": self.data,
            "train": self.train,
            "test": self.test,
            "seeds": list(self.seeds),
            "kf": plain(self.kf),
            "danae": plain(self.danae),
            "paper": plain(self.paper),
            "seconds": {k: float(self.seconds[k]) for k in ("kf", "train", "total")},
        }

    def metrics_frame(self) -> pd.DataFrame:
        """The table of ``metrics.csv``: one row per method ("kf", "danae") and angle, columns
        :data:`CSV_COLUMNS` [rad]; ``rmse_std`` is NaN for the KF, paper values NaN where absent."""
        rows = []
        for method, block in (("kf", self.kf), ("danae", self.danae)):
            for angle, vals in block.items():
                ref = (self.paper or {}).get(method, {}).get(angle, {})
                rows.append({"method": method, "angle": angle, **{m: vals[m] for m in metrics.METRICS},
                             "rmse_std": vals.get("rmse_std", np.nan),
                             **{f"paper_{m}": ref.get(m, np.nan) for m in metrics.METRICS}})
        return pd.DataFrame(rows, columns=list(CSV_COLUMNS))

    def comparison(self, samples: str = "all") -> pd.DataFrame:
        """Our numbers in the layout of the paper's Table 1/2, next to the paper's [rad], on
        ``"all"`` test samples (as the paper) or on the ``"clean"`` ones (:meth:`metrics_on`).

        Rows ``(method, metric)`` with method "KF"/"DANAE" and metric in
        :data:`~danae_lite.evaluate.metrics.METRICS`; columns ``(angle, source)`` with source "ours"
        (DANAE: mean over seeds), "seed std" (DANAE RMSE only: sample std over seeds, NaN with
        one seed; NaN elsewhere) and "paper" (NaN where the paper gives no value).
        """
        blocks = {}
        kf, danae = self.metrics_on(samples)
        for label, method, vals in (("KF", "kf", kf), ("DANAE", "danae", danae)):
            ours = pd.DataFrame(vals).loc[list(metrics.METRICS), list(self.angles)]
            table = metrics.compare_with_paper(ours, self.experiment.name, method)
            for angle in self.angles:
                table[(angle, "seed std")] = np.nan
                if method == "danae":
                    table.loc["rmse", (angle, "seed std")] = vals[angle]["rmse_std"]
            blocks[label] = table[[(a, s) for a in self.angles for s in ("ours", "seed std", "paper")]]
        return pd.concat(blocks, names=["method"])

    def rmse_reduction(self) -> pd.DataFrame:
        """RMSE reduction of DANAE over the KF [%]: ``100 (1 - rmse_danae / rmse_kf)``.

        Rows "ours" (DANAE RMSE = mean over seeds) and "paper" (from its table); columns the
        angles and their "mean".
        """
        ours = pd.Series({a: metrics.reduction_pct(self.danae[a]["rmse"], self.kf[a]["rmse"]) for a in self.angles})
        paper = metrics.paper_rmse_reduction(self.experiment.name).reindex(list(self.angles))
        out = pd.DataFrame({"ours": ours, "paper": paper}).T
        out["mean"] = out.mean(axis=1)
        out.columns.name = "RMSE reduction [%]"
        return out

    def test_series(self, angle: str, seed: int | None = None) -> pd.DataFrame:
        """Ground truth, KF and DANAE (network ``seed``, default the first) of one angle on all
        test recordings joined: columns ``ground_truth``, ``kf`` (unbounded for yaw), ``danae``
        [rad]; one row per test sample, in the order of ``experiment.test``."""
        k = ANGLES.index(angle)
        seed = self.seeds[0] if seed is None else int(seed)
        recs = self.experiment.test
        return pd.DataFrame({
            "ground_truth": _joined(r.euler[:, k] for r in recs),
            "kf": _joined(self.estimates[r.name][:, k] for r in recs),
            "danae": _joined(self.study.predictions[(angle, seed, "overlap")][r.name] for r in recs),
        })

    def _figure_spec(self, spec: PaperFigure | None) -> PaperFigure:
        return spec if spec is not None else PAPER_FIGURES[self.experiment.name]

    def figure_series(self, spec: PaperFigure | None = None, seed: int | None = None) -> pd.DataFrame:
        """The samples of the paper's figure on the first test recording.

        ``spec`` (default: the experiment's figure in :data:`danae_lite.paper.figures.PAPER_FIGURES`)
        gives the angle and the authors' sample range (:func:`~danae_lite.paper.figures.figure_window`
        shortens it on short recordings); ``seed`` picks the network (default: the first).
        Returns a :func:`~danae_lite.paper.figures.figure_series` table: ``time_s`` [s],
        ``ground_truth``, ``kf``, ``danae`` [rad], indexed by test sample.
        """
        spec = self._figure_spec(spec)
        seed = self.seeds[0] if seed is None else int(seed)
        rec = self.experiment.test[0]
        k = ANGLES.index(spec.angle)
        start, stop = figures.figure_window(spec, len(rec))
        return figures.figure_series(rec.time, rec.euler[:, k], self.estimates[rec.name][:, k],
                                     self.study.predictions[(spec.angle, seed, "overlap")][rec.name], start, stop)

    def plot_figure(self, spec: PaperFigure | None = None, seed: int | None = None) -> plt.Figure:
        """The paper's figure recreated (KF above, DANAE below, each against ground truth)."""
        spec = self._figure_spec(spec)
        seed = self.seeds[0] if seed is None else int(seed)
        series = self.figure_series(spec, seed)
        title = (f"Figure {spec.number} recreated: {spec.angle}, KF (above) and DANAE (below, seed {seed}) vs "
                 f"ground truth\n{self.test[0]} ({self.data}), test samples {series.index[0]}-{series.index[-1]}")
        return figures.plot_kf_danae(series, spec.angle, title=title)

    def write(self, out_dir: str | os.PathLike[str]) -> list[Path]:
        """Write ``metrics.json``, ``metrics.csv``, ``seed_table.csv`` and the paper's figure
        (``figureN_<angle>.csv`` with its samples, ``figureN_<angle>.png``) into ``out_dir``
        (created if needed); return the paths written, ``metrics.json`` first."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        spec = self._figure_spec(None)
        paths = [out / "metrics.json", out / "metrics.csv", out / "seed_table.csv",
                 out / f"{spec.filename}.csv", out / f"{spec.filename}.png"]
        paths[0].write_text(json.dumps(self.to_json(), indent=2) + "\n")
        self.metrics_frame().to_csv(paths[1], index=False)
        self.study.table.to_csv(paths[2], index=False)
        self.figure_series(spec).to_csv(paths[3], index=False)
        plots.use_style()
        fig = self.plot_figure(spec)
        fig.savefig(paths[4])
        plt.close(fig)
        return paths


def reproduce(
    exp: Experiment,
    *,
    angles: Sequence[str],
    seeds: Sequence[int],
    config: TrainConfig,
    kf_config: KFConfig | None = None,
    progress: bool = True,
    cache: str | os.PathLike[str] | None = None,
    jobs: int = 1,
    log: Callable[[str], None] | None = print,
) -> Reproduction:
    """Run the paper's experiment on ``exp``: KF on every recording, one DANAE per angle and
    seed trained on ``exp.train``, the paper's metrics on ``exp.test``.

    The paper's configuration of the leaderboard's methods ``paper_kf`` and ``danae``: the KF
    (``kf_config``) on the recordings as loaded (no frame alignment), DANAE
    (:class:`~danae_lite.paper.danae.PaperDanae`) with raw targets on every target sample, the
    metrics of :func:`danae_lite.evaluate.scoring.score_rows`; ``run_leaderboard(exp, extra=[PaperKF(),
    Danae(targets="raw", clean_targets=False, stride=1, val_stride=config.val_stride)],
    align=False)`` gives the same numbers (``tests/test_pipeline.py``).

    Parameters
    ----------
    exp : the recordings (:func:`danae_lite.data.experiments.load_experiment`); names must be unique.
    angles : angles to evaluate, e.g. ("roll", "pitch", "yaw").
    seeds : training seeds (distinct); one network per angle and seed.
    config : training settings; its ``seed`` is replaced by each of ``seeds``.
    kf_config : filter settings; default the paper's (identity covariances, dt = 1/fs).
    progress : show a progress bar while training.
    cache : trained-network cache folder (None: no cache), see :mod:`danae_lite.danae.networks`.
    jobs : worker processes for the networks.
    log : called with one line after the KF and after each network; None for silence.

    Returns
    -------
    Reproduction
        Estimates, networks, predictions and the metrics: per seed on all test samples taken
        together (errors wrapped), then mean and standard deviation over seeds
        (:func:`danae_lite.evaluate.metrics.spread`: the standard deviation is NaN with one seed).
    """
    t_start = time.perf_counter()
    say = log or (lambda _line: None)
    angles, seeds = _checked(exp, angles, seeds)
    check_lengths(exp, config)
    kf_config = kf_config or KFConfig()
    estimates = filter_all([*exp.train, *exp.test], kf_config)
    t_kf = time.perf_counter() - t_start
    say(f"KF on {len(estimates)} recordings: {t_kf:.2f} s")
    t0 = time.perf_counter()
    study = seed_study(exp.train, exp.test, estimates, angles=angles, seeds=seeds, config=config,
                       stitches=("overlap",), progress=progress, cache=cache, jobs=jobs)
    t_train = time.perf_counter() - t0
    for (angle, seed), res in study.results.items():
        t = study.table[(study.table.angle == angle) & (study.table.seed == seed)]
        say(f"  {angle:<5} seed {seed}: {res.steps} steps in {res.seconds:.1f} s on {res.device}; test RMSE "
            f"KF {t[t.method == 'kf'].rmse.mean():.4f} -> DANAE {t[t.method == 'danae (overlap)'].rmse.mean():.4f} rad")
    scores = score(exp, estimates, study, angles, seeds)
    kf, danae = scores.blocks("all", angles)
    return Reproduction(
        experiment=exp, angles=angles, seeds=seeds, estimates=estimates, study=study, kf=kf, danae=danae,
        paper=paper_values(exp.name, angles), seconds={"kf": t_kf, "train": t_train,
                                                       "total": time.perf_counter() - t_start},
        config=config, kf_config=kf_config, scores=scores)


def _checked(exp: Experiment, angles: Sequence[str], seeds: Sequence[int]) -> tuple[tuple[str, ...], list[int]]:
    """``angles`` as a tuple and ``seeds`` as ints; ValueError for an empty or unknown angle set,
    repeated or no seeds, or a recording name used twice."""
    angles, seeds = tuple(angles), [int(s) for s in seeds]
    unknown = [a for a in angles if a not in ANGLES]
    if not angles or unknown:
        raise ValueError(f"angles must be a non-empty subset of {ANGLES}, got {angles}")
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be distinct and non-empty, got {seeds}")
    names = [r.name for r in [*exp.train, *exp.test]]
    if len(set(names)) != len(names):
        raise ValueError(f"recording names must be unique across training and test, got {names}")
    return angles, seeds
