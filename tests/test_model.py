"""DANAE networks: layer lengths, skip sums, parameter counts, receptive field, init."""
import numpy as np
import pytest
import torch

from danae_lite.danae.model import (ARCHITECTURES, DanaeBig, DanaePaper, build_model,
                                    count_parameters, layer_table, receptive_field)


pytestmark = pytest.mark.usefixtures("one_torch_thread")


PAPER_LENGTHS = [20, 16, 12, 2, 12, 12, 16, 16, 20, 20, 20]
BIG_LENGTHS = [20, 16, 12, 8, 4, 1, 4, 4, 8, 8, 12, 12, 16, 16, 20, 20, 20]


def conv(c_in: int, c_out: int, k: int) -> int:
    """Parameters of a (transposed) 1-D convolution with bias."""
    return c_out * c_in * k + c_out


def paper_params(c_in: int, c_out: int, h: int) -> int:
    # e1; e2..e4, t1..t3, c1..c3 (9 layers h->h, k3); out
    return conv(c_in, h, 3) + 9 * conv(h, h, 3) + conv(h, c_out, 3)


def big_params(c_in: int, c_out: int, h: int) -> int:
    # e1; e2..e5 (k3); e6 and t1 (k4); t2..t5 and c1..c5 (k3); out
    return conv(c_in, h, 3) + 4 * conv(h, h, 3) + 2 * conv(h, h, 4) + 9 * conv(h, h, 3) + conv(h, c_out, 3)


def test_registry():
    from danae_lite.danae.causal import DanaeCausal

    assert ARCHITECTURES == {"paper": DanaePaper, "big": DanaeBig, "causal": DanaeCausal}
    assert isinstance(build_model("paper"), DanaePaper)
    with pytest.raises(ValueError, match="unknown architecture"):
        build_model("wavenet")


@pytest.mark.parametrize("arch, lengths, bottleneck", [("paper", PAPER_LENGTHS, "e4"), ("big", BIG_LENGTHS, "e6")])
def test_layer_lengths(arch, lengths, bottleneck):
    net = build_model(arch)
    df = layer_table(net)
    assert [s[1] for s in df["out_shape"]] == lengths
    assert all(s[0] == 128 for s in df["out_shape"][:-1]) and df["out_shape"].iloc[-1] == (1, 20)
    assert df.set_index("layer").loc[bottleneck, "out_shape"] == (128, 2 if arch == "paper" else 1)
    assert df.attrs["total_params"] == count_parameters(net)


def test_paper_layer_settings_match_text():
    net = DanaePaper()
    enc = [(m.kernel_size[0], m.dilation[0], m.padding[0]) for m in (net.e1, net.e2, net.e3, net.e4)]
    assert enc == [(3, 1, 1), (3, 3, 1), (3, 3, 1), (3, 6, 1)]
    dec_t = [(m.dilation[0], m.padding[0]) for m in (net.t1, net.t2, net.t3)]
    assert dec_t == [(6, 1), (3, 1), (3, 1)]
    assert all(isinstance(m, torch.nn.ConvTranspose1d) for m in (net.t1, net.t2, net.t3))
    assert all(m.dilation[0] == 1 for m in (net.c1, net.c2, net.c3, net.out))


@pytest.mark.parametrize("arch", ["paper", "big"])
@pytest.mark.parametrize("c_in, c_out, h", [(1, 1, 128), (9, 3, 16), (2, 1, 7)])
def test_parameter_counts(arch, c_in, c_out, h):
    net = build_model(arch, in_channels=c_in, out_channels=c_out, hidden=h)
    expected = (paper_params if arch == "paper" else big_params)(c_in, c_out, h)
    assert count_parameters(net) == expected


def test_parameter_counts_hand_values():
    assert count_parameters(DanaePaper()) == 444_417
    assert count_parameters(DanaeBig()) == 772_865


@pytest.mark.parametrize("arch", ["paper", "big"])
def test_io_shapes_multichannel(arch):
    net = build_model(arch, in_channels=3, out_channels=2, hidden=16)
    y = net(torch.randn(5, 3, 20))
    assert y.shape == (5, 2, 20)


@pytest.mark.parametrize("arch, min_len", [("paper", 19), ("big", 20)])
def test_general_lengths_and_minimum(arch, min_len):
    net = build_model(arch, hidden=8)
    assert net.min_length == min_len
    for length in (min_len, 33, 100):
        assert net(torch.randn(2, 1, length)).shape == (2, 1, length)
    with pytest.raises(ValueError, match=f"shorter than the minimum {min_len}"):
        net(torch.randn(2, 1, min_len - 1))
    with pytest.raises(ValueError, match="expects input of shape"):
        net(torch.randn(2, 2, 20))
    with pytest.raises(ValueError, match="expects input of shape"):
        net(torch.randn(1, 20))


@pytest.mark.parametrize("arch", ["paper", "big"])
def test_undilated_variant_keeps_lengths(arch):
    net = build_model(arch, dilated=False, hidden=8)
    df = layer_table(net)
    assert all(m.dilation[0] == 1 for m in net.modules() if hasattr(m, "dilation"))
    assert df["out_shape"].iloc[-1] == (1, 20)


def _capture(net, names):
    acts, ins = {}, {}
    hooks = [getattr(net, n).register_forward_hook(lambda m, i, o, n=n: acts.__setitem__(n, o.detach())) for n in names]
    hooks += [getattr(net, n).register_forward_pre_hook(lambda m, i, n=n: ins.__setitem__(n, i[0].detach())) for n in names]
    return acts, ins, hooks


@pytest.mark.parametrize(
    "arch, sums",
    [
        ("paper", {"c1": ("t1", "e3"), "c2": ("t2", "e2"), "c3": ("t3", "e1")}),
        ("big", {"c1": ("t1", "e5"), "c2": ("t2", "e4"), "c3": ("t3", "e3"), "c4": ("t4", "e2"), "c5": ("t5", "e1")}),
    ],
)
def test_skip_sums(arch, sums):
    torch.manual_seed(0)
    net = build_model(arch, hidden=16)
    names = net.layer_names()
    acts, ins, hooks = _capture(net, names)
    x = torch.randn(4, 1, 20)
    y = net(x)
    relu = torch.relu  # every layer but the last is followed by a ReLU
    for c, (t, e) in sums.items():
        torch.testing.assert_close(ins[c], relu(acts[t]) + relu(acts[e]), rtol=0, atol=0)
        assert net.sources()[c] == f"{t} + {e}"
    for h in hooks:
        h.remove()

    # same weights, skips off: c_i sees t_i only, and the output changes
    flat = build_model(arch, hidden=16, skip=False)
    flat.load_state_dict(net.state_dict())
    acts, ins, hooks = _capture(flat, names)
    y_flat = flat(x)
    for c, (t, _) in sums.items():
        torch.testing.assert_close(ins[c], relu(acts[t]), rtol=0, atol=0)
        assert flat.sources()[c] == t
    assert not torch.allclose(y, y_flat)


def test_init_like_authors():
    torch.manual_seed(0)
    net = DanaePaper()
    w = torch.cat([m.weight.detach().flatten() for m in net.modules() if isinstance(m, (torch.nn.Conv1d, torch.nn.ConvTranspose1d))])
    assert abs(float(w.std()) - 0.02) < 0.001 and abs(float(w.mean())) < 0.001
    # biases keep PyTorch's default U(-1/sqrt(fan_in), 1/sqrt(fan_in))
    assert float(net.e2.bias.detach().abs().max()) <= 1 / np.sqrt(128 * 3)
    assert float(net.e2.bias.detach().abs().max()) > 0.02 * 2  # not N(0, 0.02)


def test_receptive_field_at_window_20():
    # with dilation every output sample sees the whole 20-sample window
    for arch in ("paper", "big"):
        rf = receptive_field(build_model(arch, hidden=4))
        assert (rf["size"] == 20).all() and (rf["first"] == 0).all() and (rf["last"] == 19).all()


# Hand computation. A stride-1 convolution with kernel k, dilation d and padding p reads input
# offsets {-p, -p+d, ..., -p+(k-1)d}; a transposed one {p, p-d, ..., p-(k-1)d}. Along the
# deepest path these sums telescope to a symmetric span of radius R = sum(d (k-1)) / 2
# (the padding shifts cancel between each encoder layer and its transposed twin):
#   paper:  e1 1*2, e2 3*2, e3 3*2, e4 6*2, t1 6*2, c1 2, t2 3*2, c2 2, t3 3*2, c3 2, out 2
#           = 58  -> R = 29, 59 samples
#   paper, no dilation: 11 layers * 2 = 22 -> R = 11, 23 samples
#   big:    e1 2, e2..e5 4*6, e6 3, t1 3, c1..c5 5*2, t2..t5 4*6, out 2 = 68 -> R = 34, 69 samples
# Skip paths are shorter and lie inside the same span. Measured in the middle of a long input.
@pytest.mark.parametrize("arch, dilated, radius", [("paper", True, 29), ("paper", False, 11), ("big", True, 34)])
def test_receptive_field_hand_value(arch, dilated, radius):
    net = build_model(arch, hidden=4, dilated=dilated)
    rf = receptive_field(net, length=120)
    row = rf.loc[60]
    assert (row["first"], row["last"], row["size"]) == (60 - radius, 60 + radius, 2 * radius + 1)


def test_receptive_field_edges_without_dilation():
    # at the window edges zero padding truncates the span: output 0 sees inputs 0..11
    rf = receptive_field(build_model("paper", hidden=4, dilated=False))
    assert rf.loc[0, "size"] == 12 and rf.loc[19, "size"] == 12 and rf.loc[10, "size"] == 20


def test_kwargs_roundtrip():
    net = DanaeBig(in_channels=2, out_channels=3, hidden=8, skip=False, window=24)
    assert layer_table(net).attrs["total_params"] == count_parameters(net)
    twin = build_model("big", **net.constructor_kwargs())
    assert twin.constructor_kwargs() == net.constructor_kwargs()
    assert count_parameters(twin) == count_parameters(net)


def test_normalization_buffers():
    net = DanaePaper(hidden=8)
    x = torch.randn(3, 1, 20)
    y0 = net(x)
    net.set_normalization([1.0], [2.0], [0.5], [3.0])
    torch.testing.assert_close(net(x), net.forward_net((x - 1.0) / 2.0) * 3.0 + 0.5)
    assert net.normalization() == {"in_mean": [1.0], "in_std": [2.0], "out_mean": [0.5], "out_std": [3.0]}
    net.set_normalization([0.0], [1.0], [0.0], [1.0])
    assert torch.equal(net(x), y0)
    with pytest.raises(ValueError, match="positive"):
        net.set_normalization([0.0], [0.0], [0.0], [1.0])
    assert count_parameters(net) == paper_params(1, 1, 8)  # buffers are not parameters
