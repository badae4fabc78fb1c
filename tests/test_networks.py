"""danae_lite.danae.networks: the one training path (per head and seed), its cache and its worker processes."""
import os
import pathlib

import numpy as np
import pytest
import torch

from danae_lite.danae import networks
from danae_lite.paper import pipeline
from danae_lite.data import simulate
from danae_lite.danae.predict import predict
from danae_lite.danae.train_types import TrainConfig

from conftest import network_items, stored_networks


@pytest.fixture(scope="module")
def recs():
    return [simulate.simulate("handheld", duration=12.3, seed=s) for s in range(3)]


@pytest.fixture(scope="module")
def data(recs):
    est = pipeline.filter_all(recs)
    xs = {a: [est[r.name][:, k] for r in recs[1:]] for k, a in enumerate(("roll", "pitch"))}
    ys = {a: [r.euler[:, k] for r in recs[1:]] for k, a in enumerate(("roll", "pitch"))}
    return est, xs, ys


def _same(a, b):
    sa, sb = a.model.state_dict(), b.model.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


def test_one_network_per_head_and_seed_equals_train(recs, data):
    from danae_lite.danae.train import train

    _, xs, ys = data
    cfg = TrainConfig(max_steps=5, num_threads=1)
    nets = networks.train_networks(xs, ys, cfg, seeds=(0, 3))
    assert set(nets) == {(a, s) for a in ("roll", "pitch") for s in (0, 3)}
    alone = train(xs["pitch"], ys["pitch"], TrainConfig(max_steps=5, num_threads=1, seed=3), progress=False)
    assert _same(nets[("pitch", 3)], alone)
    assert not _same(nets[("pitch", 0)], nets[("pitch", 3)])


def test_seeds_per_head(data):
    """A head may train fewer seeds than another (DANAE-res's gate networks: the first only)."""
    _, xs, ys = data
    cfg = TrainConfig(max_steps=3, num_threads=1)
    nets = networks.train_networks(xs, ys, cfg, seeds={"roll": (0, 3), "pitch": (3,)})
    assert set(nets) == {("roll", 0), ("roll", 3), ("pitch", 3)}
    both = networks.train_networks(xs, ys, cfg, seeds=(0, 3))
    assert _same(nets[("pitch", 3)], both[("pitch", 3)]) and _same(nets[("roll", 0)], both[("roll", 0)])
    with pytest.raises(ValueError, match="heads"):
        networks.train_networks(xs, ys, cfg, seeds={"roll": (0,)})
    with pytest.raises(ValueError, match="pitch"):
        networks.train_networks(xs, ys, cfg, seeds={"roll": (0,), "pitch": ()})


def test_bad_arguments_are_named(data):
    _, xs, ys = data
    with pytest.raises(ValueError, match="same heads"):
        networks.train_networks(xs, {"roll": ys["roll"]}, TrainConfig(max_steps=1), seeds=(0,))
    with pytest.raises(ValueError, match="distinct"):
        networks.train_networks(xs, ys, TrainConfig(max_steps=1), seeds=(1, 1))


def test_cache_reuses_the_network(recs, data, tmp_path):
    est, xs, ys = data
    cfg = TrainConfig(max_steps=5, num_threads=1)
    first = networks.train_networks({"pitch": xs["pitch"]}, {"pitch": ys["pitch"]}, cfg, (0,), cache=tmp_path)
    assert [(tag, seed) for tag, seed, _ in stored_networks(tmp_path)] == [("danae-pitch", 0)]
    again = networks.train_networks({"pitch": xs["pitch"]}, {"pitch": ys["pitch"]}, cfg, (0,), cache=tmp_path)
    a, b = first[("pitch", 0)], again[("pitch", 0)]
    assert b.steps == a.steps and b.best_step == a.best_step and b.history.equals(a.history)
    x = est[recs[0].name][:, 1]
    np.testing.assert_array_equal(predict(b, x), predict(a, x))
    # another seed or other data is another entry
    networks.train_networks({"pitch": xs["pitch"]}, {"pitch": ys["pitch"]}, cfg, (1,), cache=tmp_path)
    networks.train_networks({"pitch": xs["pitch"][:1]}, {"pitch": ys["pitch"][:1]}, cfg, (0,), cache=tmp_path)
    assert len(network_items(tmp_path)) == 3


def test_no_cache_unless_one_is_passed(data, tmp_path, monkeypatch):
    # the environment is read by the entry points only: a plain call never touches a disk cache
    monkeypatch.setenv("DANAE_CACHE", str(tmp_path))
    _, xs, ys = data
    networks.train_networks({"roll": xs["roll"]}, {"roll": ys["roll"]}, TrainConfig(max_steps=2, num_threads=1), (0,))
    assert not list(tmp_path.iterdir())


def test_cached_network_is_found_under_another_tag(data, tmp_path):
    _, xs, ys = data
    cfg = TrainConfig(max_steps=5, num_threads=1)
    one = {"roll": xs["roll"]}, {"roll": ys["roll"]}
    first = networks.train_networks(*one, cfg, (0,), tag="chapter-a", cache=tmp_path)
    again = networks.train_networks(*one, cfg, (0,), tag="chapter-b", cache=tmp_path)
    assert [tag for tag, _, _ in stored_networks(tmp_path)] == ["chapter-a-roll"]  # not trained twice
    assert _same(first[("roll", 0)], again[("roll", 0)])


def _job(xs, ys, cfg):
    return networks.NetworkJob(tuple(xs), tuple(ys), None, cfg, "t", {})


@pytest.mark.parametrize("module", ["base", "model", "causal", "train_types", "train", "windows", "seeding"])
def test_cache_key_covers_the_code_that_makes_the_network(recs, tmp_path, monkeypatch, module):
    import importlib

    mod = importlib.import_module(f"danae_lite.danae.{module}")
    job = _job([recs[0].euler[:, 0]], [recs[1].euler[:, 0]], TrainConfig(max_steps=5))
    before = networks.cache_key(job)
    edited = tmp_path / f"{module}.py"
    source = pathlib.Path(mod.__file__).read_bytes()
    monkeypatch.setattr(mod, "__file__", str(edited))
    edited.write_bytes(source + b"\n# a comment\n\n\n\"\"\"More documentation.\"\"\"\n")
    assert networks.cache_key(job) == before  # comments, docstrings, blank lines: the same code
    edited.write_bytes(source + b"\n_EDIT = 1\n")
    assert networks.cache_key(job) != before
    monkeypatch.undo()
    assert networks.cache_key(job) == before
    # the thread count only changes rounding, and "cpu" is the default device: same key
    other = _job([recs[0].euler[:, 0]], [recs[1].euler[:, 0]], TrainConfig(max_steps=5, num_threads=3, device="cpu"))
    assert networks.cache_key(other) == before


def test_cache_key_hashes_one_explicit_list_of_modules():
    assert networks.NETWORK_CODE == tuple(f"danae_lite.danae.{m}" for m in
                                          ("base", "model", "causal", "train_types", "train", "windows", "seeding"))


@pytest.mark.parametrize(("module", "changes_key"), [("danae_lite.danae.checkpoints", False), ("danae_lite.runtime", False),
                                                     ("danae_lite.danae.networks", False), ("danae_lite.danae.train", True)])
def test_cache_key_ignores_checkpoint_code_but_not_training_code(recs, monkeypatch, module, changes_key):
    job = _job([recs[0].euler[:, 0]], [recs[1].euler[:, 0]], TrainConfig(max_steps=5))
    before = networks.cache_key(job)
    read = networks.module_code
    monkeypatch.setattr(networks, "module_code", lambda name: read(name) + (b"\n_EDIT = 1\n" if name == module else b""))
    assert (networks.cache_key(job) != before) is changes_key


def test_cache_key_covers_the_settings_and_masks_but_not_the_device(recs):
    job = _job([recs[0].euler[:, 0]], [recs[1].euler[:, 0]], TrainConfig(max_steps=5))
    before = networks.cache_key(job)
    assert networks.cache_key(_job(job.inputs, job.targets, TrainConfig(max_steps=6))) != before
    masked = networks.NetworkJob(job.inputs, job.targets, (np.ones(len(recs[0]), bool),), job.config, "t", {})
    assert networks.cache_key(masked) != before


def test_worker_processes_give_the_same_networks(data, tmp_path):
    # jobs changes the wall time, not the networks (up to float rounding of other thread counts)
    _, xs, ys = data
    cfg = TrainConfig(max_steps=8, num_threads=1)
    serial = networks.train_networks(xs, ys, cfg, (0, 1))
    parallel = networks.train_networks(xs, ys, cfg, (0, 1), jobs=2, cache=tmp_path)
    assert list(parallel) == list(serial)
    for key in serial:
        for k, v in serial[key].model.state_dict().items():
            torch.testing.assert_close(parallel[key].model.state_dict()[k], v, rtol=1e-5, atol=1e-6)
    assert len(network_items(tmp_path)) == 4  # stored by the parent


def test_loading_a_network_keeps_it_in_a_capped_cache(data, tmp_path):
    import os

    _, xs, ys = data
    cfg = TrainConfig(max_steps=2, num_threads=1)
    cache = networks.NetworkCache(tmp_path, max_bytes=10**9)
    assert networks.as_cache(tmp_path) == networks.NetworkCache(tmp_path.resolve())
    roll = {"roll": xs["roll"]}, {"roll": ys["roll"]}
    networks.train_networks(*roll, cfg, (0,), cache=cache)
    networks.train_networks(*roll, cfg, (1,), cache=cache)
    first, second = (tmp_path / "networks" / key / "output.pkl"
                     for _, _, key in sorted(stored_networks(tmp_path), key=lambda e: e[1]))
    os.utime(first, (1.0, 1.0))
    os.utime(second, (2.0, 2.0))
    networks.train_networks(*roll, cfg, (0,), cache=cache)  # loads seed 0: used now
    assert first.stat().st_mtime > second.stat().st_mtime
    size = sum(f.stat().st_size for f in first.parent.iterdir())
    # room for two networks: a third one pushes out seed 1, the least recently used
    small = networks.NetworkCache(tmp_path, max_bytes=2 * size + size // 2)
    networks.train_networks(*roll, cfg, (2,), cache=small)
    assert [seed for _, seed, _ in sorted(stored_networks(tmp_path), key=lambda e: e[1])] == [0, 2]


def test_a_damaged_network_is_named_and_trained_again(data, tmp_path):
    _, xs, ys = data
    cfg = TrainConfig(max_steps=2, num_threads=1)
    roll = {"roll": xs["roll"]}, {"roll": ys["roll"]}
    first = networks.train_networks(*roll, cfg, (0,), cache=tmp_path)
    (item,) = network_items(tmp_path)
    item.write_bytes(item.read_bytes()[:100])               # cut short, as by a full disk
    with pytest.warns(UserWarning, match="not a readable network") as caught:
        again = networks.train_networks(*roll, cfg, (0,), cache=tmp_path)
    assert str(item) in str(caught[0].message)
    assert network_items(tmp_path) == [item] and _same(first[("roll", 0)], again[("roll", 0)])


def _worker_state() -> tuple[int, int]:
    return os.getpid(), torch.get_num_threads()


def test_calls_run_in_kept_worker_processes_with_their_share_of_threads():
    # joblib's workers answer both calls (they keep their imports and memos), each with the
    # threads it was given; a call that raises reaches the caller with its error
    first = list(networks.in_processes(_worker_state, [()] * 6, processes=2, threads=1))
    second = list(networks.in_processes(_worker_state, [()] * 6, processes=2, threads=1))
    pids = {pid for pid, _ in first + second}
    assert os.getpid() not in pids and len(pids) <= 2
    assert {threads for _, threads in first + second} == {1}
    with pytest.raises(ValueError, match="invalid literal"):
        list(networks.in_processes(int, [("1",), ("x",), ("3",)], processes=2, threads=1))
    assert list(networks.in_processes(int, [("4",), ("5",)], processes=2, threads=1)) == [4, 5]


def test_pretrain_trains_once_what_the_fits_then_find(data, tmp_path, monkeypatch):
    # train_networks = network_jobs + run_jobs: pretrain trains those jobs in the workers and
    # stores them; a later train_networks with the same arguments then trains nothing
    _, xs, ys = data
    cfg = TrainConfig(max_steps=6, num_threads=1)
    keys, jobs = networks.network_jobs(xs, ys, cfg, (0, 1), tag="t")
    assert keys == [(a, s) for a in ("roll", "pitch") for s in (0, 1)]
    assert networks.pretrain(jobs, cache=None, jobs=2) == 0  # no cache: nothing to keep them in
    assert networks.pretrain(jobs, cache=tmp_path, jobs=1) == 0  # one process: nothing to pool
    assert not list(tmp_path.iterdir())
    in_process = networks.train_networks(xs, ys, cfg, (0, 1))
    assert networks.pretrain([*jobs, jobs[0]], cache=tmp_path, jobs=2) == 4  # the repeated job once
    assert len(network_items(tmp_path)) == 4
    assert networks.pretrain(jobs, cache=tmp_path, jobs=2) == 0
    monkeypatch.setattr(networks, "_run", lambda *a: pytest.fail("a network was trained again"))
    found = networks.train_networks(xs, ys, cfg, (0, 1), tag="t", cache=tmp_path)
    # one torch thread in a worker and here: the same operations in the same order, same bits
    assert all(_same(found[k], in_process[k]) for k in keys)


def test_pretrain_starts_the_largest_training_first(recs, monkeypatch):
    cfg = TrainConfig(window=20, batch_size=16, epochs=1)
    small = _job([np.zeros(100), np.zeros(50)], [np.zeros(100), np.zeros(50)], cfg)
    # (100 - 20 + 1) + (50 - 20 + 1) = 112 windows, 112 / 16 = 7 steps of 20 samples
    assert networks._work(small) == pytest.approx(7 * 20)
    large = _job([np.zeros(400)], [np.zeros(400)], cfg)
    capped = _job([np.zeros(400)], [np.zeros(400)], TrainConfig(window=20, batch_size=16, max_steps=3))
    assert networks._work(capped) == 3 * 20
    order = []
    monkeypatch.setattr(networks, "_cached", lambda job, store: None)
    monkeypatch.setattr(networks, "run_jobs", lambda js, **kw: order.extend(js))
    assert networks.pretrain([small, capped, large], cache="unused", jobs=2) == 3
    assert order == [large, small, capped]


def _sigint_handler() -> str:
    import signal

    return "ignored" if signal.getsignal(signal.SIGINT) == signal.SIG_IGN else "raised"


def test_workers_leave_ctrl_c_to_the_parent():
    # an interrupted or shut-down notebook kernel sends SIGINT to its workers too: they ignore it
    assert list(networks.in_processes(_sigint_handler, [()], processes=2, threads=1)) == ["ignored"]


def test_several_gpus_take_the_trainings_in_turn(monkeypatch):
    # one GPU per worker: with three GPUs the calls go to cuda:0, 1, 2, 0, ...; an explicit
    # GPU, the CPU or a single GPU stay as asked; the GPU's number is not part of the key
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 3)
    assert networks.worker_devices("cuda", 5) == ["cuda:0", "cuda:1", "cuda:2", "cuda:0", "cuda:1"]
    assert networks.worker_devices("cuda:1", 2) == ["cuda:1", "cuda:1"]
    assert networks.worker_devices("cpu", 2) == ["cpu", "cpu"] and networks.worker_devices(None, 1) == [None]
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    assert networks.worker_devices("cuda", 2) == ["cuda", "cuda"]
    monkeypatch.setattr(torch.cuda, "get_device_name", lambda index=0: "Test GPU")
    monkeypatch.setattr(networks, "default_device", lambda requested=None: requested or "cpu")
    assert networks.device_name("cuda:0") == networks.device_name("cuda:1") == "cuda Test GPU"
    assert networks.device_name(None) == networks.device_name("cpu") == "cpu"


def test_the_device_is_part_of_the_key(recs, monkeypatch):
    job = _job([recs[0].euler[:, 0]], [recs[1].euler[:, 0]], TrainConfig(max_steps=5))
    on_cpu = networks.cache_key(job)
    monkeypatch.setattr(networks, "device_name", lambda device: "cuda Test GPU" if device == "cuda" else "cpu")
    gpu = _job([recs[0].euler[:, 0]], [recs[1].euler[:, 0]], TrainConfig(max_steps=5, device="cuda"))
    assert networks.cache_key(gpu) != on_cpu and len(on_cpu) == 32
    threads = _job([recs[0].euler[:, 0]], [recs[1].euler[:, 0]], TrainConfig(max_steps=5, num_threads=3))
    assert networks.cache_key(threads) == on_cpu  # the thread count changes only rounding


def test_loky_replacing_a_worker_leaves_no_warning_for_a_chapter_to_store():
    """loky warns from its manager thread when it replaces a worker whose memory grew (the
    workers keep their runs by design); after a pool has run, that warning is not shown."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert list(networks.in_processes(abs, [(-1,), (-2,)], processes=1, threads=1)) == [1, 2]
        loky = {"__name__": "joblib.externals.loky.process_executor"}
        exec("import warnings\nwarnings.warn('A worker stopped while some jobs were given to the executor.', "
             "UserWarning)", loky)
        exec("import warnings\nwarnings.warn('another warning', UserWarning)", loky)
    assert [str(w.message) for w in caught] == ["another warning"]
