"""The grid KF (many settings in one pass) against the one-setting KF and the SciPy-based scores.

Tolerance: both paths compute the same float64 operations in the same order; additions,
products and quotients are IEEE-exact in both, but NumPy's vectorised ``sin``, ``cos`` and
``atan2`` may differ from ``math``'s (the C library's) by an ulp (2e-16 rad) on some CPUs. The
filter is stable (each step shrinks an earlier difference), so over thousands of steps the
difference stays near 1e-14 rad; 1e-9 rad leaves a wide margin on any CPU and is still seven
orders of magnitude below the errors the grid search compares (1e-2 rad).
"""
import itertools

import numpy as np
import pytest

from danae_lite.research import baselines, methods
from danae_lite.kalman import grid
from danae_lite.kalman.filter import run_kf
from danae_lite.kalman.model import KFConfig
from danae_lite.data.alignment import FrameAlignment
from danae_lite.data.simulate import simulate

ATOL = 1e-9  # rad, see the module docstring


@pytest.fixture(scope="module")
def recs():
    return [simulate("handheld", duration=20.0, seed=s) for s in (3, 4)]


def _grid():
    return [baselines.TunedKF._config(qt, qb, qy)
            for qt, qb, qy in itertools.product((1e-8, 1e-4, 1.0), (0.0, 1e-10), (1e-6, 1e-2))]


@pytest.mark.parametrize("make", [
    _grid,
    lambda: [KFConfig(), KFConfig(Q=[1e-3, 0, 1e-3, 0, 1e-3, 0], x0=[0.1, 0, -0.2, 0, 1.0, 0.01])],
    lambda: [KFConfig.authors(), KFConfig.authors(Q=[1e-2] * 6)],
    lambda: [KFConfig(init_from_truth=True, wrap_yaw_innovation=True, P0=[5.0, 1e-3] * 3)],
], ids=["tuned-grid", "x0-and-Q", "authors-dt", "from-truth"])
def test_grid_equals_one_setting_at_a_time(recs, make):
    configs = make()
    rec = recs[0]
    got = grid.run_kf_grid(rec, configs)
    assert got.shape == (len(configs), len(rec), 3)
    for k, cfg in enumerate(configs):
        np.testing.assert_allclose(got[k], run_kf(rec, cfg).euler, rtol=0, atol=ATOL)


def test_grid_rejects_settings_it_cannot_share(recs):
    with pytest.raises(ValueError, match="empty"):
        grid.run_kf_grid(recs[0], [])
    with pytest.raises(ValueError, match=r"configs\[1\]\.wrap_yaw_innovation"):
        grid.run_kf_grid(recs[0], [KFConfig(), KFConfig(wrap_yaw_innovation=True)])
    full = np.eye(6)
    full[0, 2] = full[2, 0] = 0.1
    with pytest.raises(ValueError, match=r"configs\[0\] is not block-diagonal"):
        grid.run_kf_grid(recs[0], [KFConfig(Q=full)])


def test_scores_are_the_objectives_of_each_setting(recs):
    configs = _grid()
    clean = {r.name: np.arange(len(r)) % 7 != 3 for r in recs}
    align = FrameAlignment.identity()
    north = 0.4
    scores = grid.score_kf_grid(configs, recs, clean, north_yaw=north)
    ctx = baselines.Context(train=list(recs), clean=clean, alignment=align)
    for k, cfg in enumerate(configs):
        est = {}
        for r in recs:
            e = run_kf(r, cfg).euler.copy()
            e[:, 2] += north
            est[r.name] = align.to_truth_frame(e)
        # SciPy's rotations and the package's RMSE of wrapped errors, one setting at a time
        assert scores.total[k] == pytest.approx(methods.total_error_rmse(est, recs, clean), rel=1e-9)
        np.testing.assert_allclose(scores.per_angle[k], methods.train_objective(est, ctx, (0, 1, 2)), rtol=1e-9)
    # several passes (a small memory cap) score exactly what one pass does
    small = grid.score_kf_grid(configs, recs, clean, north_yaw=north, max_bytes=24 * len(recs[0]) * 5)
    np.testing.assert_array_equal(small.total, scores.total)
    np.testing.assert_array_equal(small.per_angle, scores.per_angle)


def test_scores_name_a_bad_clean_mask(recs):
    with pytest.raises(ValueError, match=r"clean\['.*'\] has shape \(3,\)"):
        grid.score_kf_grid(_grid()[:1], recs[:1], {recs[0].name: np.ones(3, bool)})
    with pytest.raises(ValueError, match="no clean sample"):
        grid.score_kf_grid(_grid()[:1], recs[:1], {recs[0].name: np.zeros(len(recs[0]), bool)})


def test_the_tuned_kf_search_is_scored_once_and_found_again(recs, monkeypatch):
    # TunedKF.fit keeps its grid's score table in baselines.searches: a second fit on the same
    # training data scores nothing and chooses the same Q from the same table
    clean = {r.name: np.ones(len(r), bool) for r in recs}
    ctx = baselines.Context(train=list(recs), clean=clean, alignment=FrameAlignment.identity())
    baselines.searches.clear()
    first = baselines.TunedKF().fit(ctx)
    calls = []
    score = grid.score_kf_grid
    monkeypatch.setattr(grid, "score_kf_grid", lambda *a, **k: calls.append(1) or score(*a, **k))
    again = baselines.TunedKF().fit(ctx)
    assert calls == [] and again.params == first.params
    assert again.search.equals(first.search)
    other = baselines.Context(train=list(recs[:1]), clean=clean_of(recs[:1]), alignment=FrameAlignment.identity())
    baselines.TunedKF().fit(other)                       # other training data: scored again
    assert calls == [1]


def clean_of(recs):
    return {r.name: np.ones(len(r), bool) for r in recs}
