"""The paired comparison (danae_lite.evaluate.comparison) against SciPy's t-tests and closed forms."""
import numpy as np
import pandas as pd
import pytest
from scipy import stats

from danae_lite.evaluate.comparison import (TESTS, compare, family_level, header, styled, verdict_table,
                                            verdict_words)

RNG = np.random.default_rng(7)


def _pct(ci):
    return 100 * np.expm1(ci.low), 100 * np.expm1(ci.high)


def test_units_are_a_paired_t_on_the_log_ratio_as_scipy_draws_it():
    a, b = RNG.uniform(0.02, 0.06, 6), RNG.uniform(0.02, 0.06, 6)
    c = compare(a, b)
    ref = stats.ttest_rel(np.log(a), np.log(b))
    assert c.test == TESTS[0] and c.n == 6 and c.df == 5 and c.k == int((a < b).sum())
    assert c.mean == pytest.approx(np.log(a / b).mean(), rel=1e-12)
    for level in (0.95, 0.99):
        assert c.interval(level) == pytest.approx(_pct(ref.confidence_interval(level)), rel=1e-10)


def test_a_closed_form_four_recordings():
    # log ratios 0, 0.2, 0.4, 0.6: mean 0.3, sd sqrt(1/15 * ...) = 0.2582, t(0.975, 3) = 3.182446
    d = np.array([0.0, 0.2, 0.4, 0.6])
    c = compare(np.exp(d), np.ones(4))
    sd = np.sqrt(((d - 0.3) ** 2).sum() / 3)
    half = 3.182446305284263 * sd / 2
    assert c.change_pct == pytest.approx(100 * (np.exp(0.3) - 1))
    assert c.interval(0.95) == pytest.approx((100 * np.expm1(0.3 - half), 100 * np.expm1(0.3 + half)))


def test_seeds_are_averaged_within_a_unit_before_the_units_are_compared():
    a = RNG.uniform(0.02, 0.06, (5, 3))   # three seeds per recording
    b = RNG.uniform(0.02, 0.06, 5)        # a filter: one value per recording
    c = compare(a, b)
    per_unit = np.log(a).mean(axis=1) - np.log(b)
    ref = stats.ttest_1samp(per_unit, 0.0)
    assert c.n == 5 and c.mean == pytest.approx(per_unit.mean())
    assert c.interval(0.9) == pytest.approx(_pct(ref.confidence_interval(0.9)), rel=1e-10)


def test_one_recording_one_arm_deterministic_is_a_one_sample_t_over_the_seeds():
    a, b = RNG.uniform(0.04, 0.05, (1, 3)), [[0.08]]
    c = compare(a, b)
    ref = stats.ttest_1samp(np.log(a[0] / 0.08), 0.0)
    assert c.test == TESTS[1] and c.n == 3 and c.k is None
    assert c.interval() == pytest.approx(_pct(ref.confidence_interval(0.95)), rel=1e-10)
    assert compare(b, a).interval() == pytest.approx(_pct(stats.ttest_1samp(np.log(0.08 / a[0]), 0.0)
                                                         .confidence_interval(0.95)), rel=1e-10)


def test_one_recording_both_arms_trained_is_welchs_t_on_the_log_rmse():
    a, b = RNG.uniform(0.04, 0.05, (1, 3)), RNG.uniform(0.03, 0.07, (1, 5))
    c = compare(a, b)
    ref = stats.ttest_ind(np.log(a[0]), np.log(b[0]), equal_var=False)
    assert c.test == TESTS[2] and c.df == pytest.approx(ref.df)
    assert c.interval(0.99) == pytest.approx(_pct(ref.confidence_interval(0.99)), rel=1e-9)


@pytest.mark.parametrize("a, b", [([[0.05]], [[0.04]]), ([0.05, 0.06], [0.04, 0.05])])
def test_two_deterministic_values_or_two_units_give_the_numbers_only(a, b):
    c = compare(a, b)
    assert c.test == "numbers only" and not c.tested
    assert np.isnan(c.interval()).all() and np.isfinite(c.change_pct)
    assert verdict_words(*c.interval()) == "numbers only"


def test_bad_input_is_refused_with_what_was_expected():
    with pytest.raises(ValueError, match="paired by unit"):
        compare([0.1, 0.2, 0.3], [0.1, 0.2])
    with pytest.raises(ValueError, match="finite and positive"):
        compare([0.1, 0.0, 0.3], [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match=r"\(units,\) or \(units, seeds\)"):
        compare(np.ones((2, 2, 2)), np.ones((2, 2, 2)))


@pytest.mark.parametrize("low, high, kw, words", [
    (-30.0, -5.0, {}, "lower error"),
    (5.0, 30.0, {}, "higher error"),
    (-5.0, 5.0, {}, "no clear difference"),
    (-5.0, 1.5, {"no_harm_pct": 2.0}, "no worse than 2 %"),
    (-5.0, 2.5, {"no_harm_pct": 2.0}, "no clear difference"),
    (-30.0, -12.0, {"goal_pct": -10.0}, "goal met"),
    (-30.0, -5.0, {"goal_pct": -10.0}, "lower error, goal not met"),
])
def test_the_words_of_an_interval(low, high, kw, words):
    assert verdict_words(low, high, **kw) == words


def test_a_table_holds_its_family_at_the_bonferroni_level_and_names_a_direction_only_beyond_zero():
    rows = {}
    for i in range(40):
        shift = (-1.0, 0.0, 1.0)[i % 3]          # lower, equal, higher error
        a = np.exp(RNG.normal(shift, 0.1, 4)) * 0.05
        rows[f"r{i}"] = ("A against B", f"case {i}", compare(a, np.full(4, 0.05)))
    rows["only"] = ("A against B", "two recordings", compare([0.04, 0.05], [0.05, 0.05]))
    table = verdict_table(rows)
    assert table.attrs["m"] == 40 and table.attrs["level"] == pytest.approx(1 - 0.05 / 40)
    assert family_level(list(c for *_, c in rows.values())) == (pytest.approx(1 - 0.05 / 40), 40)
    tested = table.drop(index="only")
    directed = tested.verdict.isin(["lower error", "higher error"])
    excludes = (tested.high_pct < 0) | (tested.low_pct > 0)
    assert (directed == excludes).all() and directed.any() and not directed.all()
    assert table.loc["only", "verdict"] == "numbers only" and table.loc["only", "a_lower"] == "1 of 2"
    assert "simultaneous at 95 % over the table's 40 tested rows" in header(table)
    assert styled(table).caption == header(table)


def test_the_table_interval_equals_scipy_at_the_bonferroni_level():
    a, b = RNG.uniform(0.02, 0.06, 4), RNG.uniform(0.02, 0.06, 4)
    rows = {"x": ("A", "roll", compare(a, b)), "y": ("A", "pitch", compare(b, a))}
    table = verdict_table(rows)
    ref = stats.ttest_rel(np.log(a), np.log(b)).confidence_interval(1 - 0.05 / 2)
    assert (table.loc["x", "low_pct"], table.loc["x", "high_pct"]) == pytest.approx(_pct(ref), rel=1e-10)


def test_glue_table_names_each_value_by_row_and_column(monkeypatch):
    from danae_lite import book

    seen = {}
    monkeypatch.setattr(book, "glue", lambda name, value, display=False: seen.__setitem__(name, value))
    table = verdict_table({"roll_vs_kf": ("DANAE against the paper's KF", "roll",
                                          compare([0.04, 0.05, 0.045], [0.06, 0.07, 0.08]))})
    book.glue_table("cv", table)
    assert seen["cv_roll_vs_kf_verdict"] == table.loc["roll_vs_kf", "verdict"]
    assert seen["cv_roll_vs_kf_change_pct"] == pytest.approx(table.loc["roll_vs_kf", "change_pct"])
    assert isinstance(seen["cv_roll_vs_kf_n"], int) and seen["cv_roll_vs_kf_a_lower"] == "3 of 3"
    seen.clear()
    book.glue_table("ch9", table.loc["roll_vs_kf"])            # a Series: one name per label
    assert seen["ch9_verdict"] == table.loc["roll_vs_kf", "verdict"] and isinstance(seen["ch9_n"], int)
    book.glue_table("ch9", pd.DataFrame({"roll [rad]": [0.5]}, index=["all (preset)"]))
    assert seen["ch9_all_preset_roll_rad"] == 0.5                   # labels as identifiers


def test_a_row_may_carry_its_own_goal():
    rows = {"oxiod": ("a against b", "roll", compare([0.8, 0.85, 0.82, 0.84], [1.0, 1.0, 1.0, 1.0])),
            "broad": ("a against b", "total", compare([0.95, 0.96, 0.97, 0.95], [1.0, 1.0, 1.0, 1.0]))}
    table = verdict_table(rows, goal_pct=-10, goals={"broad": 0.0})
    assert table.loc["oxiod", "verdict"] == "goal met"      # about -17 %, interval below -10 %
    assert table.loc["broad", "verdict"] == "goal met"      # about -4 %, interval below 0
    assert verdict_table(rows, goal_pct=-10).loc["broad", "verdict"] == "lower error, goal not met"
    with pytest.raises(KeyError, match="nowhere"):
        verdict_table(rows, goals={"nowhere": 0.0})


def test_coverage_table_is_a_one_sample_t_of_coverage_minus_nominal():
    from danae_lite.evaluate.comparison import coverage_table

    cov = np.array([0.60, 0.55, 0.62, 0.58, 0.57])
    table = coverage_table({"in": ("68 % interval", "roll", cov, 0.68),
                            "few": ("68 % interval", "pitch", cov[:2], 0.68)})
    assert table.attrs["m"] == 1 and table.loc["few", "verdict"] == "numbers only"
    low, high = stats.ttest_1samp(100 * (cov - 0.68), 0.0).confidence_interval(0.95)
    assert table.loc["in", ["low_pts", "high_pts"]].tolist() == pytest.approx([low, high], rel=1e-10)
    assert table.loc["in", "mean_pct"] == pytest.approx(100 * cov.mean())
    assert table.loc["in", "verdict"] == "covers less"
    with pytest.raises(ValueError, match="row 'bad'"):
        coverage_table({"bad": ("68 % interval", "roll", [0.5, 1.2, 0.6], 0.68)})


def test_a_coverage_table_states_its_family_level_as_a_verdict_table_does():
    from danae_lite.evaluate.comparison import coverage_table

    cov = np.array([0.70, 0.66, 0.69, 0.71])
    table = coverage_table({f"r{i}": ("95 % interval", "roll", cov, 0.68) for i in range(4)})
    assert table.attrs["level"] == pytest.approx(1 - 0.05 / 4)
    low, high = stats.ttest_1samp(100 * (cov - 0.68), 0.0).confidence_interval(1 - 0.05 / 4)
    assert table.loc["r0", ["low_pts", "high_pts"]].tolist() == pytest.approx([low, high], rel=1e-10)
    assert styled(table).caption.endswith("over the table's 4 tested rows (Bonferroni: each at 98.75 %).")


@pytest.mark.parametrize("labels, key", [(("danae-multi[vqf]", "roll"), "danae_multi_vqf_roll"),
                                         (("multi users",), "multi_users"),
                                         (("the error as target", "pitch"), "the_error_as_target_pitch")])
def test_a_row_key_is_a_glue_name_stem(labels, key):
    from danae_lite.evaluate.comparison import row_key

    assert row_key(*labels) == key
