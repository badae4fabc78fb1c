"""The causal DANAE: causality, receptive field, streaming == batch, training, checkpoints, latency."""
import numpy as np
import pytest
import torch

from danae_lite.danae.causal import DanaeCausal
from danae_lite.danae.model import (ARCHITECTURES, DanaePaper, build_model, count_parameters, layer_table,
                                    receptive_field)
from danae_lite.research.streaming import (StreamingDanae, measure_latency,
                                           predict_causal)
from danae_lite.danae.checkpoints import load_result
from danae_lite.danae.checkpoints import load, save
from danae_lite.danae.train import train
from danae_lite.danae.train_types import TrainConfig, TrainResult

NOISE = 0.05  # rad


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def walk(n: int, channels: int = 1, seed: int = 0) -> np.ndarray:
    """A random-walk 'angle' signal (rad), shape (n, channels)."""
    return np.cumsum(np.random.default_rng(seed).normal(0.0, 0.02, (n, channels)), axis=0)


def net_with_stats(c_in: int = 1, c_out: int = 1, hidden: int = 16, seed: int = 0, **kw) -> DanaeCausal:
    """A random causal net with non-trivial standardisation buffers."""
    torch.manual_seed(seed)
    net = DanaeCausal(c_in, c_out, hidden, **kw)
    rng = np.random.default_rng(seed)
    net.set_normalization(rng.normal(0, 0.1, c_in), rng.uniform(0.5, 2, c_in),
                          rng.normal(0, 0.1, c_out), rng.uniform(0.5, 2, c_out))
    return net.eval()


def sine(n: int, phase: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Noisy input and clean target (rad) of one synthetic 100 Hz recording."""
    t = np.arange(n) * 0.01
    clean = 0.3 * np.sin(2 * np.pi * 0.5 * t + phase)
    return clean + NOISE * np.random.default_rng(seed).standard_normal(n), clean


@pytest.fixture(scope="module")
def trained() -> TrainResult:
    old = torch.get_num_threads()
    recs = [sine(n, i, seed=i) for i, n in enumerate((1500, 1200, 1800))]
    cfg = TrainConfig(arch="causal", window=64, hidden=32, normalize="standard", max_steps=240, val_every=40,
                      num_threads=1, device="cpu", seed=0)
    result = train([r[0] for r in recs], [r[1] for r in recs], cfg, progress=False)
    torch.set_num_threads(old)
    return result


# --- the network --------------------------------------------------------------------------

def test_registry_and_kwargs():
    assert ARCHITECTURES["causal"] is DanaeCausal
    net = build_model("causal", in_channels=2, out_channels=3, hidden=8, skip=False, dilated=True, window=64)
    assert isinstance(net, DanaeCausal) and net.arch == "causal"
    twin = build_model("causal", **net.constructor_kwargs())
    assert twin.constructor_kwargs() == net.constructor_kwargs()
    assert net.constructor_kwargs()["dilations"] == [1, 2, 4, 8]
    with pytest.raises(ValueError, match="dilations"):
        DanaeCausal(dilations=(1, 0))


@pytest.mark.parametrize("dilated, dilations, rf",
                         [(True, (1, 2, 4, 8), 31), (False, (1, 2, 4, 8), 9), (True, (1, 3), 9)])
def test_receptive_field_attribute_matches_computed(dilated, dilations, rf):
    net = DanaeCausal(hidden=4, dilated=dilated, dilations=dilations)
    assert net.receptive_field == rf
    table = receptive_field(net, length=120)
    assert tuple(table.loc[60, ["first", "last", "size"]]) == (60 - rf + 1, 60, rf)
    # near the start the edge padding folds the history onto sample 0: output j sees 0..j
    assert (table["first"].iloc[:rf] == 0).all() and (table["last"] == table.index).all()


def test_parameter_count_and_layer_table():
    for h in (4, 32, 128):
        assert count_parameters(DanaeCausal(hidden=h)) == 2 * h + 4 * (3 * h * h + h) + h + 1
    assert count_parameters(DanaeCausal()) == 197_505
    df = layer_table(DanaeCausal(hidden=8, window=20))
    assert df["layer"].tolist() == ["inp", "b1", "b2", "b3", "b4", "out"]
    assert [s[1] for s in df["out_shape"]] == [50, 48, 44, 36, 20, 20]  # 20 + 30 padded, valid convs
    assert df.attrs["total_params"] == count_parameters(DanaeCausal(hidden=8))


@pytest.mark.parametrize("c_in, c_out", [(1, 1), (3, 3), (3, 2)])
def test_shapes_any_length_and_residual(c_in, c_out):
    net = net_with_stats(c_in, c_out, hidden=8)
    assert net.min_length == 1 and net.residual_output == (c_in == c_out)
    for length in (1, 5, 20, 77):
        assert net(torch.randn(2, c_in, length)).shape == (2, c_out, length)
    with pytest.raises(ValueError, match="expects input of shape"):
        net(torch.randn(2, c_in + 1, 20))
    with pytest.raises(ValueError, match="shorter than the receptive field"):
        net.forward_valid(torch.randn(1, c_in, 30))


def test_residual_identity_when_correction_is_zero():
    net = DanaeCausal(hidden=8).eval()
    with torch.no_grad():
        net.out.weight.zero_()
        net.out.bias.zero_()
    x = torch.randn(2, 1, 40)
    assert torch.equal(net(x), x)


def test_edge_padding_equals_held_first_sample():
    # the padded start behaves as if the first sample had been held for ever
    net = net_with_stats(hidden=8)
    x = walk(100)
    held = np.concatenate([np.repeat(x[:1], 200, axis=0), x])
    np.testing.assert_allclose(predict_causal(net, x), predict_causal(net, held)[200:], rtol=0, atol=1e-6)


# --- (a) causality ------------------------------------------------------------------------

@pytest.mark.parametrize("t0", [0, 17, 250])
def test_causality_bit_identical(t0):
    net = net_with_stats(2, 2, hidden=16)
    x = walk(400, 2)
    x2 = x.copy()
    x2[t0 + 1 :] += np.random.default_rng(1).normal(0, 0.5, x2[t0 + 1 :].shape)
    a, b = predict_causal(net, x), predict_causal(net, x2)
    assert np.array_equal(a[: t0 + 1], b[: t0 + 1])
    assert not np.allclose(a[t0 + 1 :], b[t0 + 1 :])
    # the network itself, on a whole window
    with torch.no_grad():
        ya = net(torch.from_numpy(x.T.astype(np.float32))[None])
        yb = net(torch.from_numpy(x2.T.astype(np.float32))[None])
    assert torch.equal(ya[..., : t0 + 1], yb[..., : t0 + 1])
    assert not torch.allclose(ya[..., t0 + 1 :], yb[..., t0 + 1 :])


# --- (b) streaming == batch ---------------------------------------------------------------

@pytest.mark.parametrize("c_in, c_out", [(1, 1), (3, 3), (3, 2)])
def test_streaming_equals_batch(c_in, c_out):
    net = net_with_stats(c_in, c_out, hidden=16)
    x = walk(500, c_in, seed=c_in)
    batch = predict_causal(net, x)
    assert batch.shape == (500, c_out) and batch.dtype == np.float64
    s = StreamingDanae(net)
    streamed = s.run(x)
    np.testing.assert_allclose(streamed, batch, rtol=0, atol=1e-5)
    # step by step, and across a reset
    s.reset()
    stepped = np.array([s.step(v) for v in x[:60]])
    assert s.n_seen == 60
    np.testing.assert_allclose(stepped, batch[:60], rtol=0, atol=1e-5)
    np.testing.assert_allclose(s.run(x[60:], reset=False), batch[60:], rtol=0, atol=1e-5)
    # chunking does not change the result
    np.testing.assert_allclose(predict_causal(net, x, chunk=37), batch, rtol=0, atol=1e-6)
    # nor does the whole-window forward pass
    with torch.no_grad():
        full = net(torch.from_numpy(x.T.astype(np.float32))[None])[0].T.numpy()
    np.testing.assert_allclose(full, batch, rtol=0, atol=1e-6)


def test_scalar_steps_and_short_recordings():
    net = net_with_stats(hidden=8)
    x = walk(5)[:, 0]  # shorter than the receptive field
    s = StreamingDanae(net)
    out = np.array([s.step(float(v)) for v in x])
    np.testing.assert_allclose(out, predict_causal(net, x), rtol=0, atol=1e-5)


def test_bad_inputs_and_threads_restored():
    net = net_with_stats(2, 1, hidden=8)
    with pytest.raises(TypeError, match="DanaeCausal"):
        predict_causal(DanaePaper(hidden=4), np.zeros(40))
    with pytest.raises(TypeError, match="DanaeCausal"):
        StreamingDanae(DanaePaper(hidden=4))
    with pytest.raises(ValueError, match="shape"):
        predict_causal(net, np.zeros(40))
    with pytest.raises(ValueError, match="NaN"):
        predict_causal(net, np.full((40, 2), np.nan))
    s = StreamingDanae(net, num_threads=2)
    with pytest.raises(ValueError, match="2 value"):
        s.step([0.1])
    with pytest.raises(ValueError, match="NaN"):
        s.step([0.1, np.inf])
    s.step([0.1, 0.2])
    predict_causal(net, np.zeros((40, 2)), num_threads=2)
    assert torch.get_num_threads() == 1


# --- (c) the receptive field --------------------------------------------------------------

def test_receptive_field_boundary():
    """The oldest input in the receptive field changes the output, one sample older does not.

    Every weight is set to 1 / fan-in and every bias to 0.1 (every ReLU active, no
    cancellation, as in :func:`danae_lite.danae.model.receptive_field`): with the random init the
    oldest sample's influence can be as small as float32 rounding (7e-9 rad seen), and
    whether it survives the rounding then depends on the order of the sums."""
    net = net_with_stats(hidden=16)
    with torch.no_grad():
        for name, prm in net.named_parameters():
            prm.fill_(1.0 / prm[0].numel() if name.endswith("weight") else 0.1)
    rf, t0 = net.receptive_field, 200
    x = walk(300)
    base = predict_causal(net, x)
    s = StreamingDanae(net)
    streamed = s.run(x)
    outside, inside = x.copy(), x.copy()
    outside[t0 - rf] += 1.0
    inside[t0 - rf + 1] += 1.0
    assert base[t0, 0] == predict_causal(net, outside)[t0, 0]
    assert abs(base[t0, 0] - predict_causal(net, inside)[t0, 0]) > 1e-4
    assert streamed[t0, 0] == s.run(outside)[t0, 0]
    assert abs(streamed[t0, 0] - s.run(inside)[t0, 0]) > 1e-4


# --- (d) training -------------------------------------------------------------------------

def test_training_denoises_causally(trained):
    assert trained.config.arch == "causal" and isinstance(trained.model, DanaeCausal)
    h = trained.history
    assert h["val_loss"].iloc[-1] < h["val_loss"].iloc[0]
    x, clean = sine(800, 0.4, seed=99)
    pred = predict_causal(trained, x)[:, 0]
    mse_net, mse_in = np.mean((pred - clean) ** 2), np.mean((x - clean) ** 2)
    assert mse_net < 0.5 * mse_in, (mse_net, mse_in)
    np.testing.assert_allclose(StreamingDanae(trained).run(x)[:, 0], pred, rtol=0, atol=1e-5)


# --- (e) checkpoints ----------------------------------------------------------------------

def test_save_load_round_trip(trained, tmp_path):
    x, _ = sine(300, 1.0, seed=5)
    path = save(trained, tmp_path / "causal.pt")
    back = load_result(path)
    assert isinstance(back.model, DanaeCausal) and back.config == trained.config
    assert np.array_equal(predict_causal(back, x), predict_causal(trained, x))
    assert np.array_equal(StreamingDanae(back).run(x), StreamingDanae(trained).run(x))
    # a bare network with other dilations and standardisation buffers
    net = net_with_stats(2, 2, hidden=8, dilations=(1, 3, 9))
    save(net, tmp_path / "bare.pt")
    again, config, _ = load(tmp_path / "bare.pt", expect_arch="causal")
    assert again.dilations == (1, 3, 9) and again.receptive_field == 27 and config is None
    xx = walk(100, 2)
    assert np.array_equal(predict_causal(again, xx), predict_causal(net, xx))


# --- (f) latency --------------------------------------------------------------------------

def test_measure_latency_sane():
    s = StreamingDanae(net_with_stats(hidden=8))
    m = measure_latency(s, n=50, warmup=5, fs=100.0)
    assert m["n"] == 50 and m["num_threads"] == 1 and m["period_ms"] == 10.0 and m["fs_hz"] == 100.0
    for key in ("mean_ms", "median_ms", "p99_ms", "max_ms"):
        assert np.isfinite(m[key]) and m[key] > 0
    assert m["median_ms"] <= m["p99_ms"] <= m["max_ms"]
    assert m["p99_fraction"] == pytest.approx(m["p99_ms"] / 10.0)
    assert isinstance(m["real_time"], bool) and s.n_seen == 0
    with pytest.raises(ValueError, match="fs"):
        measure_latency(s, n=5, fs=0)
