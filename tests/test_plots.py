"""The book's two palettes: one for methods, one for angles, never mixed."""
import matplotlib.colors as mcolors
import pytest

from danae_lite.research import baselines
from danae_lite import plots


def test_every_leaderboard_method_has_its_own_colour_and_none_is_an_angle_colour():
    names = [*baselines.METHODS, "danae-res"]
    colours = [mcolors.to_hex(plots.method_color(m)) for m in names]
    assert len(set(colours)) == len(names), dict(zip(names, colours))
    angles = {mcolors.to_hex(c) for c in plots.ANGLE_COLORS.values()}
    assert not angles & set(colours)
    assert plots.method_color("paper_kf") == plots.COLORS["kf"]
    assert plots.method_color("danae") == plots.COLORS["danae"]


def test_variants_take_their_family_colour_and_unknown_names_are_refused():
    assert plots.method_color("danae-res[vqf]") == plots.METHOD_COLORS["danae-res"]
    assert plots.method_color("danae[tuned_kf]") == plots.COLORS["danae"]
    with pytest.raises(KeyError, match="no colour for method 'kalman'"):
        plots.method_color("kalman")
