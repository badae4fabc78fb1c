"""The causal DANAE (:class:`DanaeCausal`): output sample ``t`` depends only on inputs up to
``t``, so it can run on-line, one sample at a time (:mod:`danae_lite.research.streaming`).
Not from the authors; the networks they describe are in :mod:`danae_lite.danae.model`.
"""
from __future__ import annotations

from typing import Any

import torch
from torch import nn
from torch.nn import functional as F

from .base import DanaeBase

__all__ = ["DanaeCausal"]


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

    Size: ``hidden=128`` (the paper's width, the :class:`~danae_lite.danae.train_types.TrainConfig`
    default) gives 197,505 parameters for one channel in and out
    (``2h + 4(3h^2 + h) + h + 1``); ``hidden=64`` 49,601, ``hidden=32`` 12,513. Each
    streaming step runs the net on the last ``receptive_field`` samples only.

    Parameters
    ----------
    in_channels, out_channels : int
        As in :class:`~danae_lite.danae.model.DanaePaper`.
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
