"""What the learned methods beyond the paper share: their input channels and their causal network.

* :func:`to_circle` / :func:`from_circle`: angles with yaw as (sin, cos), so that no input or
  target jumps by 2π (:data:`ANGLE_CHANNELS`).
* :func:`multi_input`: the 11 channels of :data:`MULTI_CHANNELS` (a filter's angles, the
  accelerometer's tilt, the tilt-compensated magnetic heading, the Euler rates of the gyro).
* :data:`CAUSAL_SETTINGS`: the causal network of chapter 7 (the DANAE variant
  :func:`danae_lite.research.variants.causal_variant` and DANAE-res, :mod:`danae_lite.research.danae_res`).
* :data:`RES_SETTINGS`: DANAE-res's network, the causal one on 128-sample windows.
* :func:`research_config` and :data:`RESEARCH_SCORED_SAMPLES`: how the networks of chapters 7
  to 9 are validated, and DANAE-res's training budget.
* :func:`run_network`: a trained network over a whole recording, causal or not.

Used by :mod:`danae_lite.research.variants` and :mod:`danae_lite.research.danae_res`.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..kalman.model import accel_tilt, euler_rates, mag_heading
from ..data.recording import Recording
from .memo import RunMemo, digest
from .methods import PREDICT_STRIDE
from .streaming import predict_causal
from ..danae.predict import predict
from ..danae.train_types import TrainConfig, TrainResult

Array = NDArray[np.float64]

ANGLE_CHANNELS: tuple[str, ...] = ("roll", "pitch", "sin yaw", "cos yaw")
"""Channels of :func:`to_circle` (and of every variant's target)."""
MULTI_CHANNELS: tuple[str, ...] = (*ANGLE_CHANNELS, "roll acc", "pitch acc", "sin yaw mag", "cos yaw mag",
                                   "roll rate", "pitch rate", "yaw rate")
"""Input channels of the multi-input variant: angles [rad, -], accelerometer tilt [rad],
magnetic heading [-], Euler rates [rad/s]."""
CAUSAL_SETTINGS: dict[str, Any] = {"arch": "causal", "hidden": 64, "window": 64, "loss_start": 30}
"""The causal network (:class:`~danae_lite.danae.model.DanaeCausal`) as
:class:`~danae_lite.danae.train_types.TrainConfig` overrides: 64 channels, dilations 1-8 (receptive field 31
samples), trained on 64-sample windows with the loss on positions 30-63 only, where the full
past is inside the window."""

RES_SETTINGS: dict[str, Any] = {**CAUSAL_SETTINGS, "window": 128}
"""DANAE-res's network (:mod:`danae_lite.research.danae_res`): the causal network on 128-sample
windows, the loss on positions 30-127. The first 30 positions of a window are context only;
on 64-sample windows they were 47 % of the work and on 128-sample windows 23 %. Chosen on the
validation tails of 96 networks' training recordings (no test recording): the lowest
validation loss of the same scored-sample budget moved by a factor of 0.989 in the median
(0.996 on average) for half the training time."""

RESEARCH_SCORED_SAMPLES: int = 816_000
"""Scored window samples (batch x (window - loss_start) per step) at most per DANAE-res
network: 520 steps of 16 windows of 128 samples (98 scored). It is the budget of 1,500
steps of 64-sample windows (34 scored), which came from the validation losses of full-epoch
DANAE-res networks (2,000-10,000 steps on this book's data), on the tails of their training
recordings, nothing of a test recording: their lowest loss within the first 1,500 steps was,
in the median, their lowest of the whole epoch (90th percentile 16-21 % higher). The
paper-sized variants of :mod:`danae_lite.research.variants` lose more (a median of 10 %) and
keep the paper's one epoch."""
RESEARCH_CHECKS: int = 5
"""Validation checks of a capped network in a full budget (the last at its last step)."""


def research_steps(cfg: TrainConfig) -> int:
    """Optimiser steps that score :data:`RESEARCH_SCORED_SAMPLES` window samples with the
    batch, window and loss start of ``cfg``."""
    return max(1, round(RESEARCH_SCORED_SAMPLES / (cfg.batch_size * (cfg.window - cfg.loss_start))))


def research_config(base: TrainConfig, seed: int, *, capped: bool, **overrides: Any) -> TrainConfig:
    """Training settings of a research network (chapters 5-9: the variants, DANAE-res and the
    leaderboard's paper DANAE): ``base`` (the context's settings:
    device, fast-mode cap) with ``overrides`` and the seed, validated on windows
    ``window - loss_start`` apart (every validation sample scored once instead of up to
    ``window - loss_start`` times: the same loss, a fraction of the forward passes). With
    ``capped`` (DANAE-res): at most :func:`research_steps` steps (or the smaller cap ``base``
    has) and :data:`RESEARCH_CHECKS` validation checks in a full budget (a check at the end of
    a shorter run)."""
    cfg = replace(base, seed=int(seed), **overrides)
    cfg = replace(cfg, val_stride=cfg.window - cfg.loss_start)
    if not capped:
        return cfg
    budget = research_steps(cfg)
    steps = budget if cfg.max_steps is None else min(cfg.max_steps, budget)
    return replace(cfg, max_steps=steps, val_every=min(math.ceil(budget / RESEARCH_CHECKS), steps))


def to_circle(euler: Array) -> Array:
    """(N, 3) roll, pitch, yaw [rad] -> (N, 4) roll, pitch, sin yaw, cos yaw. NaN yaw -> 0, 0."""
    e = np.asarray(euler, dtype=float)
    sc = np.nan_to_num(np.column_stack([np.sin(e[:, 2]), np.cos(e[:, 2])]), nan=0.0)
    return np.column_stack([e[:, :2], sc])


def from_circle(x: Array) -> Array:
    """(N, 4) -> (N, 3): yaw = atan2(sin, cos) in (-pi, pi] (the vector need not be unit length)."""
    x = np.asarray(x, dtype=float)
    return np.column_stack([x[:, 0], x[:, 1], np.arctan2(x[:, 2], x[:, 3])])


def multi_input(rec: Recording, est: Array, north_yaw: float) -> Array:
    """The 11 channels of :data:`MULTI_CHANNELS` for an aligned recording and a filter's
    estimate ``est`` (N, 3) [rad] in the ground-truth frame. The heading from the
    magnetometer is tilt-compensated with the estimate's roll and pitch and turned to the
    ground-truth frame with ``north_yaw`` [rad]; the Euler rates use the same roll and pitch."""
    est = np.asarray(est, dtype=float)
    tilt = accel_tilt(rec.acc)
    heading = mag_heading(rec.mag, est[:, 0], est[:, 1]) + north_yaw
    rates = euler_rates(rec.gyro, est[:, 0], est[:, 1])
    return np.column_stack([to_circle(est), tilt, np.sin(heading), np.cos(heading), rates])


memo = RunMemo(1 << 30, code_of=__name__)
"""Network outputs kept by :func:`run_network` (1 GiB)."""


def network_digest(res: TrainResult) -> str:
    """:func:`~danae_lite.research.memo.digest` of a trained network: its settings and every
    parameter and buffer (weights, standardisation): equal digests, equal outputs."""
    state = res.model.state_dict()
    return digest(np.frombuffer(repr(sorted(res.config.to_dict().items())).encode(), dtype=np.uint8),
                  *(state[k].detach().cpu().numpy() for k in sorted(state)))


def run_network(res: TrainResult, x: Array) -> Array:
    """Output (N, D) of the trained network ``res`` on a whole recording's inputs ``x`` (N, C):
    a causal network sample by sample over its past (:func:`~danae_lite.research.streaming.predict_causal`),
    any other one with the average of overlapping windows :data:`~danae_lite.research.methods.PREDICT_STRIDE`
    samples apart (:func:`~danae_lite.danae.predict.predict`).
    The same network on the same inputs earlier in this process: the stored output (:data:`memo`)."""
    key = (network_digest(res), digest(np.asarray(x, dtype=float)), PREDICT_STRIDE)
    found = memo.get(key)
    if found is None:
        found = predict_causal(res, x) if res.config.arch == "causal" else predict(res, x, stride=PREDICT_STRIDE)
        memo.put(key, found)
    return found
