"""The DANAE networks: 1-D convolutional denoising autoencoders with additive skips.

Three architectures, all mapping a window ``(batch, in_channels, L)`` to
``(batch, out_channels, L)``:

* :class:`DanaePaper` -- the network the paper describes (Sec. "Autoencoder settings"):
  four dilated convolutions down to a ``128 x 2`` bottleneck, three transposed-dilated
  convolutions back up, and four standard convolutions, the ``i``-th working on the sum of
  the ``i``-th encoder and ``i``-th decoder outputs. It is the authors' ``Generator``.
* :class:`DanaeBig` -- the deeper network the authors switched to after the paper
  (``GeneratorBIG``, also used by DANAE++), with a ``128 x 1`` bottleneck. Not the paper's.
* :class:`~danae_lite.danae.causal.DanaeCausal` -- not from the authors: a causal dilated temporal-convolution
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

from .base import DanaeBase
from .causal import DanaeCausal

__all__ = [
    "ARCHITECTURES",
    "DanaeBig",
    "DanaePaper",
    "build_model",
    "count_parameters",
    "layer_table",
    "receptive_field",
]


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
        relu = torch.relu
        e1 = relu(self.e1(x))
        e2 = relu(self.e2(e1))
        e3 = relu(self.e3(e2))
        e4 = relu(self.e4(e3))
        t1 = relu(self.t1(e4))
        c1 = relu(self.c1(self._add(t1, e3)))
        t2 = relu(self.t2(c1))
        c2 = relu(self.c2(self._add(t2, e2)))
        t3 = relu(self.t3(c2))
        c3 = relu(self.c3(self._add(t3, e1)))
        return self.out(c3)


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
        relu = torch.relu
        e1 = relu(self.e1(x))
        e2 = relu(self.e2(e1))
        e3 = relu(self.e3(e2))
        e4 = relu(self.e4(e3))
        e5 = relu(self.e5(e4))
        e6 = relu(self.e6(e5))
        c1 = relu(self.c1(self._add(relu(self.t1(e6)), e5)))
        c2 = relu(self.c2(self._add(relu(self.t2(c1)), e4)))
        c3 = relu(self.c3(self._add(relu(self.t3(c2)), e3)))
        c4 = relu(self.c4(self._add(relu(self.t4(c3)), e2)))
        c5 = relu(self.c5(self._add(relu(self.t5(c4)), e1)))
        return self.out(c5)


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
            lambda mod, inp, out, n=n: shapes.__setitem__(n, tuple(out.shape[1:]))
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
