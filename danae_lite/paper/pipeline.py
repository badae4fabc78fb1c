"""The paper's experiment end to end: KF, one DANAE per angle and seed, Table 1 or 2, Figure 1 or 2.

:func:`reproduce` runs the paper's KF (:func:`filter_all`) on every recording and the paper's
DANAE (raw targets, every target sample, no frame alignment) on its output
(:func:`seed_study`, i.e. :class:`danae_lite.paper.danae.PaperDanae`, the estimator behind the
leaderboard's ``danae`` too), and scores both on the test recordings with the leaderboard's
rule (:func:`danae_lite.evaluate.scoring.score_rows`: all test samples taken together, mean over
seeds), on all samples and on the clean ones. It returns a :class:`~danae_lite.paper.reproduction.Reproduction` (Table 1 or 2
and Figure 1 or 2) that can write ``metrics.json``, ``metrics.csv``, the per-seed table and
the figure. :func:`seed_study` is also the step-by-step view of chapter 3: the networks
evaluated recording by recording, with both of the paper's reconstructions (overlap average
and tiles). The results and their tables are in :mod:`danae_lite.paper.reproduction`.

Angles are (roll, pitch, yaw) [rad] as everywhere in the package. As in the paper, one network
is trained per angle, on the KF estimate of that angle as input and the ground truth of the
same angle as target.
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ..angles import ANGLES
from ..danae.train import validation_tail
from ..danae.train_types import TrainConfig
from ..data.experiments import Experiment
from ..data.recording import DataError, Recording
from ..evaluate.scoring import seed_metrics
from ..kalman.filter import run_kf
from ..kalman.model import KFConfig
from .danae import PaperDanae, check_settings
from .reproduction import Reproduction, SeedStudy, score


def filter_all(recordings: Iterable[Recording], config: KFConfig | None = None) -> dict[str, NDArray[np.float64]]:
    """Run the paper's KF on every recording; return ``{name: euler (N, 3) [rad]}``."""
    return {r.name: run_kf(r, config).euler for r in recordings}


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
    return Reproduction(
        experiment=exp, angles=angles, seeds=seeds, estimates=estimates, study=study,
        seconds={"kf": t_kf, "train": t_train, "total": time.perf_counter() - t_start},
        config=config, kf_config=kf_config, leaderboard=score(exp, estimates, study, angles, seeds))


def _checked(exp: Experiment, angles: Sequence[str], seeds: Sequence[int]) -> tuple[tuple[str, ...], list[int]]:
    """``angles`` as a tuple and ``seeds`` as ints; ValueError for an empty or unknown angle set,
    repeated or no seeds, or a recording name used twice."""
    angles, seeds = check_settings("raw", angles), [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be distinct and non-empty, got {seeds}")
    names = [r.name for r in [*exp.train, *exp.test]]
    if len(set(names)) != len(names):
        raise ValueError(f"recording names must be unique across training and test, got {names}")
    return angles, seeds
