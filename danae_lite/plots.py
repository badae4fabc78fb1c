"""One plotting vocabulary for the whole book.

Every chapter draws the same things the same way: the ground truth, a filter estimate, a raw
measurement, a DANAE output and a ±σ band. Colours follow the authors' published figure
(ground truth #490101, KF #a87813, DANAE #43a5ff). Time axes are in seconds and angles in
radians unless a label says otherwise.
"""
from __future__ import annotations

from collections.abc import Mapping

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
    "danae-safe": "#6b8fe0",
}
"""Colour of each leaderboard method (``danae_lite.research.baselines.METHODS``, plus ``danae-res`` and
``danae-safe``): the
paper's KF and DANAE keep the colours of the authors' figure; no method uses an angle's colour."""


def method_color(name: str) -> str:
    """Colour of a leaderboard method; variants such as ``danae-res[vqf]``, ``danae[vqf]`` or
    ``danae-safe-gate[vqf]`` take their family's colour."""
    base = name.split("[", 1)[0]
    if base not in METHOD_COLORS and base.startswith("danae-safe-"):
        base = "danae-safe"
    if base not in METHOD_COLORS:
        raise KeyError(f"no colour for method {name!r}; known: {', '.join(METHOD_COLORS)}")
    return METHOD_COLORS[base]


ANGLE_COLORS: dict[str, str] = {"roll": "#1b9e77", "pitch": "#d95f02", "yaw": "#7570b3"}
"""Colour of each angle, where a figure separates angles rather than methods (a palette of its
own, so that an angle is never mistaken for a method)."""

LINE_STYLES: dict[str, dict[str, float]] = {"truth": {"lw": 1.4}, "measurement": {"lw": 0.6, "alpha": 0.6}}
"""Line width (and transparency) of the curves drawn other than at the default width of 1."""

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
        kw: dict[str, object] = {"lw": 1.0, "label": LABELS.get(name, name)}
        if name in COLORS:
            kw["color"] = COLORS[name]
        kw.update(LINE_STYLES.get(name, {}))
        kw.update((styles or {}).get(name, {}))
        ax.plot(t, np.asarray(y, dtype=float), **kw)
    ax.set_xlabel("time [s]")
    if ylabel:
        ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    return ax
