"""The matrix-product convolutions of :mod:`danae_lite.danae.gemm_conv` against torch's own.

The reference is ``torch.nn.functional.conv1d`` / ``conv_transpose1d`` on the same
parameters. In float64 the two differ only by the order of the sums (~1e-15 relative); in
float32, a sum of ``n = C_in * K`` products may differ by ``n * 2**-24`` of the sum of their
magnitudes, which bounds the tolerances below.
"""
from __future__ import annotations

import pytest
import torch
from torch.nn import functional as F

from danae_lite.danae.gemm_conv import (ChannelsLastConv1d, ChannelsLastConvTranspose1d,
                                        gather, scatter, tap_offsets)
from danae_lite.danae.model import DanaeBig, DanaePaper

# (C_in, C_out, kernel, dilation, padding, length): the paper net's layers and odd ones
SHAPES = [(1, 8, 3, 1, 1, 20), (8, 8, 3, 3, 1, 20), (8, 8, 3, 6, 1, 12), (8, 3, 4, 1, 0, 9),
          (5, 7, 3, 2, 3, 6), (4, 4, 1, 1, 0, 5)]


def _layers(c_in, c_out, k, d, p, transposed, dtype):
    torch.manual_seed(0)
    cls = ChannelsLastConvTranspose1d if transposed else ChannelsLastConv1d
    layer = cls(c_in, c_out, kernel_size=k, dilation=d, padding=p).to(dtype)
    with torch.no_grad():
        layer.bias.normal_()
    return layer


def _reference(layer, x_cf):
    k = dict(padding=layer.padding, dilation=layer.dilation)
    if isinstance(layer, ChannelsLastConvTranspose1d):
        return F.conv_transpose1d(x_cf, layer.weight, layer.bias, **k)
    return F.conv1d(x_cf, layer.weight, layer.bias, **k)


@pytest.mark.parametrize("transposed", [False, True])
@pytest.mark.parametrize("shape", SHAPES)
def test_forward_and_gradients_equal_torch_in_float64(shape, transposed):
    c_in, c_out, k, d, p, length = shape
    if transposed and length - 2 * p + d * (k - 1) < 1:
        pytest.skip("no output samples")
    if not transposed and length + 2 * p - d * (k - 1) < 1:
        pytest.skip("no output samples")
    layer = _layers(c_in, c_out, k, d, p, transposed, torch.float64)
    x = torch.randn(3, c_in, length, dtype=torch.float64, requires_grad=True)
    ref = _reference(layer, x)
    out = layer(x.transpose(1, 2)).transpose(1, 2)
    assert out.shape == ref.shape
    torch.testing.assert_close(out, ref, rtol=1e-12, atol=1e-12)
    g = torch.randn_like(ref)
    got = torch.autograd.grad((out * g).sum(), (x, layer.weight, layer.bias))
    want = torch.autograd.grad((ref * g).sum(), (x, layer.weight, layer.bias))
    for a, b, name in zip(got, want, ("input", "weight", "bias")):
        torch.testing.assert_close(a, b, rtol=1e-12, atol=1e-12, msg=name)


def test_gather_and_scatter_are_adjoint():
    # <gather(x), c> = <x, scatter(c)> for any x, c: the backward pass of one is the other
    torch.manual_seed(1)
    offs = tap_offsets(3, 3, 1)
    x = torch.randn(2, 11, 4, dtype=torch.float64)
    c = torch.randn(2, 7, 4, 3, dtype=torch.float64)
    lhs = (gather(x, offs, 7) * c).sum()
    rhs = (x * scatter(c, offs, 11)).sum()
    assert abs(lhs - rhs) < 1e-12 * abs(lhs)


@pytest.mark.parametrize("cls", [DanaePaper, DanaeBig])
def test_networks_equal_torch_convolutions_in_float32(cls):
    """The whole network against the same layers run by torch's convolutions, float32.

    11 (17) layers of sums of 384 products: 17 * 384 * 2**-24 = 4e-4 of the output scale at
    worst (measured ~1e-6)."""
    torch.manual_seed(2)
    net = cls(in_channels=2, out_channels=2).eval()
    plain = {n: getattr(net, n) for n in net.layer_names()}

    def run(x):  # the same forward with torch's convolutions, channels-first
        acts = {"x": x}
        for name, src in net.sources().items():
            inp = sum(acts[s] for s in src.split(" + "))
            out = _reference(plain[name], inp)
            acts[name] = out if name == "out" else torch.relu(out)
        return acts["out"]

    x = torch.randn(16, 2, 20) * 0.1
    with torch.no_grad():
        ref, out = run(x), net.forward_net(x)
    scale = ref.abs().max()
    assert (out - ref).abs().max() <= len(plain) * 384 * 2.0**-24 * scale


def test_channels_first_input_is_refused_with_its_shape():
    layer = ChannelsLastConv1d(1, 8, kernel_size=3, padding=1)
    with pytest.raises(ValueError, match=r"channels-last input \(batch, length, 1\), got \(4, 8, 20\)"):
        layer(torch.zeros(4, 8, 20))
    strided = ChannelsLastConv1d(8, 8, kernel_size=3, stride=2)
    with pytest.raises(ValueError, match="stride 1"):
        strided(torch.zeros(4, 20, 8))


def test_a_plain_torch_layer_put_in_by_hand_still_works():
    """Chapter 3's exercise swaps a layer for torch's own nn.Conv1d: the network runs it
    channels-first and, on the same weights, computes the same numbers (float32 rounding)."""
    torch.manual_seed(3)
    net = DanaePaper().eval()
    swapped = DanaePaper().eval()
    swapped.load_state_dict(net.state_dict())
    plain = torch.nn.Conv1d(128, 128, kernel_size=3, padding=1, dilation=6)
    plain.load_state_dict(net.e4.state_dict())
    swapped.e4 = plain
    x = torch.randn(8, 1, 20)
    with torch.no_grad():
        ref, out = net(x), swapped(x)
    assert (out - ref).abs().max() <= 11 * 384 * 2.0**-24 * ref.abs().max()
    wider = DanaePaper(window=80)
    wider.e4 = torch.nn.Conv1d(128, 128, kernel_size=3, padding=1, dilation=3)
    wider.t1 = torch.nn.ConvTranspose1d(128, 128, kernel_size=3, padding=1, dilation=3)
    assert wider(torch.zeros(2, 1, 80)).shape == (2, 1, 80)
