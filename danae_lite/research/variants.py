"""DANAE beyond the paper: on any filter's output, with more input channels, yaw on the circle, causal.

Every variant is a :class:`~danae_lite.research.methods.Method`, so the leaderboard fits and
evaluates it exactly like the baselines (``run_leaderboard(..., extra=[...])``).

* **Filter agnostic.** ``DanaeOn(source="vqf")`` trains on the output of any leaderboard
  filter instead of the paper's KF.
* **Yaw on the circle.** Targets (and angle inputs) are ``(roll, pitch, sin yaw, cos yaw)``;
  yaw comes back as ``atan2(sin, cos)``. A prediction never pays for the 2π jump, and one
  network predicts all three angles jointly.
* **Multi-input** (``inputs="multi"``, as the authors' follow-up DANAE++): the filter's
  angles plus the accelerometer's roll and pitch, the tilt-compensated magnetic heading (as
  sin/cos) and the Euler rates from the gyro — 11 channels, standardised per channel with the
  training recordings' mean and std (``TrainConfig(normalize="standard")``).
* **Causal** (``arch="causal"``, :data:`~danae_lite.research.features.CAUSAL_SETTINGS`): the network
  of :class:`~danae_lite.danae.model.DanaeCausal`; each output sample depends only on present and
  past inputs, so it runs on-line (:class:`~danae_lite.research.streaming.StreamingDanae`). The
  features above are per-sample, so causality is kept end to end when the source filter is
  causal.

The input channels, the causal settings and the network runner are shared with DANAE-res
(:mod:`danae_lite.research.danae_res`) in :mod:`danae_lite.research.features`.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .baselines import make_method
from ..data.experiments import Experiment
from .features import (ANGLE_CHANNELS, CAUSAL_SETTINGS, MULTI_CHANNELS, from_circle,
                       multi_input, research_config, run_network, to_circle)
from .leaderboard import run_leaderboard
from .methods import Context, Method, total_error_rmse
from ..evaluate.comparison import compare
from ..evaluate.metrics import reduction_pct
from ..danae.networks import NetworkJob, network_jobs, train_networks
from ..data.recording import Recording
from ..danae.train import validation_tail
from ..danae.train_types import TrainConfig

Array = NDArray[np.float64]


class DanaeOn(Method):
    """A DANAE variant trained on the output of leaderboard method ``source`` (see the module docstring).

    Parameters
    ----------
    source : leaderboard method whose output is denoised ("paper_kf", "tuned_kf", "vqf", ...).
    inputs : ``"angles"`` (the 4 circle channels) or ``"multi"`` (:data:`~danae_lite.research.features.MULTI_CHANNELS`).
    name : leaderboard name; default ``"danae[<source>]"`` / ``"danae-multi[<source>]"``
        (``-causal`` appended for the causal architecture).
    **train_overrides : fields of :class:`~danae_lite.danae.train_types.TrainConfig` replacing the
        context's settings (e.g. ``arch="causal", window=64, loss_start=30``).
    """

    def __init__(self, source: str = "paper_kf", inputs: str = "angles", name: str | None = None,
                 **train_overrides: Any) -> None:
        super().__init__()
        if inputs not in ("angles", "multi"):
            raise ValueError(f"inputs={inputs!r}: choose 'angles' or 'multi'")
        self.source, self.inputs, self.overrides = source, inputs, train_overrides
        causal = "-causal" if train_overrides.get("arch") == "causal" else ""
        self.name = name or f"danae{'-multi' if inputs == 'multi' else ''}{causal}[{source}]"
        self.causal = bool(causal) and make_method(source).causal  # a causal net on a causal filter
        self.description = (f"DANAE on {source}'s output, {len(self._channels())} input channels, "
                            f"roll/pitch/yaw jointly with yaw as (sin, cos)")

    def _channels(self) -> tuple[str, ...]:
        return MULTI_CHANNELS if self.inputs == "multi" else ANGLE_CHANNELS

    def features(self, rec: Recording) -> Array:
        """Input channels (N, C) of the aligned recording ``rec``: the source's angles on the circle
        (``inputs="angles"``) or the multi-input channels [rad, rad/s]."""
        (est,) = self.base.predict(rec)[:1]
        if self.inputs == "multi":
            return multi_input(rec, est, self.ctx.alignment.north_yaw)
        return to_circle(est)

    def config(self, seed: int) -> TrainConfig:
        """Training settings of the network of ``seed``: the context's (one epoch, as the
        paper), standardised data and the overrides, validated on tiling windows
        (:func:`~danae_lite.research.features.research_config`)."""
        return research_config(self.ctx.train_config, seed, capped=False, normalize="standard", **self.overrides)

    def _training(self, ctx: Context) -> dict[str, Any]:
        """The arguments of :func:`~danae_lite.danae.networks.train_networks` for ``ctx``
        (sets :attr:`ctx` and :attr:`base`, the fitted source)."""
        if self.source == "danae":
            raise ValueError("a DANAE variant cannot take DANAE's own output as its source")
        self.ctx = ctx
        self.base = ctx.method(self.source)
        return {"inputs": {"joint": [self.features(r) for r in ctx.train]},
                "targets": {"joint": [to_circle(r.euler) for r in ctx.train]},
                "config": self.config(ctx.seeds[0]), "seeds": ctx.seeds,
                "masks": [ctx.clean[r.name] for r in ctx.train], "tag": "variant",
                "metadata": {"variant": self.name, "train": [r.name for r in ctx.train]}}

    def network_jobs(self, ctx: Context) -> list[NetworkJob]:
        return network_jobs(**self._training(ctx))[1]

    def fit(self, ctx: Context) -> DanaeOn:
        nets = train_networks(**self._training(ctx), cache=ctx.cache, jobs=ctx.jobs, progress=ctx.progress)
        self.results = {seed: res for (_, seed), res in nets.items()}
        cfg = self.config(ctx.seeds[0])
        self.params = {"source": self.source, "inputs": list(self._channels()), "arch": cfg.arch,
                       "window": cfg.window, "loss_start": cfg.loss_start, "seeds": list(ctx.seeds),
                       "source_params": self.base.params}
        return self

    def predict(self, rec: Recording) -> list[Array]:
        x = self.features(rec)
        out = []
        for seed in self.ctx.seeds:
            out.append(from_circle(run_network(self.results[int(seed)], x)))
        return out


def validation_block(n: int, config: TrainConfig) -> slice:
    """The tail of an ``n``-sample training recording that training held out for validation
    (``max(window, round(val_fraction n))`` samples, as :func:`danae_lite.danae.train.train` splits)."""
    n_val = validation_tail(n, config.window, config.val_fraction)
    return slice(n - n_val, n)


class Selected(Method):
    """The learned variant chosen on validation data: of ``candidates`` (unfitted
    :class:`DanaeOn` objects), the one with the lowest total rotation error RMSE
    (:func:`danae_lite.research.methods.total_error_rmse`) on the clean validation blocks of the
    training recordings (:func:`validation_block`: samples none of the networks trained on),
    scored with each candidate's first-seed network. Nothing of the test recordings takes
    part; ``params`` records every candidate's score and the choice.
    """

    def __init__(self, candidates: list[DanaeOn], name: str = "danae-selected") -> None:
        super().__init__()
        if not candidates:
            raise ValueError("Selected needs at least one candidate")
        self.candidates, self.name = candidates, name
        self.causal = all(c.causal for c in candidates)
        self.description = "the DANAE variant with the lowest validation error among " + ", ".join(
            c.name for c in candidates)

    def fit(self, ctx: Context) -> Selected:
        self.ctx = ctx
        scores = {}
        for c in self.candidates:
            c.fit(ctx)
            est, clean = {}, {}
            for r in ctx.train:
                block = validation_block(len(r), c.config(ctx.seeds[0]))
                mask = np.zeros(len(r), dtype=bool)
                mask[block] = ctx.clean[r.name][block]
                est[r.name] = c.predict(r)[0]  # the first seed's network
                clean[r.name] = mask
            scores[c.name] = total_error_rmse(est, ctx.train, clean)
        self.chosen = min(self.candidates, key=lambda c: scores[c.name])
        self.params = {"chosen": self.chosen.name, "validation_total_rmse_rad": scores}
        return self

    def predict(self, rec: Recording) -> list[Array]:
        return self.chosen.predict(rec)


# ---------------------------------------------------------------------------------------
# the experiments of chapter 7, defined once for the book and the scripts
# ---------------------------------------------------------------------------------------
FILTER_SOURCES: tuple[str, ...] = ("paper_kf", "tuned_kf", "fusion", "vqf", "madgwick")
"""Filters whose output DANAE is trained on in the filter-agnostic study."""


def filter_agnostic() -> list[DanaeOn]:
    """One DANAE per filter of :data:`FILTER_SOURCES` (4 angle channels in, 4 out)."""
    return [DanaeOn(s) for s in FILTER_SOURCES]


def multi_input_variants(sources: tuple[str, ...] = ("paper_kf", "vqf")) -> list[DanaeOn]:
    """Multi-input DANAE (:data:`~danae_lite.research.features.MULTI_CHANNELS`) on each source."""
    return [DanaeOn(s, inputs="multi") for s in sources]


def causal_variant(source: str = "vqf") -> DanaeOn:
    """Multi-input causal DANAE on a causal filter (:data:`~danae_lite.research.features.CAUSAL_SETTINGS`): it runs on-line."""
    return DanaeOn(source, inputs="multi", **CAUSAL_SETTINGS)


ABLATIONS: dict[str, dict[str, Any]] = {
    "paper (baseline)": {},
    "no skip sums": {"skip": False},
    "no dilations": {"dilated": False},
    "window 40": {"window": 40},
    "authors' deeper net (big)": {"arch": "big"},
}
"""Ablations of DANAE on the paper KF's output: label -> TrainConfig overrides. (A shorter,
10-sample window would have to drop the dilations too, which need at least 19 samples; it came
out as "no dilations" and is not repeated.)"""


def ablations() -> dict[str, DanaeOn]:
    """label -> the variant (the baseline is ``DanaeOn("paper_kf")`` itself)."""
    out = {}
    for label, kw in ABLATIONS.items():
        suffix = "" if not kw else " " + ",".join(f"{k}={v}" for k, v in kw.items())
        out[label] = DanaeOn("paper_kf", name=f"danae[paper_kf]{suffix}", **kw)
    return out


def generalisation(scenarios: dict[str, Any], *, sources: tuple[str, ...] = ("paper_kf", "vqf"),
                   seeds: tuple[int, ...] = (0,), train_config: TrainConfig | None = None,
                   cache: Any = None, methods: tuple[str, ...] | None = None, jobs: int = 1) -> pd.DataFrame:
    """Train on each scenario's training recordings, test on every scenario's test recordings.

    ``scenarios`` maps a label to an :class:`~danae_lite.data.experiments.Experiment`. For each (train,
    test) pair, the filters in ``sources`` and ``DanaeOn(source)`` are fitted on the training
    side and evaluated on the test side (clean samples). Returns one row per pair, source and
    angle: the filter's RMSE, DANAE's RMSE (mean over seeds) and the gain [%]
    ``100 (1 - danae / filter)``; negative gain = the learned correction hurts;
    ``comparison``: DANAE against its filter over the test recordings as units
    (:func:`~danae_lite.evaluate.comparison.compare`). ``jobs``: worker
    processes for each pair's networks (:func:`~danae_lite.research.leaderboard.run_leaderboard`).
    """
    rows = []
    for a, exp_a in scenarios.items():
        for b, exp_b in scenarios.items():
            exp = Experiment(exp_a.name, exp_a.data, exp_a.train, exp_b.test, f"train {a}, test {b}")
            board = run_leaderboard(exp, methods=methods or sources, seeds=seeds, train_config=train_config,
                                    cache=cache, progress=False, extra=[DanaeOn(s) for s in sources], jobs=jobs)
            w = board.wide("rmse", "clean")
            for s in sources:
                for angle in ("roll", "pitch", "yaw"):
                    f, d = float(w.loc[s, angle]), float(w.loc[f"danae[{s}]", angle])
                    paired = compare(board.recording_rmse(f"danae[{s}]", angle), board.recording_rmse(s, angle))
                    rows.append({"train": a, "test": b, "source": s, "angle": angle, "filter_rmse": f,
                                 "danae_rmse": d, "gain_pct": reduction_pct(d, f), "comparison": paired})
    return pd.DataFrame(rows)
