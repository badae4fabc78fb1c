"""Cutting recordings into fixed-length windows and stitching window predictions back.

DANAE sees a signal only through windows of ``length`` samples (20 in the paper). This
module turns one recording, shape ``(N,)`` or ``(N, C)``, into windows and turns per-window
predictions back into one sequence. It knows nothing about networks.

Training uses every stride-1 window of every recording (:func:`windows_from_recordings`);
no window ever spans two recordings. For testing there are two ways back to a sequence:

* :func:`tile_windows` + :func:`stitch_tiles` -- the paper's protocol: non-overlapping
  windows at ``0, L, 2L, ...``, each predicted on its own and concatenated. The last
  ``N mod L`` samples are not covered; they come back as NaN and the count is reported
  (:attr:`Tiling.tail`), never dropped silently.
* :func:`sliding_windows` (stride 1) + :func:`stitch_overlap_average` -- every sample is
  the average of the predictions of all windows that contain it (``L`` of them in the
  interior, fewer near the ends). Every sample is covered.
"""
from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Iterator, Sequence

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

__all__ = [
    "Tiling",
    "sliding_windows",
    "stitch_overlap_average",
    "stitch_tiles",
    "tile_windows",
    "windows_from_recordings",
]


def _check_length(length: int, stride: int = 1) -> None:
    if int(length) != length or length < 1:
        raise ValueError(f"window length must be a positive integer, got {length!r}")
    if int(stride) != stride or stride < 1:
        raise ValueError(f"stride must be a positive integer, got {stride!r}")


def sliding_windows(x: np.ndarray, length: int = 20, stride: int = 1, *, copy: bool = False) -> np.ndarray:
    """All windows of ``length`` samples of one recording, ``stride`` samples apart.

    Parameters
    ----------
    x : ndarray, shape (N,) or (N, C, ...)
        One recording; time is the first axis.
    length : int
        Window length ``L`` in samples.
    stride : int
        Step between window starts; windows start at ``0, stride, 2*stride, ...`` and only
        complete windows are returned (no padding).
    copy : bool
        ``False`` (default) returns a read-only strided view of ``x`` (no memory is
        copied); ``True`` returns a contiguous, writable copy.

    Returns
    -------
    ndarray, shape (n_windows, L, ...)
        ``n_windows = (N - L) // stride + 1``; window ``k`` is ``x[k*stride : k*stride + L]``.

    Raises
    ------
    ValueError
        If ``N < L`` (no complete window fits) or ``x`` is 0-dimensional.
    """
    _check_length(length, stride)
    x = np.asarray(x)
    if x.ndim == 0:
        raise ValueError("expected a recording of shape (N,) or (N, C); got a scalar")
    n = x.shape[0]
    if n < length:
        raise ValueError(f"recording has N={n} samples, fewer than the window length {length}")
    # sliding_window_view puts the window axis last: (N-L+1, ..., L) -> (N-L+1, L, ...)
    view = np.moveaxis(sliding_window_view(x, length, axis=0), -1, 1)[::stride]
    return np.ascontiguousarray(view) if copy else view


def windows_from_recordings(
    recordings: Sequence[np.ndarray], length: int = 20, stride: int = 1
) -> np.ndarray:
    """Windows of several recordings, cut separately and concatenated.

    Windows never span two recordings: recording ``i`` contributes
    ``(N_i - L) // stride + 1`` windows, in time order, after those of recording ``i-1``.

    Parameters
    ----------
    recordings : sequence of ndarray, each (N_i,) or (N_i, C)
        All must have the same trailing shape.
    length, stride : int
        As in :func:`sliding_windows`.

    Returns
    -------
    ndarray, shape (sum_i n_windows_i, L, ...)
        A new contiguous array.

    Raises
    ------
    ValueError
        For an empty list, a recording shorter than ``length`` (its index is named) or
        mismatched trailing shapes.
    """
    if len(recordings) == 0:
        raise ValueError("no recordings given")
    parts = []
    for i, rec in enumerate(recordings):
        rec = np.asarray(rec)
        try:
            parts.append(sliding_windows(rec, length, stride))
        except ValueError as err:
            raise ValueError(f"recording {i}: {err}") from None
        if parts[-1].shape[2:] != parts[0].shape[2:]:
            raise ValueError(
                f"recording {i} has trailing shape {rec.shape[1:]}, recording 0 has {parts[0].shape[2:]}"
            )
    return np.concatenate(parts, axis=0)


@dataclass(frozen=True)
class Tiling:
    """Non-overlapping windows of one recording (the paper's test protocol).

    Attributes
    ----------
    windows : ndarray, shape (n_windows, L, ...)
        Read-only view; window ``k`` is ``x[k*L : (k+1)*L]``.
    starts : ndarray of int, shape (n_windows,)
        First sample index of each window: ``0, L, 2L, ...``.
    n_total : int
        Samples in the recording, ``N``.
    n_covered : int
        Samples inside some window, ``n_windows * L``.
    tail : int
        Samples after the last window, ``N - n_covered`` (``0 <= tail < L`` unless the
        authors' loop range was requested, see :func:`tile_windows`).

    Unpacks as ``windows, tail = tile_windows(x)``.
    """

    windows: np.ndarray
    starts: np.ndarray
    n_total: int
    n_covered: int
    tail: int

    @property
    def length(self) -> int:
        """Window length ``L``."""
        return int(self.windows.shape[1])

    def __iter__(self) -> Iterator:
        return iter((self.windows, self.tail))


def tile_windows(x: np.ndarray, length: int = 20, *, authors_range: bool = False) -> Tiling:
    """Cut one recording into non-overlapping windows starting at sample 0.

    Parameters
    ----------
    x : ndarray, shape (N,) or (N, C, ...)
        One recording, ``N >= length``.
    length : int
        Window length ``L``.
    authors_range : bool
        ``False`` (default): every complete window, ``N // L`` of them, tail ``N mod L``.
        ``True``: the starts of the authors' test loop, ``range(0, N - L, L)``, which also
        leaves out the last complete window when it ends exactly at ``N`` (tail between
        1 and ``L`` samples). For comparison with the published numbers only.

    Returns
    -------
    Tiling
        The windows and how much of the recording they cover.
    """
    _check_length(length)
    x = np.asarray(x)
    n = x.shape[0] if x.ndim else 0
    if n < length or (authors_range and n <= length):
        need = f"more than {length}" if authors_range else f"at least {length}"
        raise ValueError(f"recording has N={n} samples; tiling needs {need} (window length {length})")
    n_windows = len(range(0, n - length, length)) if authors_range else n // length
    n_covered = n_windows * length
    windows = sliding_windows(x[:n_covered], length, stride=length)
    starts = np.arange(n_windows) * length
    return Tiling(windows=windows, starts=starts, n_total=n, n_covered=n_covered, tail=n - n_covered)


def stitch_tiles(pred_windows: np.ndarray, n_total: int) -> np.ndarray:
    """Concatenate predictions of non-overlapping windows back into a sequence.

    Parameters
    ----------
    pred_windows : ndarray, shape (n_windows, L, ...)
        Prediction for each window of :func:`tile_windows`, in order.
    n_total : int
        Length ``N`` of the recording the windows were cut from.

    Returns
    -------
    ndarray of float, shape (N, ...)
        ``out[k*L:(k+1)*L] = pred_windows[k]``; the uncovered tail ``out[n_windows*L:]``
        is NaN, so that a metric computed on it fails loudly instead of using stale data.
        Use ``np.isfinite`` (or :attr:`Tiling.n_covered`) to select the covered part.
    """
    pred_windows = np.asarray(pred_windows)
    if pred_windows.ndim < 2:
        raise ValueError(f"expected windows of shape (n_windows, L, ...), got {pred_windows.shape}")
    n_windows, length = pred_windows.shape[:2]
    n_covered = n_windows * length
    if n_covered > n_total:
        raise ValueError(f"{n_windows} windows of length {length} cover {n_covered} samples > n_total={n_total}")
    dtype = np.result_type(pred_windows.dtype, np.float32)
    out = np.full((n_total, *pred_windows.shape[2:]), np.nan, dtype=dtype)
    out[:n_covered] = pred_windows.reshape(n_covered, *pred_windows.shape[2:])
    return out


def stitch_overlap_average(pred_windows: np.ndarray, n_total: int) -> np.ndarray:
    """Average the predictions of all stride-1 windows that contain each sample.

    Window ``j`` covers samples ``j .. j+L-1``; sample ``i`` is covered by windows
    ``max(0, i-L+1) .. min(i, n_windows-1)`` -- ``L`` windows in the interior, down to one
    at either end -- and the result is the plain mean of their predictions for sample ``i``.

    Vectorised over windows: one slice-add per position inside the window (``L`` numpy
    additions in all), no Python loop over samples.

    Parameters
    ----------
    pred_windows : ndarray, shape (N - L + 1, L, ...)
        Prediction for each stride-1 window of :func:`sliding_windows`, in order.
    n_total : int
        Length ``N`` of the recording; must equal ``n_windows + L - 1``.

    Returns
    -------
    ndarray of float, shape (N, ...)
        Every sample is covered (no NaN unless the predictions contain NaN).
    """
    pred_windows = np.asarray(pred_windows)
    if pred_windows.ndim < 2:
        raise ValueError(f"expected windows of shape (n_windows, L, ...), got {pred_windows.shape}")
    n_windows, length = pred_windows.shape[:2]
    if n_windows + length - 1 != n_total:
        raise ValueError(
            f"{n_windows} stride-1 windows of length {length} come from {n_windows + length - 1} "
            f"samples, not n_total={n_total}"
        )
    dtype = np.result_type(pred_windows.dtype, np.float32)
    total = np.zeros((n_total, *pred_windows.shape[2:]), dtype=np.float64)
    for k in range(length):  # position k of window j is sample j + k
        total[k : k + n_windows] += pred_windows[:, k]
    i = np.arange(n_total)
    count = np.minimum.reduce([i + 1, np.full(n_total, length), n_total - i, np.full(n_total, n_windows)])
    count = count.reshape(n_total, *([1] * (pred_windows.ndim - 2)))
    return (total / count).astype(dtype, copy=False)
