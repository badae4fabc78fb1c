"""Windows and stitching: shapes, coverage, round trips, recordings never mixed."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from danae_lite.danae.windows import (Tiling, overlap_starts, sliding_windows,
                                      stitch_overlap_average, stitch_tiles,
                                      tile_windows, windows_from_recordings)


def test_sliding_windows_match_slices():
    x = np.arange(30.0)
    w = sliding_windows(x, 20)
    assert w.shape == (11, 20)
    for k in range(11):
        np.testing.assert_array_equal(w[k], x[k : k + 20])


def test_sliding_windows_stride_and_channels():
    x = np.arange(50.0).reshape(25, 2)
    w = sliding_windows(x, 5, stride=3)
    assert w.shape == ((25 - 5) // 3 + 1, 5, 2)
    for k in range(len(w)):
        np.testing.assert_array_equal(w[k], x[3 * k : 3 * k + 5])


def test_sliding_windows_view_is_readonly_copy_is_not():
    x = np.arange(40.0)
    view = sliding_windows(x, 20)
    assert not view.flags.writeable
    assert np.shares_memory(view, x)
    c = sliding_windows(x, 20, copy=True)
    assert c.flags.writeable and c.flags.c_contiguous and not np.shares_memory(c, x)


def test_sliding_windows_short_recording_message():
    with pytest.raises(ValueError, match=r"N=19.*window length 20"):
        sliding_windows(np.zeros(19), 20)
    with pytest.raises(ValueError):
        sliding_windows(np.zeros(30), 0)
    with pytest.raises(ValueError):
        sliding_windows(np.zeros(30), 20, stride=0)


def test_exact_length_gives_one_window():
    assert sliding_windows(np.zeros(20), 20).shape == (1, 20)


def test_windows_never_cross_recordings():
    lengths = [20, 37, 25, 64]
    recs = [np.full((n, 2), float(i)) for i, n in enumerate(lengths)]
    w = windows_from_recordings(recs, 20)
    assert w.shape == (sum(n - 19 for n in lengths), 20, 2)
    # each window holds a single recording id
    assert np.all(w.min(axis=(1, 2)) == w.max(axis=(1, 2)))
    ids = w[:, 0, 0].astype(int)
    np.testing.assert_array_equal(ids, np.repeat(np.arange(4), [n - 19 for n in lengths]))


def test_windows_from_recordings_errors_name_recording():
    with pytest.raises(ValueError, match="recording 1"):
        windows_from_recordings([np.zeros(30), np.zeros(5)], 20)
    with pytest.raises(ValueError, match="recording 1"):
        windows_from_recordings([np.zeros((30, 1)), np.zeros((30, 2))], 20)
    with pytest.raises(ValueError):
        windows_from_recordings([], 20)


@pytest.mark.parametrize("n", [20, 21, 39, 40, 41, 59, 60, 1234])
def test_tiles_round_trip_and_tail(n):
    x = np.random.default_rng(n).normal(size=(n, 3))
    t = tile_windows(x, 20)
    assert isinstance(t, Tiling)
    assert t.windows.shape == (n // 20, 20, 3)
    np.testing.assert_array_equal(t.starts, np.arange(n // 20) * 20)
    assert t.n_covered == 20 * (n // 20) and t.tail == n % 20 and t.n_total == n
    windows, tail = t  # unpacks as (windows, tail)
    assert tail == n % 20
    y = stitch_tiles(windows, n)  # identity prediction
    np.testing.assert_array_equal(y[: t.n_covered], x[: t.n_covered])
    assert np.isnan(y[t.n_covered :]).all()
    assert np.isnan(y).any(axis=1).sum() == t.tail


@pytest.mark.parametrize("n, n_windows, tail", [(21, 1, 1), (40, 1, 20), (41, 2, 1), (60, 2, 20)])
def test_tiles_authors_range(n, n_windows, tail):
    # range(0, N - 20, 20): the last complete window is left out when it ends at N
    t = tile_windows(np.zeros(n), 20, authors_range=True)
    assert len(t.windows) == n_windows and t.tail == tail


def test_tiles_too_short():
    with pytest.raises(ValueError, match="uncovered"):
        overlap_starts(100, 20, 21)
    with pytest.raises(ValueError, match="N=10"):
        tile_windows(np.zeros(10), 20)


def test_stitch_tiles_errors():
    with pytest.raises(ValueError):
        stitch_tiles(np.zeros((3, 20)), 59)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(20, 300), length=st.integers(1, 25), channels=st.integers(1, 3))
def test_overlap_average_identity_round_trip(n, length, channels):
    if n < length:
        return
    x = np.random.default_rng(n).normal(size=(n, channels))
    w = sliding_windows(x, length)
    y = stitch_overlap_average(w, n)  # every window predicts the truth
    assert y.shape == x.shape and np.isfinite(y).all()
    np.testing.assert_allclose(y, x, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("n, length", [(20, 20), (21, 20), (45, 20), (7, 3), (30, 1)])
def test_overlap_average_matches_brute_force(n, length):
    rng = np.random.default_rng(n + length)
    pred = rng.normal(size=(n - length + 1, length, 2))  # arbitrary, inconsistent predictions
    expected = np.zeros((n, 2))
    count = np.zeros(n)
    for j in range(n - length + 1):
        for k in range(length):
            expected[j + k] += pred[j, k]
            count[j + k] += 1
    expected /= count[:, None]
    assert count.min() >= 1
    np.testing.assert_allclose(stitch_overlap_average(pred, n), expected, rtol=1e-12)


def test_overlap_average_counts():
    # window j predicts the constant j: sample i gets the mean of the windows covering it
    n, length = 25, 20
    pred = np.repeat(np.arange(n - length + 1.0)[:, None], length, axis=1)
    y = stitch_overlap_average(pred, n)
    assert y[0] == 0.0 and y[-1] == n - length
    assert y[10] == pytest.approx(np.mean(np.arange(0, 6)))


def test_overlap_average_wrong_total():
    with pytest.raises(ValueError, match="n_total=30"):
        stitch_overlap_average(np.zeros((5, 20)), 30)


@pytest.mark.parametrize("n, length, stride", [(20, 20, 4), (21, 20, 4), (45, 20, 4), (47, 20, 5), (30, 3, 3),
                                               (100, 64, 4), (7, 3, 1)])
def test_overlap_starts_cover_every_sample(n, length, stride):
    starts = overlap_starts(n, length, stride)
    assert starts[0] == 0 and starts[-1] == n - length and (np.diff(starts) >= 1).all()
    assert (np.diff(starts)[:-1] == stride).all()  # only the last step may be shorter
    count = np.zeros(n)
    for s in starts:
        count[s : s + length] += 1
    assert count.min() >= 1
    if n >= 3 * length:  # interior samples: ceil(L / s) windows
        assert count[length : n - length].min() == -(-length // stride)


@pytest.mark.parametrize("n, length, stride", [(45, 20, 4), (47, 20, 5), (300, 20, 4), (30, 2, 2)])
def test_strided_overlap_average_matches_brute_force(n, length, stride):
    rng = np.random.default_rng(n + stride)
    starts = overlap_starts(n, length, stride)
    pred = rng.normal(size=(len(starts), length, 2))  # arbitrary, inconsistent predictions
    expected, count = np.zeros((n, 2)), np.zeros(n)
    for j, s in enumerate(starts):
        for k in range(length):
            expected[s + k] += pred[j, k]
            count[s + k] += 1
    np.testing.assert_allclose(stitch_overlap_average(pred, n, starts), expected / count[:, None], rtol=1e-12)


def test_default_starts_are_every_window_bit_for_bit():
    # stride 1 through explicit starts: the same additions in the same order, the same bits
    n, length = 137, 20
    pred = np.random.default_rng(1).normal(size=(n - length + 1, length, 3))
    assert np.array_equal(stitch_overlap_average(pred, n), stitch_overlap_average(pred, n, overlap_starts(n, length)))


def test_overlap_starts_errors():
    with pytest.raises(ValueError, match="stride"):
        overlap_starts(100, 20, 0)
    with pytest.raises(ValueError, match="uncovered"):
        overlap_starts(100, 20, 21)
    with pytest.raises(ValueError, match="N=10"):
        overlap_starts(10, 20, 4)
    with pytest.raises(ValueError, match="distinct"):
        stitch_overlap_average(np.zeros((3, 20)), 60, np.array([0, 0, 40]))
    with pytest.raises(ValueError, match="outside"):
        stitch_overlap_average(np.zeros((2, 20)), 30, np.array([0, 20]))
