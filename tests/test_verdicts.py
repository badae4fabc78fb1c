"""The wording rule for differences over seeds or recordings (danae_lite.research.verdicts)."""
import pytest

from danae_lite.research.verdicts import (MIN_DRAWS, difference_holds,
                                          difference_phrase, group_by_verdict,
                                          join_grouped, join_labels)


def test_a_difference_larger_than_its_spread_holds_in_either_direction():
    assert difference_holds([0.010, 0.012, 0.011])
    assert difference_phrase([0.010, 0.012, 0.011], above="behind", below="ahead") == (
        "behind (by 0.0110 rad, more than the 0.0020 rad range of its 3 seeds)")
    assert difference_phrase([-0.010, -0.012, -0.011], above="behind", below="ahead").startswith(
        "ahead (by 0.0110 rad")


def test_a_difference_within_its_spread_says_so_and_states_the_rule():
    phrase = difference_phrase([0.010, -0.002, 0.001], above="behind", below="ahead",
                               draws="recordings", unit="°", digits=3)
    assert not difference_holds([0.010, -0.002, 0.001])
    assert phrase == ("within the spread of its 3 recordings (+0.003 ° against a range of "
                      "0.012 °; a difference holds when its mean exceeds that range over at "
                      f"least {MIN_DRAWS} recordings)")


def test_fewer_draws_than_the_rule_asks_never_hold():
    assert not difference_holds([0.5, 0.5])          # range 0, but only two seeds
    assert difference_phrase([0.5], above="a", below="b").startswith("within the spread of its 1 seed (")


def test_bad_differences_are_refused_with_what_was_expected():
    with pytest.raises(ValueError, match="1-D sequence of finite numbers"):
        difference_holds([[0.1, 0.2]])
    with pytest.raises(ValueError, match="finite"):
        difference_holds([0.1, float("nan"), 0.2])


def test_group_by_verdict_sorts_labels_by_the_rule_in_their_order():
    diffs = {"helps": [0.30, 0.31, 0.29], "costs": [-0.5, -0.4, -0.45], "noisy": [0.3, -0.2, 0.1],
             "two draws": [0.3, 0.3], "also helps": [1.0, 1.0, 1.0]}
    assert group_by_verdict(diffs) == {"above": ["helps", "also helps"], "below": ["costs"],
                                       "within": ["noisy", "two draws"]}
    assert group_by_verdict({}) == {"above": [], "below": [], "within": []}


def test_join_labels_writes_an_english_list():
    assert join_labels([]) == "none" and join_labels([], empty="no filter") == "no filter"
    assert join_labels(["a"]) == "a"
    assert join_labels(["a", "b"]) == "a and b"
    assert join_labels(["a", "b", "c"]) == "a, b and c"


def test_join_grouped_names_each_subject_once_with_its_details():
    pairs = [("VQF", "roll"), ("Fusion", "roll"), ("VQF", "pitch")]
    assert join_grouped(pairs) == "VQF (roll, pitch) and Fusion (roll)"
    assert join_grouped([], empty="no filter") == "no filter"
    # group_by_verdict keeps tuple labels, so the two compose
    by = group_by_verdict({("VQF", "roll"): [0.3, 0.31, 0.29], ("VQF", "pitch"): [0.2, 0.21, 0.2]})
    assert join_grouped(by["above"]) == "VQF (roll, pitch)"
