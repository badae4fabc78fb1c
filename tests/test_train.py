"""Training, prediction and checkpoints on a tiny synthetic denoising problem (sine + noise -> sine)."""

import numpy as np
import pandas as pd
import pytest
import torch

from conftest import assert_close_scaled
from danae_lite.danae.seeding import default_device
from danae_lite.danae.model import DanaeBig, DanaePaper
from danae_lite.danae.checkpoints import CheckpointError
from danae_lite.danae.predict import predict
from danae_lite.danae.checkpoints import load, save
from danae_lite.danae.train import train
from danae_lite.danae.train_types import TrainConfig, TrainResult

NOISE = 0.05  # rad

def recording(n: int, phase: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Noisy input and clean target (rad) of one synthetic recording."""
    t = np.arange(n) * 0.01
    clean = 0.3 * np.sin(2 * np.pi * 0.5 * t + phase)
    noisy = clean + NOISE * np.random.default_rng(seed).standard_normal(n)
    return noisy, clean

def dataset(lengths=(1500, 1200, 1800)):
    recs = [recording(n, i, seed=i) for i, n in enumerate(lengths)]
    return [r[0] for r in recs], [r[1] for r in recs]

def small(**kw) -> TrainConfig:
    base = dict(hidden=16, max_steps=40, num_threads=1, device="cpu")
    base.update(kw)
    return TrainConfig(**base)

@pytest.fixture(scope="module")
def trained() -> TrainResult:
    xs, ys = dataset()
    cfg = TrainConfig(hidden=32, epochs=2, max_steps=300, val_every=50, num_threads=1, device="cpu", seed=0)
    return train(xs, ys, cfg, progress=False)

def test_training_denoises(trained):
    h = trained.history
    assert list(h.columns) == ["step", "epoch", "train_loss", "val_loss"]
    assert h["step"].tolist() == [50, 100, 150, 200, 250, 300]
    # the noise MSE is NOISE**2 = 2.5e-3 rad^2; the network must beat the input
    assert trained.best_val_loss < 0.5 * NOISE**2
    assert h["val_loss"].iloc[-1] < h["val_loss"].iloc[0]
    assert h["train_loss"].iloc[-1] < h["train_loss"].iloc[0]
    assert trained.best_val_loss == h["val_loss"].min()
    assert trained.best_step == int(h.loc[h["val_loss"].idxmin(), "step"])
    x, y = recording(700, 0.4, seed=99)
    pred = predict(trained, x)
    assert np.mean((pred[:, 0] - y) ** 2) < 0.5 * np.mean((x - y) ** 2)

def test_window_counts_respect_recordings(trained):
    lengths = (1500, 1200, 1800)
    n_val = [max(20, round(0.1 * n)) for n in lengths]
    assert trained.n_train_windows == sum(n - v - 19 for n, v in zip(lengths, n_val))
    assert trained.n_val_windows == sum(v - 19 for v in n_val)
    assert trained.device == "cpu" and trained.steps == 300 and trained.seconds > 0

def test_validation_tail_is_the_held_out_block(trained):
    from danae_lite.danae.train import validation_tail

    assert [validation_tail(n, 20, 0.1) for n in (1500, 100, 40)] == [150, 20, 20]
    assert validation_tail(1500, 20, 0.0) == 0
    tails = [validation_tail(n, 20, 0.1) for n in (1500, 1200, 1800)]
    assert trained.n_val_windows == sum(t - 19 for t in tails)


def test_strided_validation_windows_tile_the_tail_and_score_what_they_say():
    """val_stride = window - loss_start: windows start every 12 samples of each tail and the
    validation loss is the MSE of exactly those windows from position loss_start on,
    recomputed here with the returned network (float32 forward, float64 sums on both sides:
    the same operations in the same order, so equal to float32 rounding of one sum)."""
    from danae_lite.danae.train import validation_tail

    xs, ys = dataset()
    cfg = small(max_steps=30, val_every=30, loss_start=8, val_stride=12)
    r = train(xs, ys, cfg, progress=False)
    tails = [validation_tail(len(x), 20, 0.1) for x in xs]
    assert r.n_val_windows == sum((t - 20) // 12 + 1 for t in tails)
    wins_x, wins_y = [], []
    for x, y, t in zip(xs, ys, tails):
        starts = range(len(x) - t, len(x) - 20 + 1, 12)
        wins_x += [x[i : i + 20] for i in starts]
        wins_y += [y[i : i + 20] for i in starts]
    xw = torch.tensor(np.array(wins_x), dtype=torch.float32)[:, None, :]
    yw = torch.tensor(np.array(wins_y), dtype=torch.float32)[:, None, :]
    with torch.no_grad():
        d = (r.model(xw) - yw)[..., 8:]
    mse = float((d.double() ** 2).sum()) / d.numel()
    assert r.history["val_loss"].iloc[-1] == pytest.approx(mse, rel=1e-6)
    # the training itself does not depend on how validation is cut
    same = train(xs, ys, small(max_steps=30, val_every=30, loss_start=8, restore_best=False), progress=False)
    last = train(xs, ys, small(max_steps=30, val_every=30, loss_start=8, val_stride=12, restore_best=False),
                 progress=False)
    for k, v in same.model.state_dict().items():
        assert torch.equal(v, last.model.state_dict()[k])
    with pytest.raises(ValueError, match="val_stride"):
        small(val_stride=0)


def test_windows_holding_a_masked_target_are_left_out():
    """The training windows are the stride-1 windows of each recording's head
    (windows.windows_from_recordings) in (n, C, L) layout, those holding a masked target
    sample left out; the validation tail is cut by its own. Copies of the same float32
    values: equality is exact on any CPU."""
    from danae_lite.danae import train as tr
    from danae_lite.danae.windows import sliding_windows, windows_from_recordings

    rng = np.random.default_rng(5)
    xs = [rng.standard_normal((n, 4)).astype(np.float32) for n in (120, 75)]
    ys = [rng.standard_normal((n, 2)).astype(np.float32) for n in (120, 75)]
    masks = [np.ones(120, bool), np.ones(75, bool)]
    masks[0][40:44] = False
    head, tail = tr._split(xs, ys, masks, 20, 0.2)
    assert [len(x) for x in head.x] == [96, 55] and [len(x) for x in tail.x] == [24, 20]
    x, y = tr._cut_windows(head, 20, 1, "cpu")
    keep = np.concatenate([sliding_windows(m, 20).all(axis=1) for m in head.mask])
    ref_x = windows_from_recordings(head.x, 20)[keep].transpose(0, 2, 1)
    ref_y = windows_from_recordings(head.y, 20)[keep].transpose(0, 2, 1)
    assert x.is_contiguous() and x.shape == (keep.sum(), 4, 20) and y.shape == (keep.sum(), 2, 20)
    assert keep.sum() == (96 - 19) + (55 - 19) - 23       # the 23 windows over samples 40-43
    assert torch.equal(x, torch.from_numpy(np.ascontiguousarray(ref_x)))
    assert torch.equal(y, torch.from_numpy(np.ascontiguousarray(ref_y)))
    # train() holds the samples once and gathers each batch by the windows' first samples:
    # the same windows, standardised by the network's statistics (elementwise float32 on the
    # same operands: equal on any CPU)
    from danae_lite.danae.model import build_model

    net = build_model("paper", in_channels=4, out_channels=2)
    net.set_normalization(rng.normal(size=4), rng.uniform(0.5, 2, 4), rng.normal(size=2), rng.uniform(0.5, 2, 2))
    view = tr._training_windows(head, net, 20, "cpu")
    idx = torch.randperm(len(view), generator=torch.Generator().manual_seed(0))[:37]
    bx, by = view.batch(idx)
    assert len(view) == keep.sum() and bx.is_contiguous() and bx.shape == (37, 4, 20)
    assert torch.equal(bx, ((x - net.in_mean) / net.in_std)[idx])
    assert torch.equal(by, ((y - net.out_mean) / net.out_std)[idx])


def test_predict_shapes_and_stitching(trained):
    x, _ = recording(613, 0.0, seed=5)
    over = predict(trained, x)
    tiles = predict(trained, x, stitch="tiles")
    assert over.shape == tiles.shape == (613, 1) and over.dtype == np.float64
    assert np.isfinite(over).all()
    assert np.isnan(tiles[:, 0]).sum() == 613 % 20 and np.isfinite(tiles[:600]).all()
    # tiles and the overlap average agree on nothing in particular, but both are estimates of
    # the same signal: their difference is small compared with the signal
    assert np.nanmax(np.abs(tiles - over)) < 0.1
    # batch size does not change the result beyond float32 rounding: the layers are matrix
    # products whose row count is the batch, and a BLAS library may block 140 rows (7 windows)
    # differently from 5120, summing the 384 products of an output in another order on some
    # CPUs; 11 layers of sums of 384 float32 terms: 11 * 384 * 2**-24 = 2.5e-4 at worst
    assert_close_scaled(predict(trained, x, batch_size=7), over, rtol=11 * 384 * 2.0**-24)
    with pytest.raises(ValueError, match="stitch"):
        predict(trained, x, stitch="median")
    with pytest.raises(ValueError, match="tiles never overlap"):
        predict(trained, x, stitch="tiles", stride=4)


def test_prediction_leaves_the_network_as_it_was(trained):
    x, _ = recording(613, 0.0, seed=5)
    trained.model.train(True)
    predict(trained, x)
    assert trained.model.training and type(trained.model.e1) is torch.nn.Conv1d
    trained.model.eval()


@pytest.mark.parametrize("stride", [2, 4, 7])
def test_strided_prediction_is_the_mean_of_its_windows(trained, stride):
    # reference: each chosen window predicted on its own (stitch="tiles" on a one-window
    # recording), then every sample averaged over the windows that cover it, by a loop
    from danae_lite.danae.windows import overlap_starts

    x, _ = recording(233, 0.3, seed=9)
    starts = overlap_starts(len(x), 20, stride)
    total, count = np.zeros(len(x)), np.zeros(len(x))
    for s in starts:
        total[s : s + 20] += predict(trained, x[s : s + 20], stitch="tiles")[:, 0]
        count[s : s + 20] += 1
    # one window per forward pass against 256: BLAS may sum the products in another order
    assert_close_scaled(predict(trained, x, stride=stride)[:, 0], total / count, rtol=11 * 384 * 2.0**-24)

def test_determinism_same_seed_bit_identical():
    xs, ys = dataset((400, 300))
    a = train(xs, ys, small(seed=3), progress=False)
    b = train(xs, ys, small(seed=3), progress=False)
    c = train(xs, ys, small(seed=4), progress=False)
    x, _ = recording(200, 0.1, seed=7)
    pa, pb, pc = (predict(r, x) for r in (a, b, c))
    assert np.array_equal(pa, pb)
    pd.testing.assert_frame_equal(a.history, b.history)
    for k, v in a.model.state_dict().items():
        assert torch.equal(v, b.model.state_dict()[k])
    assert not np.allclose(pa, pc)

def test_thread_count_changes_a_seed_only_by_rounding():
    # the same seed on 1 and 2 threads: the same training up to float32 summation order
    xs, ys = dataset((400, 300))
    one = train(xs, ys, small(seed=3, num_threads=1, hidden=128), progress=False)
    two = train(xs, ys, small(seed=3, num_threads=2, hidden=128), progress=False)
    x, _ = recording(200, 0.1, seed=7)
    np.testing.assert_allclose(predict(two, x), predict(one, x), rtol=0, atol=1e-4)
    np.testing.assert_allclose(two.history.val_loss, one.history.val_loss, rtol=1e-3)
    assert one.best_step == two.best_step


def test_default_threads_are_the_process_setting():
    # None means "what the entry point set" (torch.get_num_threads()), restored afterwards
    old = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        xs, ys = dataset((300,))
        train(xs, ys, small(num_threads=2), progress=False)
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(old)

def test_early_stopping_triggers():
    xs, ys = dataset((400, 300))
    # an unattainable min_delta: only the first check counts as an improvement
    r = train(xs, ys, small(max_steps=200, val_every=5, patience=2, min_delta=1e9), progress=False)
    assert r.stopped_early and r.steps == 15
    assert r.history["step"].tolist() == [5, 10, 15]
    assert r.best_step == 5 and r.best_val_loss == r.history["val_loss"].iloc[0]

def test_without_validation_uses_last_state():
    xs, ys = dataset((400, 300))
    r = train(xs, ys, small(val_fraction=0.0, val_every=10), progress=False)
    assert r.n_val_windows == 0 and r.best_step == r.steps == 40
    assert r.history["val_loss"].isna().all() and np.isnan(r.best_val_loss)

def test_epochs_and_progress_bar(capsys):
    xs, ys = dataset((60,))
    r = train(xs, ys, small(max_steps=None, epochs=3, batch_size=8, val_fraction=0.0), progress=True)
    # 41 windows -> 6 batches per epoch (last one smaller)
    assert r.steps == 18 and r.history["epoch"].iloc[-1] == pytest.approx(3.0)

def test_standard_normalization_roundtrip(tmp_path):
    xs, ys = dataset((400, 300))
    xs = [x + 5.0 for x in xs]  # offset input: standardisation has something to do
    r = train(xs, ys, small(normalize="standard"), progress=False)
    norm = r.model.normalization()
    assert norm["in_mean"][0] == pytest.approx(5.0, abs=0.05)
    assert norm["out_std"][0] == pytest.approx(0.3 / np.sqrt(2), rel=0.2)
    path = save(r, tmp_path / "std.pt")
    net, cfg, meta = load(path)
    assert cfg.normalize == "standard" and meta["normalization"] == norm
    x = xs[0][:100]
    np.testing.assert_array_equal(predict(net, x), predict(r, x))

def test_multichannel_io():
    xs, ys = dataset((300, 300))
    xs2 = [np.c_[x, 2 * x] for x in xs]
    ys2 = [np.c_[y, -y, y] for y in ys]
    r = train(xs2, ys2, small(max_steps=5), progress=False)
    assert r.model.in_channels == 2 and r.model.out_channels == 3
    assert predict(r, xs2[0]).shape == (300, 3)

def test_input_validation():
    xs, ys = dataset((300, 300))
    with pytest.raises(ValueError, match="recording 1"):
        train(xs, [ys[0], ys[1][:-1]], small(), progress=False)
    with pytest.raises(ValueError, match="same positive number"):
        train(xs, ys[:1], small(), progress=False)
    with pytest.raises(ValueError, match="too short"):
        train([xs[0][:30]], [ys[0][:30]], small(), progress=False)
    with pytest.raises(ValueError, match="NaN"):
        train([np.r_[np.nan, xs[0][1:]]], [ys[0]], small(), progress=False)
    with pytest.raises(ValueError, match="normalize"):
        TrainConfig(normalize="minmax")
    with pytest.raises(ValueError, match="arch"):
        TrainConfig(arch="unet")

def test_config_defaults_and_dict_roundtrip():
    cfg = TrainConfig()
    assert (cfg.arch, cfg.window, cfg.lr, cfg.batch_size, cfg.epochs) == ("paper", 20, 0.002, 16, 1)
    assert cfg.betas == (0.9, 0.999) and cfg.loss_scale == 1.0 and cfg.normalize == "none"
    d = TrainConfig(betas=(0.5, 0.999), lr=2e-4).to_dict()
    assert d["betas"] == [0.5, 0.999]
    assert TrainConfig.from_dict(d | {"unknown": 1}) == TrainConfig(betas=(0.5, 0.999), lr=2e-4)

def test_default_device():
    xs, ys = dataset((100,))
    r = train(xs, ys, TrainConfig(hidden=4, max_steps=2, num_threads=1), progress=False)
    assert r.device == default_device()
    assert next(r.model.parameters()).device.type == torch.device(r.device).type

# --- checkpoints --------------------------------------------------------------------------

def test_save_load_roundtrip(trained, tmp_path):
    path = save(trained, tmp_path / "sub" / "net.pt", metadata={"angle": "phi", "arr": np.arange(3)})
    net, cfg, meta = load(path, expect_arch="paper")
    assert isinstance(net, DanaePaper) and not net.training
    assert cfg == trained.config
    assert meta["angle"] == "phi" and meta["arr"] == [0, 1, 2]
    assert meta["history"]["val_loss"] == trained.history["val_loss"].tolist()
    assert meta["best_step"] == trained.best_step and meta["torch_version"] == torch.__version__
    x, _ = recording(333, 1.0, seed=11)
    np.testing.assert_array_equal(predict(net, x), predict(trained, x))
    np.testing.assert_array_equal(predict(net, x, stitch="tiles"), predict(trained, x, stitch="tiles"))
    # the file loads with torch's safe loader on its own
    torch.load(path, weights_only=True)

def test_save_bare_model(tmp_path):
    net = DanaeBig(hidden=4, in_channels=2)
    net2, cfg, meta = load(save(net, tmp_path / "big.pt"), expect_arch="big")
    assert isinstance(net2, DanaeBig) and cfg is None and net2.in_channels == 2
    for k, v in net.state_dict().items():
        assert torch.equal(v, net2.state_dict()[k])

def test_two_processes_storing_the_same_network_at_once_both_succeed(tmp_path, monkeypatch):
    # the other process (another chapter under pytest's workers) writes and replaces the same
    # file between this one's write and its replace: both must end with a whole, loadable file
    from danae_lite.danae import checkpoints

    path, real_replace, calls = tmp_path / "net.pt", checkpoints.os.replace, []

    def interleaved(src, dst):
        if not calls:
            calls.append(src)
            save(DanaeBig(hidden=4), path)               # the other process, start to finish
        real_replace(src, dst)

    monkeypatch.setattr(checkpoints.os, "replace", interleaved)
    save(DanaeBig(hidden=4, in_channels=2), path)
    net, _, _ = load(path, expect_arch="big")
    assert net.in_channels == 2                            # the last replace wins, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["net.pt"]   # no temporary left


def test_save_rejects_unplain_metadata(tmp_path):
    with pytest.raises(TypeError, match="metadata.bad"):
        save(DanaePaper(hidden=4), tmp_path / "x.pt", metadata={"bad": object()})

@pytest.fixture
def paper_file(tmp_path):
    return save(DanaePaper(hidden=4), tmp_path / "paper.pt")

def test_load_wrong_arch(paper_file):
    with pytest.raises(CheckpointError, match=r"paper\.pt.*holds a 'paper'.*expected 'big'"):
        load(paper_file, expect_arch="big")

def test_load_corrupt_bytes(tmp_path):
    p = tmp_path / "noise.pt"
    p.write_bytes(np.random.default_rng(0).bytes(5000))
    with pytest.raises(CheckpointError, match=r"noise\.pt.*cannot be read as a DANAE checkpoint"):
        load(p)

def test_load_truncated(paper_file, tmp_path):
    p = tmp_path / "trunc.pt"
    data = paper_file.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(CheckpointError, match=r"trunc\.pt"):
        load(p)

def test_load_foreign_torch_dict(tmp_path):
    p = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3), "epoch": 4}, p)
    with pytest.raises(CheckpointError, match=r"other\.pt.*expected a DANAE checkpoint.*found a dict with keys \['epoch', 'weights'\]"):
        load(p)
    torch.save(torch.zeros(3), p)
    with pytest.raises(CheckpointError, match="found a Tensor"):
        load(p)

def test_load_refuses_pickled_objects(tmp_path):
    p = tmp_path / "pickle.pt"
    torch.save({"format": "danae_lite.checkpoint", "obj": pd.Timestamp(0)}, p)
    with pytest.raises(CheckpointError, match="pickle.pt"):
        load(p)

def test_load_damaged_state(paper_file, tmp_path):
    ckpt = torch.load(paper_file, weights_only=True)
    del ckpt["state_dict"]["e1.weight"]
    p = tmp_path / "damaged.pt"
    torch.save(ckpt, p)
    with pytest.raises(CheckpointError, match=r"damaged\.pt.*damaged 'paper' checkpoint"):
        load(p)
    ckpt["version"] = 99
    torch.save(ckpt, p)
    with pytest.raises(CheckpointError, match="version 99"):
        load(p)

def test_load_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        load(tmp_path / "nope.pt")
