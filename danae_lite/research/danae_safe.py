"""DANAE-res that knows when it does not know: a per-sample fallback and a calibrated error bar.

DANAE-res (:mod:`danae_lite.research.danae_res`) fixes one gain per angle at training time. Here
each sample gets its own, from two signals available on-line (no ground truth):

* ``m``: the root mean square of the network's own correction over the last second [rad]
  (per angle; a correction much larger than usual is a claim to be checked);
* ``n``: the root mean square of the standardised input channels over the last second
  [dimensionless; about 1 on data like the training recordings, larger on unfamiliar motion].

Both are exponential moving averages with a time constant of :data:`SMOOTH_S` seconds, so they
are causal and cost a few operations per sample. A linear model of the log squared error of the
fully corrected output, ``log (e - c)^2 ~ b0 + b1 log m + b2 log n``, turns them into a *risk*
``sigma_A`` per sample and angle [rad]. The samples are cut into :data:`RISK_BINS` risk bins
(quantiles of ``sigma_A``); in each bin the correction is kept only where it lowered the error.

**Calibrated out of fold, on training recordings only.** DANAE-res's gate already trains, per
inner fold of the training recordings, a network that has not seen that fold's recordings
(``DanaeRes.gate_results``). On those recordings it plays the part the prediction network
plays on a new recording; every fit below uses those samples only (with a single training
recording: the validation tail of the prediction network, as the gate does). The disagreement
of the inner networks among themselves is *not* used: on a training recording all of them but
one have seen it, so their spread there says nothing about their spread on a new recording.

**Policies** (the ablation): ``"none"`` gain 1; ``"gate"`` DANAE-res's gain per angle;
``"fallback"`` gain 1 where the bin's correction helped, else 0; ``"both"`` (default) the
gate's gain where the bin's gated correction helped, else 0.

**Error bar.** Per bin, the root mean square of the final output's error over ``sigma_A`` scales
the risk; ``k68`` and ``k95``, the 68th and 95th percentiles of the out-of-fold errors in units
of that scaled risk, make the half-widths of the 68 % and 95 % intervals (:meth:`DanaeSafe.predict_bars`;
out of fold they cover 68 % and 95 % by construction; on new recordings that is the claim to test).

Frames and units as DANAE-res: ZYX Euler roll, pitch, yaw [rad] in the ground-truth frame of the
aligned recordings, yaw errors wrapped to [-pi, pi).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from ..data.recording import Recording
from ..danae.train_types import TrainResult
from .danae_res import DanaeRes, DenoiserStream, filter_error, validation_mask
from .features import run_network
from .methods import Context, Method

Array = NDArray[np.float64]

SMOOTH_S = 1.0
"""Time constant [s] of the moving averages behind the risk signals."""
RISK_BINS = 4
"""Risk bins (quantiles of the out-of-fold risk) in which the fallback decides."""
POLICIES: tuple[str, ...] = ("both", "fallback", "gate", "none")
"""Gain policies: see the module docstring."""
_FLOOR_M, _FLOOR_N, _FLOOR_E = 1e-5, 1e-3, 1e-12  # log floors [rad], [-], [rad^2]


def ema(x: Array, alpha: float) -> Array:
    """Causal exponential moving average along axis 0, ``y[t] = y[t-1] + alpha (x[t] - y[t-1])``,
    started at ``y[0] = x[0]`` (:func:`scipy.signal.lfilter`)."""
    x = np.asarray(x, dtype=float)
    zi = (1.0 - alpha) * x[:1]
    return lfilter([alpha], [1.0, alpha - 1.0], x, axis=0, zi=zi)[0]


def alpha_of(fs_hz: float, smooth_s: float = SMOOTH_S) -> float:
    """Moving-average weight of one sample at ``fs_hz`` [Hz] for a time constant ``smooth_s`` [s]."""
    return float(min(1.0, 1.0 / (fs_hz * smooth_s)))


def risk_design(corr: Array, x: Array, net: TrainResult, alpha: float) -> Array:
    """(N, 3, 3) regressors per sample and angle: ``1, log m, log n`` (see the module docstring)
    from the correction ``corr`` (N, 3) [rad] of network ``net`` and its raw inputs ``x`` (N, C)."""
    norm = net.model.normalization()
    z = (np.asarray(x, dtype=float) - np.asarray(norm["in_mean"])) / np.asarray(norm["in_std"])
    m = np.sqrt(ema(np.asarray(corr, dtype=float) ** 2, alpha))
    n = np.sqrt(ema(np.mean(z * z, axis=1), alpha))
    d = np.empty((len(m), 3, 3))
    d[:, :, 0] = 1.0
    d[:, :, 1] = np.log(m + _FLOOR_M)
    d[:, :, 2] = np.log(n + _FLOOR_N)[:, None]
    return d


@dataclass
class AngleCalibration:
    """What the fit chose for one angle, from out-of-fold samples of the training recordings."""

    coef: Array
    """(3,) risk model: ``log sigma_A^2 = coef @ (1, log m, log n)``."""
    edges: Array
    """(RISK_BINS - 1,) inner edges of the risk bins [rad]."""
    keep: dict[str, Array]
    """Per policy, (RISK_BINS,) True where the correction is kept in that bin."""
    scale: Array
    """(RISK_BINS,) RMS of the final error over ``sigma_A`` per bin (the policy of the method)."""
    k68: float
    k95: float
    samples: int


def _bins(sigma: Array, edges: Array) -> NDArray[np.intp]:
    return np.searchsorted(edges, sigma, side="right")


def calibrate_angle(design: Array, err: Array, corr: Array, gain: float, policy: str,
                    bins: int = RISK_BINS) -> AngleCalibration:
    """Fit one angle on out-of-fold samples: ``design`` (N, 3) regressors, ``err`` (N,) the
    filter's error [rad], ``corr`` (N,) the network's correction [rad], ``gain`` the gate's."""
    r_full = err - corr
    coef = np.linalg.lstsq(design, np.log(r_full ** 2 + _FLOOR_E), rcond=None)[0]
    sigma = np.exp(0.5 * design @ coef)
    edges = np.quantile(sigma, np.arange(1, bins) / bins)
    b = _bins(sigma, edges)
    keep = {}
    for p, g in (("fallback", 1.0), ("both", gain), ("gate", gain), ("none", 1.0)):
        helped = np.array([np.mean((err[b == k] - g * corr[b == k]) ** 2) < np.mean(err[b == k] ** 2)
                           if np.any(b == k) else False for k in range(bins)])
        keep[p] = helped if p in ("fallback", "both") else np.ones(bins, dtype=bool)
    g_final = _gains(policy, gain, keep[policy][b])
    u = (err - g_final * corr) / sigma
    scale = np.array([np.sqrt(np.mean(u[b == k] ** 2)) if np.any(b == k) else 1.0 for k in range(bins)])
    scale = np.where(scale > 0, scale, 1.0)
    z = np.abs(u / scale[b])
    return AngleCalibration(coef, edges, keep, scale, float(np.quantile(z, 0.68)),
                            float(np.quantile(z, 0.95)), int(len(err)))


def _gains(policy: str, gate_gain: float, kept: Array) -> Array:
    base = gate_gain if policy in ("gate", "both") else 1.0
    return base * np.asarray(kept, dtype=float)


class DanaeSafe(Method):
    """DANAE-res with a per-sample fallback and an error bar (see the module docstring).

    Parameters
    ----------
    source : the filter DANAE-res corrects (a leaderboard name: "vqf", "fusion", ...).
    policy : one of :data:`POLICIES` (default ``"both"``).
    smooth_s : time constant of the risk signals [s].
    name : leaderboard name; default ``"danae-safe[<source>]"`` (``"danae-safe-<policy>[<source>]"``
        for another policy).

    Attributes (after ``fit``)
    --------------------------
    res : the fitted DanaeRes it builds on (``ctx.method("danae-res[<source>]")``, so fitted once
        per context and shared with a ``danae-res`` row and the other policies).
    calibration_ : angle name -> :class:`AngleCalibration` (angles the source estimates).
    params : the settings and what the fit chose, as plain numbers.
    """

    def __init__(self, source: str = "vqf", *, policy: str = "both", smooth_s: float = SMOOTH_S,
                 name: str | None = None) -> None:
        super().__init__()
        if policy not in POLICIES:
            raise ValueError(f"policy={policy!r}: choose one of {POLICIES}")
        if not smooth_s > 0:
            raise ValueError(f"smooth_s must be > 0 s, got {smooth_s!r}")
        self.source, self.policy, self.smooth_s = source, policy, float(smooth_s)
        tag = "" if policy == "both" else f"-{policy}"
        self.name = name or f"danae-safe{tag}[{source}]"
        self.causal = DanaeRes(source).causal
        self.description = (f"DANAE-res on {source} with a per-sample fallback ({policy}) and a "
                            "calibrated error bar")

    def fit(self, ctx: Context) -> DanaeSafe:
        """Fit (or find) DanaeRes on ``ctx`` and calibrate on its out-of-fold samples."""
        self.ctx = ctx
        self.res: DanaeRes = ctx.method(f"danae-res[{self.source}]")  # type: ignore[assignment]
        first = int(ctx.seeds[0])
        parts = []
        for net, rec, where in self._oof_pairs():
            est, corr, design = self._signals(net, rec)
            err = filter_error(np.where(self.res.missing, 0.0, est), rec.euler)
            parts.append((err, corr, design, where & ctx.clean[rec.name]))
        gains = self.res.gains[first]
        self.calibration_: dict[str, AngleCalibration] = {}
        for k, a in enumerate(("roll", "pitch", "yaw")):
            if self.res.missing[k]:
                continue
            d = np.concatenate([p[2][p[3], k] for p in parts])
            err = np.concatenate([p[0][p[3], k] for p in parts])
            corr = np.concatenate([p[1][p[3], k] for p in parts])
            self.calibration_[a] = calibrate_angle(d, err, corr, float(gains[k]), self.policy)
        self.params = {"source": self.source, "policy": self.policy, "smooth_s": self.smooth_s,
                       "bins": RISK_BINS, "oof_data": self.res.gate_data,
                       "gate_gains": gains.tolist(),
                       "calibration": {a: {"coef": c.coef.tolist(), "edges_rad": c.edges.tolist(),
                                           "keep": c.keep[self.policy].tolist(), "scale": c.scale.tolist(),
                                           "k68": c.k68, "k95": c.k95, "samples": c.samples}
                                       for a, c in self.calibration_.items()},
                       "danae_res": self.res.params}
        return self

    def _oof_pairs(self) -> list[tuple[TrainResult, Recording, NDArray[np.bool_]]]:
        """(network, training recording, samples it has not trained on): each inner fold's
        recordings with that fold's gate network, or the prediction network's validation tails."""
        res, first = self.res, int(self.ctx.seeds[0])
        by_name = {r.name: r for r in self.ctx.train}
        folds = res.params["gate_folds"]
        if folds:
            return [(res.gate_results[(k, first)], by_name[n], np.ones(len(by_name[n]), dtype=bool))
                    for k, held in enumerate(folds) for n in held]
        cfg = res.config(first)
        return [(res.results[first], r, validation_mask(len(r), cfg)) for r in self.ctx.train]

    def _signals(self, net: TrainResult, rec: Recording) -> tuple[Array, Array, Array]:
        """The filter's estimate [rad], the network's correction [rad] and the risk regressors
        (:func:`risk_design`), per sample; no ground truth needed."""
        est = self.res.base.predict(rec)[0]
        x = self.res.features(rec, est)
        corr = run_network(net, x)
        return est, corr, risk_design(corr, x, net, alpha_of(rec.fs, self.smooth_s))

    def _gain_and_bars(self, design: Array) -> tuple[Array, Array, Array]:
        """Per sample and angle: the gain, the 68 % and the 95 % half-widths [rad] (NaN for an
        angle the source does not estimate)."""
        n = len(design)
        g, sd, hw = np.zeros((n, 3)), np.full((n, 3), np.nan), np.full((n, 3), np.nan)
        gains = self.res.gains[int(self.ctx.seeds[0])]
        for k, a in enumerate(("roll", "pitch", "yaw")):
            c = self.calibration_.get(a)
            if c is None:
                continue
            sigma = np.exp(0.5 * design[:, k] @ c.coef)
            b = _bins(sigma, c.edges)
            g[:, k] = _gains(self.policy, float(gains[k]), c.keep[self.policy][b])
            sd[:, k] = c.k68 * c.scale[b] * sigma
            hw[:, k] = c.k95 * c.scale[b] * sigma
        return g, sd, hw

    def predict_bars(self, rec: Recording) -> list[tuple[Array, Array, Array]]:
        """Per seed: the output (N, 3) [rad], the half-width of its 68 % interval (its standard
        deviation, N x 3 [rad]) and of its 95 % interval [rad]."""
        out = []
        for seed in map(int, self.ctx.seeds):
            net = self.res.results[seed]
            est, corr, design = self._signals(net, rec)
            g, sd, hw = self._gain_and_bars(design)
            out.append((self.res._output(est, corr, g), sd, hw))
        return out

    def predict(self, rec: Recording) -> list[Array]:
        return [o for o, _, _ in self.predict_bars(rec)]


class SafeStream:
    """:class:`DanaeSafe` one sample at a time (causal DanaeRes only): ``step(features, est)``
    returns the output (3,) [rad] and the 68 % and 95 % half-widths (3,) [rad], equal to
    :meth:`DanaeSafe.predict_bars` sample by sample."""

    def __init__(self, method: DanaeSafe, seed: int | None = None) -> None:
        seed = int(method.ctx.seeds[0] if seed is None else seed)
        self.method, self.inner = method, DenoiserStream(method.res, seed)
        norm = method.res.results[seed].model.normalization()
        self.mean, self.std = np.asarray(norm["in_mean"]), np.asarray(norm["in_std"])
        self.reset()

    def reset(self) -> None:
        """Forget the history (a new recording)."""
        self.inner.reset()
        self.m2: Array | None = None
        self.n2 = 0.0

    def step(self, features: Array, est: Array, fs_hz: float) -> tuple[Array, Array, Array]:
        """Output, 68 % and 95 % half-widths of one sample [rad] (``fs_hz``: the sample rate)."""
        f = np.asarray(features, dtype=float)
        corr = np.asarray(self.inner.net.step(f), dtype=float).reshape(3)
        z2 = float(np.mean(((f - self.mean) / self.std) ** 2))
        alpha = alpha_of(fs_hz, self.method.smooth_s)
        if self.m2 is None:
            self.m2, self.n2 = corr ** 2, z2
        else:
            self.m2 = self.m2 + alpha * (corr ** 2 - self.m2)
            self.n2 = self.n2 + alpha * (z2 - self.n2)
        d = np.empty((1, 3, 3))
        d[0, :, 0] = 1.0
        d[0, :, 1] = np.log(np.sqrt(self.m2) + _FLOOR_M)
        d[0, :, 2] = np.log(np.sqrt(self.n2) + _FLOOR_N)
        g, sd, hw = self.method._gain_and_bars(d)
        out = self.method.res._output(np.asarray(est, dtype=float).reshape(1, 3), corr.reshape(1, 3), g)
        return out[0], sd[0], hw[0]
