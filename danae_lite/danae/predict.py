"""Predicting with a trained DANAE: a whole recording, window by window, stitched back.

Prediction is kept apart from training (:mod:`danae_lite.danae.train`) on purpose: the
training modules are hashed into every network's cache key
(:data:`danae_lite.danae.networks.NETWORK_CODE`), this one is not, so how a trained network
is *applied* can change without retraining any network.

Two choices here change only the speed, not what is computed beyond float32 rounding:

* **PyTorch's own convolutions.** Training computes the convolutions as matrix products on
  channels-last activations (:mod:`danae_lite.danae.gemm_conv`), the faster way for the
  backward pass of these small layers. Prediction has no backward pass; there
  :func:`plain_network` swaps in :class:`torch.nn.Conv1d` / :class:`torch.nn.ConvTranspose1d`
  with the same weights (``make bench`` times both paths side by side; PyTorch's is the
  faster on the reference machines). The two agree to float32 rounding (a different order
  of the same sums).
* **The stride of the overlapping windows.** ``stride=1`` predicts every window and
  averages the ``L`` predictions of each sample (the book's chapters 3 and 4, the paper's
  recipe); ``stride=s`` predicts every ``s``-th window (:func:`~danae_lite.danae.windows.overlap_starts`)
  and averages ``ceil(L / s)`` predictions per sample, for about ``1/s`` of the work.
"""
from __future__ import annotations

import copy

import numpy as np
import torch
from torch import nn

from .gemm_conv import ChannelsLastConv1d, ChannelsLastConvTranspose1d
from .model import DanaeBase
from .train import TorchSettings, as_2d
from .train_types import TrainResult, network_of
from .windows import overlap_starts, stitch_overlap_average, stitch_tiles, tile_windows

__all__ = ["plain_network", "predict"]


def _plain_layer(layer: nn.Module) -> nn.Module:
    """The PyTorch layer with the parameters of a matrix-product layer (the same state dict)."""
    kind = nn.Conv1d if isinstance(layer, ChannelsLastConv1d) else nn.ConvTranspose1d
    plain = kind(layer.in_channels, layer.out_channels, layer.kernel_size, dilation=layer.dilation,
                 padding=layer.padding).to(device=layer.weight.device, dtype=layer.weight.dtype)
    plain.load_state_dict(layer.state_dict())
    return plain


def plain_network(net: DanaeBase) -> DanaeBase:
    """A copy of ``net`` whose convolutions are PyTorch's own layers (same weights, same
    outputs to float32 rounding); the network's forward pass transposes around them
    (:meth:`~danae_lite.danae.model.DanaeBase._layer`). ``net`` itself is not changed."""
    plain = copy.deepcopy(net)
    for module in list(plain.modules()):
        for name, child in list(module.named_children()):
            if isinstance(child, (ChannelsLastConv1d, ChannelsLastConvTranspose1d)):
                setattr(module, name, _plain_layer(child))
    return plain


def predict(
    model_or_result: DanaeBase | TrainResult,
    x: np.ndarray,
    *,
    stitch: str = "overlap",
    stride: int = 1,
    batch_size: int = 256,
    window: int | None = None,
    num_threads: int | None = None,
    convolutions: str = "torch",
) -> np.ndarray:
    """Denoise one recording window by window and stitch the windows back together.

    Parameters
    ----------
    model_or_result : DanaeBase or TrainResult
    x : ndarray, shape (N,) or (N, C_in)
        Noisy input, e.g. the KF roll estimate of the test recording (rad), ``N >= window``.
    stitch : {"overlap", "tiles"}
        ``"overlap"``: overlapping windows ``stride`` samples apart (and one ending at the
        last sample); each sample is the mean of the predictions covering it
        (:func:`~danae_lite.danae.windows.stitch_overlap_average`); all samples are covered.
        ``"tiles"``: the paper's non-overlapping windows from sample 0
        (:func:`~danae_lite.danae.windows.stitch_tiles`); the last ``N mod window`` samples are NaN.
    stride : int
        Step between the starts of overlapping windows [samples]; 1 (default): every window.
        Only with ``stitch="overlap"``.
    batch_size : int
        Windows per forward pass (256 keeps a batch's activations in the CPU caches).
    window : int, optional
        Window length; default ``net.window`` (the training window).
    num_threads : int, optional
        CPU threads for torch during the call; default ``torch.get_num_threads()``, as in
        :class:`~danae_lite.danae.train_types.TrainConfig`.
    convolutions : {"torch", "matmul"}
        ``"torch"`` (default): PyTorch's own layers (:func:`plain_network`); ``"matmul"``: the
        network as trained, its convolutions as matrix products (for comparisons: ``make bench``).

    Returns
    -------
    ndarray of float64, shape (N, C_out)
        Denoised signal (computed in float32), in the units of the training targets.
    """
    net = network_of(model_or_result)
    window = net.window if window is None else int(window)
    x = as_2d(x, "x")
    n = len(x)
    if stitch == "overlap":
        starts = overlap_starts(n, window, stride)
    elif stitch == "tiles":
        if stride != 1:
            raise ValueError(f"stride={stride!r} applies to stitch='overlap' only; tiles never overlap")
        starts = tile_windows(x, window).starts
    else:
        raise ValueError(f"stitch={stitch!r}: choose 'overlap' or 'tiles'")
    if convolutions not in ("torch", "matmul"):
        raise ValueError(f"convolutions={convolutions!r}: choose 'torch' or 'matmul'")
    plain = plain_network(net) if convolutions == "torch" else net
    was_training = plain.training
    plain.eval()
    p = next(plain.parameters())
    preds = []
    with TorchSettings(num_threads or max(1, torch.get_num_threads())), torch.inference_mode():
        for i in range(0, len(starts), batch_size):  # (batch, C_in, L), cut batch by batch
            chunk = torch.from_numpy(x[starts[i : i + batch_size, None] + np.arange(window)].transpose(0, 2, 1).copy())
            preds.append(plain(chunk.to(device=p.device, dtype=p.dtype)).transpose(1, 2).cpu().numpy())
    plain.train(was_training)
    pred = np.concatenate(preds).astype(np.float64)  # (n_windows, L, C_out)
    return stitch_overlap_average(pred, n, starts) if stitch == "overlap" else stitch_tiles(pred, n)
