"""Every method of the leaderboard behind one interface: fit on training recordings, predict angles.

A method is fitted on the training recordings only (its parameters chosen by a documented
grid search there) and then predicts roll, pitch, yaw [rad] for any recording, in the ground
truth's frame. All methods see the same inputs: recordings already rotated into the ground
truth's body frame by a :class:`~danae_lite.data.alignment.FrameAlignment` estimated on the
training recordings, and they all get the same heading correction (magnetic north -> the
ground truth's x axis). Training objectives use clean ground-truth samples only
(:mod:`danae_lite.data.groundtruth`).

========================  =========================================================================
name                      what it is / what is tuned on the training recordings
========================  =========================================================================
``constant``              the training recordings' mean attitude (yaw: circular mean), whatever
                          the sensors say: the floor any estimator must beat
``paper_kf``              the paper's KF, untuned: P0 = Q = I6, R = I3, dt = 1/fs
``tuned_kf``              the same KF with its yaw innovation wrapped to [-π, π) and
                          Q = diag(q_tilt, q_bias, q_tilt, q_bias, q_yaw, q_bias), R = I; the
                          three searched jointly on a grid (roll and pitch feed the heading
                          formula, so no angle is tuned on runs where the others had another Q)
``tuned_kf_rts``          the tuned KF followed by a Rauch-Tung-Striebel smoother
                          (:func:`danae_lite.kalman.offline.rts_smooth`): its non-causal counterpart
``butterworth``           the paper KF's output low-passed by a digital Butterworth filter
                          (``scipy.signal.butter``, order 2, second-order sections, zero phase with
                          ``sosfiltfilt``); cut-off [Hz] per angle from a grid
``moving_average``        the paper KF's output through a centred moving average; length per angle
``linear_map``            an affine map from each 20-sample window of the paper KF's angle to the
                          20-sample truth window, least squares on the training windows; windows
                          averaged back like DANAE's overlap reconstruction
``fusion`` ``vqf``        library filters (:mod:`danae_lite.research.ahrs.filters`), their main parameters searched
``madgwick`` ``mahony``   jointly on a grid (:data:`danae_lite.research.ahrs.filters.FILTERS`): Fusion gain and
                          magnetic rejection, VQF tauAcc and tauMag, Madgwick beta, Mahony k_P and k_I
``riann``                 RIANN's shipped network, nothing tuned; roll and pitch only (yaw NaN)
``danae``                 the paper's DANAE (one network per angle and seed) on the paper KF's
                          output; targets exclude ground-truth glitches
========================  =========================================================================

Grid searches of whole filters (the KFs, the library filters) minimise the RMSE of the total
rotation error on the clean training samples (:func:`total_objective`: the angle of
``R_est R_true^T``, the BROAD benchmark's "total" error), so all three angles count together;
the post-processing methods, which treat each angle on its own, choose per angle.

Every method says whether it is ``causal`` (its output at sample ``t`` uses samples up to ``t``
only): the KFs, the library filters and the constant are; the smoother, the zero-phase and
centred filters, the window map and DANAE are not.

Angles handled on the circle: the post-processing methods work on the KF's angle unwrapped
along the recording, and their training target is the truth moved next to it,
``x + wrap(truth - x)``, so that no method is taught a 2π jump; outputs are wrapped to
[-π, π) at the end. For roll and pitch this changes nothing.

The interface (:class:`~danae_lite.research.methods.Method`, the fitting context, the objectives) is
:mod:`danae_lite.research.methods`; ``danae`` is :class:`danae_lite.paper.danae.PaperDanae` on the paper
KF's output, the same estimator as the paper's experiment (:func:`danae_lite.paper.pipeline.reproduce`).
"""
from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .ahrs import filters
from ..kalman import grid as kf_grid, offline
from . import methods
from ..kalman.filter import run_kf
from ..kalman.model import KFConfig
from ..angles import ANGLES, wrap
from .features import research_config
from .post_processing import Butterworth, LinearMap, MovingAverage, OnPaperKF
from .memo import RunMemo, digest
from .methods import Method, total_objective, train_objective
from ..danae.networks import NetworkJob
from ..paper.danae import PaperDanae, check_settings
from ..data.recording import Recording

__all__ = ["KF_Q_ANGLE", "KF_Q_BIAS", "METHODS", "Constant", "Context", "Danae", "LibraryFilter", "PaperKF",
           "TunedKF", "TunedKFSmoother", "denoiser_source", "is_method_name", "make_method"]

Array = NDArray[np.float64]

METHODS: tuple[str, ...] = ("constant", "paper_kf", "tuned_kf", "tuned_kf_rts", "butterworth", "moving_average",
                            "linear_map", "fusion", "vqf", "madgwick", "mahony", "riann", "danae")
"""Leaderboard method names, in table order."""

KF_Q_ANGLE = (1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)
"""Grid of the tuned KF's angle process noise per step [rad²] (with R = 1 rad², only Q/R matters),
for roll and pitch (``q_tilt``) and for yaw (``q_yaw``)."""
KF_Q_BIAS = (0.0, 1e-12, 1e-10, 1e-8)
"""Grid of the tuned KF's bias process noise per step [(rad/s)²]."""


@dataclass
class Context(methods.Context):
    """:class:`danae_lite.research.methods.Context` that builds the methods of this module by name
    (:func:`make_method`) unless it is given another ``factory``."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.factory is None:
            self.factory = make_method


class Constant(Method):
    name = "constant"
    description = "the training recordings' mean attitude (yaw: circular mean), whatever the sensors say"
    causal = True  # it uses no sample at all

    def fit(self, ctx: Context) -> "Constant":
        self.ctx = ctx
        e = np.concatenate([r.euler[ctx.clean[r.name]] for r in ctx.train])
        self.value = np.array([e[:, 0].mean(), e[:, 1].mean(),
                               np.arctan2(np.sin(e[:, 2]).mean(), np.cos(e[:, 2]).mean())])
        self.params = {a: float(v) for a, v in zip(ANGLES, self.value)}
        return self

    def predict(self, rec: Recording) -> list[Array]:
        return [np.tile(self.value, (len(rec), 1))]


class PaperKF(Method):
    name = "paper_kf"
    description = "the paper's KF, P0 = Q = I, R = I, dt = 1/fs"
    causal = True

    def __init__(self, config: KFConfig | None = None) -> None:
        super().__init__()
        self.config = config or KFConfig()

    def fit(self, ctx: Context) -> "PaperKF":
        self.ctx = ctx
        self.params = {"Q_diag": np.diag(self.config.Q).tolist(), "R_diag": np.diag(self.config.R).tolist()}
        return self

    def raw(self, rec: Recording) -> Array:
        """KF estimate in the ground-truth frame, yaw NOT wrapped (continuous along the recording)."""
        e = run_kf(rec, self.config).euler.copy()
        e[:, 2] = e[:, 2] + self.ctx.alignment.north_yaw
        return e

    def predict(self, rec: Recording) -> list[Array]:
        e = self.raw(rec)
        e[:, 2] = wrap(e[:, 2])
        return [e]


searches = RunMemo(64 << 20, code_of=__name__)
"""Grid searches of :class:`TunedKF` and :class:`LibraryFilter` (their score table per grid
point), by method, grid and training data: a search is run once, and its many filter runs are
not stored on disk."""


class TunedKF(PaperKF):
    name = "tuned_kf"
    description = "the paper's KF with a wrapped yaw innovation and Q searched jointly on the training recordings (R = I)"

    @staticmethod
    def _config(q_tilt: float, q_bias: float, q_yaw: float) -> KFConfig:
        return KFConfig(Q=[q_tilt, q_bias, q_tilt, q_bias, q_yaw, q_bias], wrap_yaw_innovation=True)

    def fit(self, ctx: Context) -> "TunedKF":
        self.ctx = ctx
        grid = list(itertools.product(KF_Q_ANGLE, KF_Q_BIAS, KF_Q_ANGLE))
        scores = self._search(grid, ctx)
        self.search = pd.DataFrame(grid, columns=["q_tilt", "q_bias", "q_yaw"])
        self.search["objective"] = scores[:, 0]
        for j, a in enumerate(ANGLES):
            self.search[f"rmse_{a}"] = scores[:, 1 + j]
        best = self.search.loc[self.search["objective"].idxmin()]
        self.params = {"q_tilt": float(best.q_tilt), "q_bias": float(best.q_bias), "q_yaw": float(best.q_yaw)}
        self.config = self._config(**self.params)
        return self

    def _search(self, grid: list[tuple[float, float, float]], ctx: Context) -> Array:
        """Per grid point, the total-error objective and the clean-sample RMSE [rad] of roll,
        pitch and yaw over the training recordings, (len(grid), 4)
        (:func:`~danae_lite.kalman.grid.score_kf_grid`). A search made before on the same
        grid, training data and north offset is found in :data:`searches`."""
        key = ("tuned-kf", tuple(grid), float(ctx.alignment.north_yaw),
               tuple((r.fs, digest(r.gyro, r.acc, r.mag, r.quat, ctx.clean[r.name])) for r in ctx.train))
        found = searches.get(key)
        if found is None:
            scores = kf_grid.score_kf_grid([self._config(*g) for g in grid], ctx.train, ctx.clean,
                                           ctx.alignment.north_yaw)
            found = np.column_stack([scores.total, scores.per_angle])
            searches.put(key, found)
        return found


class TunedKFSmoother(PaperKF):
    name = "tuned_kf_rts"
    description = "the tuned KF followed by a Rauch-Tung-Striebel smoother (every sample, past and future)"
    causal = False

    def fit(self, ctx: Context) -> "TunedKFSmoother":
        self.ctx = ctx
        self.config = ctx.method("tuned_kf").config
        self.params = {"from": "tuned_kf"}
        return self

    def raw(self, rec: Recording) -> Array:
        e = offline.rts_smooth(run_kf(rec, self.config))[:, 0::2].copy()
        e[:, 2] = e[:, 2] + self.ctx.alignment.north_yaw
        return e


class LibraryFilter(Method):
    """A filter of :data:`danae_lite.research.ahrs.filters.FILTERS`, its grid searched on the training recordings."""

    causal = True  # each runs sample by sample on the past only (see danae_lite.research.ahrs.filters)

    def __init__(self, name: str) -> None:
        super().__init__()
        if name not in filters.FILTERS:
            raise ValueError(f"unknown filter {name!r}; choose one of {', '.join(filters.FILTERS)}")
        self.name = name
        self.spec = filters.FILTERS[name]
        self.description = (self.spec.run.__doc__ or "").strip().split("\n")[0]

    def run(self, rec: Recording, **params: Any) -> Array:
        return self._frame(filters.run_filter(self.name, rec.gyro, rec.acc, rec.mag, rec.fs, **params))

    def _frame(self, q: Array) -> Array:
        """The filter's quaternions as Euler angles [rad] in the ground-truth frame."""
        e = filters.to_euler(self.name, q)
        return self.ctx.alignment.to_truth_frame(e) if self.spec.has_yaw else e

    def fit(self, ctx: Context) -> "LibraryFilter":
        self.ctx = ctx
        keys = list(self.spec.grid)
        grid = [dict(zip(keys, values)) for values in itertools.product(*(self.spec.grid[k] for k in keys))]
        if grid:
            scores = self._search(grid, ctx)
            self.search = pd.DataFrame([{**params, **{f"rmse_{a}": float(v) for a, v in zip(ANGLES, row[:3])},
                                         "objective": float(row[3])} for params, row in zip(grid, scores)])
            best = self.search.loc[self.search["objective"].idxmin()]
            self.params = {k: (float(best[k]) if isinstance(best[k], (int, float, np.floating)) else best[k]) for k in keys}
        return self

    def _search(self, grid: list[dict[str, Any]], ctx: Context) -> Array:
        """Per grid point, the clean-sample RMSE [rad] of roll, pitch, yaw and the total-error
        objective over the training recordings, (len(grid), 4). A search made before with the
        same filter, grid, training data and alignment is found in :data:`searches`."""
        al = ctx.alignment
        key = ("search", self.name, tuple((k, tuple(self.spec.grid[k])) for k in self.spec.grid),
               digest(al.sensor_to_body, np.array([al.north_yaw])),
               tuple((r.fs, digest(r.gyro, r.acc, r.mag, r.quat, ctx.clean[r.name])) for r in ctx.train))
        found = searches.get(key)
        if found is None:
            runs = iter(filters.run_many([(self.name, r.gyro, r.acc, r.mag, r.fs, params)
                                          for params in grid for r in ctx.train], jobs=ctx.jobs, persist=False))
            rows = []
            for _ in grid:
                est = {r.name: self._frame(next(runs)) for r in ctx.train}
                rows.append([*train_objective(est, ctx, (0, 1, 2)), total_objective(est, ctx)])
            found = np.array(rows, dtype=float)
            searches.put(key, found)
        return found

    def predict(self, rec: Recording) -> list[Array]:
        return [self.run(rec, **self.params)]


class Danae(OnPaperKF):
    """The paper's DANAE: one network per angle and seed on the paper KF's output.

    Parameters
    ----------
    targets : ``"continuous"`` (default: the truth moved next to the KF's unwrapped angle,
        ``x + wrap(truth - x)``, so no target jumps by 2π) or ``"raw"`` (the ground-truth angle
        as recorded, yaw in [-π, π): the paper's and the authors' code).
    clean_targets : leave the ground truth's glitches out of the loss (default) or train on
        every sample as the paper did.
    angles : the angles that get a network; the others are predicted as NaN.
    stride : step between the overlapping windows of its predictions [samples]; default
        :data:`~danae_lite.research.methods.PREDICT_STRIDE`, 1 for every window (chapter 4's
        :func:`~danae_lite.paper.pipeline.reproduce`).
    val_stride : step between its validation windows [samples]; default None: windows that
        tile the validation tails (the window length apart, each validation sample scored once,
        as every network of Part III: :func:`~danae_lite.research.features.research_config`);
        1 for every window, the paper's recipe (chapter 4's
        :func:`~danae_lite.paper.pipeline.reproduce`). The training itself is the same; the
        validation loss, and so the checkpoint kept, is estimated with a tenth to a twentieth
        of the forward passes.
    """

    name = "danae"
    source = "paper_kf"
    description = "the paper's DANAE per angle on the paper KF's output, glitch-free targets"

    def __init__(self, targets: str = "continuous", clean_targets: bool = True,
                 angles: Sequence[str] = ANGLES, stride: int = methods.PREDICT_STRIDE,
                 val_stride: int | None = None) -> None:
        super().__init__()
        self.angles = check_settings(targets, angles)
        self.targets, self.clean_targets, self.stride = targets, bool(clean_targets), int(stride)
        self.val_stride = val_stride
        if targets == "raw" or not clean_targets:
            self.description = (f"the paper's DANAE per angle on the paper KF's output, {targets} targets, "
                                f"{'glitch-free' if clean_targets else 'every'} target sample")

    def _model(self, ctx: Context) -> tuple[PaperDanae, tuple[list[Array], list[Array], list[NDArray[np.bool_]] | None]]:
        """The unfitted networks and the arguments of their ``fit``: the paper KF's angles, the
        truth and the clean masks of the training recordings."""
        super().fit(ctx)
        cfg = ctx.train_config
        cfg = (research_config(cfg, cfg.seed, capped=False) if self.val_stride is None
               else replace(cfg, val_stride=int(self.val_stride)))
        model = PaperDanae(self.angles, targets=self.targets, config=cfg, seeds=ctx.seeds,
                           tag=self.name, metadata={"method": self.name, "train": [r.name for r in ctx.train]},
                           cache=ctx.cache, jobs=ctx.jobs, progress=ctx.progress)
        return model, ([self.kf_train[r.name] for r in ctx.train], [r.euler for r in ctx.train],
                       [ctx.clean[r.name] for r in ctx.train] if self.clean_targets else None)

    def network_jobs(self, ctx: Context) -> list[NetworkJob]:
        model, args = self._model(ctx)
        return model.network_jobs(*args)

    def fit(self, ctx: Context) -> Danae:
        self.model, args = self._model(ctx)
        self.model.fit(*args)
        self.results = self.model.results_
        cfg = ctx.train_config
        self.params = {"arch": cfg.arch, "window": cfg.window, "lr": cfg.lr, "batch_size": cfg.batch_size,
                       "epochs": cfg.epochs, "max_steps": cfg.max_steps, "seeds": list(ctx.seeds),
                       "targets": self.targets, "clean_targets": self.clean_targets,
                       "val_stride": self.model.config.val_stride}
        self.seconds_training = self.model.seconds_
        return self

    def predict(self, rec: Recording) -> list[Array]:
        return self.model.predict(self.kf.raw(rec), stride=self.stride)


def make_method(name: str) -> Method:
    """A fresh, unfitted method of this module by leaderboard name: one of :data:`METHODS`
    (a library filter for the names of :data:`danae_lite.research.ahrs.filters.FILTERS`).
    :func:`danae_lite.research.registry.make_method` builds the ``danae-res[<filter>]`` names too."""
    simple = {"constant": Constant, "paper_kf": PaperKF, "tuned_kf": TunedKF, "tuned_kf_rts": TunedKFSmoother,
              "butterworth": Butterworth, "moving_average": MovingAverage, "linear_map": LinearMap, "danae": Danae}
    if name in simple:
        return simple[name]()
    if name in filters.FILTERS:
        return LibraryFilter(name)
    if denoiser_source(name) is not None:
        raise ValueError(f"{name!r} is the denoiser of danae_lite.research.danae_res: build it with "
                         "danae_lite.research.registry.make_method")
    raise ValueError(f"unknown method {name!r}; choose from {', '.join(METHODS)} or danae-res[<filter>]")


DENOISER_FAMILIES: tuple[str, ...] = ("danae-res", "danae-safe")
"""Learned correctors a leaderboard name can put behind a filter, ``<family>[<filter>]``:
DANAE-res (:class:`danae_lite.research.danae_res.DanaeRes`) and DANAE-res with a per-sample
fallback and an error bar (:class:`danae_lite.research.danae_safe.DanaeSafe`)."""


def denoiser_name(name: str) -> tuple[str, str] | None:
    """``"danae-res[vqf]"`` -> ``("danae-res", "vqf")`` when the family is one of
    :data:`DENOISER_FAMILIES` and the bracket holds a filter of :data:`METHODS`, else None."""
    for family in DENOISER_FAMILIES:
        if name.startswith(f"{family}[") and name.endswith("]"):
            source = name[len(family) + 1:-1]
            if source in METHODS and not source.startswith("danae"):
                return family, source
    return None


def denoiser_source(name: str) -> str | None:
    """``"danae-res[vqf]"`` (or ``"danae-safe[vqf]"``) -> ``"vqf"``, see :func:`denoiser_name`; else None."""
    found = denoiser_name(name)
    return None if found is None else found[1]


def is_method_name(name: str) -> bool:
    """Whether :func:`danae_lite.research.registry.make_method` knows ``name``: one of :data:`METHODS`,
    ``danae-res[<filter>]`` or ``danae-safe[<filter>]`` (:func:`denoiser_name`)."""
    return name in METHODS or denoiser_source(name) is not None
