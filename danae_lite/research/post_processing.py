"""Post-processing of the paper KF's output, three methods of the leaderboard
(:mod:`danae_lite.research.baselines`): a zero-phase Butterworth low-pass (``butterworth``), a centred
moving average (``moving_average``), each with its setting chosen per angle on the training
recordings, and an affine least-squares map of 20-sample windows (``linear_map``). Each works on
the KF's angle unwrapped along the recording (continuous, in the ground truth's frame) and uses
samples after ``t`` for its output at ``t``: none is causal. :class:`OnPaperKF` is what they share
with the paper's DANAE (:class:`danae_lite.research.baselines.Danae`)."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy import signal
from scipy.ndimage import uniform_filter1d

from . import methods
from ..angles import ANGLES, wrap
from ..danae.windows import sliding_windows, stitch_overlap_average
from ..data.recording import Recording
from ..paper.danae import continuous_target
from .methods import Method, train_objective

__all__ = ["BUTTER_CUTOFFS_HZ", "BUTTER_ORDER", "LINEAR_WINDOW", "MA_LENGTHS", "Butterworth", "LinearMap",
           "MovingAverage", "OnPaperKF", "apply_linear_map", "butterworth_lowpass", "fit_linear_map",
           "moving_average"]

Array = NDArray[np.float64]

BUTTER_ORDER = 2
"""Order of the Butterworth low-pass."""
BUTTER_CUTOFFS_HZ = (0.02, 0.05, 0.1, 0.25, 0.5, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0)
"""Grid of cut-off frequencies [Hz]; values at or above 0.8 x Nyquist are skipped."""
MA_LENGTHS = (3, 5, 9, 15, 25, 41, 61, 101, 201, 401, 801)
"""Grid of moving-average lengths [samples] (odd, so the average is centred)."""
LINEAR_WINDOW = 20
"""Window of the linear map [samples], DANAE's."""


def butterworth_lowpass(x: Array, cutoff_hz: float, fs: float, order: int = BUTTER_ORDER) -> Array:
    """Zero-phase digital Butterworth low-pass along axis 0 (``butter(..., fs=fs, output="sos")``
    + ``sosfiltfilt``). ``cutoff_hz`` [Hz] must be below the Nyquist frequency ``fs / 2``."""
    if not 0.0 < cutoff_hz < fs / 2.0:
        raise ValueError(f"cut-off {cutoff_hz} Hz must be in (0, {fs / 2.0}) Hz (Nyquist at fs = {fs} Hz)")
    sos = signal.butter(order, cutoff_hz, btype="low", fs=fs, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0)


def moving_average(x: Array, length: int) -> Array:
    """Centred moving average of odd ``length`` [samples] along axis 0, edges repeating the end samples."""
    if length < 1 or length % 2 == 0:
        raise ValueError(f"moving-average length must be a positive odd number of samples, got {length}")
    return uniform_filter1d(np.asarray(x, dtype=float), length, axis=0, mode="nearest")


class OnPaperKF(Method):
    """Post-processing of the paper KF's output (continuous angles, truth frame); every one of
    them uses samples after ``t`` for its output at ``t``."""

    def fit(self, ctx: methods.Context) -> "OnPaperKF":
        self.ctx = ctx
        self.kf = ctx.method("paper_kf")
        self.kf_train = {r.name: self.kf.raw(r) for r in ctx.train}
        return self


class _Smoother(OnPaperKF):
    grid_name = ""

    def grid(self, fs: float) -> list[Any]:
        raise NotImplementedError

    def apply(self, x: Array, value: Any, fs: float) -> Array:
        raise NotImplementedError

    def fit(self, ctx: methods.Context) -> "_Smoother":
        super().fit(ctx)
        fs = ctx.train[0].fs
        rows = []
        for v in self.grid(fs):
            est = {name: self.apply(x, v, fs) for name, x in self.kf_train.items()}
            obj = train_objective(est, ctx, (0, 1, 2))
            rows.append({self.grid_name: v, **{f"rmse_{a}": float(o) for a, o in zip(ANGLES, obj)}})
        self.search = pd.DataFrame(rows)
        self.params = {a: float(self.search.loc[self.search[f"rmse_{a}"].idxmin(), self.grid_name]) for a in ANGLES}
        return self

    def predict(self, rec: Recording) -> list[Array]:
        x = self.kf.raw(rec)
        out = np.column_stack([self.apply(x[:, k], self._value(self.params[a]), rec.fs) for k, a in enumerate(ANGLES)])
        out[:, 2] = wrap(out[:, 2])
        return [out]

    def _value(self, v: float) -> Any:
        return v


class Butterworth(_Smoother):
    name = "butterworth"
    description = f"paper KF + digital Butterworth low-pass, order {BUTTER_ORDER}, zero phase (sosfiltfilt)"
    grid_name = "cutoff_hz"

    def grid(self, fs: float) -> list[Any]:
        return [c for c in BUTTER_CUTOFFS_HZ if c < 0.8 * fs / 2.0]

    def apply(self, x: Array, value: Any, fs: float) -> Array:
        return butterworth_lowpass(x, float(value), fs)


class MovingAverage(_Smoother):
    name = "moving_average"
    description = "paper KF + centred moving average"
    grid_name = "length"

    def grid(self, fs: float) -> list[Any]:
        return list(MA_LENGTHS)

    def apply(self, x: Array, value: Any, fs: float) -> Array:
        return moving_average(x, int(value))

    def _value(self, v: float) -> Any:
        return int(v)


def fit_linear_map(inputs: Sequence[Array], targets: Sequence[Array], window: int = LINEAR_WINDOW,
                   masks: Sequence[NDArray[np.bool_]] | None = None) -> Array:
    """Least-squares affine map from input windows to target windows.

    Returns ``W`` of shape (window + 1, window): ``y_window ≈ [x_window, 1] @ W``. Windows
    (stride 1, never across recordings) holding a masked-out target sample are left out."""
    xs, ys = [], []
    for i, (x, y) in enumerate(zip(inputs, targets)):
        wx, wy = sliding_windows(np.asarray(x, dtype=float), window), sliding_windows(np.asarray(y, dtype=float), window)
        if masks is not None:
            ok = sliding_windows(np.asarray(masks[i], dtype=bool), window).all(axis=1)
            wx, wy = wx[ok], wy[ok]
        xs.append(wx)
        ys.append(wy)
    X, Y = np.concatenate(xs), np.concatenate(ys)
    if len(X) <= window:
        raise ValueError(f"{len(X)} usable windows: too few to fit a {window + 1} x {window} affine map")
    A = np.hstack([X, np.ones((len(X), 1))])
    W, *_ = np.linalg.lstsq(A, Y, rcond=None)
    return W


def apply_linear_map(W: Array, x: Array) -> Array:
    """Apply :func:`fit_linear_map`'s ``W`` to every stride-1 window of ``x`` (N,) and average the
    overlapping window outputs back to (N,)."""
    window = W.shape[1]
    wx = sliding_windows(np.asarray(x, dtype=float), window)
    pred = np.hstack([wx, np.ones((len(wx), 1))]) @ W
    return stitch_overlap_average(pred[:, :, None], len(x))[:, 0]


class LinearMap(OnPaperKF):
    name = "linear_map"
    description = f"paper KF + affine least-squares map of {LINEAR_WINDOW}-sample windows (overlap average)"

    def fit(self, ctx: methods.Context) -> "LinearMap":
        super().fit(ctx)
        self.W = {}
        for k, a in enumerate(ANGLES):
            xs = [self.kf_train[r.name][:, k] for r in ctx.train]
            ys = [continuous_target(self.kf_train[r.name][:, k], r.euler[:, k]) for r in ctx.train]
            self.W[a] = fit_linear_map(xs, ys, masks=[ctx.clean[r.name] for r in ctx.train])
        self.params = {"window": LINEAR_WINDOW, "coefficients": (LINEAR_WINDOW + 1) * LINEAR_WINDOW}
        return self

    def predict(self, rec: Recording) -> list[Array]:
        x = self.kf.raw(rec)
        out = np.column_stack([apply_linear_map(self.W[a], x[:, k]) for k, a in enumerate(ANGLES)])
        out[:, 2] = wrap(out[:, 2])
        return [out]
