"""DANAE-res with a per-sample fallback and an error bar (danae_lite.research.danae_safe)."""
from __future__ import annotations

import numpy as np
import pytest

from danae_lite.data.experiments import Experiment
from danae_lite.data.simulate import simulate
from danae_lite.danae.train_types import TrainConfig
from danae_lite.research import crossval
from danae_lite.research.danae_res import filter_error
from danae_lite.research.danae_safe import (POLICIES, RISK_BINS, DanaeSafe, SafeStream,
                                            alpha_of, calibrate_angle, ema)
from danae_lite.research.leaderboard import run_leaderboard
from danae_lite.research.baselines import is_method_name
from danae_lite.research.registry import make_method

from conftest import stored_networks

# E[log chi^2_1] = psi(1/2) + log 2 = -gamma - log 2 (closed form)
E_LOG_CHI2_1 = -np.euler_gamma - np.log(2.0)


def test_ema_is_the_recursion_started_at_the_first_sample():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(500, 3))
    alpha = 0.07
    y = np.empty_like(x)
    y[0] = x[0]
    for t in range(1, len(x)):
        y[t] = y[t - 1] + alpha * (x[t] - y[t - 1])
    np.testing.assert_allclose(ema(x, alpha), y, rtol=0, atol=1e-12)  # float64, same operations up to order
    assert alpha_of(100.0, 1.0) == pytest.approx(0.01)
    assert alpha_of(0.5, 1.0) == 1.0  # never more than the newest sample


def test_risk_model_recovers_a_known_log_variance():
    """Errors N(0, exp(b0 + b1 u)): least squares of log e^2 on (1, u) has slope b1 and intercept
    b0 + E[log chi^2_1] (closed form); 200,000 samples put both within 0.02."""
    rng = np.random.default_rng(1)
    n = 200_000
    u = rng.uniform(-2, 2, n)
    design = np.column_stack([np.ones(n), u, np.zeros(n)])
    err = np.exp(0.5 * (-7.0 + 0.8 * u)) * rng.normal(size=n)
    c = calibrate_angle(design, err, np.zeros(n), 1.0, "none")
    assert c.coef[1] == pytest.approx(0.8, abs=0.02)
    assert c.coef[0] == pytest.approx(-7.0 + E_LOG_CHI2_1, abs=0.02)


def test_fallback_drops_the_bins_where_the_correction_hurt_and_the_bars_cover_out_of_fold():
    """A correction that removes the error in the three low-risk bins and adds noise in the top
    one: the fallback keeps three bins and drops the fourth; the gate-only and no-gate policies
    keep all; out of fold the intervals cover 68 % and 95 % (quantiles: to 1/n)."""
    rng = np.random.default_rng(2)
    n = 40_000
    u = np.sort(rng.uniform(0, 4, n))
    design = np.column_stack([np.ones(n), u, np.zeros(n)])
    scale = 0.01 * np.exp(0.5 * u)
    err = scale * rng.normal(size=n)
    top = u > np.quantile(u, 0.8)
    corr = np.where(top, err + 3 * scale * rng.normal(size=n), 0.9 * err)
    c = calibrate_angle(design, err, corr, 0.75, "both")
    assert c.keep["both"].tolist() == [True] * (RISK_BINS - 1) + [False]
    assert c.keep["fallback"].tolist() == [True] * (RISK_BINS - 1) + [False]
    assert c.keep["gate"].all() and c.keep["none"].all()
    sigma = np.exp(0.5 * design @ c.coef)
    b = np.searchsorted(c.edges, sigma, side="right")
    final = err - 0.75 * c.keep["both"][b] * corr
    half = c.scale[b] * sigma
    assert np.mean(np.abs(final) <= c.k68 * half) == pytest.approx(0.68, abs=2 / n)
    assert np.mean(np.abs(final) <= c.k95 * half) == pytest.approx(0.95, abs=2 / n)


def test_interval_coverage_counts_wrapped_errors():
    out = np.zeros((4, 3))
    truth = np.array([[0.1, 0.0, np.pi - 0.01], [0.3, 0.0, -np.pi + 0.01], [0.0, 0.0, 0.0], [-0.05, 0.0, 0.0]])
    out[:, 2] = np.pi - 0.005  # yaw errors across the +-pi seam: 0.005 and 0.015 rad, then ~pi
    sd = np.full((4, 3), 0.2)
    hw = np.full((4, 3), 0.4)
    sd[:, 1] = np.nan  # an angle without a bar
    res = crossval.interval_coverage(out, sd, hw, truth)
    np.testing.assert_allclose(res[0], [0.75, 1.0, 0.2])
    assert np.isnan(res[1]).all()
    np.testing.assert_allclose(res[2, :2], [0.5, 0.5])


def test_names_and_arguments():
    assert is_method_name("danae-safe[vqf]") and not is_method_name("danae-safe[danae]")
    m = make_method("danae-safe[fusion]")
    assert isinstance(m, DanaeSafe) and m.source == "fusion" and m.policy == "both"
    assert DanaeSafe("vqf", policy="gate").name == "danae-safe-gate[vqf]"
    with pytest.raises(ValueError, match="policy='sometimes'"):
        DanaeSafe("vqf", policy="sometimes")
    with pytest.raises(ValueError, match="smooth_s"):
        DanaeSafe("vqf", smooth_s=0.0)


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    recs = [simulate("handheld", duration=20.0, seed=s, name=f"safe-{s}") for s in range(3)]
    exp = Experiment("oxiod", "simulated", recs[1:], recs[:1], "fallback")
    cfg = TrainConfig(max_steps=20, num_threads=1)
    cache = tmp_path_factory.mktemp("safe-cache")
    b = run_leaderboard(exp, methods=["vqf", "danae-res[vqf]"], seeds=(0, 1), train_config=cfg, progress=False,
                        cache=cache)
    trained = stored_networks(cache)
    b2 = run_leaderboard(exp, methods=["vqf", "danae-res[vqf]"], seeds=(0, 1), train_config=cfg, progress=False,
                         cache=cache, extra=[DanaeSafe("vqf", policy=p) for p in POLICIES])
    return b2, trained, stored_networks(cache)


def test_builds_on_the_danae_res_of_the_context_without_new_networks(board):
    b, before, after = board
    assert before == after  # the same networks: DanaeSafe trains none of its own
    res = b.methods["danae-res[vqf]"]
    for p in POLICIES:
        assert b.methods[DanaeSafe("vqf", policy=p).name].res is res  # fitted once, shared
    rec = b.alignment.apply(b.experiment.test[0])
    gate = b.methods["danae-safe-gate[vqf]"]
    # the gate-only policy is DANAE-res itself (same networks, same gains): the same numbers
    for a, c in zip(gate.predict(rec), res.predict(rec)):
        np.testing.assert_allclose(a, c, rtol=0, atol=1e-12)
    none = b.methods["danae-safe-none[vqf]"]
    est = none.res.base.predict(rec)[0]
    corr = none.res._network_output(0, none.res.features(rec, est))
    np.testing.assert_allclose(none.predict(rec)[0], none.res._output(est, corr, np.ones(3)), atol=1e-12)


def test_error_bars_are_positive_and_the_95_interval_is_wider(board):
    b, _, _ = board
    m = b.methods["danae-safe[vqf]"]
    rec = b.alignment.apply(b.experiment.test[0])
    for out, sd, hw in m.predict_bars(rec):
        assert out.shape == sd.shape == hw.shape == (len(rec), 3)
        assert (sd > 0).all() and (hw >= sd).all()
    assert set(m.params["calibration"]) == {"roll", "pitch", "yaw"}
    assert m.params["oof_data"] == "held-out training recordings"
    cal = m.calibration_["roll"]
    assert cal.samples == int(sum(b.clean[r.name].sum() for r in b.experiment.train))


def test_stream_equals_the_batch_output(board):
    """Per sample, the streamed output and bars equal the batch ones. The network's step and the
    batch pass differ by float32 rounding (~1e-6 rad); a risk that lands within 1e-4 (relative) of a
    bin edge may fall in the neighbouring bin, so such samples are left out of the comparison."""
    b, _, _ = board
    m = b.methods["danae-safe[vqf]"]
    rec = b.alignment.apply(b.experiment.test[0]).slice(0, 400)
    est = m.res.base.predict(rec)[0]
    feats = m.res.features(rec, est)
    stream = SafeStream(m)
    got = [stream.step(feats[i], est[i], rec.fs) for i in range(len(rec))]
    out, sd, hw = m.predict_bars(rec)[0]
    _, corr, design = m._signals(m.res.results[0], rec)
    sigma = np.column_stack([np.exp(0.5 * design[:, k] @ m.calibration_[a].coef)
                             for k, a in enumerate(("roll", "pitch", "yaw"))])
    edges = np.column_stack([m.calibration_[a].edges for a in ("roll", "pitch", "yaw")])
    near = (np.abs(sigma[:, None, :] / edges[None] - 1) < 1e-4).any(axis=(1, 2))
    assert (~near).sum() >= 390
    so = np.array([g[0] for g in got])
    ssd = np.array([g[1] for g in got])
    assert np.abs(filter_error(so, out)[~near]).max() < 1e-5
    np.testing.assert_allclose(ssd[~near], sd[~near], rtol=1e-4)


def test_leaderboard_writes_per_sample_estimates_with_bars(board, tmp_path):
    b, _, _ = board
    paths = b.write_estimates(tmp_path, ["vqf", "danae-safe[vqf]"])
    import pandas as pd

    safe = pd.read_csv(paths["estimates_danae-safe[vqf]"])
    plain = pd.read_csv(paths["estimates_vqf"])
    n = len(b.experiment.test[0])
    assert len(safe) == 2 * n and len(plain) == n  # two seeds, one filter run
    assert {"roll_sd_rad", "roll_hw95_rad", "yaw_hw95_rad"} <= set(safe.columns)
    assert "roll_sd_rad" not in plain.columns
    out, sd, _ = b.methods["danae-safe[vqf]"].predict_bars(b.alignment.apply(b.experiment.test[0]))[1]
    s1 = safe[safe.seed == 1]
    np.testing.assert_allclose(s1[["roll_rad", "pitch_rad", "yaw_rad"]].to_numpy(), out, rtol=2e-6, atol=1e-9)
    np.testing.assert_allclose(s1.pitch_sd_rad.to_numpy(), sd[:, 1], rtol=2e-6)  # 7 significant digits
