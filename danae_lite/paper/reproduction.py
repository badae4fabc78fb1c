"""The results of the paper's experiment (:func:`danae_lite.paper.pipeline.reproduce`): the
per-seed study, the scores by the leaderboard's rule, and the :class:`Reproduction` with its
tables (Table 1 or 2 beside the paper's values) and figure (Figure 1 or 2). The files the
command line writes from it are :mod:`danae_lite.commands.reproduce`'s.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from numpy.typing import NDArray

from . import figures
from ..angles import ANGLES, wrap
from ..data.experiments import Experiment
from ..data.groundtruth import clean_mask
from ..danae.train_types import TrainConfig, TrainResult
from ..evaluate import metrics
from ..evaluate.scoring import SUBSETS, score_rows
from ..kalman.model import KFConfig

MetricDict = dict[str, float]
"""``{"mean_dev", "max_dev", "rmse"}`` [rad] (DANAE: also ``"rmse_std"``)."""


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
        out.loc["mean"], out.loc["std"] = zip(*(metrics.spread(out[a]) for a in out.columns))
        return out


@dataclass
class Scores:
    """The paper's metrics of a reproduction, by the leaderboard's rule
    (:func:`danae_lite.evaluate.scoring.score_rows`: all test samples taken together, errors wrapped,
    mean over seeds), on all samples and on the clean ones."""

    table: pd.DataFrame
    """One row per method, subset and angle: ``method`` "kf" or "danae", ``samples`` "all" or
    "clean", ``angle``, the metrics ``mean_dev``, ``max_dev``, ``rmse`` [rad] (mean over seeds),
    ``rmse_std`` (their sample std, NaN with one seed and for the KF), ``n`` (samples scored)."""
    clean: dict[str, NDArray[np.bool_]]
    """Clean ground-truth mask (:func:`danae_lite.data.groundtruth.clean_mask`) per recording name,
    training and test."""

    def blocks(self, samples: str, angles: Sequence[str]) -> tuple[dict[str, MetricDict], dict[str, MetricDict]]:
        """``(kf, danae)``: ``{angle: {mean_dev, max_dev, rmse}}`` [rad] on ``samples`` ("all" or
        "clean"), DANAE's also with ``rmse_std``."""
        rows = self.table[self.table.samples == samples].set_index(["method", "angle"])
        kf = rows.loc["kf"].loc[list(angles), list(metrics.METRICS)]
        danae = rows.loc["danae"].loc[list(angles), [*metrics.METRICS, "rmse_std"]]
        return kf.T.to_dict(), danae.T.to_dict()


def score(exp: Experiment, estimates: dict[str, NDArray[np.float64]], study: SeedStudy,
          angles: Sequence[str], seeds: Sequence[int]) -> Scores:
    """Score the paper's KF (``estimates``, its yaw wrapped to [-π, π)) and DANAE (the overlap
    predictions of ``study``, one per seed; NaN for an angle without a network) on all
    ``exp.test`` samples taken together, on all and on the clean samples."""
    clean = {r.name: clean_mask(r) for r in [*exp.train, *exp.test]}
    truth = np.concatenate([r.euler for r in exp.test])
    ok = np.concatenate([clean[r.name] for r in exp.test])
    kf = np.concatenate([estimates[r.name] for r in exp.test])
    kf[:, 2] = wrap(kf[:, 2])
    danae = []
    for seed in seeds:
        e = np.full_like(truth, np.nan)
        for a in angles:
            e[:, ANGLES.index(a)] = np.concatenate([study.predictions[(a, seed, "overlap")][r.name] for r in exp.test])
        danae.append(e)
    rows = [{"method": method, **row} for method, per_seed in (("kf", [kf]), ("danae", danae))
            for row in score_rows(per_seed, truth, ok, angles)]
    return Scores(table=pd.DataFrame(rows), clean=clean)


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
    seconds: dict[str, float]
    """Wall time [s]: ``kf`` (filter on every recording), ``train`` (training and inference),
    ``total`` (the whole :func:`reproduce` call)."""
    config: TrainConfig
    """Training settings shared by every network (the seed is replaced per network)."""
    kf_config: KFConfig
    """Filter settings."""
    leaderboard: Scores
    """The metrics on all and on clean test samples by the leaderboard's rule, and the clean masks."""

    @property
    def kf(self) -> dict[str, MetricDict]:
        """``{angle: {mean_dev, max_dev, rmse}}`` of the KF on all test samples [rad]."""
        return self.leaderboard.blocks("all", self.angles)[0]

    @property
    def danae(self) -> dict[str, MetricDict]:
        """``{angle: {mean_dev, max_dev, rmse, rmse_std}}`` of DANAE on all test samples, mean (and
        RMSE std) over seeds [rad]; ``rmse_std`` is NaN with one seed
        (:func:`danae_lite.evaluate.metrics.spread`)."""
        return self.leaderboard.blocks("all", self.angles)[1]

    @property
    def paper(self) -> dict[str, dict[str, MetricDict]] | None:
        """The paper's Table 1 (OxIOD) or 2 (UCS) in the layout of :attr:`kf` / :attr:`danae`, under
        keys "kf" and "danae" [rad]; angles the paper does not report are left out; None when it
        reports none of :attr:`angles`."""
        name = self.experiment.name
        if name not in metrics.PAPER:
            return None
        out = {method: metrics.paper_table(name, method)[list(self.angles)].dropna(axis=1).to_dict()
               for method in metrics.PAPER[name]}
        return out if any(out.values()) else None

    def metrics_on(self, samples: str = "all") -> tuple[dict[str, MetricDict], dict[str, MetricDict]]:
        """``(kf, danae)`` as :attr:`kf` / :attr:`danae`, on ``"all"`` test samples (those
        attributes) or on the ``"clean"`` ones (ground-truth glitches of
        :mod:`danae_lite.data.groundtruth` left out)."""
        if samples not in SUBSETS:
            raise ValueError(f"samples={samples!r}: choose 'all' or 'clean'")
        return self.leaderboard.blocks(samples, self.angles)

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
                table[(angle, "seed std")] = pd.Series({"rmse": vals[angle].get("rmse_std", np.nan)})
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
            "ground_truth": np.concatenate([r.euler[:, k] for r in recs]),
            "kf": np.concatenate([self.estimates[r.name][:, k] for r in recs]),
            "danae": np.concatenate([self.study.predictions[(angle, seed, "overlap")][r.name] for r in recs]),
        })

    def figure_series(self, spec: figures.PaperFigure | None = None, seed: int | None = None) -> pd.DataFrame:
        """The samples of the paper's figure on the first test recording.

        ``spec`` (default: the experiment's figure in :data:`danae_lite.paper.figures.PAPER_FIGURES`)
        gives the angle and the authors' sample range (:func:`~danae_lite.paper.figures.figure_window`
        shortens it on short recordings); ``seed`` picks the network (default: the first).
        Returns a :func:`~danae_lite.paper.figures.figure_series` table: ``time_s`` [s],
        ``ground_truth``, ``kf``, ``danae`` [rad], indexed by test sample.
        """
        spec = spec or figures.PAPER_FIGURES[self.experiment.name]
        seed = self.seeds[0] if seed is None else int(seed)
        rec = self.experiment.test[0]
        k = ANGLES.index(spec.angle)
        start, stop = figures.figure_window(spec, len(rec))
        return figures.figure_series(rec.time, rec.euler[:, k], self.estimates[rec.name][:, k],
                                     self.study.predictions[(spec.angle, seed, "overlap")][rec.name], start, stop)

    def plot_figure(self, spec: figures.PaperFigure | None = None, seed: int | None = None) -> plt.Figure:
        """The paper's figure recreated (KF above, DANAE below, each against ground truth)."""
        spec = spec or figures.PAPER_FIGURES[self.experiment.name]
        seed = self.seeds[0] if seed is None else int(seed)
        series = self.figure_series(spec, seed)
        title = (f"Figure {spec.number} recreated: {spec.angle}, KF (above) and DANAE (below, seed {seed}) vs "
                 f"ground truth\n{self.test[0]} ({self.data}), test samples {series.index[0]}-{series.index[-1]}")
        return figures.plot_kf_danae(series, spec.angle, title=title)
