"""The recommended learned denoiser, DANAE-res: a correction learned on a filter's error.

The paper's DANAE rebuilds every angle from a bottleneck, in raw radians: it learns the
*level* of the training angles as much as their noise, adds error behind a good filter and
does not travel to another motion (chapter 7). DANAE-res changes what is learned, not the
networks or the training loop (:func:`danae_lite.danae.networks.train_networks`):

* **Residual target.** The network predicts the filter's error ``truth - filter`` (roll,
  pitch and the wrapped yaw difference, rad); the output is ``filter + gain * correction``.
  A zero correction is the filter itself.
* **Standardised inputs, unscaled-mean targets.** Inputs are standardised per channel and the
  targets divided by their root mean square, not centred: the network is not handed the
  training recordings' mean error as a free bias. The statistics come from the clean
  training samples outside the validation tails and are stored in the network's buffers,
  so a saved network maps raw features [rad, rad/s] to a correction [rad].
* **Level augmentation** (``offset_rad``): during training, a slowly varying offset (a sum of
  three sinusoids of random phase with periods of 20-60 s, each of amplitude
  ``offset_rad / 3``) is added to every angle-like input channel of a rotation axis (the
  filter's roll and the accelerometer's roll, and so on; headings are rotated as sin/cos
  pairs). Within what the network sees of its input (the causal network: 31 samples) it is
  nearly constant, so the network cannot read the correction
  off the absolute angle. The target (an error) does not change.
* **Inputs.** ``inputs="multi"``: the 11 channels of :data:`danae_lite.research.features.MULTI_CHANNELS`
  (filter angles, accelerometer tilt, magnetic heading, Euler rates); ``"angles"``: the
  filter's angles only.
* **Architecture.** ``arch="causal"`` (default, :data:`danae_lite.research.features.RES_SETTINGS`:
  :class:`~danae_lite.danae.model.DanaeCausal`, 64 channels, 128-sample windows, loss on positions
  30-127): on a causal filter it runs on-line
  (:class:`DenoiserStream`). ``arch="paper"`` looks ahead.
* **Gate chosen across recordings** (``gate=True``): per angle, the gain ``g`` in
  :data:`GATE_GAINS` with the lowest RMSE on training recordings the scoring network has not
  seen. The training recordings are split into at most ``gate_folds`` inner folds; for each,
  a network trained on the other folds corrects that fold's recordings (clean samples). A
  network's validation tail would flatter it: it shares its recording's frame offsets and
  motion with the samples the network trained on, and what the network learns of one
  recording does not transfer to the next. ``g = 0`` falls back to the filter. The gate's
  networks are trained with the first seed only and its gains serve every seed's prediction
  network (the seed spread is that of the prediction networks). With a single training
  recording, the validation tails (of each seed's network) are all there is, and
  ``gate_data`` says so.
  Nothing of the test recordings takes part.
* **Angles the filter does not estimate** (RIANN gives no yaw: NaN throughout): their filter
  channels enter the network as a constant, their target is zero, their gain is 0 and the
  output keeps the filter's NaN ("no estimate"); nothing is guessed. A filter whose estimate is
  NaN on only some samples of an angle is refused, naming the recording and the angle.

Frames and units: every angle is ZYX Euler (roll, pitch, yaw) [rad] in the ground-truth
frame of the aligned recordings; yaw differences are wrapped to [-pi, pi).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..angles import wrap
from .baselines import make_method
from .features import (ANGLE_CHANNELS, MULTI_CHANNELS, RES_SETTINGS, multi_input,
                       research_config, run_network, to_circle)
from .methods import Context, Method
from ..danae.networks import NetworkJob, network_jobs, train_networks
from ..data.recording import Recording
from .streaming import StreamingDanae
from ..danae.train import validation_tail
from ..danae.train_types import TrainConfig, TrainResult

Array = NDArray[np.float64]

GATE_GAINS: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)
"""Gains the validation gate chooses from, per angle (0: the filter, 1: the full correction)."""
OFFSET_PERIODS_S: tuple[float, float] = (20.0, 60.0)
"""Range of the periods [s] of the level-augmentation sinusoids."""

# channels of each input set that carry the level of one rotation axis: (roll, pitch) channels
# are shifted, (sin, cos) pairs rotated by the yaw offset
_LEVEL_CHANNELS = {
    "multi": {"roll": (0, 4), "pitch": (1, 5), "yaw": ((2, 3), (6, 7))},
    "angles": {"roll": (0,), "pitch": (1,), "yaw": ((2, 3),)},
}


def validation_mask(n: int, config: TrainConfig) -> NDArray[np.bool_]:
    """True on the validation tail of an ``n``-sample training recording."""
    m = np.zeros(n, dtype=bool)
    m[n - validation_tail(n, config.window, config.val_fraction) :] = True
    return m


def filter_error(est: Array, truth: Array) -> Array:
    """``truth - est`` per angle [rad], (N, 3); the yaw difference wrapped to [-pi, pi)."""
    d = np.asarray(truth, dtype=float) - np.asarray(est, dtype=float)
    d[:, 2] = wrap(d[:, 2])
    return d


def level_offsets(n: int, rate_hz: float, amplitude_rad: float, rng: np.random.Generator) -> Array:
    """(n, 3) slowly varying offsets [rad] for roll, pitch and yaw: per axis, a sum of three
    sinusoids with periods drawn from :data:`OFFSET_PERIODS_S`, random phases and amplitude
    ``amplitude_rad / 3`` each (so ``|offset| <= amplitude_rad``)."""
    t = np.arange(n) / float(rate_hz)
    out = np.zeros((n, 3))
    for k in range(3):
        for _ in range(3):
            period = rng.uniform(*OFFSET_PERIODS_S)
            out[:, k] += amplitude_rad / 3 * np.sin(2 * np.pi * t / period + rng.uniform(0, 2 * np.pi))
    return out


def shift_levels(x: Array, offsets: Array, inputs: str) -> Array:
    """Features ``x`` (N, C) of input set ``inputs`` with the level ``offsets`` (N, 3) [rad]
    added to every angle-like channel (sin/cos pairs rotated by the yaw offset)."""
    x = np.array(x, dtype=float)
    spec = _LEVEL_CHANNELS[inputs]
    for k, axis in enumerate(("roll", "pitch")):
        for c in spec[axis]:
            x[:, c] += offsets[:, k]
    c, s = np.cos(offsets[:, 2]), np.sin(offsets[:, 2])
    for i_sin, i_cos in spec["yaw"]:
        sn, cs = x[:, i_sin].copy(), x[:, i_cos].copy()
        x[:, i_sin], x[:, i_cos] = sn * c + cs * s, cs * c - sn * s
    return x


class DanaeRes(Method):
    """DANAE-res on the output of leaderboard method ``source`` (see the module docstring).

    Parameters
    ----------
    source : leaderboard filter whose output is corrected ("vqf", "fusion", "paper_kf", ...).
    inputs : ``"multi"`` (default) or ``"angles"``.
    residual : predict the filter's error (default). ``False`` (ablation): predict the angles
        themselves, standardised, as chapter 7's variants do, and output them (the gate then
        blends filter and network output).
    offset_rad : amplitude of the level augmentation [rad] (0 turns it off); default 0.3.
    gate : choose each angle's gain on held-out training data (default); ``False``: gain 1.
    gate_folds : inner folds of the training recordings for the gate (at most this many).
    name : leaderboard name; default ``"danae-res[<source>]"``.
    **train_overrides : :class:`~danae_lite.danae.train_types.TrainConfig` fields replacing
        :data:`~danae_lite.research.features.RES_SETTINGS` and the context's settings (e.g. ``arch="paper", window=20``).

    Attributes (after ``fit``)
    --------------------------
    results : seed -> :class:`~danae_lite.danae.train_types.TrainResult` (networks with the feature
        standardisation and the target scale in their buffers).
    gate_results : (inner fold, first seed) -> the network trained without that fold's recordings.
    gains : seed -> (3,) gain per angle (the same for every seed when the gate has inner folds).
    gate_data : what the gate was chosen on ("held-out training recordings" or "validation tails").
    missing : (3,) bool, the angles ``source`` gives no estimate of (corrected: never).
    params : the settings, the chosen gains and the gate's RMSE per gain and angle.
    """

    def __init__(self, source: str = "vqf", *, inputs: str = "multi", residual: bool = True,
                 offset_rad: float = 0.3, gate: bool = True, gate_folds: int = 4, name: str | None = None,
                 **train_overrides: Any) -> None:
        super().__init__()
        if inputs not in _LEVEL_CHANNELS:
            raise ValueError(f"inputs={inputs!r}: choose 'multi' or 'angles'")
        if not offset_rad >= 0:
            raise ValueError(f"offset_rad must be >= 0 rad, got {offset_rad!r}")
        if source.startswith("danae"):
            raise ValueError(f"source={source!r}: DANAE-res corrects a filter, not a network's output")
        self.source, self.inputs, self.residual = source, inputs, bool(residual)
        if int(gate_folds) != gate_folds or gate_folds < 2:
            raise ValueError(f"gate_folds must be an integer >= 2, got {gate_folds!r}")
        self.offset_rad, self.gate, self.gate_folds = float(offset_rad), bool(gate), int(gate_folds)
        self.overrides = {**RES_SETTINGS, **train_overrides}
        self.name = name or f"danae-res[{source}]"
        self.causal = self.overrides["arch"] == "causal" and make_method(source).causal
        self.description = (f"DANAE-res: a learned correction of {source}'s output "
                            f"({len(self.channels())} input channels, {self.overrides['arch']} network)")

    def channels(self) -> tuple[str, ...]:
        """Names of the input channels."""
        return MULTI_CHANNELS if self.inputs == "multi" else ANGLE_CHANNELS

    def config(self, seed: int) -> TrainConfig:
        """Training settings of the network of ``seed`` (data standardised here, not by
        ``train``), with DANAE-res's budget of steps (:func:`~danae_lite.research.features.research_config`)."""
        return research_config(self.ctx.train_config, seed, capped=True, normalize="none", **self.overrides)

    def features(self, rec: Recording, est: Array) -> Array:
        """Input channels (N, C) for the aligned recording ``rec`` and the filter's estimate ``est`` (N, 3) [rad]
        (an angle in :attr:`missing` enters as the constant 0 rad)."""
        est = np.where(self.missing, 0.0, np.asarray(est, dtype=float))
        if self.inputs == "multi":
            return multi_input(rec, est, self.ctx.alignment.north_yaw)
        return to_circle(est)

    def _target(self, rec: Recording, est: Array) -> Array:
        if self.residual:
            return np.where(self.missing, 0.0, filter_error(est, rec.euler))
        return to_circle(rec.euler)

    def _missing_angles(self, est: dict[str, Array]) -> NDArray[np.bool_]:
        """(3,) True where the source gives no estimate of an angle on any training recording;
        an angle estimated on some samples only is an error naming the recording."""
        finite = {n: np.isfinite(e).all(axis=0) for n, e in est.items()}
        none = {n: ~np.isfinite(e).any(axis=0) for n, e in est.items()}
        missing = np.all(list(none.values()), axis=0)
        for n in est:
            for k, a in enumerate(("roll", "pitch", "yaw")):
                if not (finite[n][k] or missing[k]):
                    raise ValueError(f"{self.name}: {self.source}'s {a} on training recording {n!r} is NaN "
                                     "or inf on some samples only; expected a finite estimate throughout "
                                     "(or none at all, as RIANN's yaw)")
        return missing

    def _output(self, est: Array, y: Array, gains: Array) -> Array:
        """Filter estimate + gain x correction (residual) or a gain-weighted blend (angles)."""
        if self.residual:
            out = est + gains * y
        else:
            net = np.column_stack([y[:, 0], y[:, 1], np.arctan2(y[:, 2], y[:, 3])])
            out = est + gains * filter_error(est, net)
        out[:, 2] = wrap(out[:, 2])
        return out

    def _gate_folds(self, names: list[str]) -> list[list[str]]:
        """Inner folds of the training recordings for the gate (round robin, at most
        ``gate_folds``); none with fewer than two recordings or without a gate."""
        if not self.gate or len(names) < 2:
            return []
        k = min(self.gate_folds, len(names))
        return [names[i::k] for i in range(k)]

    def _prepare(self, recs: list[Recording], x: dict[str, Array], y: dict[str, Array], cfg: TrainConfig,
                 rng: np.random.Generator) -> tuple[list[Array], list[Array], list[Array], dict[str, Array]]:
        """Standardised (and level-augmented) inputs, scaled targets, masks and the scaling of ``recs``."""
        # statistics: clean samples outside the validation tails
        rows = [self.ctx.clean[r.name] & ~validation_mask(len(r), cfg) for r in recs]
        xa = np.concatenate([x[r.name][k] for r, k in zip(recs, rows)])
        ya = np.concatenate([y[r.name][k] for r, k in zip(recs, rows)])
        in_mean, in_std = xa.mean(0), np.where(xa.std(0) > 1e-12, xa.std(0), 1.0)
        if self.residual:
            out_mean, out_std = np.zeros(ya.shape[1]), np.sqrt(np.mean(ya * ya, axis=0))
        else:
            out_mean, out_std = ya.mean(0), ya.std(0)
        scaling = {"in_mean": in_mean, "in_std": in_std, "out_mean": out_mean,
                   "out_std": np.where(out_std > 1e-12, out_std, 1.0)}
        xs, ys = [], []
        for r in recs:
            xr = x[r.name]
            if self.offset_rad > 0:
                offsets = np.where(self.missing, 0.0, level_offsets(len(r), r.fs, self.offset_rad, rng))
                xr = shift_levels(xr, offsets, self.inputs)
            xs.append((xr - scaling["in_mean"]) / scaling["in_std"])
            ys.append((y[r.name] - scaling["out_mean"]) / scaling["out_std"])
        return xs, ys, [self.ctx.clean[r.name] for r in recs], scaling

    def fit(self, ctx: Context) -> DanaeRes:
        """Train the prediction network and the gate's networks on ``ctx.train`` (one per seed
        each) and choose the gains; see the class docstring for the attributes set."""
        est, x, y, folds = self._data(ctx)
        cfg = self.config(ctx.seeds[0])
        nets = self._train(folds, x, y, cfg)
        self.results: dict[int, TrainResult] = {seed: nets[("joint", seed)] for seed in map(int, ctx.seeds)}
        first = int(ctx.seeds[0])
        self.gate_results: dict[tuple[int, int], TrainResult] = {
            (k, first): nets[(f"without-{k}", first)] for k in range(len(folds))}
        self.gate_data = "held-out training recordings" if folds else "validation tails"
        scores = self._choose_gains(nets, folds, x, est, cfg)
        self.params = {"source": self.source, "inputs": list(self.channels()), "residual": self.residual,
                       "offset_rad": self.offset_rad, "gate": self.gate, "gate_data": self.gate_data,
                       "gate_folds": [list(f) for f in folds], "arch": cfg.arch, "window": cfg.window,
                       "seeds": list(ctx.seeds), "gate_gains": list(GATE_GAINS),
                       "gains": {s: g.tolist() for s, g in self.gains.items()},
                       "missing": [a for a, m in zip(("roll", "pitch", "yaw"), self.missing) if m],
                       "gate_rmse_rad": scores, "source_params": self.base.params}
        return self

    def _data(self, ctx: Context) -> tuple[dict[str, Array], dict[str, Array], dict[str, Array], list[list[str]]]:
        """The source's estimate, the features and the targets per training recording of
        ``ctx``, and the gate's inner folds; sets :attr:`ctx`, :attr:`base` and :attr:`missing`."""
        self.ctx = ctx
        self.base = ctx.method(self.source)
        est = {r.name: self.base.predict(r)[0] for r in ctx.train}
        self.missing = self._missing_angles(est)
        x = {r.name: self.features(r, est[r.name]) for r in ctx.train}
        y = {r.name: self._target(r, est[r.name]) for r in ctx.train}
        return est, x, y, self._gate_folds([r.name for r in ctx.train])

    def network_jobs(self, ctx: Context) -> list[NetworkJob]:
        _, x, y, folds = self._data(ctx)
        return network_jobs(**self._training(folds, x, y, self.config(ctx.seeds[0]))[1])[1]

    def _training(self, folds: list[list[str]], x: dict[str, Array], y: dict[str, Array], cfg: TrainConfig
                  ) -> tuple[dict[str, Any], dict[str, Any]]:
        """The standardised data and scaling per head (:meth:`_prepare`), and the arguments of
        :func:`~danae_lite.danae.networks.train_networks`: head ``"joint"`` (every training
        recording, for prediction; every seed) and ``"without-k"`` (all but inner fold ``k``,
        for the gate; the first seed)."""
        ctx = self.ctx
        sets = {"joint": list(ctx.train)}
        for k, held in enumerate(folds):
            sets[f"without-{k}"] = [r for r in ctx.train if r.name not in held]
        seed = int(ctx.seeds[0])
        prepared = {head: self._prepare(recs, x, y, cfg, np.random.default_rng([seed, i]) if i else
                                        np.random.default_rng(seed))
                    for i, (head, recs) in enumerate(sets.items())}
        seeds = {h: list(ctx.seeds) if h == "joint" else [seed] for h in sets}
        return prepared, {"inputs": {h: p[0] for h, p in prepared.items()},
                          "targets": {h: p[1] for h, p in prepared.items()}, "config": cfg, "seeds": seeds,
                          "masks": {h: p[2] for h, p in prepared.items()}, "tag": "denoiser",
                          "metadata": {"method": self.name, "offset_rad": self.offset_rad,
                                       "residual": self.residual, "train": [r.name for r in ctx.train]}}

    def _train(self, folds: list[list[str]], x: dict[str, Array], y: dict[str, Array],
               cfg: TrainConfig) -> dict[tuple[str, int], TrainResult]:
        """The networks per head and seed (:meth:`_training`), each with its standardisation in
        its buffers; sets :attr:`scaling` (the joint network's)."""
        ctx = self.ctx
        prepared, kwargs = self._training(folds, x, y, cfg)
        nets = train_networks(**kwargs, cache=ctx.cache, jobs=ctx.jobs, progress=ctx.progress)
        for (head, _), res in nets.items():
            sc = prepared[head][3]
            res.model.set_normalization(sc["in_mean"], sc["in_std"], sc["out_mean"], sc["out_std"])
        self.scaling = prepared["joint"][3]
        return nets

    def _choose_gains(self, nets: dict[tuple[str, int], TrainResult], folds: list[list[str]], x: dict[str, Array],
                      est: dict[str, Array], cfg: TrainConfig) -> dict[int, dict[str, list[float]]]:
        """The gate: per angle, the gain of :data:`GATE_GAINS` with the lowest RMSE on clean
        samples no network it scores has trained on: each inner fold's recordings for that
        fold's network (first seed; the gains serve every seed) or, with one training
        recording, per seed the validation tails of that seed's prediction network. Sets
        :attr:`gains`; returns the RMSE [rad] per seed, angle and gain."""
        by_name = {r.name: r for r in self.ctx.train}
        self.gains: dict[int, Array] = {}
        scores: dict[int, dict[str, list[float]]] = {}
        first = int(self.ctx.seeds[0])
        for seed in map(int, self.ctx.seeds):
            if folds and seed != first:  # one gate for every seed
                self.gains[seed], scores[seed] = self.gains[first], scores[first]
                continue
            pairs = ([(nets[(f"without-{k}", seed)], by_name[n], np.ones(len(by_name[n]), bool))
                      for k, held in enumerate(folds) for n in held] if folds else
                     [(nets[("joint", seed)], r, validation_mask(len(r), cfg)) for r in self.ctx.train])
            val_rmse = self._gate_rmse(pairs, x, est)  # NaN for an angle the filter does not estimate
            gains = (np.array([GATE_GAINS[i] for i in np.nan_to_num(val_rmse, nan=0.0).argmin(0)])
                     if self.gate else np.ones(3))
            self.gains[seed] = np.where(self.missing, 0.0, gains)
            scores[seed] = {a: val_rmse[:, k].tolist() for k, a in enumerate(("roll", "pitch", "yaw"))}
        return scores

    def _gate_rmse(self, pairs: list[tuple[TrainResult, Recording, NDArray[np.bool_]]], x: dict[str, Array],
                   est: dict[str, Array]) -> Array:
        """RMSE [rad] per gain of :data:`GATE_GAINS` (rows) and angle of the output on the clean
        samples of ``pairs`` (network, recording, samples it may be scored on) taken together."""
        sq, count = np.zeros((len(GATE_GAINS), 3)), 0
        for res, r, where in pairs:
            ok = where & self.ctx.clean[r.name]
            if not ok.any():
                continue
            corr = run_network(res, x[r.name])
            for i, g in enumerate(GATE_GAINS):
                d = filter_error(self._output(est[r.name], corr, np.full(3, g))[ok], r.euler[ok])
                sq[i] += np.sum(d * d, axis=0)
            count += int(ok.sum())
        if count == 0:
            raise ValueError(f"{self.name}: no clean sample to choose the gate on "
                             "(set val_fraction > 0, give more training recordings, or gate=False)")
        return np.sqrt(sq / count)

    def _network_output(self, seed: int, x: Array) -> Array:
        """The prediction network's correction (N, 3) [rad] (residual) for features ``x``."""
        return run_network(self.results[seed], x)

    def fallback_share(self) -> float:
        """Fraction of (seed, angle) pairs whose gate fell back to the filter (gain 0)."""
        g = np.array(list(self.gains.values()))
        return float(np.mean(g == 0.0))

    def predict(self, rec: Recording) -> list[Array]:
        est = self.base.predict(rec)[0]
        x = self.features(rec, est)
        return [self._output(est, self._network_output(int(s), x), self.gains[int(s)]) for s in self.ctx.seeds]


class DenoiserStream:
    """DANAE-res one sample at a time, for a fitted causal :class:`DanaeRes` of one seed.

    ``step(features, est)`` takes the sample's input channels (``DanaeRes.features`` of that
    sample) and the filter's estimate (3,) [rad] and returns the corrected roll, pitch, yaw
    [rad]. It equals :meth:`DanaeRes.predict` sample by sample (same edge padding of the history).
    """

    def __init__(self, method: DanaeRes, seed: int | None = None, *, num_threads: int | None = 1) -> None:
        seed = int(method.ctx.seeds[0] if seed is None else seed)
        if method.results[seed].config.arch != "causal":
            raise ValueError(f"{method.name}: only the causal network streams (arch={method.results[seed].config.arch!r})")
        self.method, self.gains = method, method.gains[seed]
        self.net = StreamingDanae(method.results[seed], num_threads=num_threads)

    def reset(self) -> None:
        """Forget the history (a new recording)."""
        self.net.reset()

    def step(self, features: Array, est: Array) -> Array:
        """Corrected (roll, pitch, yaw) [rad] of one sample."""
        corr = self.net.step(np.asarray(features, dtype=float))
        return self.method._output(np.asarray(est, dtype=float).reshape(1, 3),
                                   np.asarray(corr, dtype=float).reshape(1, -1), self.gains)[0]
