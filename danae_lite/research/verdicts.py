"""Wording of a verdict drawn from a difference measured over several seeds or recordings.

The rule the chapters of Parts II and III follow: a difference *holds* only if it was measured
on at least :data:`MIN_DRAWS` seeds (or recordings) and the absolute value of its mean exceeds
the range (largest minus smallest) of the per-draw differences; otherwise the sentence says the
difference lies within that spread. Both the threshold and the spread are written into the
sentence, so the reader sees what the verdict rests on.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

MIN_DRAWS = 3
"""Fewest seeds or recordings a difference must be measured on before a verdict is drawn."""


def difference_holds(diffs: Sequence[float]) -> bool:
    """True when the per-draw differences ``diffs`` (one per seed or recording, any unit) are at
    least :data:`MIN_DRAWS` and the absolute value of their mean exceeds their range."""
    d = np.asarray(diffs, dtype=float)
    if d.ndim != 1 or not np.isfinite(d).all():
        raise ValueError(f"diffs must be a 1-D sequence of finite numbers, got {d!r}")
    return d.size >= MIN_DRAWS and abs(float(d.mean())) > float(d.max() - d.min())


def difference_phrase(diffs: Sequence[float], *, above: str, below: str, unit: str = "rad",
                      draws: str = "seeds", digits: int = 4) -> str:
    """A phrase for the differences ``diffs`` (a - b, one per draw, in ``unit``): ``above`` when
    the difference holds and is positive, ``below`` when it holds and is negative, each
    followed by its size and the range it exceeds; otherwise a phrase saying that the mean
    difference lies within the range of the ``draws``."""
    d = np.asarray(diffs, dtype=float)
    holds = difference_holds(d)
    mean, spread = float(d.mean()), float(d.max() - d.min())
    counted = draws.removesuffix("s") if d.size == 1 else draws
    if holds:
        return (f"{above if mean > 0 else below} (by {abs(mean):.{digits}f} {unit}, more than "
                f"the {spread:.{digits}f} {unit} range of its {d.size} {counted})")
    return (f"within the spread of its {d.size} {counted} ({mean:+.{digits}f} {unit} against a "
            f"range of {spread:.{digits}f} {unit}; a difference holds when its mean exceeds "
            f"that range over at least {MIN_DRAWS} {draws})")
