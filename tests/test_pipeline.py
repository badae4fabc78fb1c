"""The pipeline wires KF -> DANAE -> metrics; check its bookkeeping on small simulated data."""
import numpy as np
import pytest

from danae_lite import kalman, metrics, pipeline, simulate
from danae_lite.train import TrainConfig


@pytest.fixture(scope="module")
def recs():
    return [simulate.simulate("handheld", duration=12.3, seed=s) for s in range(3)]


def test_filter_all_matches_run_kf(recs):
    est = pipeline.filter_all(recs)
    assert set(est) == {r.name for r in recs}
    np.testing.assert_array_equal(est[recs[0].name], kalman.run_kf(recs[0]).euler)


def test_seed_study_tables(recs):
    train, test = recs[1:], recs[:1]
    est = pipeline.filter_all(recs)
    cfg = TrainConfig(max_steps=5, val_fraction=0.1, num_threads=1)
    study = pipeline.seed_study(train, test, est, angles=("roll",), seeds=(0, 1), config=cfg, progress=False)
    assert set(study.results) == {("roll", 0), ("roll", 1)}
    t = study.table
    assert len(t) == 2 * 3  # 2 seeds x (kf, overlap, tiles)
    n = len(test[0])
    assert set(t[t.method == "kf"].samples) == {n}
    assert set(t[t.method == "danae (tiles)"].samples) == {n - n % 20}
    # the KF row equals the metric table computed directly
    kf_rmse = metrics.metric_table(est[test[0].name][:, 0], test[0].euler[:, 0], angles=("roll",)).loc["rmse", "roll"]
    assert t[t.method == "kf"].rmse.iloc[0] == pytest.approx(kf_rmse)
    red = study.reduction()
    assert list(red.index) == [0, 1, "mean", "std"]
    row = t[(t.method == "danae (overlap)") & (t.seed == 1)].rmse.iloc[0]
    assert red.loc[1, "roll"] == pytest.approx(100 * (1 - row / kf_rmse))
    assert red.loc["mean", "roll"] == pytest.approx(red.loc[[0, 1], "roll"].mean())


def test_train_angle_cache_reuses_the_network(recs, tmp_path):
    est = pipeline.filter_all(recs)
    cfg = TrainConfig(max_steps=5, num_threads=1)
    first = pipeline.train_angle(recs[1:], est, "pitch", cfg, progress=False, cache=tmp_path)
    files = list(tmp_path.glob("danae-pitch-seed0-*.pt"))
    assert len(files) == 1
    again = pipeline.train_angle(recs[1:], est, "pitch", cfg, progress=False, cache=tmp_path)
    assert again.steps == first.steps and again.best_step == first.best_step
    assert again.history.equals(first.history)
    x = est[recs[0].name][:, 1]
    from danae_lite.train import predict
    np.testing.assert_array_equal(predict(again, x), predict(first, x))
    # another seed or other data is another entry
    pipeline.train_angle(recs[1:], est, "pitch", TrainConfig(max_steps=5, num_threads=1, seed=1), progress=False,
                         cache=tmp_path)
    pipeline.train_angle(recs[:2], est, "pitch", cfg, progress=False, cache=tmp_path)
    assert len(list(tmp_path.glob("*.pt"))) == 3
