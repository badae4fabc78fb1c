"""The paper's DANAE as one estimator: a network per angle and seed, on a filter's angle.

:class:`PaperDanae` is the single mechanism behind every run of the paper's DANAE: the
reproduction (:func:`danae_lite.paper.pipeline.reproduce`, :func:`danae_lite.paper.pipeline.seed_study`)
and the leaderboard's ``danae`` (:class:`danae_lite.research.baselines.Danae`). For each angle it trains
one network per seed (:func:`danae_lite.danae.networks.train_networks`) with the filter's estimate of
that angle as input and the ground truth of the same angle as target, one array per training
recording so that no window crosses two recordings; it predicts with the overlap average of
:func:`danae_lite.danae.predict.predict` (or the paper's tiles).

Targets: ``"raw"``, the ground-truth angle as recorded (the paper's; yaw in [-π, π) while the
KF's yaw runs on), or ``"continuous"``, the truth moved next to the filter's unwrapped angle,
``x + wrap(truth - x)`` (:func:`continuous_target`), so that no target jumps by 2π; the yaw
predicted from continuous targets is wrapped to [-π, π).
"""
from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..angles import ANGLES, wrap
from ..danae.networks import NetworkJob, network_jobs, train_networks
from ..danae.predict import predict
from ..danae.train_types import TrainConfig, TrainResult

Array = NDArray[np.float64]

TARGETS: tuple[str, str] = ("continuous", "raw")
"""Target kinds of :class:`PaperDanae` (see the module docstring)."""


def continuous_target(x: Array, truth: Array) -> Array:
    """Truth [rad] moved next to ``x`` [rad] (``x + wrap(truth - x)``), so a target never jumps by 2π."""
    return x + wrap(truth - x)


def check_settings(targets: str, angles: Sequence[str]) -> tuple[str, ...]:
    """``angles`` as a tuple; ValueError for an unknown target kind or an empty or unknown angle set."""
    if targets not in TARGETS:
        raise ValueError(f"targets={targets!r}: choose 'continuous' or 'raw'")
    if not angles or not set(angles) <= set(ANGLES):
        raise ValueError(f"angles must be a non-empty subset of {ANGLES}, got {tuple(angles)}")
    return tuple(angles)


class PaperDanae:
    """One DANAE per angle and seed on a filter's angles (see the module docstring).

    Parameters
    ----------
    angles : angles that get a network; the others are predicted as NaN.
    targets : ``"raw"`` (the paper's) or ``"continuous"``.
    config : training settings (default the paper's); its ``seed`` is replaced by each seed.
    seeds : training seeds (distinct).
    tag, metadata : cache file prefix and what is stored with each network.
    cache, jobs, progress : see :func:`danae_lite.danae.networks.train_networks`.

    Attributes (after ``fit``)
    --------------------------
    results_ : ``{(angle, seed): TrainResult}``, angles in the order of ``angles``.
    seconds_ : training time of all networks [s].
    """

    def __init__(self, angles: Sequence[str] = ANGLES, *, targets: str = "raw", config: TrainConfig | None = None,
                 seeds: Sequence[int] = (0,), tag: str = "danae", metadata: Mapping[str, Any] | None = None,
                 cache: str | os.PathLike[str] | None = None, jobs: int = 1, progress: bool = False) -> None:
        self.angles = check_settings(targets, angles)
        self.targets, self.config, self.seeds = targets, config or TrainConfig(), tuple(int(s) for s in seeds)
        self.tag, self.metadata = tag, dict(metadata or {})
        self.cache, self.jobs, self.progress = cache, jobs, progress

    def fit(self, estimates: Sequence[Array], truths: Sequence[Array],
            masks: Sequence[NDArray[np.bool_]] | None = None) -> PaperDanae:
        """Train every network.

        Parameters
        ----------
        estimates : the filter's roll, pitch, yaw (N, 3) [rad] per training recording (yaw unwrapped).
        truths : the ground truth (N, 3) [rad] of the same recordings.
        masks : per recording, the target samples allowed in the loss (e.g. the clean ones); None: all.
        """
        self.results_: dict[tuple[str, int], TrainResult] = train_networks(
            *self._heads(estimates, truths), self.config, self.seeds, masks=masks, tag=self.tag,
            metadata=self.metadata, cache=self.cache, jobs=self.jobs, progress=self.progress)
        self.seconds_ = float(sum(r.seconds for r in self.results_.values()))
        return self

    def network_jobs(self, estimates: Sequence[Array], truths: Sequence[Array],
                     masks: Sequence[NDArray[np.bool_]] | None = None) -> list[NetworkJob]:
        """The networks :meth:`fit` trains with the same arguments, as jobs, without training
        them (:func:`danae_lite.danae.networks.pretrain` trains those of several fits together)."""
        return network_jobs(*self._heads(estimates, truths), self.config, self.seeds, masks=masks, tag=self.tag,
                            metadata=self.metadata)[1]

    def _heads(self, estimates: Sequence[Array], truths: Sequence[Array]) -> tuple[dict[str, list[Array]],
                                                                                    dict[str, list[Array]]]:
        """Input and target per angle and training recording (see the module docstring)."""
        xs, ys = {}, {}
        for a in self.angles:
            k = ANGLES.index(a)
            xs[a] = [x[:, k] for x in estimates]
            ys[a] = ([y[:, k] for y in truths] if self.targets == "raw" else
                     [continuous_target(x[:, k], y[:, k]) for x, y in zip(estimates, truths)])
        return xs, ys

    def predict(self, est: Array, *, stitch: str = "overlap", stride: int = 1) -> list[Array]:
        """Denoised roll, pitch, yaw (N, 3) [rad] of one recording's filter estimate ``est``
        (N, 3), one array per seed; NaN for an angle without a network (and, with
        ``stitch="tiles"``, on the samples the tiles leave uncovered). ``stride``: step between
        the overlapping windows [samples] (:func:`~danae_lite.danae.predict.predict`)."""
        out = []
        for seed in self.seeds:
            e = np.full_like(est, np.nan, dtype=float)
            for a in self.angles:
                k = ANGLES.index(a)
                e[:, k] = predict(self.results_[(a, seed)], est[:, k], stitch=stitch, stride=stride)[:, 0]
            if self.targets == "continuous":  # raw targets: the network's output as it is (the paper's)
                e[:, 2] = wrap(e[:, 2])
            out.append(e)
        return out
