"""Wording of a verdict drawn from a difference measured over several seeds or recordings.

The rule the chapters of Parts II and III follow: a difference *holds* only if it was measured
on at least :data:`MIN_DRAWS` seeds (or recordings) and the absolute value of its mean exceeds
the range (largest minus smallest) of the per-draw differences; otherwise the sentence says the
difference lies within that spread. Both the threshold and the spread are written into the
sentence, so the reader sees what the verdict rests on.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

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


def group_by_verdict(diffs: Mapping[Any, Sequence[float]]) -> dict[str, list[Any]]:
    """The labels of ``diffs`` (label -> per-draw differences a - b) sorted by verdict, in their
    order: ``"above"`` (the difference holds and is positive), ``"below"`` (it holds and is
    negative) and ``"within"`` (it does not hold: within the spread of its draws)."""
    out: dict[str, list[Any]] = {"above": [], "below": [], "within": []}
    for label, d in diffs.items():
        kind = "within" if not difference_holds(d) else "above" if float(np.mean(d)) > 0 else "below"
        out[kind].append(label)
    return out


def join_labels(labels: Sequence[str], empty: str = "none") -> str:
    """``labels`` as an English list ("a", "a and b", "a, b and c"); ``empty`` when there are none."""
    if not labels:
        return empty
    return labels[0] if len(labels) == 1 else f"{', '.join(labels[:-1])} and {labels[-1]}"


def join_grouped(pairs: Sequence[tuple[str, str]], empty: str = "none") -> str:
    """``(subject, detail)`` pairs as an English list with each subject once, its details in
    brackets in their order: ``[("VQF", "roll"), ("VQF", "pitch"), ("Fusion", "roll")]`` ->
    "VQF (roll, pitch) and Fusion (roll)"; ``empty`` when there are none."""
    grouped: dict[str, list[str]] = {}
    for subject, detail in pairs:
        grouped.setdefault(subject, []).append(detail)
    return join_labels([f"{s} ({', '.join(d)})" for s, d in grouped.items()], empty)
