"""DANAE-res: residual target, level augmentation, validation gate, streaming equals batch."""
from __future__ import annotations

import numpy as np
import pytest

from danae_lite.angles import wrap
from danae_lite.data.experiments import Experiment
from danae_lite.research.danae_res import (GATE_GAINS, DanaeRes, DenoiserStream,
                                           filter_error, level_offsets, shift_levels)
from danae_lite.research.features import multi_input, run_network, to_circle
from danae_lite.research.leaderboard import run_leaderboard
from danae_lite.data.simulate import simulate
from danae_lite.danae.train_types import TrainConfig
from danae_lite.research.variants import validation_block

from conftest import network_items


def test_filter_error_wraps_yaw_only():
    est = np.array([[0.1, 0.2, 3.1], [0.0, -0.1, -3.1]])
    truth = np.array([[0.3, 0.1, -3.1], [0.0, 0.0, 3.1]])
    d = filter_error(est, truth)
    np.testing.assert_allclose(d[:, :2], truth[:, :2] - est[:, :2])
    np.testing.assert_allclose(d[:, 2], [2 * np.pi - 6.2, 6.2 - 2 * np.pi], atol=1e-12)


def test_level_offsets_are_bounded_slow_and_seeded():
    a = level_offsets(6000, 100.0, 0.3, np.random.default_rng(4))
    b = level_offsets(6000, 100.0, 0.3, np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)
    assert np.abs(a).max() <= 0.3 + 1e-12 and np.abs(a).max() > 0.05
    # the fastest sinusoid (20 s) of amplitude 0.1 changes by at most 2 pi 0.1 / 20 rad/s:
    # over the causal network's 31-sample receptive field at 100 Hz, 3 x 0.01 rad at most
    step = np.abs(np.diff(a, axis=0)).max()
    assert step <= 3 * 2 * np.pi * 0.1 / 20 / 100 + 1e-12


def test_shift_levels_moves_every_angle_channel_like_the_angles_themselves():
    rec = simulate("handheld", duration=3.0, seed=1)
    est = rec.euler + 0.02
    off = np.column_stack([np.full(len(rec), 0.1), np.full(len(rec), -0.2), np.full(len(rec), 0.7)])
    shifted = shift_levels(multi_input(rec, est, 0.0), off, "multi")
    # the filter's angles and the magnetic heading as if the device were turned by the offsets
    direct = to_circle(est + off)
    np.testing.assert_allclose(shifted[:, :4], direct, atol=1e-12)
    x = multi_input(rec, est, 0.0)
    np.testing.assert_allclose(shifted[:, 4:6], x[:, 4:6] + off[:, :2])
    heading = np.arctan2(x[:, 6], x[:, 7]) + 0.7
    np.testing.assert_allclose(shifted[:, 6:8], np.c_[np.sin(heading), np.cos(heading)], atol=1e-12)
    np.testing.assert_array_equal(shifted[:, 8:], x[:, 8:])  # rates carry no level
    np.testing.assert_allclose(shift_levels(to_circle(est), off, "angles"), direct, atol=1e-12)


@pytest.fixture(scope="module")
def board():
    recs = [simulate("handheld", duration=20.0, seed=s, name=f"res-{s}") for s in range(3)]
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "denoiser")
    cfg = TrainConfig(max_steps=20, num_threads=1)
    extra = [DanaeRes("vqf", hidden=16), DanaeRes("paper_kf", inputs="angles", arch="paper", window=20,
                                                  loss_start=0, name="res-paper")]
    return run_leaderboard(exp, methods=["paper_kf", "vqf"], seeds=(0, 1), train_config=cfg, progress=False,
                           extra=extra)


def _gate_rmse(m: DanaeRes, pairs) -> np.ndarray:
    """RMSE per gain (rows) and angle of filter + gain x correction, recomputed here."""
    sq, n = np.zeros((len(GATE_GAINS), 3)), 0
    for res, r, where in pairs:
        est = m.base.predict(r)[0]
        corr = run_network(res, m.features(r, est))
        ok = where & m.ctx.clean[r.name]
        for i, g in enumerate(GATE_GAINS):
            d = r.euler - (est + g * corr)
            d[:, 2] = wrap(d[:, 2])
            sq[i] += (d[ok] ** 2).sum(0)
        n += ok.sum()
    return np.sqrt(sq / n)


def test_gate_is_chosen_on_training_recordings_the_scoring_network_never_saw(board):
    m = board.methods["danae-res[vqf]"]
    train = {r.name: r for r in m.ctx.train}
    assert m.gate_data == "held-out training recordings"
    assert m.params["gate_folds"] == [[n] for n in train]  # two recordings: each held out once
    # the gate's networks are trained with the first seed only; its gains serve every seed
    assert set(m.gate_results) == {(0, 0), (1, 0)}
    assert m.results[1].config.val_stride == 128 - 30  # the research budget (features.research_config)
    np.testing.assert_array_equal(m.gains[1], m.gains[0])
    assert m.params["gate_rmse_rad"][1] == m.params["gate_rmse_rad"][0]
    for seed in (0,):
        assert set(m.gains[seed]) <= set(GATE_GAINS)
        pairs = []
        for k, (held,) in enumerate(m.params["gate_folds"]):
            res = m.gate_results[(k, seed)]
            # the inner network trained on the other recording only
            other = next(r for n, r in train.items() if n != held)
            assert res.n_train_windows + res.n_val_windows < len(other)
            pairs.append((res, train[held], np.ones(len(train[held]), bool)))
        val = _gate_rmse(m, pairs)
        np.testing.assert_allclose(val.T, np.array([m.params["gate_rmse_rad"][seed][a]
                                                    for a in ("roll", "pitch", "yaw")]), rtol=1e-9)
        np.testing.assert_array_equal(m.gains[seed], np.array(GATE_GAINS)[val.argmin(0)])
        assert (val.min(0) <= val[0] + 1e-15).all()  # never worse than the filter where it was chosen


def test_one_training_recording_gates_on_its_validation_tail():
    recs = [simulate("handheld", duration=15.0, seed=s, name=f"one-{s}") for s in range(2)]
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "one")
    m = DanaeRes("paper_kf", hidden=16)
    run_leaderboard(exp, methods=(), seeds=(0,), train_config=TrainConfig(max_steps=10, num_threads=1),
                    progress=False, extra=[m])
    assert m.gate_data == "validation tails" and m.gate_results == {}
    r = m.ctx.train[0]
    tail = np.zeros(len(r), bool)
    tail[validation_block(len(r), m.config(0))] = True
    val = _gate_rmse(m, [(m.results[0], r, tail)])
    np.testing.assert_array_equal(m.gains[0], np.array(GATE_GAINS)[val.argmin(0)])


def test_gain_zero_is_the_filter_exactly_and_predictions_are_seeded(board):
    m = board.methods["danae-res[vqf]"]
    rec = board.alignment.apply(board.experiment.test[0])
    est = m.base.predict(rec)[0]
    saved = {s: g.copy() for s, g in m.gains.items()}
    try:
        m.gains = {s: np.zeros(3) for s in saved}
        for out in m.predict(rec):
            np.testing.assert_allclose(out, np.column_stack([est[:, :2], wrap(est[:, 2])]), atol=1e-15)
    finally:
        m.gains = saved
    assert m.causal  # a causal network on a causal filter
    assert not board.methods["res-paper"].causal
    # the seeds' networks differ, and a refit with the same seed gives the same numbers
    p = m.predict(rec)
    assert not np.allclose(m._network_output(0, m.features(rec, est)), m._network_output(1, m.features(rec, est)))
    again = DanaeRes("vqf", hidden=16).fit(m.ctx)
    np.testing.assert_array_equal(again.predict(rec)[0], p[0])


def test_network_buffers_map_raw_features_to_a_correction_in_rad(board):
    m = board.methods["danae-res[vqf]"]
    norm = m.results[0].model.normalization()
    np.testing.assert_allclose(norm["in_mean"], m.scaling["in_mean"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(norm["out_mean"], 0.0)  # targets scaled, not centred
    rms = np.sqrt(np.mean(np.concatenate(
        [filter_error(m.base.predict(r)[0], r.euler)[m.ctx.clean[r.name] & _fit_rows(m, r)] for r in m.ctx.train]) ** 2,
        axis=0))
    np.testing.assert_allclose(norm["out_std"], rms, rtol=1e-5)


def _fit_rows(m: DanaeRes, r) -> np.ndarray:
    keep = np.ones(len(r), bool)
    keep[validation_block(len(r), m.config(0))] = False
    return keep


def test_streaming_equals_batch(board):
    m = board.methods["danae-res[vqf]"]
    rec = board.alignment.apply(board.experiment.test[0]).slice(0, 400)
    est = m.base.predict(rec)[0]
    x = m.features(rec, est)
    stream = DenoiserStream(m, seed=1)
    online = np.array([stream.step(x[i], est[i]) for i in range(len(rec))])
    batch = m._output(est, m._network_output(1, x), m.gains[1])
    np.testing.assert_allclose(online, batch, atol=2e-6)
    with pytest.raises(ValueError, match="only the causal network streams"):
        DenoiserStream(board.methods["res-paper"])


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="inputs='raw'"):
        DanaeRes("vqf", inputs="raw")
    with pytest.raises(ValueError, match="offset_rad must be >= 0"):
        DanaeRes("vqf", offset_rad=-0.1)
    with pytest.raises(ValueError, match="corrects a filter"):
        DanaeRes("danae")
    with pytest.raises(ValueError, match="gate_folds must be an integer >= 2"):
        DanaeRes("vqf", gate_folds=1)


def test_cli_runs_the_recommended_denoiser_by_name(tmp_path, capsys, monkeypatch):
    import json

    from danae_lite import cli

    monkeypatch.delenv("DANAE_DATA", raising=False)
    monkeypatch.delenv("DANAE_CACHE", raising=False)
    code = cli.main(["leaderboard", "--fast", "--seeds", "0", "--max-steps", "2", "--threads", "1",
                     "--methods", "vqf", "danae-res[vqf]", "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().err
    data = json.loads((tmp_path / "leaderboard.json").read_text())
    assert list(data["methods"]) == ["vqf", "danae-res[vqf]"]
    rows = [r for r in (tmp_path / "leaderboard.csv").read_text().splitlines() if "danae-res[vqf]" in r]
    assert rows and all(",True," in r for r in rows)  # causal: a causal net behind a causal filter
    code = cli.main(["leaderboard", "--methods", "danae-res[danae]", "--out", str(tmp_path / "x")])
    assert code == 2 and "invalid choice" in capsys.readouterr().err


def test_a_filter_without_yaw_is_corrected_on_roll_and_pitch_only():
    # RIANN estimates no heading (NaN yaw): DANAE-res keeps that NaN, corrects the rest
    recs = [simulate("handheld", duration=15.0, seed=s, name=f"ri-{s}") for s in range(3)]
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "riann")
    m = DanaeRes("riann", hidden=16)
    board = run_leaderboard(exp, methods=["riann"], seeds=(0,), progress=False, extra=[m],
                            train_config=TrainConfig(max_steps=10, num_threads=1))
    np.testing.assert_array_equal(m.missing, [False, False, True])
    assert m.params["missing"] == ["yaw"] and m.gains[0][2] == 0.0
    test = board.alignment.apply(exp.test[0])
    est, out = m.base.predict(test)[0], m.predict(test)[0]
    assert np.isnan(est[:, 2]).all() and np.isnan(out[:, 2]).all()
    assert np.isfinite(out[:, :2]).all()
    # the filter's yaw channels are a constant (0 rad) and carry nothing
    x = m.features(test, est)
    np.testing.assert_allclose(x[:, 2:4], np.tile([0.0, 1.0], (len(test), 1)))
    # roll and pitch: filter + gain x the network's correction, as for any filter
    corr = run_network(m.results[0], x)
    np.testing.assert_allclose(out[:, :2], est[:, :2] + m.gains[0][:2] * corr[:, :2], atol=1e-12)
    w = board.wide("rmse", "clean")
    assert np.isnan(w.loc["danae-res[riann]", "yaw"]) and np.isfinite(w.loc["danae-res[riann]", "roll"])


def test_an_estimate_missing_on_some_samples_only_is_refused_naming_the_recording():
    m = DanaeRes("vqf")
    m.name = "danae-res[vqf]"
    est = {"good": np.zeros((5, 3)), "bad": np.zeros((5, 3))}
    est["bad"][2, 1] = np.nan
    with pytest.raises(ValueError, match=r"pitch on training recording 'bad'.*some samples only"):
        m._missing_angles(est)
    est["bad"][:, 1] = 0.0
    est["good"][:, 2] = est["bad"][:, 2] = np.nan
    np.testing.assert_array_equal(m._missing_angles(est), [False, False, True])
    est["good"][:, 2] = 0.0   # yaw on one recording, none on the other: refused
    with pytest.raises(ValueError, match="yaw on training recording 'bad'"):
        m._missing_angles(est)


def test_a_pooled_leaderboard_trains_first_what_each_fit_then_finds(board, tmp_path, monkeypatch):
    """With a cache and two workers, the leaderboard trains every method's networks together
    first (Method.network_jobs, networks.pretrain); the fits find them all and the predictions
    are those of the leaderboard without cache or workers, to the bit (one torch thread in
    both: the same float32 operations in the same order)."""
    from danae_lite.research import leaderboard

    pooled = []
    pretrain = leaderboard.pretrain
    monkeypatch.setattr(leaderboard, "pretrain", lambda js, **kw: pooled.append(pretrain(js, **kw)) or pooled[-1])
    exp = board.experiment
    extra = [DanaeRes("vqf", hidden=16), DanaeRes("paper_kf", inputs="angles", arch="paper", window=20,
                                                  loss_start=0, name="res-paper")]
    again = run_leaderboard(exp, methods=["paper_kf", "vqf"], seeds=(0, 1), train_config=board.train_config,
                            progress=False, extra=extra, cache=tmp_path, jobs=2)
    # per method: the prediction network of each of 2 seeds, the gate's 2 inner-fold networks
    assert pooled == [8] and len(network_items(tmp_path)) == 8
    for name in ("danae-res[vqf]", "res-paper"):
        for rec in exp.test:
            for a, b in zip(again.predictions[name][rec.name], board.predictions[name][rec.name]):
                np.testing.assert_array_equal(a, b)
