"""The in-process memo of filter runs and network outputs (danae_lite.research.memo)."""
import numpy as np

from danae_lite.core.train import TrainConfig, train
from danae_lite.research import features
from danae_lite.research.memo import RunMemo, digest


def test_digest_follows_content_dtype_and_shape_not_memory():
    a = np.arange(12.0).reshape(3, 4)
    assert digest(a) == digest(a.copy()) == digest(np.asfortranarray(a))
    assert digest(a) != digest(a.reshape(4, 3))           # same bytes, other shape
    assert digest(a) != digest(a.astype(np.float32))      # same values, other dtype
    b = a.copy()
    b[2, 3] = np.nextafter(b[2, 3], 99.0)                # one ulp
    assert digest(a) != digest(b)
    assert digest(a, None) != digest(a) != digest(None, a)


def test_the_memo_drops_the_least_recently_used_past_its_cap():
    memo = RunMemo(max_bytes=3 * 800)
    for k in range(3):
        memo.put(("run", k), np.full((100, 1), float(k)))
    assert memo.get(("run", 0)) is not None  # 0 used last: 1 is now the oldest
    memo.put(("run", 3), np.zeros((100, 1)))
    assert memo.get(("run", 1)) is None and memo.get(("run", 0)) is not None
    assert memo.nbytes == 3 * 800
    got = memo.get(("run", 3))
    got[:] = 7.0                                          # a copy: the stored one is unchanged
    assert memo.get(("run", 3)).max() == 0.0


def test_a_network_run_twice_is_computed_once_and_equal():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(300, 2))
    y = x[:, :1] + 0.1 * rng.normal(size=(300, 1))
    cfg = TrainConfig(window=20, hidden=8, epochs=1, max_steps=3, seed=0)
    res, other = train(x, y, config=cfg), train(x, y, config=TrainConfig(**{**cfg.to_dict(), "seed": 1}))
    assert features.network_digest(res) != features.network_digest(other)
    first = features.run_network(res, x)
    hits = features.memo.hits
    again = features.run_network(res, x.copy())
    assert features.memo.hits == hits + 1
    np.testing.assert_array_equal(again, first)
    np.testing.assert_array_equal(features.run_network(other, x), features.predict(other, x, stride=features.PREDICT_STRIDE))


def test_inside_bypassed_every_run_is_computed_and_nothing_stored():
    memo = RunMemo(max_bytes=10_000)
    memo.put(("run", 0), np.zeros(10))
    with memo.bypassed():
        assert memo.get(("run", 0)) is None      # computed afresh, as a timing needs
        memo.put(("run", 1), np.ones(10))
    assert memo.get(("run", 0)) is not None and memo.get(("run", 1)) is None
