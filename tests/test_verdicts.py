"""The wording rule for differences over seeds or recordings (danae_lite.research.verdicts)."""
import pytest

from danae_lite.research.verdicts import MIN_DRAWS, difference_holds, difference_phrase


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
