"""The paired comparison: one rule for every verdict that two methods' errors differ.

A verdict compares the RMSE of a method A with that of a method B on the same test data, on the
log scale, where a ratio of errors is a difference:

* **Units.** (i) Three or more held-out recordings (or BROAD trials): per unit the mean over
  seeds of ``log(RMSE_A / RMSE_B)``, then a paired t over the units (their recordings are the
  sample; the scope is "held-out recordings of this kind"). (ii) One test recording, one arm
  deterministic (one value), the other trained with several seeds: a one-sample t over the
  seeds' log ratios (the scope is "training noise on this recording"). (iii) One test
  recording, both arms trained with several seeds: Welch's t on the seeds' log RMSE.
  (iv) Both arms with one value on one recording, or two units: the numbers only, no verdict.
* **Change** = ``100 * (exp(mean log ratio) - 1)`` %: negative means A has the lower error.
  Its interval is the t-interval of the mean log ratio, mapped the same way.
* **Family.** The comparisons of one table answer one question; their intervals are printed at
  the family's Bonferroni level, simultaneous ``1 - 0.05`` for the ``m`` tested rows (each at
  ``1 - 0.05 / m``), so that an interval excludes 0 exactly when its verdict names a direction.
* **Words** (:func:`verdict_words`): "lower error" when the interval lies below 0, "higher
  error" when it lies above, else "no clear difference"; with a no-harm margin (e.g. +2 %),
  "no worse than 2 %" when the interval's upper end lies below it; with a goal (e.g. -10 %),
  "goal met" when the upper end lies below the goal. Counts (A lower on k of n units) are
  descriptive.

* **Coverage** of error bars is no RMSE comparison: :func:`coverage_table` draws a one-sample t
  over units of the share of samples inside an interval minus its nominal level.

:func:`compare` draws one comparison from the RMSEs, :func:`verdict_table` the table of a family.
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike
from scipy import stats

ALPHA = 0.05
"""Simultaneous error rate of a family of comparisons (one table)."""
MIN_UNITS = 3
"""Fewest held-out units (recordings, trials) over which a paired t is drawn."""
TESTS = ("paired t over units", "one-sample t over seeds", "Welch's t over seeds", "numbers only")
"""The four ways a comparison is drawn, in the order of the module docstring."""
COLUMNS = ("comparison", "setting", "test", "n", "change_pct", "low_pct", "high_pct", "a_lower", "verdict")
"""Columns of :func:`verdict_table`: ``n`` units (recordings or trials; seeds on one recording),
``change_pct`` with its interval ``low_pct``..``high_pct`` [%] (NaN for the numbers only),
``a_lower`` "k of n" (units on which A has the lower error; blank on one recording)."""


@dataclass(frozen=True)
class Comparison:
    """Method A against method B: the mean log RMSE ratio ``mean``, its standard error ``se``
    and degrees of freedom ``df`` (NaN for the numbers only), how it was drawn (``test``, one
    of :data:`TESTS`), the number of units ``n`` (seeds on one recording) and ``k``, the units on
    which A has the lower error (None on one recording)."""

    test: str
    n: int
    mean: float
    se: float
    df: float
    k: int | None

    @property
    def change_pct(self) -> float:
        """``100 * (exp(mean) - 1)`` [%]: negative when A has the lower error."""
        return float(100.0 * np.expm1(self.mean))

    @property
    def tested(self) -> bool:
        """False for the numbers only (no interval, no verdict)."""
        return self.test != "numbers only"

    def interval(self, level: float = 1 - ALPHA) -> tuple[float, float]:
        """The two-sided ``level`` t-interval of the change [%] (NaN, NaN for the numbers only)."""
        low, high = _t_interval(self.mean, self.se, self.df, level)
        return float(100.0 * np.expm1(low)), float(100.0 * np.expm1(high))


def _t_interval(mean: float, se: float, df: float, level: float) -> tuple[float, float]:
    """The two-sided ``level`` t-interval ``mean ± t·se`` on the scale of ``mean`` (NaN, NaN when
    ``df`` is NaN: the numbers only)."""
    if not np.isfinite(df):
        return np.nan, np.nan
    half = float(stats.t.ppf(0.5 + level / 2, df)) * se
    return mean - half, mean + half


def _rmse_array(values: ArrayLike, name: str) -> np.ndarray:
    x = np.asarray(values, dtype=float)
    x = x[:, None] if x.ndim == 1 else x
    if x.ndim != 2 or x.size == 0:
        raise ValueError(f"{name}: expected RMSEs as (units,) or (units, seeds), got shape {np.shape(values)}")
    if not (np.isfinite(x).all() and (x > 0).all()):
        raise ValueError(f"{name}: every RMSE must be finite and positive, got {x.tolist()}")
    return x


def _one_sample(test: str, d: np.ndarray, k: int | None) -> Comparison:
    """The t of the mean of the log ratios ``d`` (paired over units, or over one arm's seeds)."""
    return Comparison(test, len(d), float(d.mean()), float(d.std(ddof=1) / np.sqrt(len(d))), float(len(d) - 1), k)


def compare(a: ArrayLike, b: ArrayLike) -> Comparison:
    """Method A against method B from their RMSEs (any one unit: rad or deg), each ``(units,)``
    or ``(units, seeds)``: row ``u`` holds the seeds' RMSE on unit ``u`` (a deterministic method
    has one column). The test follows the module docstring's rule; ValueError for rows that do
    not match or an RMSE that is not finite and positive."""
    la, lb = np.log(_rmse_array(a, "a")), np.log(_rmse_array(b, "b"))
    if len(la) != len(lb):
        raise ValueError(f"a has {len(la)} units and b {len(lb)}: the comparison is paired by unit")
    if len(la) >= MIN_UNITS:  # (i) per unit the mean over seeds of the log ratio
        d = la.mean(axis=1) - lb.mean(axis=1)
        return _one_sample(TESTS[0], d, int((d < 0).sum()))
    if len(la) == 1:
        sa, sb = la[0], lb[0]
        if min(len(sa), len(sb)) == 1 < max(len(sa), len(sb)):  # (ii) one arm deterministic
            return _one_sample(TESTS[1], sa - sb, None)
        if len(sa) > 1 and len(sb) > 1:  # (iii) both arms trained: Welch
            va, vb = sa.var(ddof=1) / len(sa), sb.var(ddof=1) / len(sb)
            df = (va + vb) ** 2 / (va ** 2 / (len(sa) - 1) + vb ** 2 / (len(sb) - 1))
            return Comparison(TESTS[2], max(len(sa), len(sb)), float(sa.mean() - sb.mean()),
                              float(np.sqrt(va + vb)), float(df), None)
    d = la.mean(axis=1) - lb.mean(axis=1)  # (iv) the numbers only
    return _numbers_only(d, int((d < 0).sum()) if len(d) > 1 else None)


def _numbers_only(d: np.ndarray, k: int | None) -> Comparison:
    """The mean of ``d`` without a t: no interval, no verdict (too few units)."""
    return Comparison(TESTS[3], len(d), float(d.mean()), np.nan, np.nan, k)


def verdict_words(low: float, high: float, *, goal_pct: float | None = None,
                  no_harm_pct: float | None = None) -> str:
    """The verdict of a change whose interval is ``low``..``high`` [%] (NaN: the numbers only).

    "goal met" when ``goal_pct`` (negative, e.g. -10) is given and ``high`` lies below it;
    "lower error" when ``high < 0``; "no worse than N %" when ``no_harm_pct`` (positive, e.g. 2)
    is given and ``high`` lies below it; "higher error" when ``low > 0``; otherwise "no clear
    difference". With a goal that is not met, "lower error" reads "lower error, goal not met"."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return "numbers only"
    if goal_pct is not None and high < goal_pct:
        return "goal met"
    if high < 0:
        return "lower error" if goal_pct is None else "lower error, goal not met"
    if no_harm_pct is not None and high < no_harm_pct:
        return f"no worse than {no_harm_pct:g} %"
    return "higher error" if low > 0 else "no clear difference"


def family_level(comparisons: Sequence[Comparison], alpha: float = ALPHA) -> tuple[float, int]:
    """``(level, m)``: the Bonferroni level ``1 - alpha / m`` of each interval of a family whose
    ``m`` tested comparisons hold simultaneously at ``1 - alpha`` (1.0 and 0 when none is tested)."""
    m = sum(c.tested for c in comparisons)
    return (1.0 - alpha / m if m else 1.0), m


def row_key(*labels: str) -> str:
    """A row key of :func:`verdict_table` (the stem of its glue names) from ``labels`` joined by
    underscores, each run of characters other than letters, digits and underscores made one
    underscore: ``row_key("danae-multi[vqf]", "roll")`` is ``"danae_multi_vqf_roll"``."""
    return "_".join(re.sub(r"\W+", "_", label).strip("_") for label in labels)


def verdict_table(rows: Mapping[str, tuple[str, str, Comparison]], *, goal_pct: float | None = None,
                  no_harm_pct: float | None = None, goals: Mapping[str, float] | None = None,
                  alpha: float = ALPHA) -> pd.DataFrame:
    """The verdict table of one family: ``rows`` maps a row key (the index, and the glue names'
    stem) to ``(comparison, setting, Comparison)``, e.g. ``"roll_vs_kf": ("DANAE against the
    paper's KF", "roll, in-motion", compare(...))``. Columns :data:`COLUMNS`; every interval at
    the family's Bonferroni level (:func:`family_level`), which ``attrs`` holds as ``level`` and
    ``m``, with ``alpha``, ``goal_pct`` and ``no_harm_pct``. ``goals`` maps a row key to that
    row's own goal [%] in place of ``goal_pct`` (a table whose rows answer one question with
    two targets, e.g. -10 % on one data set and any reduction, 0 %, on another)."""
    level, m = family_level([c for _, _, c in rows.values()], alpha)
    unknown = set(goals or {}) - set(rows)
    if unknown:
        raise KeyError(f"goals for rows the table does not have: {sorted(unknown)}")
    records = []
    for key, (what, setting, c) in rows.items():
        low, high = c.interval(level)
        goal = (goals or {}).get(key, goal_pct)
        records.append({"key": key, "comparison": what, "setting": setting, "test": c.test, "n": c.n,
                        "change_pct": c.change_pct, "low_pct": low, "high_pct": high,
                        "a_lower": "" if c.k is None else f"{c.k} of {c.n}",
                        "verdict": verdict_words(low, high, goal_pct=goal, no_harm_pct=no_harm_pct)})
    table = pd.DataFrame(records, columns=["key", *COLUMNS]).set_index("key")
    table.attrs = {"level": level, "m": m, "alpha": alpha, "goal_pct": goal_pct, "no_harm_pct": no_harm_pct}
    return table


COVERAGE_COLUMNS = ("comparison", "setting", "test", "n", "nominal_pct", "mean_pct", "low_pts", "high_pts",
                    "verdict")
"""Columns of :func:`coverage_table`: the interval's ``nominal_pct`` coverage, the mean coverage
``mean_pct`` over the units [%] and the interval ``low_pts``..``high_pts`` of its shortfall
(mean - nominal) [percentage points]."""


def coverage_table(rows: Mapping[str, tuple[str, str, ArrayLike, float]], *, alpha: float = ALPHA) -> pd.DataFrame:
    """Do error bars cover what they claim? ``rows`` maps a row key to ``(comparison, setting,
    coverage, nominal)``: the fraction of samples inside the interval on each unit (held-out
    recording or trial), in [0, 1], and the interval's nominal coverage (e.g. 0.68). Per row a
    one-sample t over the units of ``100 * (coverage - nominal)`` [percentage points], with
    fewer than :data:`MIN_UNITS` units the numbers only; the intervals at the table's Bonferroni
    level, as in :func:`verdict_table`. Verdicts: "covers less" (the interval lies below 0),
    "covers more" (above), "no clear difference"; columns :data:`COVERAGE_COLUMNS`."""
    diffs = {}
    for key, (_, _, values, nominal) in rows.items():
        v = np.asarray(values, dtype=float)
        if v.ndim != 1 or not np.isfinite(v).all() or ((v < 0) | (v > 1)).any() or not 0 < nominal < 1:
            raise ValueError(f"row {key!r}: expected coverage fractions in [0, 1] per unit and a nominal "
                             f"level in (0, 1), got {v.tolist()} and {nominal!r}")
        d = 100.0 * (v - nominal)
        diffs[key] = (_one_sample("one-sample t over units", d, None) if len(d) >= MIN_UNITS
                      else _numbers_only(d, None))
    level, m = family_level(list(diffs.values()), alpha)
    records = []
    for key, (what, setting, _, nominal) in rows.items():
        c = diffs[key]
        low, high = _t_interval(c.mean, c.se, c.df, level)
        verdict = ("numbers only" if not c.tested else "covers less" if high < 0
                   else "covers more" if low > 0 else "no clear difference")
        records.append({"key": key, "comparison": what, "setting": setting, "test": c.test, "n": c.n,
                        "nominal_pct": 100.0 * nominal, "mean_pct": 100.0 * nominal + c.mean,
                        "low_pts": low, "high_pts": high, "verdict": verdict})
    table = pd.DataFrame(records, columns=["key", *COVERAGE_COLUMNS]).set_index("key")
    table.attrs = {"level": level, "m": m, "alpha": alpha}
    return table


def header(table: pd.DataFrame) -> str:
    """One line saying at which level the intervals of ``table`` (:func:`verdict_table`) hold."""
    return _caption(table, "Change of A's RMSE against B's [%] (negative: A has the lower error); intervals")


def _caption(table: pd.DataFrame, what: str) -> str:
    """``what`` (the table's values and its intervals), then the family level they hold at."""
    level, m, alpha = table.attrs["level"], table.attrs["m"], table.attrs["alpha"]
    if m == 0:
        return "No row is tested: the numbers only."
    each = f"{100 * level:.2f}".rstrip("0").rstrip(".")
    return (f"{what} simultaneous at {100 * (1 - alpha):g} % over the table's {m} tested rows "
            f"(Bonferroni: each at {each} %).")


def styled(table: pd.DataFrame) -> "pd.io.formats.style.Styler":
    """``table`` (:func:`verdict_table` or :func:`coverage_table`) for the reader: the interval
    as "low to high", the header of :func:`header` as its caption, the row keys hidden."""
    if "nominal_pct" in table.columns:
        return _styled_coverage(table)
    shown = table.assign(interval=[f"{lo:+.1f} to {hi:+.1f}" if np.isfinite(lo) else "—"
                                   for lo, hi in zip(table.low_pct, table.high_pct)])
    shown = shown[["comparison", "setting", "n", "change_pct", "interval", "a_lower", "verdict", "test"]]
    shown = shown.rename(columns={"change_pct": "change [%]", "interval": "interval [%]",
                                  "a_lower": "A lower on"})
    return (shown.style.format({"change [%]": "{:+.1f}"}).hide(axis="index")
            .set_caption(header(table)))


def _styled_coverage(table: pd.DataFrame) -> "pd.io.formats.style.Styler":
    shown = table.assign(interval=[f"{lo:+.1f} to {hi:+.1f}" if np.isfinite(lo) else "—"
                                   for lo, hi in zip(table.low_pts, table.high_pts)])
    shown = shown[["comparison", "setting", "n", "nominal_pct", "mean_pct", "interval", "verdict", "test"]]
    shown = shown.rename(columns={"nominal_pct": "nominal [%]", "mean_pct": "covered [%]",
                                  "interval": "covered - nominal [points]"})
    caption = _caption(table, "Mean share of samples inside the interval over the units [%]; the "
                              "interval of covered - nominal")
    return (shown.style.format({"nominal [%]": "{:.0f}", "covered [%]": "{:.1f}"})
            .hide(axis="index").set_caption(caption))
