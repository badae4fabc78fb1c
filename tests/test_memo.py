"""The memo of filter runs and network outputs, in memory and on disk (danae_lite.research.memo)."""
import os

import numpy as np
import pytest

from danae_lite.danae.train import train
from danae_lite.danae.train_types import TrainConfig
from danae_lite.research import features, memo
from danae_lite.research.memo import RunMemo, RunStore, digest


def _store_in_use():
    return memo._store.folder if memo._store is not None else None


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
    memo = RunMemo(max_bytes=3 * 800, code_of="danae_lite.research.ahrs.filters")
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
    memo = RunMemo(max_bytes=10_000, code_of="danae_lite.research.ahrs.filters")
    memo.put(("run", 0), np.zeros(10))
    with memo.bypassed():
        assert memo.get(("run", 0)) is None      # computed afresh, as a timing needs
        memo.put(("run", 1), np.ones(10))
    assert memo.get(("run", 0)) is not None and memo.get(("run", 1)) is None


# ---- the store on disk ------------------------------------------------------------------------

@pytest.fixture
def store(tmp_path):
    s = RunStore(tmp_path / "runs", max_bytes=None)
    memo.use_store(s)
    yield s
    memo.use_store(None)


def test_a_run_stored_on_disk_is_found_by_a_fresh_memo_of_the_same_code(store):
    first = RunMemo(max_bytes=1 << 20, code_of="danae_lite.research.ahrs.filters")
    first.put(("run", 1), np.arange(6.0).reshape(3, 2))
    later = RunMemo(max_bytes=1 << 20, code_of="danae_lite.research.ahrs.filters")  # another process
    np.testing.assert_array_equal(later.get(("run", 1)), np.arange(6.0).reshape(3, 2))
    assert later.get(("run", 2)) is None
    other_code = RunMemo(max_bytes=1 << 20, code_of="danae_lite.research.features")
    assert other_code.get(("run", 1)) is None          # same key, computed by other code
    with later.bypassed():
        assert later.get(("run", 1)) is None
    memo.use_store(None)
    assert RunMemo(max_bytes=1 << 20, code_of="danae_lite.research.ahrs.filters").get(("run", 1)) is None


def test_keep_runs_puts_the_store_in_the_modes_folder_of_the_cache(tmp_path):
    from danae_lite.runtime import RunSettings

    try:
        memo.keep_runs(RunSettings(fast=True, cache_root=tmp_path, cache_gb=0.5))
        assert memo._store == RunStore(tmp_path / "runs" / "fast", 500_000_000)
        memo.keep_runs(RunSettings(fast=False, cache_root=tmp_path))
        assert _store_in_use() == tmp_path / "runs" / "full"
        memo.keep_runs(RunSettings(cache_root=None))  # the cache is off: runs stay in memory
        assert memo._store is None
    finally:
        memo.use_store(None)


def test_a_damaged_stored_run_counts_as_missing_and_is_removed(store):
    m = RunMemo(max_bytes=1 << 20, code_of="danae_lite.research.ahrs.filters")
    m.put(("run", 1), np.ones(100))
    (f,) = store.folder.glob("runs/*/output.pkl")  # one item of joblib's store
    f.write_bytes(f.read_bytes()[:50])                  # cut short, as by a full disk
    assert RunMemo(max_bytes=1 << 20, code_of="danae_lite.research.ahrs.filters").get(("run", 1)) is None
    assert not f.exists()


def _stored(folder):
    return sorted(p.parent.name for p in folder.glob("runs/*/output.pkl"))


def test_the_store_removes_the_least_recently_used_runs_past_its_cap(tmp_path):
    names = [f"{k:032x}" for k in range(4)]               # run names: 32 hex digits
    s = RunStore(tmp_path, max_bytes=None)
    for k in range(3):
        s.save(names[k], np.full((1000, 1), float(k)))
    size = sum(f.stat().st_size for f in tmp_path.glob("runs/*/*"))
    for k in range(3):
        f = tmp_path / "runs" / names[k] / "output.pkl"
        os.utime(f, (1000.0 + k, 1000.0 + k))
    assert s.load(names[0]) is not None                  # loading marks it used: 1 is now the oldest
    capped = RunStore(tmp_path, max_bytes=size)          # room for three runs
    capped.save(names[3], np.zeros((1000, 1)))
    capped.prune()
    assert _stored(tmp_path) == [names[0], names[2], names[3]]


def test_code_fingerprint_follows_the_code_the_runs_import_and_nothing_else(monkeypatch):
    before = memo.code_fingerprint("danae_lite.research.ahrs.filters")
    ours, theirs = memo._import_closure("danae_lite.research.ahrs.filters")
    assert {"danae_lite.research.ahrs.filters", "danae_lite.research.ahrs.grid", "danae_lite.angles"} <= ours
    assert "danae_lite.research.crossval" not in ours and "danae_lite.book" not in ours
    assert {"ahrs", "vqf", "imufusion", "riann", "numpy", "scipy"} <= theirs
    from danae_lite.danae import networks

    read = networks.module_code
    for module, changes in (("danae_lite.research.crossval", False), ("danae_lite.research.memo", False),
                            ("danae_lite.research.ahrs.grid", True)):
        memo.code_fingerprint.cache_clear()
        monkeypatch.setattr(networks, "module_code", lambda name: read(name) + (b"\n_EDIT = 1\n" if name == module else b""))
        assert (memo.code_fingerprint("danae_lite.research.ahrs.filters") != before) is changes, module
    memo.code_fingerprint.cache_clear()


def test_a_worker_call_uses_the_store_of_the_process_that_sent_it(store):
    call = memo.carrying_store(_store_in_use)
    memo.use_store(None)
    assert call() == store.folder                        # what a worker process does first


def test_code_fingerprint_imports_none_of_the_libraries_it_names():
    # looking up another library's submodule would import it, with its side effects (tqdm.auto
    # warns on import in a kernel without widgets): only the package's own modules are looked up
    import subprocess
    import sys

    probe = ("import sys; from danae_lite.research import memo; before = set(sys.modules); "
             "memo.code_fingerprint('danae_lite.research.features'); "
             "print(sorted(set(sys.modules) - before))")
    new = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert "tqdm.auto" not in new and "danae_lite.research.crossval" not in new
