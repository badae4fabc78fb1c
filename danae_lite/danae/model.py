"""The DANAE networks: 1-D convolutional denoising autoencoders with additive skips.

Three architectures, all mapping a window ``(batch, in_channels, L)`` to
``(batch, out_channels, L)``:

* :class:`DanaePaper` -- the network the paper describes (Sec. "Autoencoder settings"):
  four dilated convolutions down to a ``128 x 2`` bottleneck, three transposed-dilated
  convolutions back up, and four standard convolutions, the ``i``-th working on the sum of
  the ``i``-th encoder and ``i``-th decoder outputs. It is the authors' ``Generator``.
* :class:`DanaeBig` -- the deeper network the authors switched to after the paper
  (``GeneratorBIG``, also used by DANAE++), with a ``128 x 1`` bottleneck. Not the paper's.
* :class:`DanaeCausal` -- not from the authors: a causal dilated temporal-convolution
  network whose output sample ``t`` depends only on inputs up to ``t`` (by default the 31 samples
  ``t-30 ... t``), so it can run on-line, one sample at a time (:mod:`danae_lite.research.streaming`).

The authors' two networks use 128 channels, 1-D kernels of size 3 (the paper's "3x3
kernels"), biases, ReLU after every layer except the last one, and no normalisation layers.
Weights of every convolution are drawn from N(0, 0.02) as in the authors' code; biases keep
PyTorch's default (the causal net follows the same init).

Window length (authors' networks): the stride-1 (transposed) convolutions change the length
by a fixed amount each, and every transposed convolution exactly undoes the length change of
its encoder counterpart, so the networks work on any window of at least
:attr:`~DanaeBase.min_length` samples (19 for the paper net, 20 for the big one) and return
the same length. The paper uses ``L = 20``; at that length the paper net's bottleneck is
``128 x 2`` and the big net's ``128 x 1``. ``window`` only records the length the net is
meant to be applied on (used by :func:`layer_table`, :func:`receptive_field` and by
prediction). The causal net works on any length (its input is edge-padded on the left).

``dilated=False`` sets every dilation to 1. Padding is left as it is; lengths then stay
consistent because each transposed convolution still inverts its encoder convolution, but the
bottleneck is no longer compressed in time (``128 x L`` for the paper net, ``128 x (L-3)`` for
the big one). It is an ablation, not something the authors ran.
"""
from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pandas as pd
import torch
from torch import nn
from torch.nn import functional as F

from .gemm_conv import ChannelsLastConv1d, ChannelsLastConvTranspose1d

__all__ = [
    "ARCHITECTURES",
    "DanaeBase",
    "DanaeBig",
    "DanaeCausal",
    "DanaePaper",
    "build_model",
    "count_parameters",
    "layer_table",
    "receptive_field",
]

INIT_STD = 0.02


class DanaeBase(nn.Module):
    """Shared machinery: layer bookkeeping, input checks, init, optional standardisation.

    Subclasses define ``_encoder``/``_decoder`` layer specs and ``forward_net``.

    Standardisation: the buffers ``in_mean``, ``in_std``, ``out_mean``, ``out_std``
    (shape ``(1, C, 1)``, default 0 and 1) are applied around the network,
    ``y = net((x - in_mean) / in_std) * out_std + out_mean``. With the defaults this is
    exactly the bare network on raw radians, as in the paper. They are set by training with
    ``normalize="standard"`` (:meth:`set_normalization`) and travel in the ``state_dict``.
    """

    arch: str = ""
    #: layer name -> the input it is applied to (for :func:`layer_table`)
    _sources: dict[str, str] = {}

    def __init__(
        self,
        in_channels: int = 1,
        out_channels: int = 1,
        hidden: int = 128,
        *,
        skip: bool = True,
        dilated: bool = True,
        window: int = 20,
    ) -> None:
        super().__init__()
        for name, v in (("in_channels", in_channels), ("out_channels", out_channels), ("hidden", hidden)):
            if int(v) != v or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        self.in_channels = int(in_channels)
        self.out_channels = int(out_channels)
        self.hidden = int(hidden)
        self.skip = bool(skip)
        self.dilated = bool(dilated)
        self.window = int(window)
        self.register_buffer("in_mean", torch.zeros(1, self.in_channels, 1))
        self.register_buffer("in_std", torch.ones(1, self.in_channels, 1))
        self.register_buffer("out_mean", torch.zeros(1, self.out_channels, 1))
        self.register_buffer("out_std", torch.ones(1, self.out_channels, 1))

    # -- construction helpers -------------------------------------------------------------
    def _conv(self, c_in: int, c_out: int, k: int = 3, d: int = 1, p: int = 1) -> nn.Conv1d:
        """A convolution computed as a matrix product on channels-last activations
        (:mod:`danae_lite.danae.gemm_conv`; parameters as :class:`torch.nn.Conv1d`)."""
        return ChannelsLastConv1d(c_in, c_out, kernel_size=k, dilation=d if self.dilated else 1, padding=p)

    def _convt(self, k: int = 3, d: int = 1, p: int = 1) -> nn.ConvTranspose1d:
        h = self.hidden
        return ChannelsLastConvTranspose1d(h, h, kernel_size=k, dilation=d if self.dilated else 1, padding=p)

    def _finish(self) -> None:
        """Authors' init (weights N(0, 0.02), default biases) and the minimum length."""
        for m in self.modules():
            if isinstance(m, (nn.Conv1d, nn.ConvTranspose1d)):
                nn.init.normal_(m.weight, 0.0, INIT_STD)
        self.min_length = self._min_length()
        if self.window < self.min_length:
            raise ValueError(f"window={self.window} is shorter than the minimum length {self.min_length} of {self.arch!r}")

    def _min_length(self) -> int:
        """Smallest input length for which every encoder output has at least one sample."""
        for length in range(1, 10_000):
            ok, cur = True, length
            for m in self.encoder_layers():
                cur = cur + 2 * m.padding[0] - m.dilation[0] * (m.kernel_size[0] - 1)
                if cur < 1:
                    ok = False
                    break
            if ok:
                return length
        raise RuntimeError("no valid input length")  # pragma: no cover

    def encoder_layers(self) -> list[nn.Conv1d]:
        """The encoder convolutions, input to bottleneck."""
        return [getattr(self, n) for n in self.layer_names() if n.startswith("e")]

    def layer_names(self) -> list[str]:
        """Names of the convolution layers in execution order."""
        return list(self._sources)

    def sources(self) -> dict[str, str]:
        """Layer name -> what it is applied to, e.g. ``"c1": "t1 + e3"`` (``"t1"`` without skips)."""
        if self.skip:
            return dict(self._sources)
        return {k: v.split(" + ")[0] for k, v in self._sources.items()}

    def constructor_kwargs(self) -> dict[str, Any]:
        """Keyword arguments that rebuild this network with :func:`build_model`."""
        return dict(
            in_channels=self.in_channels,
            out_channels=self.out_channels,
            hidden=self.hidden,
            skip=self.skip,
            dilated=self.dilated,
            window=self.window,
        )

    # -- standardisation -------------------------------------------------------------------
    @torch.no_grad()
    def set_normalization(self, in_mean, in_std, out_mean, out_std) -> None:
        """Store per-channel input/target mean and std (raw units, e.g. rad)."""
        for name, value, c in (
            ("in_mean", in_mean, self.in_channels),
            ("in_std", in_std, self.in_channels),
            ("out_mean", out_mean, self.out_channels),
            ("out_std", out_std, self.out_channels),
        ):
            t = torch.as_tensor(np.asarray(value, dtype=np.float32)).reshape(-1)
            if t.numel() != c:
                raise ValueError(f"{name} needs {c} values, got {t.numel()}")
            if name.endswith("std") and not bool((t > 0).all()):
                raise ValueError(f"{name} must be positive, got {t.tolist()}")
            getattr(self, name).copy_(t.reshape(1, c, 1))

    def normalization(self) -> dict[str, list[float]]:
        """The standardisation buffers as plain lists (all 0/1 when unused)."""
        return {k: getattr(self, k).reshape(-1).tolist() for k in ("in_mean", "in_std", "out_mean", "out_std")}

    # -- forward ---------------------------------------------------------------------------
    def _check_input(self, x: torch.Tensor) -> None:
        if x.ndim != 3 or x.shape[1] != self.in_channels:
            raise ValueError(
                f"{type(self).__name__} expects input of shape (batch, {self.in_channels}, length), got {tuple(x.shape)}"
            )
        if x.shape[2] < self.min_length:
            raise ValueError(
                f"{type(self).__name__}: window length {x.shape[2]} is shorter than the minimum "
                f"{self.min_length} allowed by its kernel/dilation arithmetic"
            )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Denoise a batch of windows.

        Parameters
        ----------
        x : Tensor, shape (batch, in_channels, L)
            Noisy input windows (e.g. KF angles, rad), ``L >= min_length``.

        Returns
        -------
        Tensor, shape (batch, out_channels, L)
            Denoised windows in the units of the training targets.
        """
        self._check_input(x)
        z = (x - self.in_mean) / self.in_std
        return self.forward_net(z) * self.out_std + self.out_mean

    def forward_net(self, x: torch.Tensor) -> torch.Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def _add(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        return a + b if self.skip else a

    @staticmethod
    def _layer(layer: nn.Module, h: torch.Tensor) -> torch.Tensor:
        """One layer on channels-last ``h`` (batch, length, channels). A plain torch layer put
        in by hand (an ablation, an exercise) works channels-first: it is transposed around."""
        if isinstance(layer, (ChannelsLastConv1d, ChannelsLastConvTranspose1d)):
            return layer(h)
        return layer(h.transpose(1, 2)).transpose(1, 2)

    def describe(self, length: int | None = None) -> pd.DataFrame:
        """Layer table of this network, see :func:`layer_table`."""
        return layer_table(self, length)


class DanaePaper(DanaeBase):
    """DANAE as described in the paper (the authors' ``Generator``).

    Lengths for a 20-sample window (all layers ``hidden = 128`` channels, kernel 3,
    padding 1, ReLU after each except ``out``)::

        e1 = Conv(in -> 128, d1)(x)          20
        e2 = Conv(d3)(e1)                    16
        e3 = Conv(d3)(e2)                    12
        e4 = Conv(d6)(e3)                     2   bottleneck 128 x 2
        t1 = ConvT(d6)(e4)                   12
        c1 = Conv(d1)(t1 + e3)               12
        t2 = ConvT(d3)(c1)                   16
        c2 = Conv(d1)(t2 + e2)               16
        t3 = ConvT(d3)(c2)                   20
        c3 = Conv(d1)(t3 + e1)               20
        out = Conv(128 -> out, d1)(c3)       20   linear

    A convolution with kernel 3, padding 1 and dilation ``d`` shortens the signal by
    ``2d - 2``; the transposed one with the same settings lengthens it by as much. Works for
    any ``L >= 19`` (bottleneck length ``L - 18``).

    Parameters
    ----------
    in_channels, out_channels : int
        Channels of the input windows (1: one KF angle) and of the output (1: that angle).
    hidden : int
        Channels of every hidden layer (128 in the paper).
    skip : bool
        Add the encoder outputs into the decoder (the paper). ``False`` for an ablation:
        ``c_i`` then sees only ``t_i``.
    dilated : bool
        Use the dilations above (the paper); ``False`` sets all to 1 (see module docstring).
    window : int
        Nominal window length (20 in the paper).
    """

    arch = "paper"
    _sources = {
        "e1": "x",
        "e2": "e1",
        "e3": "e2",
        "e4": "e3",
        "t1": "e4",
        "c1": "t1 + e3",
        "t2": "c1",
        "c2": "t2 + e2",
        "t3": "c2",
        "c3": "t3 + e1",
        "out": "c3",
    }

    def __init__(
        self,
        in_channels: int = 1,
        out_channels: int = 1,
        hidden: int = 128,
        *,
        skip: bool = True,
        dilated: bool = True,
        window: int = 20,
    ) -> None:
        super().__init__(in_channels, out_channels, hidden, skip=skip, dilated=dilated, window=window)
        h = hidden
        self.e1 = self._conv(in_channels, h, d=1)
        self.e2 = self._conv(h, h, d=3)
        self.e3 = self._conv(h, h, d=3)
        self.e4 = self._conv(h, h, d=6)
        self.t1 = self._convt(d=6)
        self.c1 = self._conv(h, h)
        self.t2 = self._convt(d=3)
        self.c2 = self._conv(h, h)
        self.t3 = self._convt(d=3)
        self.c3 = self._conv(h, h)
        self.out = self._conv(h, out_channels)
        self._finish()

    def forward_net(self, x: torch.Tensor) -> torch.Tensor:
        relu, f = torch.relu, self._layer  # f(layer, h): one layer on channels-last h
        x = x.transpose(1, 2)  # (batch, length, channels)
        e1 = relu(f(self.e1, x))
        e2 = relu(f(self.e2, e1))
        e3 = relu(f(self.e3, e2))
        e4 = relu(f(self.e4, e3))
        t1 = relu(f(self.t1, e4))
        c1 = relu(f(self.c1, self._add(t1, e3)))
        t2 = relu(f(self.t2, c1))
        c2 = relu(f(self.c2, self._add(t2, e2)))
        t3 = relu(f(self.t3, c2))
        c3 = relu(f(self.c3, self._add(t3, e1)))
        return f(self.out, c3).transpose(1, 2)


# DanaeBig's constructor has DanaePaper's signature and builds its layers the same way, line by
# line (deliberate: each architecture reads as its layer list, like the paper's figure).
class DanaeBig(DanaeBase):
    """The authors' later, deeper variant (``GeneratorBIG``, July 2020 on, DANAE++).

    Not the network of the paper. Lengths for a 20-sample window (kernel 3 and padding 1
    unless stated; ReLU after each layer except ``out``)::

        e1 = Conv(in -> 128)(x)              20
        e2..e5 = Conv(d3)                    16, 12, 8, 4
        e6 = Conv(k4, p0)(e5)                 1   bottleneck 128 x 1
        t1 = ConvT(k4, p0)(e6)                4
        c1 = Conv(t1 + e5)                    4
        t2 = ConvT(d3)(c1); c2 = Conv(t2 + e4)    8
        t3 = ConvT(d3)(c2); c3 = Conv(t3 + e3)   12
        t4 = ConvT(d3)(c3); c4 = Conv(t4 + e2)   16
        t5 = ConvT(d3)(c4); c5 = Conv(t5 + e1)   20
        out = Conv(128 -> out)(c5)           20   linear

    Works for any ``L >= 20`` (bottleneck length ``L - 19``). Parameters as in
    :class:`DanaePaper`.
    """

    arch = "big"
    _sources = {
        "e1": "x",
        "e2": "e1",
        "e3": "e2",
        "e4": "e3",
        "e5": "e4",
        "e6": "e5",
        "t1": "e6",
        "c1": "t1 + e5",
        "t2": "c1",
        "c2": "t2 + e4",
        "t3": "c2",
        "c3": "t3 + e3",
        "t4": "c3",
        "c4": "t4 + e2",
        "t5": "c4",
        "c5": "t5 + e1",
        "out": "c5",
    }

    def __init__(
        self,
        in_channels: int = 1,
        out_channels: int = 1,
        hidden: int = 128,
        *,
        skip: bool = True,
        dilated: bool = True,
        window: int = 20,
    ) -> None:
        super().__init__(in_channels, out_channels, hidden, skip=skip, dilated=dilated, window=window)
        h = hidden
        self.e1 = self._conv(in_channels, h)
        self.e2 = self._conv(h, h, d=3)
        self.e3 = self._conv(h, h, d=3)
        self.e4 = self._conv(h, h, d=3)
        self.e5 = self._conv(h, h, d=3)
        self.e6 = self._conv(h, h, k=4, p=0)
        self.t1 = self._convt(k=4, p=0)
        self.c1 = self._conv(h, h)
        self.t2 = self._convt(d=3)
        self.c2 = self._conv(h, h)
        self.t3 = self._convt(d=3)
        self.c3 = self._conv(h, h)
        self.t4 = self._convt(d=3)
        self.c4 = self._conv(h, h)
        self.t5 = self._convt(d=3)
        self.c5 = self._conv(h, h)
        self.out = self._conv(h, out_channels)
        self._finish()

    def forward_net(self, x: torch.Tensor) -> torch.Tensor:
        relu, f = torch.relu, self._layer  # channels-last, as in DanaePaper
        x = x.transpose(1, 2)
        e1 = relu(f(self.e1, x))
        e2 = relu(f(self.e2, e1))
        e3 = relu(f(self.e3, e2))
        e4 = relu(f(self.e4, e3))
        e5 = relu(f(self.e5, e4))
        e6 = relu(f(self.e6, e5))
        c1 = relu(f(self.c1, self._add(relu(f(self.t1, e6)), e5)))
        c2 = relu(f(self.c2, self._add(relu(f(self.t2, c1)), e4)))
        c3 = relu(f(self.c3, self._add(relu(f(self.t3, c2)), e3)))
        c4 = relu(f(self.c4, self._add(relu(f(self.t4, c3)), e2)))
        c5 = relu(f(self.c5, self._add(relu(f(self.t5, c4)), e1)))
        return f(self.out, c5).transpose(1, 2)


class DanaeCausal(DanaeBase):
    """A causal, streaming-capable DANAE: a small dilated temporal-convolution network.

    Not in the paper. The paper's networks see the whole window, future samples included,
    so they cannot run on-line. Here output sample ``t`` depends only on input samples
    ``t - receptive_field + 1 .. t``: never on the future.

    Layers (``h = hidden`` channels; default dilations ``1, 2, 4, 8``)::

        pad  = edge padding: receptive_field - 1 copies of the first sample on the left
        inp  = Conv(in -> h, k1)(pad)                   linear 1x1 lift
        r0   = inp
        b_i  = Conv(h -> h, k3, d_i, no padding)(r_{i-1})   i = 1..4, causal ("valid")
        r_i  = r_{i-1}[last samples] + relu(b_i)         residual stream (skip=True)
               relu(b_i)                                 (skip=False)
        out  = Conv(h -> out, k1)(relu(r_4))            linear
        y    = x + out   if in_channels == out_channels (a learned correction of the input)
               out       otherwise

    Each kernel-3 convolution with dilation ``d`` reads samples ``t - 2d, t - d, t`` and
    shortens the signal by ``2d``, so ``receptive_field = 1 + 2 * sum(d_i)`` (31 for
    ``1, 2, 4, 8``; 9 with ``dilated=False``). Padding the input once with
    ``receptive_field - 1`` copies of its first sample makes the output as long as the input
    and equals replicate-padding every layer: a constant history produces constant
    activations. A recording's start is therefore treated the same in a training window,
    in batch inference (:func:`danae_lite.research.streaming.predict_causal`) and in streaming
    (:class:`danae_lite.research.streaming.StreamingDanae`, which fills its buffer with the first
    sample): the history before the first sample is taken to be that sample, held.

    Any length ``L >= 1`` works (:attr:`min_length` is 1). In a training window the first
    ``receptive_field - 1`` outputs see padded rather than true history; train on windows
    longer than the receptive field (e.g. ``window=64``) so that most outputs see the real
    past, as they do on-line.

    Size: ``hidden=128`` (the paper's width, the :class:`~danae_lite.danae.train.TrainConfig`
    default) gives 197,505 parameters for one channel in and out
    (``2h + 4(3h^2 + h) + h + 1``); ``hidden=64`` 49,601, ``hidden=32`` 12,513. Each
    streaming step runs the net on the last ``receptive_field`` samples only.

    Parameters
    ----------
    in_channels, out_channels : int
        As in :class:`DanaePaper`.
    hidden : int
        Channels of the residual stream and of every dilated convolution (used as given).
    skip : bool
        Residual connections between the blocks (default). ``False``: a plain stack.
    dilated : bool
        Use ``dilations``; ``False`` sets all to 1.
    window : int
        Training window length (only recorded; any length works).
    dilations : sequence of int
        Dilation of each kernel-3 block, input to output.

    Standardisation buffers, :meth:`forward` and :meth:`forward_net` behave as in
    :class:`DanaeBase`; the residual ``y = x + out`` is taken in standardised units.
    """

    arch = "causal"

    def __init__(
        self,
        in_channels: int = 1,
        out_channels: int = 1,
        hidden: int = 128,
        *,
        skip: bool = True,
        dilated: bool = True,
        window: int = 20,
        dilations: tuple[int, ...] | list[int] = (1, 2, 4, 8),
    ) -> None:
        super().__init__(in_channels, out_channels, hidden, skip=skip, dilated=dilated, window=window)
        dil = tuple(int(d) for d in dilations)
        if not dil or any(d < 1 for d in dil):
            raise ValueError(f"dilations must be a non-empty sequence of positive integers, got {dilations!r}")
        self.dilations = dil
        h = self.hidden
        self.inp = nn.Conv1d(self.in_channels, h, kernel_size=1)
        self.block_names = [f"b{i + 1}" for i in range(len(dil))]
        for name, d in zip(self.block_names, dil):
            setattr(self, name, nn.Conv1d(h, h, kernel_size=3, dilation=d if self.dilated else 1, padding=0))
        self.out = nn.Conv1d(h, self.out_channels, kernel_size=1)
        self.residual_output = self.in_channels == self.out_channels
        stream = ["inp"]
        sources = {"inp": "x"}
        for name in self.block_names:
            sources[name] = " + ".join(stream)
            stream.append(name)
        sources["out"] = " + ".join(stream)
        self._sources = sources  # per instance: the number of blocks varies
        self._finish()

    # -- bookkeeping -----------------------------------------------------------------------
    @property
    def receptive_field(self) -> int:
        """Input samples each output sample depends on: ``1 + 2 * sum(dilation)``."""
        convs = [getattr(self, n) for n in self.block_names]
        return 1 + sum(m.dilation[0] * (m.kernel_size[0] - 1) for m in convs)

    def _min_length(self) -> int:
        return 1  # the input is edge-padded, any length works

    def encoder_layers(self) -> list[nn.Conv1d]:
        """No encoder/decoder split: every layer, input to output."""
        return [getattr(self, n) for n in self.layer_names()]

    def sources(self) -> dict[str, str]:
        """Layer -> what it is applied to; with skips the residual stream is a running sum."""
        if self.skip:
            return dict(self._sources)
        names = self.layer_names()
        return {n: ("x" if i == 0 else names[i - 1]) for i, n in enumerate(names)}

    def constructor_kwargs(self) -> dict[str, Any]:
        kw = super().constructor_kwargs()
        kw["dilations"] = list(self.dilations)
        return kw

    # -- forward ---------------------------------------------------------------------------
    def _body(self, z: torch.Tensor) -> torch.Tensor:
        """Unpadded ("valid") causal net on standardised input ``(B, C_in, L)``, ``L >= receptive_field``.

        Returns ``(B, C_out, L - receptive_field + 1)``: output ``j`` is sample
        ``j + receptive_field - 1`` of the input.
        """
        r = self.inp(z)
        for name in self.block_names:
            b = torch.relu(getattr(self, name)(r))
            r = r[..., r.shape[-1] - b.shape[-1]:] + b if self.skip else b
        y = self.out(torch.relu(r))
        if self.residual_output:
            y = y + z[..., z.shape[-1] - y.shape[-1]:]
        return y

    def forward_net(self, x: torch.Tensor) -> torch.Tensor:
        """Causal net on standardised input: edge-pad ``receptive_field - 1`` samples, then :meth:`_body`."""
        return self._body(F.pad(x, (self.receptive_field - 1, 0), mode="replicate"))

    def forward_valid(self, x: torch.Tensor) -> torch.Tensor:
        """Outputs that need no padding, in raw units (standardisation applied around the net).

        Parameters
        ----------
        x : Tensor, shape (batch, in_channels, L)
            Input history, e.g. KF angles (rad), ``L >= receptive_field``.

        Returns
        -------
        Tensor, shape (batch, out_channels, L - receptive_field + 1)
            Output ``j`` is the network's estimate for input sample ``j + receptive_field - 1``,
            computed from input samples ``j .. j + receptive_field - 1`` only.
        """
        if x.ndim != 3 or x.shape[1] != self.in_channels:
            raise ValueError(
                f"{type(self).__name__} expects input of shape (batch, {self.in_channels}, length), got {tuple(x.shape)}"
            )
        if x.shape[2] < self.receptive_field:
            raise ValueError(
                f"{type(self).__name__}.forward_valid: length {x.shape[2]} is shorter than the receptive field "
                f"{self.receptive_field}"
            )
        z = (x - self.in_mean) / self.in_std
        return self._body(z) * self.out_std + self.out_mean


ARCHITECTURES: dict[str, type[DanaeBase]] = {"paper": DanaePaper, "big": DanaeBig, "causal": DanaeCausal}


def build_model(arch: str = "paper", **kwargs: Any) -> DanaeBase:
    """Build a DANAE network by name (``"paper"``, ``"big"`` or ``"causal"``), passing ``kwargs`` on."""
    try:
        cls = ARCHITECTURES[arch]
    except KeyError:
        raise ValueError(f"unknown architecture {arch!r}; choose one of {sorted(ARCHITECTURES)}") from None
    return cls(**kwargs)


def count_parameters(net: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in net.parameters() if p.requires_grad)


def _describe_layer(m: nn.Module) -> str:
    kind = "ConvT" if isinstance(m, nn.ConvTranspose1d) else "Conv"
    return (
        f"{kind}({m.in_channels}->{m.out_channels}, k{m.kernel_size[0]}, "
        f"d{m.dilation[0]}, p{m.padding[0]})"
    )


def _channels_first_shape(layer: nn.Module, out: torch.Tensor) -> tuple[int, int]:
    """(channels, length) of one window's output, whatever layout the layer works in."""
    channels_last = isinstance(layer, (ChannelsLastConv1d, ChannelsLastConvTranspose1d))
    return (out.shape[2], out.shape[1]) if channels_last else (out.shape[1], out.shape[2])


def layer_table(net: DanaeBase, length: int | None = None) -> pd.DataFrame:
    """One row per convolution: name, what it is applied to, settings, output shape, parameters.

    The output shapes are measured by running a zero batch of one window of ``length``
    samples (default ``net.window``) through the network.

    Returns
    -------
    DataFrame
        Columns ``layer`` (e.g. ``"e1"``), ``input`` (e.g. ``"t1 + e3"``), ``op``
        (e.g. ``"Conv(128->128, k3, d3, p1)"``), ``out_shape`` (channels, length) and
        ``params``. ``df.attrs["total_params"]`` holds the sum.
    """
    length = net.window if length is None else int(length)
    names = net.layer_names()
    shapes: dict[str, tuple[int, ...]] = {}
    hooks = [
        getattr(net, n).register_forward_hook(
            lambda mod, inp, out, n=n: shapes.__setitem__(n, _channels_first_shape(mod, out))
        )
        for n in names
    ]
    try:
        p = next(net.parameters())
        with torch.no_grad():
            net(torch.zeros(1, net.in_channels, length, dtype=p.dtype, device=p.device))
    finally:
        for h in hooks:
            h.remove()
    src = net.sources()
    rows = [
        dict(
            layer=n,
            input=src[n],
            op=_describe_layer(getattr(net, n)),
            out_shape=shapes[n],
            params=count_parameters(getattr(net, n)),
        )
        for n in names
    ]
    df = pd.DataFrame(rows)
    df.attrs["total_params"] = int(df["params"].sum())
    return df


def receptive_field(net: DanaeBase, length: int | None = None) -> pd.DataFrame:
    """Which input samples each output sample of a window depends on.

    Computed, not derived: a copy of the network with every weight and bias set positive
    (so every ReLU is active and no contributions cancel) is run on a window of ``length``
    samples (default ``net.window``); the gradient of output sample ``j`` with respect to
    the input is nonzero exactly on the samples ``j`` depends on. Summed over channels.

    Returns
    -------
    DataFrame, indexed by output sample ``j``
        ``first``/``last``: first and last input sample output ``j`` depends on;
        ``size``: how many input samples it depends on. ``df.attrs["dependency"]`` is the
        boolean matrix ``(L_out, L_in)``.
    """
    length = net.window if length is None else int(length)
    probe = copy.deepcopy(net).to(device="cpu", dtype=torch.float64).eval()
    with torch.no_grad():
        for name, prm in probe.named_parameters():
            prm.fill_(1.0 / prm[0].numel() if name.endswith("weight") else 1.0)
        for name in ("in_mean", "out_mean"):
            getattr(probe, name).zero_()
        for name in ("in_std", "out_std"):
            getattr(probe, name).fill_(1.0)

    # one batch of L identical windows; window j back-propagates only its output sample j,
    # so the gradient of window j is row j of the Jacobian (positive weights: no cancellation)
    x = torch.ones(length, probe.in_channels, length, dtype=torch.float64, requires_grad=True)
    y = probe(x).sum(dim=1)  # (L, L_out), summed over output channels
    idx = torch.arange(length)
    y[idx, idx].sum().backward()
    dep = (x.grad.abs().sum(dim=1) > 0).numpy()  # (L_out, L_in)
    first = np.where(dep.any(1), dep.argmax(1), -1)
    last = np.where(dep.any(1), length - 1 - dep[:, ::-1].argmax(1), -1)
    df = pd.DataFrame({"first": first, "last": last, "size": dep.sum(1)}, index=pd.RangeIndex(length, name="output"))
    df.attrs["dependency"] = dep
    return df
