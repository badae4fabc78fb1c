"""Leaderboard names -> methods: the one place that knows every method the leaderboard can run.

* the names of :data:`~danae_lite.research.baselines.METHODS` (the baselines and the library filters of
  :mod:`danae_lite.research.baselines`, and the paper's DANAE), in table order;
* ``danae-res[<filter>]``: the recommended denoiser (:class:`danae_lite.research.danae_res.DanaeRes`) on
  the output of a filter of :data:`~danae_lite.research.baselines.METHODS`;
* ``danae-safe[<filter>]``: DANAE-res with a per-sample fallback and an error bar
  (:class:`danae_lite.research.danae_safe.DanaeSafe`).

Further methods (the variants of :mod:`danae_lite.research.variants`, a method of one's own) are given
to the leaderboard as objects (``run_leaderboard(..., extra=[...])``), not by name.
"""
from __future__ import annotations

from .baselines import denoiser_name
from .baselines import make_method as make_baseline
from .danae_res import DanaeRes
from .danae_safe import DanaeSafe
from .methods import Method

__all__ = ["make_method"]


def make_method(name: str) -> Method:
    """A fresh, unfitted method by leaderboard name (:func:`is_method_name`); ValueError for
    any other name."""
    found = denoiser_name(name)
    if found is None:
        return make_baseline(name)
    family, source = found
    return DanaeSafe(source) if family == "danae-safe" else DanaeRes(source)
