"""Stride-1 1-D convolutions computed as matrix products, on channels-last activations.

The DANAE networks are small: 128 channels, kernel 3, windows of 20 samples, batches of
16. At that size PyTorch's default CPU convolution (oneDNN's direct kernels) spends most of
a training step outside arithmetic -- on AVX2-only CPUs its backward pass alone takes more
than half the step. Written as one matrix product per layer (and two for its gradients),
the same convolution runs in the BLAS library's matrix kernels, which are fast on every
instruction set.

Layout: activations are ``(batch, length, channels)`` ("channels-last"), so that the rows of
every matrix product are time samples and no transposes are needed between layers.

A kernel-``K`` convolution with dilation ``d`` and padding ``p`` reads, for output sample
``t``, the input samples ``t + o_k`` with offsets ``o_k = k d - p``, ``k = 0 .. K-1``
(samples outside the input count as zero):

* **convolution**: gather those ``K`` samples of every input channel into one row
  (:func:`gather`, the classic "im2col"), then ``y = cols @ W.T + b`` with ``W`` the weight
  ``(C_out, C_in, K)`` viewed as a ``(C_out, C_in K)`` matrix;
* **transposed convolution** (stride 1), the adjoint: ``z = x @ W``, ``W`` the weight
  ``(C_in, C_out, K)`` viewed as ``(C_in, C_out K)``, gives, for every input
  sample ``i`` and tap ``k``, a contribution to output sample ``i + o_k``; :func:`scatter`
  adds them up ("col2im"). Only real input samples are multiplied, never padded zeros.

:func:`gather` and :func:`scatter` are each other's adjoint, so the backward pass of one
layer type uses the other's data movement. The layer classes are subclasses of
:class:`torch.nn.Conv1d` / :class:`torch.nn.ConvTranspose1d` with the same parameters
(names, shapes, initialisation), so a state dict moves between them and the plain layers
unchanged; their results agree with the plain layers to float32 rounding (a different
order of the same sums).
"""
from __future__ import annotations

from typing import Any

import torch
from torch import nn

__all__ = ["ChannelsLastConv1d", "ChannelsLastConvTranspose1d", "gather", "scatter", "tap_offsets"]


def tap_offsets(kernel_size: int, dilation: int, padding: int) -> list[int]:
    """Offsets ``o_k = k * dilation - padding`` [samples] of a kernel's taps, ``k = 0 .. K-1``."""
    return [k * dilation - padding for k in range(kernel_size)]


def _span(off: int, n_rows: int, n_other: int) -> tuple[int, int]:
    """Rows ``t`` in ``[lo, hi)`` with ``0 <= t + off < n_other``."""
    return max(0, -off), max(max(0, -off), min(n_rows, n_other - off))


def gather(x: torch.Tensor, offsets: list[int], n_rows: int) -> torch.Tensor:
    """``cols[:, t, :, k] = x[:, t + offsets[k]]`` (zero where that sample does not exist).

    x : (B, L, C) -> cols : (B, n_rows, C, K). Taps last, as in a convolution's weight
    ``(C_out, C_in, K)``, so that ``cols.view(B * n_rows, C * K)`` multiplies the weight's
    own memory (viewed as ``(C_out, C_in K)``) without reordering it.
    """
    b, length, c = x.shape
    cols = x.new_zeros(b, n_rows, c, len(offsets))
    for k, off in enumerate(offsets):
        lo, hi = _span(off, n_rows, length)
        cols[:, lo:hi, :, k] = x[:, lo + off : hi + off]
    return cols


def scatter(cols: torch.Tensor, offsets: list[int], length: int) -> torch.Tensor:
    """The adjoint of :func:`gather`: ``x[:, t + offsets[k]] += cols[:, t, :, k]``.

    cols : (B, n_rows, C, K) -> x : (B, length, C).
    """
    b, n_rows, c, _ = cols.shape
    x = cols.new_zeros(b, length, c)
    for k, off in enumerate(offsets):
        lo, hi = _span(off, n_rows, length)
        x[:, lo + off : hi + off] += cols[:, lo:hi, :, k]
    return x


class _ConvFn(torch.autograd.Function):
    """y = gather(x) @ W.T + b, with W = weight viewed as a (C_out, C_in K) matrix."""

    @staticmethod
    def forward(ctx: Any, x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor, offsets: list[int], n_out: int) -> torch.Tensor:
        b, length, _ = x.shape
        c_out = weight.shape[0]
        w = weight.view(c_out, -1)
        cols = gather(x, offsets, n_out).view(b * n_out, w.shape[1])
        ctx.save_for_backward(cols, w)
        ctx.offsets, ctx.length = offsets, length
        return torch.addmm(bias, cols, w.t()).view(b, n_out, c_out)

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[Any, ...]:
        cols, w = ctx.saved_tensors
        b, n_out, c_out = grad.shape
        g = grad.reshape(b * n_out, c_out)
        dx = None
        if ctx.needs_input_grad[0]:
            dx = scatter((g @ w).view(b, n_out, -1, len(ctx.offsets)), ctx.offsets, ctx.length)
        dw = (g.t() @ cols).view(c_out, -1, len(ctx.offsets))
        return dx, dw, g.sum(0), None, None


class _ConvTransposeFn(torch.autograd.Function):
    """y = b + scatter(x @ W), with W = weight viewed as a (C_in, C_out K) matrix."""

    @staticmethod
    def forward(ctx: Any, x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor, offsets: list[int], n_out: int) -> torch.Tensor:
        b, length, c_in = x.shape
        w = weight.view(c_in, -1)
        x2 = x.reshape(b * length, c_in)
        ctx.save_for_backward(x2, w)
        ctx.offsets, ctx.length = offsets, length
        y = scatter((x2 @ w).view(b, length, -1, len(offsets)), offsets, n_out)
        return y.add_(bias)

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[Any, ...]:
        x2, w = ctx.saved_tensors
        b, length, c_in = grad.shape[0], ctx.length, w.shape[0]
        dz = gather(grad, ctx.offsets, length).view(b * length, w.shape[1])
        dx = (dz @ w.t()).view(b, length, c_in) if ctx.needs_input_grad[0] else None
        dw = (x2.t() @ dz).view(c_in, -1, len(ctx.offsets))
        return dx, dw, grad.sum((0, 1)), None, None


def _check(layer: nn.Module, x: torch.Tensor) -> None:
    if layer.stride != (1,) or layer.groups != 1 or layer.bias is None or layer.padding_mode != "zeros":
        raise ValueError(f"{type(layer).__name__} supports stride 1, groups 1, a bias and zero padding only")
    if x.ndim != 3 or x.shape[2] != layer.in_channels:
        raise ValueError(
            f"{type(layer).__name__} expects channels-last input (batch, length, {layer.in_channels}), "
            f"got {tuple(x.shape)}"
        )


class ChannelsLastConv1d(nn.Conv1d):
    """:class:`torch.nn.Conv1d` (stride 1) on ``(batch, length, channels)`` tensors, as a matrix product.

    Same parameters as the parent; ``forward`` takes and returns channels-last tensors:
    ``(B, L, C_in) -> (B, L + 2p - d(K-1), C_out)``.
    """

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # type: ignore[override]
        _check(self, x)
        k, d, p = self.kernel_size[0], self.dilation[0], self.padding[0]
        n_out = x.shape[1] + 2 * p - d * (k - 1)
        return _ConvFn.apply(x, self.weight, self.bias, tap_offsets(k, d, p), n_out)


class ChannelsLastConvTranspose1d(nn.ConvTranspose1d):
    """:class:`torch.nn.ConvTranspose1d` (stride 1) on ``(batch, length, channels)`` tensors.

    Same parameters as the parent; ``(B, L, C_in) -> (B, L - 2p + d(K-1), C_out)``.
    """

    def forward(self, x: torch.Tensor, output_size: Any = None) -> torch.Tensor:  # type: ignore[override]
        _check(self, x)
        if self.output_padding != (0,) or output_size is not None:
            raise ValueError("ChannelsLastConvTranspose1d supports no output padding")
        k, d, p = self.kernel_size[0], self.dilation[0], self.padding[0]
        n_out = x.shape[1] - 2 * p + d * (k - 1)
        return _ConvTransposeFn.apply(x, self.weight, self.bias, tap_offsets(k, d, p), n_out)
