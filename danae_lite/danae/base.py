"""What every DANAE network shares (:class:`DanaeBase`): layer bookkeeping, input checks, the
authors' initialisation and the optional standardisation around the network.

The architectures are in :mod:`danae_lite.danae.model` (the authors' two) and
:mod:`danae_lite.danae.causal` (a causal one for on-line use).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

__all__ = ["INIT_STD", "DanaeBase"]

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
        """A convolution of kernel ``k``, dilation ``d`` (1 when not ``dilated``), padding ``p``."""
        return nn.Conv1d(c_in, c_out, kernel_size=k, dilation=d if self.dilated else 1, padding=p)

    def _convt(self, k: int = 3, d: int = 1, p: int = 1) -> nn.ConvTranspose1d:
        """A transposed convolution, ``hidden`` channels in and out."""
        h = self.hidden
        return nn.ConvTranspose1d(h, h, kernel_size=k, dilation=d if self.dilated else 1, padding=p)

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
