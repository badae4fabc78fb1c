"""The paper's pipeline as a few reusable steps: KF estimates -> one DANAE per angle -> metrics.

Each step calls the module that owns the work (:mod:`~danae_lite.kalman`,
:mod:`~danae_lite.train`, :mod:`~danae_lite.metrics`); this module only wires them together
so that chapters and the command line run exactly the same code.

Angles are (roll, pitch, yaw) [rad] as everywhere in the package. As in the paper, one network
is trained per angle, on the KF estimate of that angle as input and the ground truth of the
same angle as target.
"""
from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from . import kalman, metrics
from .angles import ANGLES
from .recording import Recording
from .config import cache_dir as resolve_cache_dir
from .train import TrainConfig, TrainResult, load_result, predict, save, train


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
    config = config or TrainConfig()
    inputs = [np.ascontiguousarray(estimates[r.name][:, k]) for r in train_recs]
    targets = [np.ascontiguousarray(r.euler[:, k]) for r in train_recs]
    folder = resolve_cache_dir(cache)
    path = folder / f"danae-{angle}-seed{config.seed}-{_cache_key(inputs, targets, config)}.pt" if folder else None
    if path is not None and path.is_file():
        return load_result(path)
    res = train(inputs, targets, config, progress=progress)
    if path is not None:
        save(res, path, metadata={"angle": angle, "train": [r.name for r in train_recs]})
    return res


def _cache_key(inputs: list[NDArray[np.float64]], targets: list[NDArray[np.float64]], config: TrainConfig) -> str:
    """Hash of everything that determines a trained network (not the device or thread count)."""
    from . import model as model_module, train as train_module

    h = hashlib.sha256()
    for module in (model_module, train_module):
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
