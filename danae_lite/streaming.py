"""On-line DANAE: causal batch inference, a sample-by-sample streamer, latency measurement.

The paper's networks (:class:`~danae_lite.model.DanaePaper`, :class:`~danae_lite.model.DanaeBig`)
denoise a 20-sample window using all of it, future samples included, so an estimate for
time ``t`` is only available ``L - 1`` samples later. :class:`~danae_lite.model.DanaeCausal`
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
* :class:`StreamingDanae` -- one sample in, one corrected sample out, ring buffer of ``R``.
* :func:`measure_latency` -- per-sample latency of a streamer against the sample period.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np
import torch

from .model import DanaeBase, DanaeCausal

__all__ = ["StreamingDanae", "measure_latency", "predict_causal"]


def _causal_net(model_or_result: Any) -> DanaeCausal:
    """The :class:`DanaeCausal` inside a network or a :class:`~danae_lite.train.TrainResult`."""
    net = getattr(model_or_result, "model", model_or_result)
    if not isinstance(net, DanaeCausal):
        kind = type(net).__name__
        hint = (" (the paper's networks see future samples; train with TrainConfig(arch='causal'))"
                if isinstance(net, DanaeBase) else "")
        raise TypeError(f"expected a DanaeCausal network or a TrainResult holding one, got {kind}{hint}")
    return net


def _as_2d(x: np.ndarray, channels: int, what: str = "x") -> np.ndarray:
    x = np.asarray(x, dtype=np.float32)
    if x.ndim == 1 and channels == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[1] != channels:
        raise ValueError(f"{what}: expected shape (N, {channels})" + (" or (N,)" if channels == 1 else "")
                         + f", got {x.shape}")
    if len(x) == 0:
        raise ValueError(f"{what}: empty recording")
    if not np.isfinite(x).all():
        raise ValueError(f"{what}: contains NaN or inf")
    return x


class _Threads:
    """Set torch's intra-op thread count for a block and restore it (no-op when already equal)."""

    def __init__(self, n: int | None) -> None:
        self.n = n

    def __enter__(self) -> None:
        self.old = torch.get_num_threads()
        if self.n is not None and self.n != self.old:
            torch.set_num_threads(self.n)

    def __exit__(self, *exc: object) -> None:
        if torch.get_num_threads() != self.old:
            torch.set_num_threads(self.old)


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
    (:meth:`~danae_lite.model.DanaeCausal.forward_valid`) in chunks of ``chunk`` outputs,
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
    net = _causal_net(model_or_result)
    if int(chunk) != chunk or chunk < 1:
        raise ValueError(f"chunk must be a positive integer, got {chunk!r}")
    x = _as_2d(x, net.in_channels)
    n, rf = len(x), net.receptive_field
    padded = np.concatenate([np.repeat(x[:1], rf - 1, axis=0), x])  # (N + R - 1, C_in)
    p = next(net.parameters())
    was_training = net.training
    net.eval()
    out = np.empty((n, net.out_channels), dtype=np.float64)
    try:
        with _Threads(num_threads):
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

    Keeps the last ``R = net.receptive_field`` input samples in a ring buffer (stored twice
    over ``2 R`` slots so that the newest ``R`` are always one contiguous slice) and, for each
    new sample, runs the network's unpadded convolutions on exactly those ``R`` samples under
    ``torch.no_grad`` with ``num_threads`` torch threads (1 by default). At the first sample
    after construction or :meth:`reset` the whole buffer is filled with that sample, which is
    the edge padding used in training and in :func:`predict_causal`; :meth:`run` therefore
    returns the same numbers as :func:`predict_causal` (to float32 rounding, ~1e-6 rad).

    Causality: :meth:`step` returns the estimate for the sample it was just given, computed
    from that sample and the ``R - 1`` before it; there is no look-ahead and no delay beyond
    the computation time (see :func:`measure_latency`).

    Parameters
    ----------
    model_or_result : DanaeCausal or TrainResult
        The trained causal network. It is used as it is (not copied) and put in eval mode.
    num_threads : int or None
        Torch CPU threads while stepping (restored after each call); ``None``: leave as is.

    Examples
    --------
    >>> s = StreamingDanae(result)            # doctest: +SKIP
    >>> for roll_kf in kf_roll_stream:        # doctest: +SKIP
    ...     roll = s.step([roll_kf])[0]       # rad, available now
    """

    def __init__(self, model_or_result: Any, *, num_threads: int | None = 1) -> None:
        self.net = _causal_net(model_or_result)
        self.net.eval()
        self.num_threads = num_threads
        self.receptive_field = self.net.receptive_field
        p = next(self.net.parameters())
        self._device, self._dtype = p.device, p.dtype
        self._buf = torch.zeros(1, self.net.in_channels, 2 * self.receptive_field, dtype=p.dtype, device=p.device)
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
        """Forget the history: the next sample starts a new recording (and fills the buffer)."""
        self._n = 0
        self._pos = self.receptive_field - 1

    def _sample(self, sample: Any) -> torch.Tensor:
        a = np.asarray(sample, dtype=np.float32).reshape(-1)
        if a.size != self.in_channels:
            raise ValueError(f"step expects one sample of {self.in_channels} value(s), got shape {np.shape(sample)}")
        if not np.isfinite(a).all():
            raise ValueError(f"step: sample contains NaN or inf: {a.tolist()}")
        return torch.from_numpy(a).to(device=self._device, dtype=self._dtype)

    @torch.no_grad()
    def _step(self, v: torch.Tensor) -> np.ndarray:
        rf, buf = self.receptive_field, self._buf
        if self._n == 0:
            buf.copy_(v.reshape(1, -1, 1).expand_as(buf))
            self._pos = rf - 1
        else:
            self._pos = (self._pos + 1) % rf
            buf[0, :, self._pos] = v
            buf[0, :, self._pos + rf] = v
        self._n += 1
        window = buf[:, :, self._pos + 1 : self._pos + 1 + rf]  # oldest .. newest
        return self.net.forward_valid(window)[0, :, 0].cpu().numpy().astype(np.float64)

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
        v = self._sample(sample)
        with _Threads(self.num_threads):
            return self._step(v)

    def run(self, x: np.ndarray, *, reset: bool = True) -> np.ndarray:
        """Step through a whole recording; ``(N,)`` or ``(N, C_in)`` in, ``(N, C_out)`` out (rad).

        ``reset=True`` (default) starts from an empty history; ``False`` continues the stream.
        """
        x = _as_2d(x, self.in_channels)
        if reset:
            self.reset()
        out = np.empty((len(x), self.out_channels), dtype=np.float64)
        xt = torch.from_numpy(x).to(device=self._device, dtype=self._dtype)
        with _Threads(self.num_threads):
            for i in range(len(x)):
                out[i] = self._step(xt[i])
        return out


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
    x = _as_2d(x, streamer.in_channels)
    if len(x) < total:
        raise ValueError(f"x has {len(x)} samples, need warmup + n = {total}")
    times = np.empty(n)
    clock = time.perf_counter
    streamer.reset()
    try:
        for i in range(warmup):
            streamer.step(x[i])
        for i in range(n):
            t0 = clock()
            streamer.step(x[warmup + i])
            times[i] = clock() - t0
    finally:
        streamer.reset()
    ms = times * 1e3
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
