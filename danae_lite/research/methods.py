"""The interface every leaderboard method implements, and the objectives their grid searches minimise.

A :class:`Method` is fitted on a :class:`Context` (the aligned training recordings, their clean
ground-truth masks and the run's settings; nothing of the test recordings) and then predicts
roll, pitch, yaw [rad] in the ground truth's frame for any recording, one (N, 3) array per
training seed. A method built on another one (a smoother on a KF, a learned correction on a
filter) asks the context for it by name (:meth:`Context.method`), so that each is fitted, and
grid-searched, once per context.

The classical methods are in :mod:`danae_lite.research.baselines`, the learned ones in
:mod:`danae_lite.research.variants` and :mod:`danae_lite.research.danae_res`; :mod:`danae_lite.research.registry` turns a
leaderboard name into a method.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ..data.alignment import FrameAlignment
from ..angles import euler_error_angle
from ..evaluate.metrics import errors, rmse
from ..danae.networks import NetworkJob
from ..data.recording import Recording
from ..danae.train_types import TrainConfig

Array = NDArray[np.float64]

PREDICT_STRIDE = 4
"""Stride [samples] of the overlapping windows with which the learned methods of this package
predict (non-causal networks: :func:`danae_lite.danae.predict.predict`); each interior sample
is then the mean of ``ceil(L / 4)`` window predictions (5 for the paper's 20-sample window)
instead of ``L``, for a quarter of the work. Chosen on the validation tails of the training
recordings (chapter 5's nine paper networks), never on a test recording: against stride 1 the
mean validation RMSE changed by +0.01 % (roll), +0.03 % (pitch), +0.06 % (yaw) at stride 4,
and by +0.31 % (yaw) at stride 5. Chapters 3 and 4 keep every window (stride 1), as the
paper's recipe."""


class Method:
    """Base class: ``fit(ctx)`` then ``predict(rec) -> list of (N, 3) [rad]`` (one per seed).

    ``causal`` says whether the output at sample ``t`` depends only on samples up to ``t`` (so
    the method could run on-line as it is); a method that looks ahead (a zero-phase filter, a
    centred window, DANAE's window around the sample) is not causal.

    Attributes
    ----------
    params : the parameters chosen on the training recordings (plain numbers), after ``fit``.
    search : the grid search on the training recordings, one row per candidate with its
        objective [rad]; None for a method without one.
    """

    name = "method"
    description = ""
    causal = False

    def __init__(self) -> None:
        self.params: dict[str, Any] = {}
        self.search: pd.DataFrame | None = None

    def fit(self, ctx: Context) -> Method:
        """Fit on the training recordings of ``ctx``; returns ``self``."""
        self.ctx = ctx
        return self

    def predict(self, rec: Recording) -> list[Array]:
        """Roll, pitch, yaw (N, 3) [rad] of the aligned recording ``rec``, one array per seed."""
        raise NotImplementedError

    def network_jobs(self, ctx: Context) -> list[NetworkJob]:
        """The networks ``fit(ctx)`` trains, as jobs, without training them (none here): a
        caller fitting several methods or splits trains them together first
        (:func:`danae_lite.danae.networks.pretrain`), and each ``fit`` finds its own in the cache."""
        return []


@dataclass
class Context:
    """What every method may use to fit: the aligned training recordings, their clean masks and
    the run's settings. Nothing of the test recordings is in it."""

    train: list[Recording]
    """Training recordings, aligned (:meth:`FrameAlignment.apply`)."""
    clean: dict[str, NDArray[np.bool_]]
    """Clean ground-truth mask per training recording name."""
    alignment: FrameAlignment
    seeds: tuple[int, ...] = (0,)
    """Training seeds of the learned methods."""
    train_config: TrainConfig = field(default_factory=TrainConfig)
    """Training settings of the learned methods (the seed is replaced per network)."""
    cache: str | os.PathLike[str] | None = None
    """Trained-network cache folder (None: no cache), from the entry point."""
    jobs: int = 1
    """Worker processes for the networks (:func:`danae_lite.danae.networks.train_networks`)."""
    progress: bool = False
    fitted: dict[str, Method] = field(default_factory=dict)
    """Methods already fitted on ``train`` by name, so that a method another one builds on
    (e.g. a DANAE variant's source filter) is fitted, and grid-searched, only once."""
    factory: Callable[[str], Method] | None = None
    """Builds an unfitted method from its leaderboard name for :meth:`method`
    (:func:`danae_lite.research.registry.make_method`; :class:`danae_lite.research.baselines.Context` defaults
    to :func:`danae_lite.research.baselines.make_method`)."""

    def __post_init__(self) -> None:
        names = {r.name for r in self.train}
        extra = sorted(set(self.clean) - names)
        if extra:
            raise ValueError(f"the fitting context holds masks of recordings that are not training ones: {extra}")

    def method(self, name: str) -> Method:
        """The leaderboard method ``name`` fitted on this context (fitted once, then reused)."""
        if name not in self.fitted:
            if self.factory is None:
                raise LookupError(f"method {name!r} is not fitted on this context and the context has no factory")
            self.fitted[name] = self.factory(name).fit(self)
        return self.fitted[name]


def train_objective(est: dict[str, Array], ctx: Context, angles: Sequence[int]) -> Array:
    """Clean-sample RMSE [rad] per angle index over all training recordings taken together."""
    errs = [errors(est[r.name][ctx.clean[r.name]][:, angles], r.euler[ctx.clean[r.name]][:, angles])
            for r in ctx.train]
    return np.atleast_1d(rmse(np.concatenate(errs)))


def total_error_rmse(est: dict[str, Array], recs: Sequence[Recording], clean: dict[str, NDArray[np.bool_]]) -> float:
    """RMSE [rad] of the total rotation error on the clean samples of ``recs`` taken together:
    the angle of ``R(est) R(truth)^T`` per sample (``est[name]``: Euler angles (N, 3) [rad] in
    the ground-truth frame). A missing yaw (NaN: a filter without heading) is replaced by the
    true one, so that only the tilt error counts."""
    angles = []
    for r in recs:
        ok = clean[r.name]
        e = np.array(est[r.name][ok], dtype=float)
        missing = np.isnan(e[:, 2])
        e[missing, 2] = r.euler[ok][missing, 2]
        angles.append(euler_error_angle(e, r.quat[ok]))
    a = np.concatenate(angles)
    return float(np.sqrt(np.mean(a * a)))


def total_objective(est: dict[str, Array], ctx: Context) -> float:
    """:func:`total_error_rmse` over the training recordings of ``ctx``: the objective of every
    whole-filter grid search."""
    return total_error_rmse(est, ctx.train, ctx.clean)
