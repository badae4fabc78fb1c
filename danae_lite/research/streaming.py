"""On-line DANAE: causal batch inference, a sample-by-sample streamer, latency measurement.

The paper's networks (:class:`~danae_lite.danae.model.DanaePaper`, :class:`~danae_lite.danae.model.DanaeBig`)
denoise a 20-sample window using all of it, future samples included, so an estimate for
time ``t`` is only available ``L - 1`` samples later. :class:`~danae_lite.danae.model.DanaeCausal`
(``TrainConfig(arch="causal")``) is causal: its output for sample ``t`` depends only on input
samples ``t - R + 1 .. t``, ``R`` = its ``receptive_field`` (31 by default, 0.31 s at 100 Hz).

Signals are those of the rest of the book: the input is a KF estimate of one or more Euler
angles (roll, pitch, yaw order; rad, reference frame z up, see ``book/conventions.md``) and
the output is the network's estimate of the same angles in the units of its training targets
(rad). Samples are equally spaced at the recording's rate.

Causality guarantee, for all three entry points: output ``t`` is computed from ``x[:t+1]``
only -- inputs after ``t`` are never read -- and from at most the last ``R`` of them. Before
the first sample the history is taken to be the first sample, held (edge padding), in
training windows, in :func:`predict_causal` and in :class:`StreamingDanae` alike, so the
three agree from the very first sample.

* :func:`predict_causal` -- a whole recording at once (chunked, overlap ``R - 1``).
* :class:`StreamingDanae` -- one sample in, one corrected sample out, one output per layer per sample.
* :func:`measure_latency` -- per-sample latency of a streamer against the sample period.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np
import torch

from ..danae.causal import DanaeCausal
from ..danae.train import TorchSettings, as_2d
from ..danae.train_types import network_of

__all__ = ["StreamingDanae", "measure_latency", "predict_causal"]


@torch.no_grad()
def predict_causal(
    model_or_result: Any,
    x: np.ndarray,
    *,
    chunk: int = 65_536,
    num_threads: int | None = 1,
) -> np.ndarray:
    """Causal denoising of a whole recording: output ``t`` uses only ``x[:t+1]``.

    The recording is edge-padded on the left with ``R - 1`` copies of ``x[0]``
    (``R = net.receptive_field``) and run through the network's unpadded convolutions
    (:meth:`~danae_lite.danae.model.DanaeCausal.forward_valid`) in chunks of ``chunk`` outputs,
    consecutive chunks overlapping by ``R - 1`` input samples, so the result does not depend
    on ``chunk`` (beyond float32 rounding) and equals running :class:`StreamingDanae` over
    ``x``.

    Parameters
    ----------
    model_or_result : DanaeCausal or TrainResult
        A causal network (``TrainConfig(arch="causal")``); the paper's networks are refused.
    x : ndarray, shape (N,) or (N, C_in)
        Input recording, e.g. the KF roll estimate (rad), any ``N >= 1``.
    chunk : int
        Output samples per forward pass (bounds memory: about ``4 * hidden * chunk`` floats).
    num_threads : int or None
        Torch CPU threads during the call (restored after); ``None`` leaves them as they are.

    Returns
    -------
    ndarray of float64, shape (N, C_out)
        The network's estimate (computed in float32), in the units of its training targets
        (rad).
    """
    net = network_of(model_or_result, DanaeCausal)
    if int(chunk) != chunk or chunk < 1:
        raise ValueError(f"chunk must be a positive integer, got {chunk!r}")
    x = as_2d(x, "x", net.in_channels)
    n, rf = len(x), net.receptive_field
    padded = np.concatenate([np.repeat(x[:1], rf - 1, axis=0), x])  # (N + R - 1, C_in)
    p = next(net.parameters())
    was_training = net.training
    net.eval()
    out = np.empty((n, net.out_channels), dtype=np.float64)
    try:
        with TorchSettings(num_threads):
            for s in range(0, n, chunk):
                e = min(n, s + chunk)
                # outputs s..e-1 need padded inputs s .. e - 1 + R - 1
                seg = torch.from_numpy(np.ascontiguousarray(padded[s : e + rf - 1].T))[None]
                y = net.forward_valid(seg.to(device=p.device, dtype=p.dtype))
                out[s:e] = y[0].T.cpu().numpy()
    finally:
        net.train(was_training)
    return out


class StreamingDanae:
    """Run a causal DANAE on-line: one input sample in, one corrected sample out.

    Each new sample costs one output per layer, not a pass over a whole window: a kernel-3
    block with dilation ``d`` needs its input at ``t``, ``t - d`` and ``t - 2d`` only, so the
    streamer keeps, per block, the last ``2d + 1`` values of that block's input (its
    "history") and computes the block's newest output as one matrix-vector product
    (``W`` viewed as ``(h, 3h)`` times the three stacked history vectors). The cost per
    sample is about ``4 * 3 h^2`` multiply-adds (0.2 M for ``h = 128``) instead of a forward
    pass over ``R`` samples. The arithmetic is NumPy float32 on the CPU; the weights are read
    once, at construction.

    At the first sample after construction or :meth:`reset` every history is filled with
    that sample's own activations: a history of the first sample held constant, which is
    the edge padding used in training and in :func:`predict_causal`. :meth:`run` therefore
    returns the same numbers as :func:`predict_causal` (to float32 rounding, ~1e-6 rad).

    Causality: :meth:`step` returns the estimate for the sample it was just given, computed
    from that sample and the ``R - 1`` before it; there is no look-ahead and no delay beyond
    the computation time (see :func:`measure_latency`).

    Parameters
    ----------
    model_or_result : DanaeCausal or TrainResult
        The trained causal network (put in eval mode; its weights are copied at construction).
    num_threads : int or None
        Recorded for :func:`measure_latency`; the step itself is single-threaded NumPy.

    Examples
    --------
    >>> s = StreamingDanae(result)            # doctest: +SKIP
    >>> for roll_kf in kf_roll_stream:        # doctest: +SKIP
    ...     roll = s.step([roll_kf])[0]       # rad, available now
    """

    def __init__(self, model_or_result: Any, *, num_threads: int | None = 1) -> None:
        self.net = network_of(model_or_result, DanaeCausal)
        self.net.eval()
        self.num_threads = num_threads
        self.receptive_field = self.net.receptive_field
        net = self.net

        def arr(t: torch.Tensor) -> np.ndarray:
            return t.detach().to(device="cpu", dtype=torch.float32).numpy().copy()

        self._in_mean, self._in_std = arr(net.in_mean).ravel(), arr(net.in_std).ravel()
        self._out_mean, self._out_std = arr(net.out_mean).ravel(), arr(net.out_std).ravel()
        self._w_in, self._b_in = arr(net.inp.weight)[:, :, 0], arr(net.inp.bias)
        # per block: weight (h, h, 3) as (h, 3h) with column c*3 + k, bias, dilation
        self._blocks = [(arr(m.weight).reshape(m.weight.shape[0], -1), arr(m.bias), m.dilation[0])
                        for m in (getattr(net, n) for n in net.block_names)]
        self._w_out, self._b_out = arr(net.out.weight)[:, :, 0], arr(net.out.bias)
        self._hist = [np.zeros((2 * d + 1, len(b)), dtype=np.float32) for _, b, d in self._blocks]
        self.reset()

    @property
    def in_channels(self) -> int:
        return self.net.in_channels

    @property
    def out_channels(self) -> int:
        return self.net.out_channels

    @property
    def n_seen(self) -> int:
        """Samples stepped since the last :meth:`reset`."""
        return self._n

    def reset(self) -> None:
        """Forget the history: the next sample starts a new recording (and fills the histories)."""
        self._n = 0

    def _sample(self, sample: Any) -> np.ndarray:
        a = np.asarray(sample, dtype=np.float32).reshape(-1)
        if a.size != self.in_channels:
            raise ValueError(f"step expects one sample of {self.in_channels} value(s), got shape {np.shape(sample)}")
        if not np.isfinite(a).all():
            raise ValueError(f"step: sample contains NaN or inf: {a.tolist()}")
        return a

    def _step(self, v: np.ndarray) -> np.ndarray:
        n, net = self._n, self.net
        z = (v - self._in_mean) / self._in_std
        r = self._w_in @ z + self._b_in
        for (w, b, d), hist in zip(self._blocks, self._hist):
            if n == 0:
                hist[:] = r  # the first sample, held: the edge padding of training
            m = len(hist)
            hist[n % m] = r
            taps = np.stack([hist[(n - 2 * d) % m], hist[(n - d) % m], r], axis=1)  # (h, 3): t-2d, t-d, t
            out = np.maximum(w @ taps.reshape(-1) + b, 0.0)
            r = r + out if net.skip else out
        y = self._w_out @ np.maximum(r, 0.0) + self._b_out
        if net.residual_output:
            y = y + z
        self._n += 1
        return (y * self._out_std + self._out_mean).astype(np.float64)

    def step(self, sample: Any) -> np.ndarray:
        """Feed one input sample, get the corrected sample for the same time.

        Parameters
        ----------
        sample : array-like, shape (C_in,) (a scalar when ``C_in == 1``)
            The newest input, e.g. the KF roll estimate (rad).

        Returns
        -------
        ndarray of float64, shape (C_out,)
            The network's estimate for this sample (rad), from this and the previous
            ``receptive_field - 1`` samples only.
        """
        return self._step(self._sample(sample))

    def run(self, x: np.ndarray, *, reset: bool = True) -> np.ndarray:
        """Step through a whole recording; ``(N,)`` or ``(N, C_in)`` in, ``(N, C_out)`` out (rad).

        ``reset=True`` (default) starts from an empty history; ``False`` continues the stream.
        """
        x = as_2d(x, "x", self.in_channels)
        if reset:
            self.reset()
        out = np.empty((len(x), self.out_channels), dtype=np.float64)
        for i in range(len(x)):
            out[i] = self._step(x[i])
        return out


def _step_times_ms(streamer: StreamingDanae, x: np.ndarray, warmup: int) -> np.ndarray:
    """Wall-clock time [ms] of each :meth:`StreamingDanae.step` over ``x[warmup:]``, after
    ``warmup`` untimed steps; the streamer is reset before and after."""
    times = np.empty(len(x) - warmup)
    clock = time.perf_counter
    streamer.reset()
    try:
        for i in range(warmup):
            streamer.step(x[i])
        for i in range(len(times)):
            t0 = clock()
            streamer.step(x[warmup + i])
            times[i] = clock() - t0
    finally:
        streamer.reset()
    return times * 1e3


def measure_latency(
    streamer: StreamingDanae,
    n: int = 2000,
    *,
    fs: float = 100.0,
    warmup: int = 100,
    x: np.ndarray | None = None,
    seed: int = 0,
) -> dict[str, Any]:
    """Per-sample latency of :meth:`StreamingDanae.step`, against the sample period ``1/fs``.

    Times ``n`` consecutive calls of ``streamer.step`` with :func:`time.perf_counter`
    (input validation, buffer update, forward pass and conversion back to numpy: what a
    caller pays per sample), after ``warmup`` untimed calls. The streamer is reset before
    and after, and runs with its own ``num_threads``.

    Parameters
    ----------
    streamer : StreamingDanae
    n : int
        Timed samples.
    fs : float
        Sample rate [Hz] to compare against (100 Hz for OxIOD: 10 ms per sample).
    warmup : int
        Untimed calls first (allocator and kernel warm-up).
    x : ndarray, shape (>= warmup + n, C_in), optional
        Input to feed (rad); default a random walk of 0.01 rad steps.
    seed : int
        Seed of the default input.

    Returns
    -------
    dict
        ``n``, ``num_threads``, ``mean_ms``, ``median_ms``, ``p99_ms``, ``max_ms`` (per-sample
        latency), ``fs_hz``, ``period_ms`` (``1000 / fs``), ``median_fraction`` and
        ``p99_fraction`` (latency / period) and ``real_time`` (``p99_ms < period_ms``).
    """
    if int(n) != n or n < 1 or int(warmup) != warmup or warmup < 0:
        raise ValueError(f"n must be >= 1 and warmup >= 0, got n={n!r}, warmup={warmup!r}")
    if not fs > 0:
        raise ValueError(f"fs must be positive, got {fs!r}")
    total = n + warmup
    if x is None:
        rng = np.random.default_rng(seed)
        x = np.cumsum(rng.normal(0.0, 0.01, (total, streamer.in_channels)), axis=0)
    x = as_2d(x, "x", streamer.in_channels)
    if len(x) < total:
        raise ValueError(f"x has {len(x)} samples, need warmup + n = {total}")
    ms = _step_times_ms(streamer, x[:total], warmup)
    period = 1000.0 / fs
    med, p99 = float(np.median(ms)), float(np.percentile(ms, 99))
    return dict(
        n=int(n),
        num_threads=streamer.num_threads if streamer.num_threads is not None else torch.get_num_threads(),
        mean_ms=float(ms.mean()),
        median_ms=med,
        p99_ms=p99,
        max_ms=float(ms.max()),
        fs_hz=float(fs),
        period_ms=period,
        median_fraction=med / period,
        p99_fraction=p99 / period,
        real_time=bool(p99 < period),
    )
