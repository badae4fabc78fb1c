"""One plotting vocabulary for the whole book.

Every chapter draws the same things the same way: the ground truth, a filter estimate, a raw
measurement, a DANAE output and a ±σ band. Colours follow the authors' published figure
(ground truth #490101, KF #a87813, DANAE #43a5ff). Time axes are in seconds and angles in
radians unless a label says otherwise.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib as mpl
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import ArrayLike

from .angles import SYMBOLS

COLORS: dict[str, str] = {
    "truth": "#490101",
    "kf": "#a87813",
    "danae": "#43a5ff",
    "measurement": "#7f7f7f",
    "gyro": "#2ca02c",
    "other": "#9467bd",
}
"""Colour of each kind of curve (methods and signals)."""

METHOD_COLORS: dict[str, str] = {
    "constant": "#bdbdbd",
    "paper_kf": COLORS["kf"],
    "tuned_kf": "#8c564b",
    "tuned_kf_rts": "#c49c94",
    "butterworth": "#bcbd22",
    "moving_average": "#dbdb8d",
    "linear_map": "#7f7f7f",
    "fusion": "#e377c2",
    "vqf": "#17becf",
    "madgwick": "#9edae5",
    "mahony": "#f7b6d2",
    "riann": "#9467bd",
    "danae": COLORS["danae"],
    "danae-res": "#1f3b99",
}
"""Colour of each leaderboard method (``danae_lite.baselines.METHODS``, plus ``danae-res``): the
paper's KF and DANAE keep the colours of the authors' figure; no method uses an angle's colour."""


def method_color(name: str) -> str:
    """Colour of a leaderboard method; variants such as ``danae-res[vqf]`` or ``danae[vqf]``
    take their family's colour."""
    base = name.split("[", 1)[0]
    if base not in METHOD_COLORS:
        raise KeyError(f"no colour for method {name!r}; known: {', '.join(METHOD_COLORS)}")
    return METHOD_COLORS[base]


ANGLE_COLORS: dict[str, str] = {"roll": "#1b9e77", "pitch": "#d95f02", "yaw": "#7570b3"}
"""Colour of each angle, where a figure separates angles rather than methods (a palette of its
own, so that an angle is never mistaken for a method)."""

LABELS: dict[str, str] = {
    "truth": "ground truth",
    "kf": "KF",
    "danae": "DANAE",
    "measurement": "measurement",
    "gyro": "gyro integration",
}


def use_style() -> None:
    """Apply the book's matplotlib style (idempotent)."""
    mpl.rcParams.update(
        {
            "figure.figsize": (9.0, 3.6),
            "figure.dpi": 100,
            "savefig.dpi": 150,
            "axes.grid": True,
            "grid.alpha": 0.3,
            "axes.spines.top": False,
            "axes.spines.right": False,
            "legend.frameon": False,
            "font.size": 10,
        }
    )


def angle_label(angle: str, unit: str = "rad") -> str:
    """Axis label for an angle, e.g. ``'roll φ [rad]'``."""
    return f"{angle} {SYMBOLS.get(angle, '')} [{unit}]".replace("  ", " ")


def plot_series(
    t: ArrayLike,
    series: Mapping[str, ArrayLike],
    *,
    ax: plt.Axes | None = None,
    ylabel: str = "",
    title: str | None = None,
    styles: Mapping[str, Mapping[str, object]] | None = None,
) -> plt.Axes:
    """Plot named curves against time ``t`` [s].

    Names found in :data:`COLORS` (``truth``, ``kf``, ``danae``, ``measurement`` …) get the
    book's colour and legend label; any other name is plotted with its own name as label.
    """
    ax = ax or plt.gca()
    t = np.asarray(t, dtype=float)
    for name, y in series.items():
        kw: dict[str, object] = {"lw": 1.0}
        if name in COLORS:
            kw["color"] = COLORS[name]
        if name == "truth":
            kw["lw"] = 1.4
        if name == "measurement":
            kw.update(lw=0.6, alpha=0.6)
        kw.update((styles or {}).get(name, {}))
        kw.setdefault("label", LABELS.get(name, name))
        ax.plot(t, np.asarray(y, dtype=float), **kw)
    ax.set_xlabel("time [s]")
    if ylabel:
        ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    return ax


def plot_band(t: ArrayLike, mean: ArrayLike, std: ArrayLike, *, ax: plt.Axes | None = None,
              color: str = COLORS["kf"], label: str = "±1σ") -> plt.Axes:
    """Shade ``mean ± std`` against time ``t`` [s]."""
    ax = ax or plt.gca()
    m, s = np.asarray(mean, dtype=float), np.asarray(std, dtype=float)
    ax.fill_between(np.asarray(t, dtype=float), m - s, m + s, color=color, alpha=0.2, lw=0, label=label)
    return ax


def plot_angles(
    t: ArrayLike,
    truth: ArrayLike,
    estimates: Mapping[str, ArrayLike],
    *,
    angles: Sequence[str] = ("roll", "pitch", "yaw"),
    title: str | None = None,
) -> plt.Figure:
    """One row per angle: ground truth and each estimate, arrays of shape (N, 3) [rad]."""
    from .angles import ANGLES

    fig, axes = plt.subplots(len(angles), 1, figsize=(9.0, 2.4 * len(angles)), sharex=True, squeeze=False)
    truth = np.asarray(truth, dtype=float)
    for ax, angle in zip(axes[:, 0], angles):
        k = ANGLES.index(angle)
        series = {"truth": truth[:, k]}
        series.update({name: np.asarray(est, dtype=float)[:, k] for name, est in estimates.items()})
        plot_series(t, series, ax=ax, ylabel=angle_label(angle))
        ax.set_xlabel("")
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
