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
  interior, fewer near the ends). Every sample is covered. With a stride ``s``
  (:func:`overlap_starts`) ``ceil(L / s)`` windows cover an interior sample, for about
  ``1/s`` of the work.
"""
from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Iterator, Sequence

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

__all__ = [
    "Tiling",
    "sliding_windows",
    "overlap_starts",
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


def overlap_starts(n_total: int, length: int, stride: int = 1) -> np.ndarray:
    """Starts of the overlapping windows that cover a recording: ``0, s, 2s, ...`` and, when
    the last of those does not end at sample ``N``, one more window ending there.

    Parameters
    ----------
    n_total : int
        Length ``N`` of the recording, ``N >= length``.
    length : int
        Window length ``L``.
    stride : int
        Step ``s`` between window starts, ``1 <= s <= L`` (1: every window, as
        :func:`sliding_windows`; a longer step would leave samples uncovered).

    Returns
    -------
    ndarray of int, increasing
        Every sample lies in at least one window, ``ceil(L / s)`` of them in the interior.
    """
    _check_length(length, stride)
    if stride > length:
        raise ValueError(f"stride={stride} is longer than the window length {length}: samples would be left uncovered")
    if n_total < length:
        raise ValueError(f"recording has N={n_total} samples, fewer than the window length {length}")
    starts = np.arange(0, n_total - length + 1, stride)
    return starts if starts[-1] == n_total - length else np.append(starts, n_total - length)


def stitch_overlap_average(pred_windows: np.ndarray, n_total: int, starts: np.ndarray | None = None) -> np.ndarray:
    """Average the predictions of all windows that contain each sample.

    Window ``j`` starts at ``starts[j]`` and covers samples ``starts[j] .. starts[j]+L-1``;
    every sample is the plain mean of the predictions of the windows that contain it. With
    the default stride-1 windows (``starts = 0 .. N-L``) that is ``L`` windows in the
    interior, down to one at either end.

    Vectorised over windows: one indexed addition per position inside the window (``L``
    numpy additions in all), no Python loop over samples.

    Parameters
    ----------
    pred_windows : ndarray, shape (n_windows, L, ...)
        Prediction for each window, in the order of ``starts``.
    n_total : int
        Length ``N`` of the recording.
    starts : ndarray of int, optional
        Distinct starts of the windows (e.g. :func:`overlap_starts` with a stride); default
        every stride-1 window of :func:`sliding_windows`, ``0 .. N-L``.

    Returns
    -------
    ndarray of float, shape (N, ...)
        NaN only where the predictions are NaN or no window covers a sample.
    """
    pred_windows = np.asarray(pred_windows)
    if pred_windows.ndim < 2:
        raise ValueError(f"expected windows of shape (n_windows, L, ...), got {pred_windows.shape}")
    n_windows, length = pred_windows.shape[:2]
    if starts is None:
        if n_windows + length - 1 != n_total:
            raise ValueError(
                f"{n_windows} stride-1 windows of length {length} come from {n_windows + length - 1} "
                f"samples, not n_total={n_total}"
            )
        starts = np.arange(n_windows)
    starts = np.asarray(starts)
    if starts.shape != (n_windows,) or len(np.unique(starts)) != n_windows:
        raise ValueError(f"starts: expected {n_windows} distinct window starts, got shape {starts.shape}")
    if n_windows and (starts.min() < 0 or starts.max() + length > n_total):
        raise ValueError(f"a window starting at {starts.min()} or {starts.max()} (length {length}) "
                         f"lies outside the recording of {n_total} samples")
    dtype = np.result_type(pred_windows.dtype, np.float32)
    total = np.zeros((n_total, *pred_windows.shape[2:]), dtype=np.float64)
    count = np.zeros(n_total)
    for k in range(length):  # position k of window j is sample starts[j] + k (distinct for one k)
        total[starts + k] += pred_windows[:, k]
        count[starts + k] += 1
    count = count.reshape(n_total, *([1] * (pred_windows.ndim - 2)))
    with np.errstate(invalid="ignore", divide="ignore"):
        return (total / count).astype(dtype, copy=False)
