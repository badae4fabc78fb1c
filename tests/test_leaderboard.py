"""The leaderboard end to end on a small simulated split: schema, files, numbers recomputed independently."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from danae_lite import cli
from danae_lite.evaluate import metrics
from danae_lite.research.baselines import METHODS
from danae_lite.data.experiments import Experiment
from danae_lite.research.leaderboard import CSV_COLUMNS, run_leaderboard
from danae_lite.data.simulate import simulate
from danae_lite.danae.train_types import TrainConfig

from conftest import stored_networks


@pytest.fixture(scope="module")
def board():
    recs = [simulate("handheld", duration=25.0, seed=s, name=f"sim-{s}") for s in range(3)]
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "test split")
    cfg = TrainConfig(max_steps=3, num_threads=1)
    return run_leaderboard(exp, methods=["paper_kf", "butterworth", "linear_map", "vqf", "riann", "danae"],
                           seeds=(0, 1), train_config=cfg, cache=None, progress=False)


def test_table_schema_and_order(board):
    t = board.table
    assert list(t.columns) == list(CSV_COLUMNS)
    assert set(t.samples) == {"all", "clean"}
    assert list(board.wide().index) == ["paper_kf", "butterworth", "linear_map", "vqf", "riann", "danae"]
    assert board.wide().loc["riann", "yaw"] != board.wide().loc["riann", "yaw"]  # NaN: no heading reference
    assert (t.n == len(board.experiment.test[0])).all()  # the simulator has no ground-truth glitches


def test_metrics_match_an_independent_computation(board):
    rec = board.experiment.test[0]
    (est,) = board.predictions["vqf"][rec.name]
    ref = metrics.metric_table(est, rec.euler)
    got = board.wide("rmse", "all").loc["vqf"]
    np.testing.assert_allclose(got.values, ref.loc["rmse"].values, rtol=1e-12)
    # DANAE: mean over the two seeds and the std of the RMSE
    per_seed = [metrics.metric_table(p, rec.euler).loc["rmse"] for p in board.predictions["danae"][rec.name]]
    row = board.table[(board.table.method == "danae") & (board.table.samples == "all") & (board.table.angle == "roll")]
    assert float(row.rmse.iloc[0]) == pytest.approx((per_seed[0]["roll"] + per_seed[1]["roll"]) / 2)
    assert float(row.rmse_std.iloc[0]) == pytest.approx(np.std([p["roll"] for p in per_seed], ddof=1))


def test_clean_samples_exclude_ground_truth_glitches():
    recs = [simulate("handheld", duration=25.0, seed=s, name=f"sim-{s}") for s in range(3)]
    q = recs[0].quat.copy()
    q[500] = [1.0, 0.0, 0.0, 0.0]  # a one-sample 180-degree spike in the test ground truth
    test = type(recs[0])(recs[0].name, recs[0].source, recs[0].fs, recs[0].gyro, recs[0].acc, recs[0].mag, q)
    exp = Experiment("oxiod", "simulated", recs[1:], [test], "spike")
    b = run_leaderboard(exp, methods=["paper_kf"], seeds=(0,), progress=False)
    all_, clean = b.wide("max_dev", "all").loc["paper_kf"], b.wide("max_dev", "clean").loc["paper_kf"]
    assert all_["roll"] > 1.0 > 0.3 > clean["roll"]
    assert int(b.table[b.table.samples == "clean"].n.iloc[0]) == len(test) - 1


def test_plot_draws_the_table_linear_in_method_colours_hatching_what_looks_ahead(board):
    import matplotlib.colors as mcolors
    import matplotlib.pyplot as plt

    from danae_lite.plots import method_color

    fig = board.plot("clean")
    w = board.wide("rmse", "clean").astype(float)
    axes = fig.axes
    assert [ax.get_title().split()[0] for ax in axes] == ["roll", "pitch", "yaw"]
    for ax, a in zip(axes, w.columns):
        assert ax.get_xscale() == "linear"
        assert "RMSE [rad]" in ax.get_xlabel()
        bars = ax.patches
        assert len(bars) == len(w)
        for bar, m in zip(bars, w.index):
            want = w.loc[m, a]
            assert bar.get_width() == pytest.approx(want if np.isfinite(want) else 0.0)
            assert mcolors.to_hex(bar.get_facecolor()) == method_color(m)
            assert bool(bar.get_hatch()) == (not board.methods[m].causal)
        texts = [t.get_text().strip() for t in ax.texts]
        assert texts == [f"{v:.3f}" if np.isfinite(v) else "no estimate" for v in w[a]]
        assert ax.get_xlim()[1] >= np.nanmax(w[a])
    # roll and pitch share one scale
    assert axes[0].get_xlim() == axes[1].get_xlim()
    plt.close(fig)


def test_write_produces_csv_json_png(board, tmp_path):
    paths = board.write(tmp_path)
    csv = pd.read_csv(paths["csv"])
    assert list(csv.columns) == list(CSV_COLUMNS) and len(csv) == 6 * 2 * 3
    data = json.loads(paths["json"].read_text())
    assert set(data) >= {"experiment", "data", "train", "test", "seeds", "alignment", "glitches", "methods", "seconds"}
    assert data["methods"]["butterworth"]["params"]["roll"] > 0
    assert data["methods"]["riann"]["clean"]["yaw"]["rmse"] is None
    assert paths["png"].stat().st_size > 10_000
    assert (tmp_path / "search_butterworth.csv").is_file()


def test_best_excludes_danae(board):
    assert board.best("roll") in set(METHODS) - {"danae"}


def test_unknown_method_is_rejected(board):
    with pytest.raises(ValueError, match="unknown method"):
        run_leaderboard(board.experiment, methods=["kalman9000"])


def test_cli_leaderboard_on_the_simulator(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DANAE_DATA", raising=False)
    monkeypatch.setenv("DANAE_CACHE", "off")
    code = cli.main(["leaderboard", "--fast", "--seeds", "0", "--max-steps", "2", "--threads", "1",
                     "--methods", "paper_kf", "moving_average", "danae", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "simulator stands in" in out and "RMSE [rad] on clean test samples" in out
    data = json.loads((tmp_path / "leaderboard.json").read_text())
    assert data["data"] == "simulated" and list(data["methods"]) == ["paper_kf", "moving_average", "danae"]


def test_cli_leaderboard_errors(tmp_path, capsys):
    code = cli.main(["leaderboard", "--methods", "kalman9000", "--out", str(tmp_path)])
    assert code == 2 and "invalid choice" in capsys.readouterr().err
    code = cli.main(["leaderboard", "--data-dir", str(tmp_path), "--out", str(tmp_path / "o")])
    assert code == 2 and "no oxiod/ folder" in capsys.readouterr().err


def test_the_papers_danae_lists_the_networks_its_fit_trains(tmp_path):
    """Danae.network_jobs: the jobs of its fit (one per angle and seed), so that a pooled
    leaderboard finds every one of its networks in the cache afterwards."""
    from danae_lite.danae import networks
    from danae_lite.research.baselines import Danae
    from danae_lite.research.leaderboard import _context
    from danae_lite.data.groundtruth import clean_mask

    recs = [simulate("handheld", duration=6.0, seed=s, name=f"j{s}") for s in range(3)]
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "jobs")
    ctx, _ = _context(exp, {r.name: clean_mask(r) for r in recs}, (0, 2), TrainConfig(max_steps=2, num_threads=1),
                      None, cache=tmp_path)
    jobs = Danae().network_jobs(ctx)
    assert [(j.tag, j.config.seed) for j in jobs] == [("danae-" + a, s) for a in ("roll", "pitch", "yaw") for s in (0, 2)]
    Danae().fit(ctx)
    stored = sorted(key for _, _, key in stored_networks(tmp_path))
    assert stored == sorted(networks.cache_key(j) for j in jobs)
    # validated on windows that tile the tails (the research networks' way) unless told otherwise
    assert {j.config.val_stride for j in jobs} == {20}
    assert {j.config.val_stride for j in Danae(val_stride=1).network_jobs(ctx)} == {1}


def test_seed_rmse_gives_each_seeds_rmse_and_their_mean_is_the_tables(board):
    rec = board.experiment.test[0]
    per_seed = [metrics.metric_table(p, rec.euler).loc["rmse", "pitch"] for p in board.predictions["danae"][rec.name]]
    np.testing.assert_allclose(board.seed_rmse("danae", "pitch", "all"), per_seed, rtol=1e-12)
    for m in ("danae", "vqf"):
        row = board.table[(board.table.method == m) & (board.table.samples == "clean") & (board.table.angle == "roll")]
        assert board.seed_rmse(m, "roll").mean() == pytest.approx(float(row.rmse.iloc[0]), rel=1e-12)
    assert len(board.seed_rmse("vqf", "roll")) == 1 and len(board.seed_rmse("danae", "roll")) == 2
    with pytest.raises(ValueError, match="choose 'clean' or 'all'"):
        board.seed_rmse("vqf", "roll", "some")


def test_recording_rmse_scores_each_test_recording_alone_per_seed(board):
    rec = board.experiment.test[0]
    got = board.recording_rmse("danae", "pitch", "all")
    assert got.shape == (1, 2)
    ref = [metrics.metric_table(p, rec.euler).loc["rmse", "pitch"] for p in board.predictions["danae"][rec.name]]
    np.testing.assert_allclose(got[0], ref, rtol=1e-12)
    # one test recording: the joined score of every seed is the recording's own
    np.testing.assert_allclose(board.seed_rmse("danae", "pitch", "all"), got[0], rtol=1e-12)
    with pytest.raises(ValueError, match="choose 'clean' or 'all'"):
        board.recording_rmse("danae", "pitch", "some")
