"""Predicting with a trained DANAE: a whole recording, window by window, stitched back.

Prediction is kept apart from training (:mod:`danae_lite.danae.train`) on purpose: the
training modules are hashed into every network's cache key
(:data:`danae_lite.danae.networks.NETWORK_CODE`), this one is not, so how a trained network
is *applied* can change without retraining any network.

The stride of the overlapping windows changes only the work, not what a sample's prediction
means: ``stride=1`` predicts every window and averages the ``L`` predictions of each sample
(the book's chapters 3 and 4, the paper's recipe); ``stride=s`` predicts every ``s``-th
window (:func:`~danae_lite.danae.windows.overlap_starts`) and averages ``ceil(L / s)``
predictions per sample, for about ``1/s`` of the work.
"""
from __future__ import annotations

import numpy as np
import torch

from .base import DanaeBase
from .train import TorchSettings, as_2d
from .train_types import TrainResult, network_of
from .windows import overlap_starts, stitch_overlap_average, stitch_tiles, tile_windows

__all__ = ["predict"]


def predict(
    model_or_result: DanaeBase | TrainResult,
    x: np.ndarray,
    *,
    stitch: str = "overlap",
    stride: int = 1,
    batch_size: int = 256,
    window: int | None = None,
    num_threads: int | None = None,
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
    was_training = net.training
    net.eval()
    p = next(net.parameters())
    preds = []
    with TorchSettings(num_threads or max(1, torch.get_num_threads())), torch.inference_mode():
        for i in range(0, len(starts), batch_size):  # (batch, C_in, L), cut batch by batch
            chunk = torch.from_numpy(x[starts[i : i + batch_size, None] + np.arange(window)].transpose(0, 2, 1).copy())
            preds.append(net(chunk.to(device=p.device, dtype=p.dtype)).transpose(1, 2).cpu().numpy())
    net.train(was_training)
    pred = np.concatenate(preds).astype(np.float64)  # (n_windows, L, C_out)
    return stitch_overlap_average(pred, n, starts) if stitch == "overlap" else stitch_tiles(pred, n)
