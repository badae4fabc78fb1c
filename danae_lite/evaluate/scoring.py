"""From predictions to the rows of the package's result tables, one rule for every table.

* :func:`seed_metrics`: the paper's metrics (:func:`danae_lite.evaluate.metrics.metric_table`: mean
  dev, max dev, RMSE [rad], errors wrapped to [-π, π)) of one angle for each seed's estimate;
* :func:`over_seeds`: their mean over seeds and the sample standard deviation of the RMSE
  (:func:`danae_lite.evaluate.metrics.spread`);
* :func:`score_rows`: both on all samples and on the clean ones, per angle: the rows of the
  leaderboard (:mod:`danae_lite.research.leaderboard`), of the cross-validation per held-out
  recording (:mod:`danae_lite.research.crossval`) and of the reproduction (:mod:`danae_lite.paper.pipeline`);
* :func:`plain`: a JSON-able copy of a result (numpy numbers to Python ones, NaN to None).
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from . import metrics
from ..angles import ANGLES

Array = NDArray[np.float64]

SUBSETS: tuple[str, str] = ("all", "clean")
"""Sample subsets of every table: every sample, or the clean ground-truth samples only."""


def seed_metrics(estimates: Sequence[Array], truth: Array, angle: str,
                 samples: NDArray[np.bool_] | None = None) -> list[pd.Series]:
    """The paper's metrics [rad] of one angle, one Series (``mean_dev``, ``max_dev``, ``rmse``)
    per seed.

    Parameters
    ----------
    estimates : one (N,) estimate [rad] per seed; a seed whose estimate is NaN throughout (a
        method without an estimate of this angle, e.g. RIANN's yaw) is left out.
    truth : (N,) ground truth [rad].
    angle : the angle's name ("roll", "pitch", "yaw").
    samples : (N,) bool, the samples scored; default all.
    """
    return [metrics.metric_table(e, truth, angles=(angle,), mask=samples)[angle]
            for e in estimates if not np.isnan(e).all()]


def over_seeds(per_seed: Sequence[pd.Series]) -> dict[str, float]:
    """``{mean_dev, max_dev, rmse}``: each the mean over seeds [rad], and ``rmse_std``: the
    sample standard deviation of the RMSE over seeds (NaN with one seed), all by
    :func:`danae_lite.evaluate.metrics.spread`; every value NaN when no seed has an estimate."""
    if not per_seed:
        return {**{m: np.nan for m in metrics.METRICS}, "rmse_std": np.nan}
    out = {m: metrics.spread([s[m] for s in per_seed])[0] for m in metrics.METRICS}
    out["rmse_std"] = metrics.spread([s["rmse"] for s in per_seed])[1]
    return out


def score_rows(per_seed: Sequence[Array], truth: Array, clean: NDArray[np.bool_],
               angles: Sequence[str] = ANGLES) -> list[dict[str, Any]]:
    """One row per subset (:data:`SUBSETS`) and angle: ``samples``, ``angle``, the metrics of
    :func:`over_seeds` [rad] and ``n`` (samples scored).

    ``per_seed``: one (N, 3) roll, pitch, yaw estimate [rad] per seed (all test recordings
    joined, or one recording); ``truth``: (N, 3) [rad]; ``clean``: (N,) bool, the clean
    ground-truth samples."""
    rows = []
    for subset, sel in zip(SUBSETS, (np.ones(len(truth), dtype=bool), np.asarray(clean, dtype=bool))):
        for a in angles:
            k = ANGLES.index(a)
            scores = over_seeds(seed_metrics([e[:, k] for e in per_seed], truth[:, k], a, sel))
            rows.append({"samples": subset, "angle": a, **scores, "n": int(sel.sum())})
    return rows


def plain(obj: Any) -> Any:
    """JSON-able copy: numpy scalars and arrays to Python numbers and lists, tuples to lists,
    keys to str, non-finite floats to None."""
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, (np.ndarray, np.generic)):
        return plain(obj.tolist())
    if isinstance(obj, float):
        return float(obj) if np.isfinite(obj) else None
    return obj
