"""One leaderboard: every method on the same train/test split, on all and on clean samples.

:func:`run_leaderboard` does, in order:

1. find the ground-truth glitches of every recording (:func:`danae_lite.data.groundtruth.clean_mask`);
2. estimate the sensor -> body rotation and the heading of magnetic north on the training
   recordings only (:func:`danae_lite.data.alignment.estimate_alignment`) and rotate every
   recording's sensors into the body frame (none for an experiment whose frames are already
   aligned, ``exp.aligned``: BROAD);
3. fit every method (:mod:`danae_lite.research.registry`: the baselines of :mod:`danae_lite.research.baselines`
   and DANAE-res by name, any :class:`~danae_lite.research.methods.Method` as an object) on the training
   recordings (its grid search included) and predict the test recordings;
4. compute the paper's metrics (mean dev, max dev, RMSE [rad], errors wrapped to [-π, π), yaw
   included) on all test samples taken together, once on every sample and once on the clean
   samples only. Methods with several seeds (DANAE) report the mean over seeds and the
   standard deviation of the RMSE.

:class:`Leaderboard` writes ``leaderboard.csv``, ``leaderboard.json`` and ``leaderboard.png``.
On the BROAD benchmark (``experiment.name == "broad"``) it also writes ``broad_trials.csv``:
:meth:`Leaderboard.trial_metrics`, one row per method and test trial with the benchmark's own
figures (total, heading and inclination RMSE [deg] over the movement phases,
:func:`danae_lite.research.broad_benchmark.benchmark_rmse`).
"""
from __future__ import annotations

import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from . import broad_benchmark
from ..evaluate import metrics
from ..data.alignment import FrameAlignment, estimate_alignment
from ..angles import ANGLES, euler_to_quat
from ..data.experiments import Experiment
from ..data.groundtruth import clean_mask, glitch_table
from ..danae.networks import NetworkJob, pretrain
from .methods import Context, Method
from ..data.recording import Recording
from .baselines import METHODS, is_method_name
from .registry import make_method
from ..evaluate.scoring import SUBSETS, plain, score_rows, seed_metrics
from ..danae.train_types import TrainConfig

if TYPE_CHECKING:
    import matplotlib.pyplot as plt

CSV_COLUMNS: tuple[str, ...] = ("method", "causal", "samples", "angle", "mean_dev", "max_dev", "rmse", "rmse_std", "n")
"""Columns of ``leaderboard.csv``; ``causal`` whether the method uses only past samples
(:attr:`danae_lite.research.methods.Method.causal`), ``samples`` "all" or "clean", metrics in rad, ``n``
the sample count."""
TRIAL_COLUMNS: tuple[str, ...] = ("method", "causal", "test", *broad_benchmark.METRICS,
                                  *(f"{m}_std" for m in broad_benchmark.METRICS), "n_samples", "seeds")
"""Columns of :meth:`Leaderboard.trial_metrics` (``broad_trials.csv``); figures in degrees."""


@dataclass
class Leaderboard:
    """Result of :func:`run_leaderboard`."""

    experiment: Experiment
    table: pd.DataFrame
    """Long table with :data:`CSV_COLUMNS` (one row per method, subset and angle)."""
    methods: dict[str, Method]
    """Fitted methods by name (their ``params`` and ``search``)."""
    predictions: dict[str, dict[str, list[NDArray[np.float64]]]]
    """``{method: {test recording: [(N, 3) euler, one per seed]}}`` [rad], ground-truth frame."""
    alignment: FrameAlignment
    glitches: pd.DataFrame
    """:func:`danae_lite.data.groundtruth.glitch_table` of every recording (train and test)."""
    clean: dict[str, NDArray[np.bool_]]
    seconds: dict[str, float]
    """Wall time per method (fit + predict) and ``total`` [s]."""
    seeds: tuple[int, ...] = (0,)
    train_config: TrainConfig = field(default_factory=TrainConfig)

    def wide(self, metric: str = "rmse", samples: str = "clean") -> pd.DataFrame:
        """Methods (rows: :data:`METHODS` order, then extra methods as run) x angles (columns) of one metric [rad]."""
        t = self.table[self.table.samples == samples]
        out = t.pivot(index="method", columns="angle", values=metric)
        order = [m for m in METHODS if m in out.index] + [m for m in dict.fromkeys(t.method) if m not in METHODS]
        return out.loc[order, [a for a in ANGLES if a in out.columns]]

    def best(self, angle: str, samples: str = "clean", learned: bool = False) -> str:
        """Name of the method with the lowest RMSE for ``angle``; with ``learned=False`` DANAE and
        its variants (names starting with "danae") are left out, i.e. the best classical method."""
        w = self.wide("rmse", samples)
        if not learned:
            w = w.drop(index=[m for m in w.index if m.startswith("danae")])
        return str(w[angle].astype(float).idxmin())

    def seed_rmse(self, name: str, angle: str, samples: str = "clean") -> NDArray[np.float64]:
        """Method ``name``'s RMSE [rad] of ``angle`` on every test recording taken together, one
        value per seed (a filter has one; the mean is the ``rmse`` of :attr:`table`), on the
        ``samples`` "clean" or "all"; the spread a verdict over seeds is drawn from."""
        if samples not in ("clean", "all"):
            raise ValueError(f"samples={samples!r}: choose 'clean' or 'all'")
        k = ANGLES.index(angle)
        test = self.experiment.test
        truth = np.concatenate([r.euler[:, k] for r in test])
        sel = np.concatenate([self.clean[r.name] if samples == "clean" else np.ones(len(r), dtype=bool)
                              for r in test])
        n_seeds = len(self.predictions[name][test[0].name])
        joined = [np.concatenate([self.predictions[name][r.name][s][:, k] for r in test]) for s in range(n_seeds)]
        return np.array([s["rmse"] for s in seed_metrics(joined, truth, angle, sel)])

    def recording_rmse(self, name: str, angle: str, samples: str = "clean") -> NDArray[np.float64]:
        """Method ``name``'s RMSE [rad] of ``angle`` on each test recording alone, one row per
        recording (in :attr:`experiment` order) and one column per seed, on the ``samples``
        "clean" or "all": the units of a comparison (:func:`danae_lite.evaluate.comparison.compare`)."""
        if samples not in ("clean", "all"):
            raise ValueError(f"samples={samples!r}: choose 'clean' or 'all'")
        k = ANGLES.index(angle)
        return np.array([[s["rmse"] for s in seed_metrics(
            [p[:, k] for p in self.predictions[name][r.name]], r.euler[:, k], angle,
            self.clean[r.name] if samples == "clean" else None)] for r in self.experiment.test])

    def trial_metrics(self) -> pd.DataFrame:
        """The BROAD benchmark's figures per method and test recording (:data:`TRIAL_COLUMNS`):
        total, heading and inclination RMSE [deg] over the movement phases by
        :func:`trial_figures`, the mean over seeds and ``*_std`` their sample standard deviation
        over seeds (NaN with one seed), as in the main table. A method without a heading (RIANN)
        reports its inclination only; total and heading are NaN."""
        rows = []
        for name, per_test in self.predictions.items():
            for rec in self.experiment.test:
                agg, n_samples = trial_figures(rec, per_test[rec.name])
                rows.append({"method": name, "causal": bool(getattr(self.methods[name], "causal", False)),
                             "test": rec.name, **{m: agg[m][0] for m in broad_benchmark.METRICS},
                             **{f"{m}_std": agg[m][1] for m in broad_benchmark.METRICS},
                             "n_samples": n_samples, "seeds": len(per_test[rec.name])})
        return pd.DataFrame(rows, columns=list(TRIAL_COLUMNS))

    def to_json(self) -> dict[str, Any]:
        """``{"experiment", "data", "train", "test", "seeds", "alignment", "glitches", "methods", "seconds"}``;
        ``methods[name]`` holds ``description``, ``causal``, ``params`` and ``all``/``clean``:
        ``{angle: {mean_dev, max_dev, rmse, rmse_std, n}}`` [rad]."""
        methods: dict[str, Any] = {}
        for name, m in self.methods.items():
            entry: dict[str, Any] = {"description": m.description, "causal": bool(m.causal),
                                     "params": plain(m.params)}
            for subset in SUBSETS:
                rows = self.table[(self.table.method == name) & (self.table.samples == subset)]
                entry[subset] = {r.angle: {k: (None if pd.isna(getattr(r, k)) else float(getattr(r, k)))
                                           for k in ("mean_dev", "max_dev", "rmse", "rmse_std", "n")}
                                 for r in rows.itertuples()}
            methods[name] = entry
        return {
            "experiment": self.experiment.name,
            "data": self.experiment.data,
            "train": [r.name for r in self.experiment.train],
            "test": [r.name for r in self.experiment.test],
            "seeds": list(self.seeds),
            "alignment": self.alignment.summary(),
            "glitches": plain(self.glitches.to_dict(orient="records")),
            "methods": methods,
            "seconds": {k: float(v) for k, v in self.seconds.items()},
        }

    def plot(self, samples: str = "clean") -> "plt.Figure":
        """RMSE [rad] per method on ``samples``: one horizontal-bar panel per angle on a linear
        axis (roll and pitch share theirs), bars in the method palette
        (:func:`danae_lite.plots.method_color`), hatched where the method looks ahead (not
        causal), each bar labelled with its value; a method without an estimate of an angle
        is labelled so instead of drawn."""
        import matplotlib.pyplot as plt
        from matplotlib.patches import Patch

        from ..plots import angle_label, method_color, use_style

        use_style()
        w = self.wide("rmse", samples).astype(float)
        y = np.arange(len(w))
        fig, axes = plt.subplots(1, len(w.columns), figsize=(10, 1.2 + 0.3 * len(w)),
                                 sharey=True, squeeze=False)
        tilt = [a for a in ("roll", "pitch") if a in w.columns]
        tilt_max = 1.3 * np.nanmax(w[tilt].to_numpy()) if tilt else np.nan
        for ax, a in zip(axes[0], w.columns):
            bars = ax.barh(y, w[a].fillna(0.0), color=[method_color(m) for m in w.index],
                           edgecolor="black", linewidth=0.4)
            for bar, m, v in zip(bars, w.index, w[a]):
                if not self.methods[m].causal:
                    bar.set_hatch("///")
                label = f" {v:.3f}" if np.isfinite(v) else " no estimate"
                ax.text(v if np.isfinite(v) else 0.0, bar.get_y() + bar.get_height() / 2,
                        label, va="center", fontsize=7)
            right = tilt_max if a in tilt else 1.3 * np.nanmax(w[a])
            ax.set_xlim(0, right if np.isfinite(right) and right > 0 else 1.0)
            ax.set_title(angle_label(a).split(" [")[0])
            ax.set_xlabel(f"RMSE [rad], {samples} samples")
            ax.grid(True, axis="x", alpha=0.3)
            ax.grid(False, axis="y")
        axes[0, 0].set_yticks(y, w.index)
        axes[0, 0].invert_yaxis()
        fig.legend(handles=[Patch(facecolor="white", edgecolor="black", label="causal"),
                            Patch(facecolor="white", edgecolor="black", hatch="///",
                                  label="looks ahead (not causal)")],
                   loc="lower center", ncol=2, bbox_to_anchor=(0.5, 0.0))
        exp = self.experiment
        fig.suptitle(f"{exp.name} ({exp.data}): test {', '.join(r.name for r in exp.test)}")
        fig.tight_layout(rect=(0, 0.06, 1, 1))
        return fig

    def write(self, out_dir: str | os.PathLike[str]) -> dict[str, Path]:
        """Write ``leaderboard.csv``, ``leaderboard.json``, ``leaderboard.png``,
        ``search_<method>.csv`` (each grid search) and, for BROAD, ``broad_trials.csv``
        (:meth:`trial_metrics`) into ``out_dir``; return the paths."""
        import matplotlib.pyplot as plt

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"csv": out / "leaderboard.csv", "json": out / "leaderboard.json", "png": out / "leaderboard.png"}
        self.table.to_csv(paths["csv"], index=False, float_format="%.6g")
        paths["json"].write_text(json.dumps(self.to_json(), indent=2) + "\n")
        fig = self.plot()
        fig.savefig(paths["png"], dpi=120)
        plt.close(fig)
        if self.experiment.name == "broad":
            paths["broad_trials"] = out / "broad_trials.csv"
            self.trial_metrics().to_csv(paths["broad_trials"], index=False, float_format="%.6g")
        for name, m in self.methods.items():
            if m.search is not None:
                p = out / f"search_{name}.csv"
                m.search.to_csv(p, index=False, float_format="%.6g")
                paths[f"search_{name}"] = p
        return paths

    def estimates(self, name: str) -> pd.DataFrame:
        """Method ``name``'s per-sample output on every test recording, one row per recording,
        seed and sample: ``recording, seed, sample, t_s`` (seconds from the recording's start),
        ``roll_rad, pitch_rad, yaw_rad`` and, for a method with an error bar (``predict_bars``),
        the half-widths of its 68 % (``<angle>_sd_rad``, its standard deviation) and 95 %
        (``<angle>_hw95_rad``) intervals [rad]."""
        m = self.methods[name]
        blocks = []
        for rec in self.experiment.test:
            per_seed = (m.predict_bars(self.alignment.apply(rec)) if hasattr(m, "predict_bars")
                        else [(p, None, None) for p in self.predictions[name][rec.name]])
            for seed, (out, sd, hw) in zip(self.seeds, per_seed):
                cols: dict[str, Any] = {"recording": rec.name, "seed": int(seed), "sample": np.arange(len(out)),
                                        "t_s": np.arange(len(out)) / rec.fs}
                for k, a in enumerate(ANGLES):
                    cols[f"{a}_rad"] = out[:, k]
                for k, a in enumerate(ANGLES if sd is not None else ()):
                    cols[f"{a}_sd_rad"], cols[f"{a}_hw95_rad"] = sd[:, k], hw[:, k]
                blocks.append(pd.DataFrame(cols))
        return pd.concat(blocks, ignore_index=True)

    def write_estimates(self, out_dir: str | os.PathLike[str], names: Sequence[str]) -> dict[str, Path]:
        """``estimates_<method>.csv`` (:meth:`estimates`) per method of ``names``; returns the paths."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {}
        for name in names:
            paths[f"estimates_{name}"] = p = out / f"estimates_{name}.csv"
            self.estimates(name).to_csv(p, index=False, float_format="%.7g")
        return paths


def trial_figures(rec: Recording, per_seed: Sequence[NDArray[np.float64]]
                  ) -> tuple[dict[str, tuple[float, float]], int]:
    """The BROAD benchmark's figures of one test recording: ``({metric: (mean, std)}, n)``.

    Each seed's prediction (roll, pitch, yaw (N, 3) [rad], ground-truth frame) becomes a
    quaternion and is scored by :func:`danae_lite.research.broad_benchmark.benchmark_rmse` (total,
    heading, inclination RMSE [deg]) on the samples where ``rec.meta["movement"]`` and
    ``rec.meta["gt_valid"]`` hold (every sample when the recording has neither, e.g. a
    simulated one); ``n`` is their number. A prediction without a heading (NaN yaw: RIANN)
    gets the true yaw, so that only its inclination counts: its total and heading are NaN.
    Mean and sample std over seeds by :func:`danae_lite.evaluate.metrics.spread` (std NaN with one
    seed); (NaN, NaN) for a figure some seed lacks.
    """
    n = len(rec)
    movement = np.asarray(rec.meta.get("movement", np.ones(n, dtype=bool)), dtype=bool)
    valid = np.asarray(rec.meta.get("gt_valid", np.ones(n, dtype=bool)), dtype=bool)
    q_true = np.where(valid[:, None], rec.quat, np.nan)
    figures = []
    for est in per_seed:
        e = np.array(est, dtype=float)
        no_heading = bool(np.isnan(e[:, 2]).all())
        if no_heading:
            e[:, 2] = rec.euler[:, 2]
        r = broad_benchmark.benchmark_rmse(euler_to_quat(e), q_true, movement)
        f = r.as_dict()
        if no_heading:
            f["total_rmse_deg"] = f["heading_rmse_deg"] = np.nan
        figures.append(f)
    agg = {m: (metrics.spread([f[m] for f in figures]) if all(np.isfinite(f[m]) for f in figures)
               else (np.nan, np.nan)) for m in broad_benchmark.METRICS}
    return agg, r.n_samples


def _rows(name: str, causal: bool, preds: dict[str, list[NDArray[np.float64]]], exp: Experiment,
          clean: dict[str, NDArray[np.bool_]]) -> list[dict[str, Any]]:
    """The paper's metrics on all test samples taken together (all / clean) per angle, mean
    over seeds (:func:`danae_lite.evaluate.scoring.score_rows`)."""
    truth = np.concatenate([r.euler for r in exp.test])
    ok = np.concatenate([clean[r.name] for r in exp.test])
    n_seeds = len(next(iter(preds.values())))
    joined = [np.concatenate([preds[r.name][s] for r in exp.test]) for s in range(n_seeds)]
    return [{"method": name, "causal": causal, **row} for row in score_rows(joined, truth, ok)]


def run_leaderboard(
    exp: Experiment,
    *,
    methods: Sequence[str] = METHODS,
    seeds: Sequence[int] = (0, 1, 2),
    train_config: TrainConfig | None = None,
    cache: str | os.PathLike[str] | None = None,
    progress: bool = True,
    extra: Sequence[Method] = (),
    align: bool | None = None,
    jobs: int = 1,
) -> Leaderboard:
    """Fit every method on ``exp.train`` and evaluate it on ``exp.test`` (see the module docstring).

    Parameters
    ----------
    exp : the recordings (:func:`danae_lite.data.experiments.load_experiment` or the CLI's selection).
    methods : names from :data:`danae_lite.research.baselines.METHODS`, ``danae-res[<filter>]`` or ``danae-safe[<filter>]``
        (:class:`danae_lite.research.danae_res.DanaeRes` on that filter).
    seeds : DANAE training seeds (one network per angle and seed).
    train_config : DANAE settings; default the paper's (:class:`~danae_lite.danae.train_types.TrainConfig`).
    cache : trained-network cache folder; None (default): no cache. Entry points pass the
        folder of their settings (:class:`danae_lite.runtime.RunSettings`).
    progress : show a progress bar over the methods (and DANAE's training bars).
    extra : further unfitted :class:`~danae_lite.research.methods.Method` objects (e.g. the variants
        of :mod:`danae_lite.research.variants`), fitted and evaluated after ``methods`` under their ``name``.
    align : None (default): estimate the frame alignment on the training recordings, or take
        the identity when ``exp.aligned``, and give every method the rotated specific force;
        False: the recordings exactly as loaded, sensor signals and frames untouched (as the
        paper's experiment, :func:`danae_lite.paper.pipeline.reproduce`, runs them).
    jobs : worker processes for the networks of each method (:mod:`danae_lite.danae.networks`).
    """
    if progress:  # the notebook widget when available
        from tqdm.auto import tqdm
    else:
        from tqdm import tqdm

    t_total = time.perf_counter()
    todo = _check_names(exp, methods, extra)
    clean = {r.name: clean_mask(r) for r in [*exp.train, *exp.test]}
    ctx, aligned_test = _context(exp, clean, seeds, train_config, align, cache=cache, jobs=jobs, progress=progress)
    pretrain(_network_jobs(todo, ctx), cache=cache, jobs=jobs)  # every worker busy
    fitted: dict[str, Method] = {}
    preds: dict[str, dict[str, list[NDArray[np.float64]]]] = {}
    seconds: dict[str, float] = {}
    rows: list[dict[str, Any]] = []
    for item in tqdm(todo, desc="leaderboard", unit="method", disable=not progress):
        t0 = time.perf_counter()
        m = ctx.method(item) if isinstance(item, str) else item.fit(ctx)
        name = m.name
        preds[name] = {r.name: m.predict(r) for r in aligned_test}
        seconds[name] = time.perf_counter() - t0
        fitted[name] = m
        rows += _rows(name, bool(m.causal), preds[name], exp, clean)
    seconds["total"] = time.perf_counter() - t_total
    table = pd.DataFrame(rows, columns=list(CSV_COLUMNS))
    return Leaderboard(experiment=exp, table=table, methods=fitted, predictions=preds, alignment=ctx.alignment,
                       glitches=glitch_table([*exp.train, *exp.test]), clean=clean, seconds=seconds,
                       seeds=ctx.seeds, train_config=ctx.train_config)


def _network_jobs(todo: Sequence[Method | str], ctx: Context) -> list[NetworkJob]:
    """The networks the methods ``todo`` (names or objects) train when fitted on ``ctx``
    (:meth:`~danae_lite.research.methods.Method.network_jobs`), for :func:`pretrain`."""
    return [j for item in todo for j in (make_method(item) if isinstance(item, str) else item).network_jobs(ctx)]


def network_jobs(exp: Experiment, *, methods: Sequence[str] = METHODS, seeds: Sequence[int] = (0, 1, 2),
                 train_config: TrainConfig | None = None, extra: Sequence[Method] = (), align: bool | None = None
                 ) -> list[NetworkJob]:
    """The networks :func:`run_leaderboard` trains with these arguments, as jobs, without
    training them: what :func:`danae_lite.research.crossval.run_splits` trains for all of its
    splits together before it runs them. ``extra`` objects are given their context (use copies)."""
    todo = _check_names(exp, methods, extra)
    clean = {r.name: clean_mask(r) for r in [*exp.train, *exp.test]}
    return _network_jobs(todo, _context(exp, clean, seeds, train_config, align)[0])


def _context(exp: Experiment, clean: dict[str, NDArray[np.bool_]], seeds: Sequence[int],
             train_config: TrainConfig | None, align: bool | None, **settings: Any
             ) -> tuple[Context, list[Recording]]:
    """The fitting context of the methods (``settings``: cache, jobs, progress) and the test
    recordings as they see them (:func:`_align`)."""
    alignment, aligned_train, aligned_test = _align(exp, clean, align)
    ctx = Context(train=aligned_train, clean={r.name: clean[r.name] for r in exp.train}, alignment=alignment,
                  seeds=tuple(int(s) for s in seeds), train_config=train_config or TrainConfig(),
                  factory=make_method, **settings)
    return ctx, aligned_test


def _check_names(exp: Experiment, methods: Sequence[str], extra: Sequence[Method]) -> list[Method | str]:
    """The methods to run (names, then objects); ValueError for an unknown method name, a
    method name given twice or a recording name that is not unique."""
    unknown = [m for m in methods if not is_method_name(m)]
    if unknown:
        raise ValueError(f"unknown method(s) {', '.join(unknown)}; choose from {', '.join(METHODS)} "
                         "or danae-res[<filter>] / danae-safe[<filter>]")
    seen: set[str] = set()
    dup = sorted({r.name for r in [*exp.train, *exp.test] if r.name in seen or seen.add(r.name)})
    if dup:
        raise ValueError(f"recording names must be unique across training and test, repeated: {', '.join(dup)}")
    todo: list[Method | str] = [*methods, *extra]
    names = [m if isinstance(m, str) else m.name for m in todo]
    if len(set(names)) != len(names):
        raise ValueError(f"method names must be unique, got {names}")
    return todo


def _align(exp: Experiment, clean: dict[str, NDArray[np.bool_]], align: bool | None
           ) -> tuple[FrameAlignment, list[Recording], list[Recording]]:
    """The frame alignment and the training and test recordings every method sees: rotated
    by the alignment estimated on the clean training samples, by the identity for an aligned
    experiment, or (``align=False``) exactly as loaded."""
    alignment = (FrameAlignment.identity() if exp.aligned or align is False
                 else estimate_alignment(exp.train, [clean[r.name] for r in exp.train]))
    if align is False:  # the recordings exactly as loaded
        return alignment, list(exp.train), list(exp.test)
    return alignment, [alignment.apply(r) for r in exp.train], [alignment.apply(r) for r in exp.test]
