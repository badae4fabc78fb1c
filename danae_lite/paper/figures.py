"""Recreations of the paper's result figures: KF (above) and DANAE (below) against the ground truth.

* Figure 1: roll on the OxIOD test recording. The authors plotted test samples 12500-14999
  (25 s at 100 Hz).
* Figure 2: pitch on the UCS test set, samples 0-1399 (140 s at about 10 Hz).

Both figures have two panels sharing the time axis [s] and the angle axis [rad]: the KF
estimate with the ground truth above, the DANAE reconstruction with the ground truth below,
in the colours of the published figure (:data:`danae_lite.plots.COLORS`). The authors' own
plots labelled the x axis "Time [0.01s]" and swapped two legend entries; here time is in
seconds and each curve carries its own label.

Every figure is drawn from a :func:`figure_series` table (columns ``time_s``,
``ground_truth``, ``kf``, ``danae``), so the plotted points can be saved next to the picture
and checked one by one.
"""
from __future__ import annotations

from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from .. import plots

SERIES_COLUMNS: tuple[str, str, str, str] = ("time_s", "ground_truth", "kf", "danae")
"""Columns of a figure's data table: time [s] and three angle series [rad]."""


@dataclass(frozen=True)
class PaperFigure:
    """Which angle and which test samples one of the paper's figures shows."""

    number: int
    """Figure number in the paper."""
    angle: str
    """``"roll"``, ``"pitch"`` or ``"yaw"``."""
    start: int
    """First test sample the authors plotted."""
    stop: int
    """One past the last test sample the authors plotted."""

    @property
    def filename(self) -> str:
        """File stem used for the picture and its data, e.g. ``"figure1_roll"``."""
        return f"figure{self.number}_{self.angle}"


PAPER_FIGURES: dict[str, PaperFigure] = {
    "oxiod": PaperFigure(1, "roll", 12500, 15000),
    "ucs": PaperFigure(2, "pitch", 0, 1400),
}
"""The paper's Figure 1 (OxIOD roll) and Figure 2 (UCS pitch), by experiment."""


def figure_window(fig: PaperFigure, n: int) -> tuple[int, int]:
    """Sample range ``[start, stop)`` to plot on a test recording of ``n`` samples.

    The authors' range when the recording is long enough; otherwise a range of the same
    length ending at the last sample (the whole recording when it is shorter than that).
    """
    if n < 1:
        raise ValueError(f"cannot plot an empty recording (n={n})")
    if fig.stop <= n:
        return fig.start, fig.stop
    return max(0, n - (fig.stop - fig.start)), n


def figure_series(time_s: ArrayLike, truth: ArrayLike, kf: ArrayLike, danae: ArrayLike,
                  start: int = 0, stop: int | None = None) -> pd.DataFrame:
    """The table behind a figure: samples ``start:stop`` of four aligned (N,) arrays.

    Parameters
    ----------
    time_s : (N,) sample times [s].
    truth, kf, danae : (N,) ground truth, KF estimate and DANAE reconstruction of one angle [rad].
    start, stop : sample range to keep (Python slice semantics).

    Returns
    -------
    pandas.DataFrame
        Columns :data:`SERIES_COLUMNS`, one row per sample, indexed by the sample number in
        the test recording (index name ``sample``).
    """
    arrays = [np.asarray(a, dtype=float) for a in (time_s, truth, kf, danae)]
    n = arrays[0].shape
    for name, a in zip(SERIES_COLUMNS, arrays):
        if a.ndim != 1 or a.shape != n:
            raise ValueError(f"{name} must be a 1-D array of the same length as time_s {n}, got {a.shape}")
    index = pd.RangeIndex(n[0], name="sample")[start:stop]
    if len(index) == 0:
        raise ValueError(f"sample range {start}:{stop} is empty for {n[0]} samples")
    return pd.DataFrame({c: a[start:stop] for c, a in zip(SERIES_COLUMNS, arrays)}, index=index)


def plot_kf_danae(series: pd.DataFrame, angle: str, *, title: str | None = None,
                  figsize: tuple[float, float] = (9.0, 5.6)) -> plt.Figure:
    """Draw the paper's two-panel layout from a :func:`figure_series` table.

    Top panel: ground truth and KF; bottom panel: ground truth and DANAE. Both share the
    time axis [s] and the angle axis [rad], so the two errors can be compared by eye.
    """
    fig, (top, bottom) = plt.subplots(2, 1, figsize=figsize, sharex=True, sharey=True)
    t = series["time_s"].to_numpy()
    for ax, method in ((top, "kf"), (bottom, "danae")):
        plots.plot_series(t, {"truth": series["ground_truth"], method: series[method]}, ax=ax,
                          ylabel=plots.angle_label(angle))
        ax.legend(loc="upper right", fontsize=8)
    top.set_xlabel("")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig
