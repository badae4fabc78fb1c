"""DANAE variants: circle channels, multi-input features, fitting through the leaderboard, causality."""
from __future__ import annotations

import numpy as np
import pytest

from danae_lite.kalman.model import accel_tilt, euler_rates, mag_heading
from danae_lite.data.experiments import Experiment
from danae_lite.research.features import (MULTI_CHANNELS, from_circle, multi_input,
                                          to_circle)
from danae_lite.research.leaderboard import run_leaderboard
from danae_lite.research.methods import total_error_rmse
from danae_lite.data.simulate import simulate
from danae_lite.research.streaming import predict_causal
from danae_lite.danae.train_types import TrainConfig
from danae_lite.research.variants import DanaeOn, Selected, validation_block


def test_circle_round_trip_and_nan_yaw():
    e = np.array([[0.1, -0.2, 3.1], [0.0, 0.0, -3.1], [0.3, 0.1, np.nan]])
    c = to_circle(e)
    np.testing.assert_allclose(c[:2, 2:], np.c_[np.sin(e[:2, 2]), np.cos(e[:2, 2])])
    np.testing.assert_allclose(from_circle(c[:2]), e[:2])
    np.testing.assert_allclose(c[2, 2:], [0.0, 0.0])
    # scaled (sin, cos) vectors give the same yaw
    np.testing.assert_allclose(from_circle(c[:2] * [1, 1, 3, 3])[:, 2], e[:2, 2])


def test_multi_input_channels_by_hand():
    rec = simulate("handheld", duration=5.0, seed=0)
    est = rec.euler + 0.01
    x = multi_input(rec, est, north_yaw=0.25)
    assert x.shape == (len(rec), len(MULTI_CHANNELS))
    np.testing.assert_allclose(x[:, 4:6], accel_tilt(rec.acc))
    heading = mag_heading(rec.mag, est[:, 0], est[:, 1]) + 0.25
    np.testing.assert_allclose(x[:, 6:8], np.c_[np.sin(heading), np.cos(heading)])
    np.testing.assert_allclose(x[:, 8:], euler_rates(rec.gyro, est[:, 0], est[:, 1]))


@pytest.fixture(scope="module")
def board():
    recs = [simulate("handheld", duration=20.0, seed=s, name=f"sim-{s}") for s in range(3)]
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "variants")
    cfg = TrainConfig(max_steps=5, num_threads=1)
    extra = [DanaeOn("vqf"), DanaeOn("paper_kf", inputs="multi"),
             DanaeOn("vqf", inputs="multi", arch="causal", hidden=16, window=40, loss_start=30)]
    return run_leaderboard(exp, methods=["paper_kf", "vqf"], seeds=(0,), train_config=cfg, progress=False,
                           extra=extra)


def test_variants_are_evaluated_like_every_method(board):
    w = board.wide("rmse", "clean")
    assert list(w.index) == ["paper_kf", "vqf", "danae[vqf]", "danae-multi[paper_kf]", "danae-multi-causal[vqf]"]
    assert np.isfinite(w.values).all()
    assert board.best("roll") in ("paper_kf", "vqf")
    assert board.methods["danae-multi-causal[vqf]"].params["loss_start"] == 30


def test_causal_variant_never_reads_future_samples(board):
    m = board.methods["danae-multi-causal[vqf]"]
    rec = board.experiment.test[0]
    aligned = board.alignment.apply(rec)

    x = m.features(aligned)
    res = m.results[0]
    y = predict_causal(res, x)
    x2 = x.copy()
    x2[300:] += np.random.default_rng(0).normal(0, 1.0, x2[300:].shape)
    y2 = predict_causal(res, x2)
    np.testing.assert_array_equal(y[:300], y2[:300])
    assert not np.allclose(y[300:], y2[300:])


def test_duplicate_names_and_danae_source_are_rejected(board):
    with pytest.raises(ValueError, match="unique"):
        run_leaderboard(board.experiment, methods=["paper_kf"], extra=[DanaeOn("paper_kf", name="paper_kf")],
                        progress=False)
    with pytest.raises(ValueError, match="inputs="):
        DanaeOn("vqf", inputs="everything")


def test_selected_variant_is_chosen_on_validation_blocks_only():
    recs = [simulate("handheld", duration=12.0, seed=s, name=f"sel-{s}") for s in range(3)]
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "selection")
    cfg = TrainConfig(max_steps=5, num_threads=1)
    sel = Selected([DanaeOn("paper_kf", name="a"), DanaeOn("paper_kf", name="b", window=40)])
    board = run_leaderboard(exp, methods=(), extra=[sel], seeds=(0,), train_config=cfg, progress=False)
    scores = sel.params["validation_total_rmse_rad"]
    assert set(scores) == {"a", "b"} and sel.params["chosen"] == min(scores, key=scores.get)
    # the score is the total error on the held-out tail of each training recording, recomputed here
    cand = {c.name: c for c in sel.candidates}["b"]
    est, masks = {}, {}
    for r in sel.ctx.train:
        m = np.zeros(len(r), bool)
        m[validation_block(len(r), cand.config(0))] = True
        est[r.name], masks[r.name] = cand.predict(r)[0], m & board.clean[r.name]
    assert scores["b"] == pytest.approx(total_error_rmse(est, sel.ctx.train, masks))
    assert not (set(sel.ctx.clean) & {r.name for r in exp.test})  # no test recording in the fitting context
    chosen = {c.name: c for c in sel.candidates}[sel.params["chosen"]]
    np.testing.assert_array_equal(board.predictions["danae-selected"][recs[0].name][0],
                                  chosen.predict(sel.ctx.alignment.apply(recs[0]))[0])


def test_research_budget_caps_steps_and_tiles_validation():
    """Part III's networks validate on windows window - loss_start apart; DANAE-res's
    (capped) score at most RESEARCH_SCORED_SAMPLES window samples, batch x (window -
    loss_start) per step (a smaller step cap, fast mode's, wins), with RESEARCH_CHECKS checks;
    the variants keep the context's epoch. The step counts are worked out by hand."""
    from danae_lite.research.danae_res import DanaeRes
    from danae_lite.research.features import (CAUSAL_SETTINGS, RES_SETTINGS,
                                              RESEARCH_CHECKS, RESEARCH_SCORED_SAMPLES,
                                              research_config)

    assert (RESEARCH_SCORED_SAMPLES, RESEARCH_CHECKS) == (1500 * 16 * 34, 5)
    # paper network: 20 scored positions per window, 816,000 / (16 * 20) = 2550 steps
    capped = research_config(TrainConfig(epochs=1), 2, capped=True, normalize="standard")
    assert (capped.max_steps, capped.val_every, capped.val_stride, capped.seed) == (2550, 510, 20, 2)
    causal = research_config(TrainConfig(), 0, capped=True, **CAUSAL_SETTINGS)
    assert (causal.max_steps, causal.val_every, causal.val_stride, causal.window) == (1500, 300, 34, 64)
    # DANAE-res: 98 scored positions, 816,000 / (16 * 98) = 520.4 -> 520 steps, ceil(520 / 5) = 104
    res = research_config(TrainConfig(), 0, capped=True, **RES_SETTINGS)
    assert (res.max_steps, res.val_every, res.val_stride, res.window) == (520, 104, 98, 128)
    fast = research_config(TrainConfig(max_steps=40), 0, capped=True)
    assert (fast.max_steps, fast.val_every) == (40, 40)
    free = research_config(TrainConfig(epochs=1), 0, capped=False)
    assert (free.max_steps, free.val_every, free.val_stride) == (None, None, 20)
    for method, steps in ((DanaeOn("vqf"), None), (DanaeRes("vqf"), 520)):
        method.ctx = type("Ctx", (), {"train_config": TrainConfig(epochs=1)})()
        assert method.config(0).max_steps == steps


def test_generalisation_compares_danae_with_its_filter_seed_by_seed():
    from danae_lite.research.variants import generalisation

    recs = [simulate("handheld", duration=12.0, seed=s, name=f"g-{s}") for s in range(2)]
    scen = {"a": Experiment("oxiod", "simulated", recs[1:], recs[:1], "a")}
    gen = generalisation(scen, sources=("paper_kf",), seeds=(0, 1),
                         train_config=TrainConfig(max_steps=2, num_threads=1))
    assert len(gen) == 3
    for _, row in gen.iterrows():   # one test recording, the filter deterministic: a t over the seeds
        c = row.comparison
        assert (c.test, c.n) == ("one-sample t over seeds", 2)
        # DANAE's geometric mean over seeds, exp(mean log ratio) * filter, is at most their mean
        geometric = np.exp(c.mean) * row.filter_rmse
        assert geometric <= row.danae_rmse * (1 + 1e-12)
        assert geometric == pytest.approx(row.danae_rmse, rel=0.25)
