"""The paper's pipeline as a few reusable steps: KF estimates -> one DANAE per angle -> metrics.

Each step calls the module that owns the work (:mod:`~danae_lite.kalman`,
:mod:`~danae_lite.train`, :mod:`~danae_lite.metrics`); this module only wires them together
so that chapters and the command line run exactly the same code. :func:`reproduce` runs the
whole experiment of the paper (Table 1 or 2 and Figure 1 or 2) and returns a
:class:`Reproduction` that can write ``metrics.json``, ``metrics.csv``, the per-seed table
and the figure.

Angles are (roll, pitch, yaw) [rad] as everywhere in the package. As in the paper, one network
is trained per angle, on the KF estimate of that angle as input and the ground truth of the
same angle as target.
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from . import kalman, metrics
from .angles import ANGLES
from .datasets import Experiment
from .recording import DataError, Recording
from .config import cache_dir as resolve_cache_dir
from .train import TrainConfig, TrainResult, load_result, predict, save, train

if TYPE_CHECKING:
    import matplotlib.pyplot as plt

    from .figures import PaperFigure

CSV_COLUMNS: tuple[str, ...] = ("method", "angle", "mean_dev", "max_dev", "rmse", "rmse_std",
                                "paper_mean_dev", "paper_max_dev", "paper_rmse")
"""Columns of :meth:`Reproduction.metrics_frame` (``metrics.csv``); metrics in rad."""


def filter_all(recordings: Iterable[Recording], config: kalman.KFConfig | None = None) -> dict[str, NDArray[np.float64]]:
    """Run the paper's KF on every recording; return ``{name: euler (N, 3) [rad]}``."""
    return {r.name: kalman.run_kf(r, config).euler for r in recordings}


def train_angle(
    train_recs: Sequence[Recording],
    estimates: dict[str, NDArray[np.float64]],
    angle: str,
    config: TrainConfig | None = None,
    *,
    progress: bool = True,
    cache: str | os.PathLike[str] | None = None,
) -> TrainResult:
    """Train one DANAE for ``angle`` on the training recordings.

    Inputs are ``estimates[rec.name][:, k]`` (the filter's angle, rad), targets
    ``rec.euler[:, k]`` (ground truth, rad), one array per recording so that no window
    crosses two recordings.

    ``cache`` (default: the ``DANAE_CACHE`` directory, see :func:`danae_lite.config.cache_dir`;
    none when unset) keeps trained networks on disk, keyed by a hash of the inputs, targets,
    training settings and the source of the model/training code. A second chapter asking for
    the same network loads it instead of training it again.
    """
    k = ANGLES.index(angle)
    inputs = [np.ascontiguousarray(estimates[r.name][:, k]) for r in train_recs]
    targets = [np.ascontiguousarray(r.euler[:, k]) for r in train_recs]
    return train_cached(inputs, targets, config, tag=f"danae-{angle}", progress=progress, cache=cache,
                        metadata={"angle": angle, "train": [r.name for r in train_recs]})


def train_cached(
    inputs: Sequence[NDArray[np.float64]],
    targets: Sequence[NDArray[np.float64]],
    config: TrainConfig | None = None,
    *,
    target_masks: Sequence[NDArray[np.bool_]] | None = None,
    tag: str = "danae",
    progress: bool = True,
    cache: str | os.PathLike[str] | None = None,
    metadata: dict[str, Any] | None = None,
) -> TrainResult:
    """:func:`danae_lite.train.train` with an on-disk cache.

    The file is ``<cache>/<tag>-seed<seed>-<hash>.pt``, the hash covering the inputs, targets,
    target masks, training settings and the source of the code that builds, windows, seeds
    and trains the network (:mod:`~danae_lite.model`, :mod:`~danae_lite.train`,
    :mod:`~danae_lite.windows`, :mod:`~danae_lite.config`), not the device or thread count.
    A file with the same hash under another tag is the same network and is loaded.
    ``cache`` defaults to ``DANAE_CACHE`` (none when unset).
    """
    config = config or TrainConfig()
    inputs = [np.ascontiguousarray(a) for a in inputs]
    targets = [np.ascontiguousarray(a) for a in targets]
    masks = None if target_masks is None else [np.ascontiguousarray(m, dtype=bool) for m in target_masks]
    folder = resolve_cache_dir(cache)
    key = _cache_key([*inputs, *(masks or [])], targets, config)
    path = folder / f"{tag}-seed{config.seed}-{key}.pt" if folder else None
    if folder is not None:
        # the key alone identifies the network: one trained under another tag is the same one
        for found in sorted(folder.glob(f"*-seed{config.seed}-{key}.pt")):
            return load_result(found)
    res = train(inputs, targets, config, progress=progress, target_masks=masks)
    if path is not None:
        save(res, path, metadata=metadata or {"tag": tag})
    return res


def _cache_key(inputs: list[NDArray[np.float64]], targets: list[NDArray[np.float64]], config: TrainConfig) -> str:
    """Hash of everything that determines a trained network (not the device or thread count):
    the data, the settings, and the source of the code that builds, windows, seeds and trains it."""
    from . import config as config_module, model as model_module, train as train_module
    from . import windows as windows_module

    h = hashlib.sha256()
    for module in (model_module, train_module, windows_module, config_module):
        h.update(Path(module.__file__).read_bytes())
    settings = {k: v for k, v in config.to_dict().items() if k not in ("device", "num_threads")}
    h.update(repr(sorted(settings.items())).encode())
    for a in (*inputs, *targets):
        h.update(str(a.shape).encode())
        h.update(a.astype(np.float64).tobytes())
    return h.hexdigest()[:16]


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
        red = (100.0 * (1.0 - dn / kf)).rename("reduction [%]").reset_index()
        out = red.pivot_table(index="seed", columns="angle", values="reduction [%]", aggfunc="mean")
        out.loc["mean"] = out.mean()
        out.loc["std"] = out.iloc[:-1].std(ddof=1) if len(out) > 2 else np.nan
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
) -> SeedStudy:
    """Train one DANAE per angle and seed; evaluate KF and DANAE on every test recording.

    Metrics follow :func:`danae_lite.metrics.metric_table` (errors wrapped to [-pi, pi)). The
    ``"overlap"`` reconstruction covers every sample. The ``"tiles"`` reconstruction (the
    paper's non-overlapping windows) leaves the last ``N mod window`` samples uncovered; its
    rows are computed on the covered samples only and the ``samples`` column says how many.
    The KF rows always use every sample. ``cache`` is passed to :func:`train_angle`.
    """
    base = config or TrainConfig()
    results: dict[tuple[str, int], TrainResult] = {}
    preds: dict[tuple[str, int, str], dict[str, NDArray[np.float64]]] = {}
    rows = []
    for angle in angles:
        k = ANGLES.index(angle)
        for seed in seeds:
            res = train_angle(train_recs, estimates, angle, replace(base, seed=int(seed)), progress=progress,
                              cache=cache)
            results[(angle, int(seed))] = res
            for rec in test_recs:
                est, truth = estimates[rec.name][:, k], rec.euler[:, k]
                rows.append(_row(rec.name, angle, seed, "kf", est, truth))
                for stitch in stitches:
                    p = predict(res, est, stitch=stitch)[:, 0]
                    preds.setdefault((angle, int(seed), stitch), {})[rec.name] = p
                    rows.append(_row(rec.name, angle, seed, f"danae ({stitch})", p, truth))
    return SeedStudy(results=results, predictions=preds, table=pd.DataFrame(rows))


def _row(test: str, angle: str, seed: int, method: str, est: NDArray[np.float64], truth: NDArray[np.float64]) -> dict:
    ok = np.isfinite(est)  # the tiles reconstruction leaves the tail as NaN
    m = metrics.metric_table(est[ok], truth[ok], angles=(angle,))[angle]
    return {"test": test, "angle": angle, "seed": int(seed), "method": method, "samples": int(ok.sum()), **m.to_dict()}


# ---------------------------------------------------------------------------------------
# the paper's experiment end to end
# ---------------------------------------------------------------------------------------
MetricDict = dict[str, float]
"""``{"mean_dev", "max_dev", "rmse"}`` [rad] (DANAE: also ``"rmse_std"``)."""


def merge_studies(studies: Sequence[SeedStudy]) -> SeedStudy:
    """Join several :class:`SeedStudy` objects (e.g. one per angle and seed) into one."""
    results: dict[tuple[str, int], TrainResult] = {}
    preds: dict[tuple[str, int, str], dict[str, NDArray[np.float64]]] = {}
    for s in studies:
        results.update(s.results)
        for key, per_test in s.predictions.items():
            preds.setdefault(key, {}).update(per_test)
    table = pd.concat([s.table for s in studies], ignore_index=True) if studies else pd.DataFrame()
    return SeedStudy(results=results, predictions=preds, table=table)


def check_lengths(exp: Experiment, config: TrainConfig) -> None:
    """Raise :class:`~danae_lite.recording.DataError`, naming the recording, when one is too
    short to train on (a window plus a validation block) or to test (one window)."""
    w = config.window
    for rec in exp.train:
        n_val = 0 if config.val_fraction == 0 else max(w, int(round(config.val_fraction * len(rec))))
        if len(rec) - n_val < w:
            raise DataError(f"training recording {rec.name} has {len(rec)} samples; at least {2 * w} are needed "
                            f"(a {w}-sample window to train on plus a validation block)")
    for rec in exp.test:
        if len(rec) < w:
            raise DataError(f"test recording {rec.name} has {len(rec)} samples; at least one {w}-sample window "
                            "is needed")


def _joined(arrays: Iterable[NDArray[np.float64]]) -> NDArray[np.float64]:
    return np.concatenate([np.asarray(a, dtype=float) for a in arrays])


def _metric_dict(est: NDArray[np.float64], truth: NDArray[np.float64], angle: str) -> MetricDict:
    table = metrics.metric_table(est, truth, angles=(angle,))
    return {m: float(table.loc[m, angle]) for m in metrics.METRICS}


def aggregate_metrics(
    test_recs: Sequence[Recording],
    estimates: dict[str, NDArray[np.float64]],
    predictions: dict[tuple[str, int, str], dict[str, NDArray[np.float64]]],
    angles: Sequence[str],
    seeds: Sequence[int],
    stitch: str = "overlap",
) -> tuple[dict[str, MetricDict], dict[str, MetricDict]]:
    """The paper's metrics [rad] on all test samples taken together (errors wrapped).

    Returns ``(kf, danae)``, each ``{angle: {mean_dev, max_dev, rmse}}``. DANAE values are the
    mean over ``seeds`` of the per-seed metrics, plus ``rmse_std``: the sample standard
    deviation of the RMSE over seeds (0.0 with one seed).
    """
    kf_out: dict[str, MetricDict] = {}
    danae_out: dict[str, MetricDict] = {}
    for angle in angles:
        k = ANGLES.index(angle)
        truth = _joined(r.euler[:, k] for r in test_recs)
        kf_out[angle] = _metric_dict(_joined(estimates[r.name][:, k] for r in test_recs), truth, angle)
        per_seed = [_metric_dict(_joined(predictions[(angle, int(s), stitch)][r.name] for r in test_recs), truth, angle)
                    for s in seeds]
        danae_out[angle] = {m: float(np.mean([d[m] for d in per_seed])) for m in metrics.METRICS}
        rmses = [d["rmse"] for d in per_seed]
        danae_out[angle]["rmse_std"] = float(np.std(rmses, ddof=1)) if len(rmses) > 1 else 0.0
    return kf_out, danae_out


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
    """``{angle: {mean_dev, max_dev, rmse, rmse_std}}`` of DANAE, mean (and RMSE std) over seeds [rad]."""
    paper: dict[str, dict[str, MetricDict]] | None
    """The paper's values in the layout of ``kf``/``danae`` under keys "kf" and "danae", or None."""
    seconds: dict[str, float]
    """Wall time [s]: ``kf`` (filter on every recording), ``train`` (training and inference),
    ``total`` (the whole :func:`reproduce` call)."""
    config: TrainConfig
    """Training settings shared by every network (the seed is replaced per network)."""
    kf_config: kalman.KFConfig
    """Filter settings."""

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
            "kf": self.kf,
            "danae": self.danae,
            "paper": self.paper,
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

    def comparison(self) -> pd.DataFrame:
        """Our numbers in the layout of the paper's Table 1/2, next to the paper's [rad].

        Rows ``(method, metric)`` with method "KF"/"DANAE" and metric in
        :data:`~danae_lite.metrics.METRICS`; columns ``(angle, source)`` with source "ours"
        (DANAE: mean over seeds), "seed std" (DANAE RMSE only: sample std over seeds, 0 with
        one seed; NaN elsewhere) and "paper" (NaN where the paper gives no value).
        """
        blocks = {}
        for label, method, vals in (("KF", "kf", self.kf), ("DANAE", "danae", self.danae)):
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
        ours = pd.Series({a: 100.0 * (1.0 - self.danae[a]["rmse"] / self.kf[a]["rmse"]) for a in self.angles})
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
        from .figures import PAPER_FIGURES

        return spec if spec is not None else PAPER_FIGURES[self.experiment.name]

    def figure_series(self, spec: PaperFigure | None = None, seed: int | None = None) -> pd.DataFrame:
        """The samples of the paper's figure on the first test recording.

        ``spec`` (default: the experiment's figure in :data:`danae_lite.figures.PAPER_FIGURES`)
        gives the angle and the authors' sample range (:func:`~danae_lite.figures.figure_window`
        shortens it on short recordings); ``seed`` picks the network (default: the first).
        Returns a :func:`~danae_lite.figures.figure_series` table: ``time_s`` [s],
        ``ground_truth``, ``kf``, ``danae`` [rad], indexed by test sample.
        """
        from . import figures

        spec = self._figure_spec(spec)
        seed = self.seeds[0] if seed is None else int(seed)
        rec = self.experiment.test[0]
        k = ANGLES.index(spec.angle)
        start, stop = figures.figure_window(spec, len(rec))
        return figures.figure_series(rec.time, rec.euler[:, k], self.estimates[rec.name][:, k],
                                     self.study.predictions[(spec.angle, seed, "overlap")][rec.name], start, stop)

    def plot_figure(self, spec: PaperFigure | None = None, seed: int | None = None) -> plt.Figure:
        """The paper's figure recreated (KF above, DANAE below, each against ground truth)."""
        from . import figures

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
        import matplotlib.pyplot as plt

        from . import plots

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


def _train_networks(
    exp: Experiment,
    estimates: dict[str, NDArray[np.float64]],
    angles: Sequence[str],
    seeds: Sequence[int],
    config: TrainConfig,
    progress: bool,
    cache: str | os.PathLike[str] | None,
    log: Callable[[str], None],
) -> SeedStudy:
    """One :func:`seed_study` per angle and seed (overlap stitch), logged one line each."""
    studies = []
    for angle in angles:
        for seed in seeds:
            study = seed_study(exp.train, exp.test, estimates, angles=(angle,), seeds=(seed,), config=config,
                               stitches=("overlap",), progress=progress, cache=cache)
            studies.append(study)
            res, t = study.results[(angle, seed)], study.table
            log(f"  {angle:<5} seed {seed}: {res.steps} steps in {res.seconds:.1f} s on {res.device}; test RMSE "
                f"KF {t[t.method == 'kf'].rmse.mean():.4f} -> DANAE {t[t.method == 'danae (overlap)'].rmse.mean():.4f} rad")
    return merge_studies(studies)


def reproduce(
    exp: Experiment,
    *,
    angles: Sequence[str],
    seeds: Sequence[int],
    config: TrainConfig,
    kf_config: kalman.KFConfig | None = None,
    progress: bool = True,
    cache: str | os.PathLike[str] | None = None,
    log: Callable[[str], None] | None = print,
) -> Reproduction:
    """Run the paper's experiment on ``exp``: KF on every recording, one DANAE per angle and
    seed trained on ``exp.train``, the paper's metrics on ``exp.test``.

    Parameters
    ----------
    exp : the recordings (:func:`danae_lite.datasets.load_experiment`); names must be unique.
    angles : angles to evaluate, e.g. ("roll", "pitch", "yaw").
    seeds : training seeds (distinct); one network per angle and seed.
    config : training settings; its ``seed`` is replaced by each of ``seeds``.
    kf_config : filter settings; default the paper's (identity covariances, dt = 1/fs).
    progress : show a progress bar while training.
    cache : trained-network cache, passed to :func:`train_angle` (default ``DANAE_CACHE``).
    log : called with one line after the KF and after each network; None for silence.

    Returns
    -------
    Reproduction
        Estimates, networks, predictions and the aggregated metrics (see :func:`aggregate_metrics`).
    """
    t_start = time.perf_counter()
    say = log or (lambda _line: None)
    angles, seeds = tuple(angles), [int(s) for s in seeds]
    unknown = [a for a in angles if a not in ANGLES]
    if not angles or unknown:
        raise ValueError(f"angles must be a non-empty subset of {ANGLES}, got {angles}")
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be distinct and non-empty, got {seeds}")
    check_lengths(exp, config)
    kf_config = kf_config or kalman.KFConfig()

    t0 = time.perf_counter()
    estimates = filter_all([*exp.train, *exp.test], kf_config)
    seconds_kf = time.perf_counter() - t0
    say(f"KF on {len(exp.train) + len(exp.test)} recordings: {seconds_kf:.2f} s")

    t0 = time.perf_counter()
    study = _train_networks(exp, estimates, angles, seeds, config, progress, cache, say)
    seconds_train = time.perf_counter() - t0

    kf_out, danae_out = aggregate_metrics(exp.test, estimates, study.predictions, angles, seeds)
    return Reproduction(
        experiment=exp, angles=angles, seeds=seeds, estimates=estimates, study=study, kf=kf_out, danae=danae_out,
        paper=paper_values(exp.name, angles),
        seconds={"kf": seconds_kf, "train": seconds_train, "total": time.perf_counter() - t_start},
        config=config, kf_config=kf_config)
