"""The pipeline wires KF -> DANAE -> metrics; check its bookkeeping on small simulated data."""
import json

import numpy as np
import pytest
import torch

from danae_lite.kalman.filter import run_kf
from danae_lite.evaluate import metrics
from danae_lite.paper import pipeline
from danae_lite.data import simulate
from danae_lite.angles import ANGLES
from danae_lite.research.baselines import Danae, PaperKF
from danae_lite.data.experiments import Experiment
from danae_lite.research.leaderboard import run_leaderboard
from danae_lite.data.recording import DataError
from danae_lite.danae.train_types import TrainConfig
from danae_lite.commands.reproduce import metrics_json, metrics_table, write_outputs


@pytest.fixture(scope="module")
def recs():
    return [simulate.simulate("handheld", duration=12.3, seed=s) for s in range(3)]


def test_filter_all_matches_run_kf(recs):
    est = pipeline.filter_all(recs)
    assert set(est) == {r.name for r in recs}
    np.testing.assert_array_equal(est[recs[0].name], run_kf(recs[0]).euler)


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


def test_reproduce_metrics_match_an_independent_computation(recs, tmp_path):
    """reproduce(): the JSON numbers are metric_table on the joined test samples, DANAE a mean over seeds."""
    test2 = simulate.simulate("handheld", duration=4.0, seed=7, name="sim-extra")
    exp = Experiment("oxiod", "simulated", recs[1:], [recs[0], test2], "tiny simulated data")
    cfg = TrainConfig(max_steps=5, num_threads=1)
    lines: list[str] = []
    rep = pipeline.reproduce(exp, angles=("roll", "yaw"), seeds=(0, 1), config=cfg, progress=False,
                             cache=tmp_path / "cache", log=lines.append)
    assert len(lines) == 1 + 2 * 2 and set(rep.study.results) == {(a, s) for a in ("roll", "yaw") for s in (0, 1)}
    out = metrics_json(rep)
    assert list(out) == ["experiment", "data", "train", "test", "seeds", "kf", "danae", "paper", "seconds"]
    assert out["test"] == [recs[0].name, "sim-extra"] and out["seeds"] == [0, 1]
    for angle, k in (("roll", 0), ("yaw", 2)):
        truth = np.concatenate([r.euler[:, k] for r in exp.test])
        kf = np.concatenate([rep.estimates[r.name][:, k] for r in exp.test])
        expected = metrics.metric_table(kf, truth, angles=(angle,))[angle]
        assert out["kf"][angle] == pytest.approx(expected.to_dict(), rel=1e-12)
        per_seed = [metrics.metric_table(np.concatenate([rep.study.predictions[(angle, s, "overlap")][r.name]
                                                         for r in exp.test]), truth, angles=(angle,))[angle]
                    for s in (0, 1)]
        dn = out["danae"][angle]
        for m in metrics.METRICS:
            assert dn[m] == pytest.approx(np.mean([t[m] for t in per_seed]), rel=1e-12)
        assert dn["rmse_std"] == pytest.approx(np.std([t["rmse"] for t in per_seed], ddof=1), rel=1e-12)
        assert out["paper"]["kf"][angle]["rmse"] == metrics.PAPER["oxiod"]["kf"]["rmse"][angle]
    assert out["kf"]["yaw"]["max_dev"] <= np.pi  # wrapped errors
    s = out["seconds"]
    assert list(s) == ["kf", "train", "total"] and s["total"] >= s["kf"] + s["train"]

    frame = metrics_table(rep)
    assert list(zip(frame.method, frame.angle)) == [(m, a) for m in ("kf", "danae") for a in ("roll", "yaw")]
    assert frame.set_index(["method", "angle"]).loc[("danae", "yaw"), "rmse"] == out["danae"]["yaw"]["rmse"]

    cmp = rep.comparison()
    assert cmp.loc[("DANAE", "rmse"), ("yaw", "ours")] == out["danae"]["yaw"]["rmse"]
    assert cmp.loc[("DANAE", "rmse"), ("yaw", "seed std")] == out["danae"]["yaw"]["rmse_std"]
    assert cmp.loc[("KF", "max_dev"), ("roll", "paper")] == metrics.PAPER["oxiod"]["kf"]["max_dev"]["roll"]
    red = rep.rmse_reduction()
    assert red.loc["ours", "roll"] == pytest.approx(100 * (1 - out["danae"]["roll"]["rmse"] / out["kf"]["roll"]["rmse"]))
    assert red.loc["paper", "mean"] == pytest.approx((65.4 + 45.0) / 2, abs=0.1)  # roll and yaw only
    np.testing.assert_array_equal(rep.test_series("yaw", seed=1).danae,
                                  np.concatenate([rep.study.predictions[("yaw", 1, "overlap")][r.name] for r in exp.test]))

    series = rep.figure_series(seed=1)
    assert list(series.columns) == ["time_s", "ground_truth", "kf", "danae"] and len(series) == len(recs[0])
    np.testing.assert_array_equal(series.danae, rep.study.predictions[("roll", 1, "overlap")][recs[0].name])

    written = write_outputs(rep, tmp_path / "out")
    assert [p.name for p in written] == ["metrics.json", "metrics.csv", "seed_table.csv",
                                        "figure1_roll.csv", "figure1_roll.png"]
    assert json.loads(written[0].read_text()) == out  # floats survive JSON exactly
    # a second run finds every network in the cache
    again = pipeline.reproduce(exp, angles=("roll", "yaw"), seeds=(0, 1), config=cfg, progress=False,
                               cache=tmp_path / "cache", log=None)
    assert again.danae == rep.danae


def test_reproduce_equals_the_leaderboards_paper_kf_and_danae(recs):
    """Table 1 of reproduce() (KF and DANAE per seed, then over seeds, on all and on clean samples)
    is, bit for bit, the leaderboard's paper_kf and danae configured as the paper (raw targets on
    every sample, recordings as loaded, every overlapping window), each path training its own networks."""
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "tiny simulated data")
    cfg = TrainConfig(max_steps=5, num_threads=1)
    rep = pipeline.reproduce(exp, angles=ANGLES, seeds=(0, 1), config=cfg, progress=False, log=None)
    paper = Danae(targets="raw", clean_targets=False, stride=1, val_stride=1)
    board = run_leaderboard(exp, methods=(), extra=[PaperKF(), paper], seeds=(0, 1), train_config=cfg,
                            progress=False, align=False)
    for samples in ("all", "clean"):
        kf, danae = rep.metrics_on(samples)
        rows = board.table[board.table.samples == samples].set_index(["method", "angle"])
        for a in ANGLES:
            assert kf[a] == {m: rows.loc[("paper_kf", a), m] for m in metrics.METRICS}
            assert danae[a] == {m: rows.loc[("danae", a), m] for m in (*metrics.METRICS, "rmse_std")}
    for s, seed in enumerate((0, 1)):
        for a in ANGLES:
            np.testing.assert_array_equal(rep.study.predictions[(a, seed, "overlap")][recs[0].name],
                                          board.predictions["danae"][recs[0].name][s][:, ANGLES.index(a)])
    assert rep.leaderboard.clean.keys() == board.clean.keys()


def test_reproduce_rejects_bad_arguments(recs):

    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "")
    cfg = TrainConfig(max_steps=5, num_threads=1)
    with pytest.raises(ValueError, match="seeds"):
        pipeline.reproduce(exp, angles=("roll",), seeds=(0, 0), config=cfg, log=None)
    with pytest.raises(ValueError, match="angles"):
        pipeline.reproduce(exp, angles=("heading",), seeds=(0,), config=cfg, log=None)
    short = Experiment("oxiod", "simulated", [recs[1].slice(0, 25)], recs[:1], "")
    with pytest.raises(DataError, match="training recording"):
        pipeline.reproduce(short, angles=("roll",), seeds=(0,), config=cfg, log=None)
