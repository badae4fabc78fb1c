"""Data-directory lookup: real OxIOD/UCS layouts, fast mode, and the simulated stand-in."""
from __future__ import annotations

import numpy as np
import pytest

from danae_lite.data.recording import DataError
from danae_lite.data import experiments
from danae_lite.data.experiments import Experiment, load_experiment, oxiod_root
from danae_lite.data.oxiod import load_recording

from conftest import write_ucs


@pytest.fixture(autouse=True)
def no_env(monkeypatch):
    monkeypatch.delenv("DANAE_DATA", raising=False)
    monkeypatch.delenv("DANAE_FAST", raising=False)


def test_real_oxiod_split(tmp_oxiod, capsys):
    exp = load_experiment("oxiod", tmp_oxiod.data_dir, fast=False)
    assert isinstance(exp, Experiment) and (exp.name, exp.data) == ("oxiod", "real")
    assert [r.name for r in exp.train] == ["handheld/data1/imu3", "handheld/data1/imu4", "handheld/data1/imu7"]
    assert [r.name for r in exp.test] == ["handheld/data1/imu2"]
    np.testing.assert_array_equal(exp.test[0].quat, tmp_oxiod.vi[2][:, 5:9])
    assert exp.source == "real OxIOD data" and "<data dir>/oxiod:" in exp.note and str(tmp_oxiod.root) not in exp.note and "test imu2" in exp.note and "slow-walking" in exp.note
    printed = capsys.readouterr().out
    assert " ".join(printed.split()) == exp.note and max(map(len, printed.splitlines())) <= 88


def test_real_oxiod_from_environment_through_the_settings(tmp_oxiod, monkeypatch, capsys):
    """An entry point reads DANAE_DATA (config.data_dir) and passes the folder down."""
    from danae_lite.runtime import data_dir

    monkeypatch.setenv("DANAE_DATA", str(tmp_oxiod.data_dir))
    exp = load_experiment("oxiod", data_dir(), fast=False, verbose=False)
    assert exp.data == "real" and capsys.readouterr().out == ""
    assert oxiod_root(data_dir()) == tmp_oxiod.root


def test_fast_mode_truncates_real_oxiod(tmp_oxiod, monkeypatch):
    monkeypatch.setattr(experiments, "FAST_SAMPLES", 50)
    exp = load_experiment("oxiod", tmp_oxiod.data_dir, fast=True, verbose=False)
    full = load_recording(tmp_oxiod.syn / "imu3.csv")
    rec = exp.train[0]
    assert [len(r) for r in exp.train + exp.test] == [50, 50, 50, 50]
    np.testing.assert_array_equal(rec.acc, full.acc[:50])
    np.testing.assert_array_equal(rec.meta["gravity"], full.meta["gravity"][:50])  # per-sample meta too
    assert "fast mode: first 50 samples" in exp.note


def test_partial_oxiod_folder_raises(tmp_oxiod):
    (tmp_oxiod.syn / "vi7.csv").unlink()
    (tmp_oxiod.syn / "imu4.csv").unlink()
    with pytest.raises(DataError, match=r"oxiod exists but lacks .*imu4\.csv, .*vi7\.csv"):
        load_experiment("oxiod", tmp_oxiod.data_dir, verbose=False)


def test_real_ucs_split(tmp_path, capsys):
    path = write_ucs(tmp_path / "ucs" / "full_dataset" / "imu_adis.txt")
    exp = load_experiment("ucs", tmp_path, fast=True)
    assert (exp.name, exp.data) == ("ucs", "real")
    assert [len(r) for r in exp.train + exp.test] == [240, 60]  # fast mode keeps UCS whole
    assert "<data dir>/ucs/full_dataset/imu_adis.txt" in exp.note and "80%" in exp.note
    printed = capsys.readouterr().out
    assert " ".join(printed.split()) == exp.note and max(map(len, printed.splitlines())) <= 88


def test_ucs_folder_without_file_raises(tmp_path):
    (tmp_path / "ucs").mkdir()
    with pytest.raises(DataError, match=r"ucs exists but lacks .*full_dataset[/\\]imu_adis\.txt"):
        load_experiment("ucs", tmp_path, verbose=False)


def test_helpers_return_none_without_data(tmp_path):
    assert oxiod_root(tmp_path) is None
    assert oxiod_root() is None  # no data directory given


def test_library_functions_never_read_the_environment(monkeypatch, tmp_oxiod):
    """Settings are read by the entry points only: DANAE_DATA/DANAE_FAST do not reach the loaders."""
    monkeypatch.setenv("DANAE_DATA", str(tmp_oxiod.data_dir))
    monkeypatch.setenv("DANAE_FAST", "1")
    exp = load_experiment("oxiod", verbose=False)
    assert exp.data == "simulated" and len(exp.test[0]) == 18_000  # no directory given, full mode
    assert oxiod_root() is None


def test_simulated_oxiod_when_no_data(capsys):
    from danae_lite.data.simulate import simulate

    exp = load_experiment("oxiod", fast=True, seed=3)
    assert (exp.name, exp.data) == ("oxiod", "simulated")
    assert [r.name for r in exp.test] == ["sim-handheld-0"]
    assert [r.name for r in exp.train] == ["sim-handheld-1", "sim-handheld-2", "sim-handheld-3"]
    assert [r.meta["seed"] for r in exp.test + exp.train] == [3, 4, 5, 6]
    assert all(len(r) == 100 * experiments.FAST_DURATION["handheld"] and r.fs == 100.0 for r in exp.train + exp.test)
    reference = simulate("handheld", duration=experiments.FAST_DURATION["handheld"], seed=4)
    np.testing.assert_array_equal(exp.train[0].gyro, reference.gyro)
    assert "(no data directory given)" in exp.note and "handheld simulator stands in" in exp.note
    printed = capsys.readouterr().out
    assert " ".join(printed.split()) == exp.note and max(map(len, printed.splitlines())) <= 88


def test_simulated_full_length_outside_fast_mode():
    exp = load_experiment("oxiod", fast=False, verbose=False)
    assert len(exp.test[0]) == 18_000  # the scenario default: 180 s at 100 Hz


def test_simulated_ucs_in_empty_data_dir(tmp_path):
    exp = load_experiment("ucs", tmp_path, fast=True, verbose=False)
    assert (exp.name, exp.data) == ("ucs", "simulated")
    (train,), (test,) = exp.train, exp.test
    n = int(10 * experiments.FAST_DURATION["underwater"])  # samples at 10 Hz, split 80/20
    assert (len(train), len(test), train.fs) == (0.8 * n, 0.2 * n, 10.0)
    from danae_lite.data.simulate import simulate

    full = simulate("underwater", duration=experiments.FAST_DURATION["underwater"], seed=0)
    np.testing.assert_array_equal(np.r_[train.acc, test.acc], full.acc)
    np.testing.assert_array_equal(test.meta["true_acc"], full.meta["true_acc"][len(train):])
    assert exp.source == "the simulator standing in for UCS" and "under <data dir>" in exp.note and str(tmp_path) not in exp.note and "underwater simulator" in exp.note


def test_unknown_experiment():
    with pytest.raises(ValueError, match="unknown experiment 'euroc'"):
        load_experiment("euroc")


def test_missing_explicit_data_dir(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_experiment("oxiod", tmp_path / "nowhere")


def test_simulated_experiment_ignores_real_data(monkeypatch, tmp_path):
    (tmp_path / "oxiod").mkdir()
    monkeypatch.setenv("DANAE_DATA", str(tmp_path))
    from danae_lite.data.experiments import simulated_experiment

    exp = simulated_experiment("oxiod", fast=True, verbose=False)
    assert exp.data == "simulated" and [r.name for r in exp.test] == ["sim-handheld-0"]
    assert simulated_experiment("ucs", fast=True, verbose=False).data == "simulated"


@pytest.mark.parametrize("name", ["oxiod", "ucs"])
def test_more_simulated_test_recordings_leave_the_training_recordings_as_they_are(name):
    from danae_lite.data.experiments import simulated_experiment

    one = simulated_experiment(name, fast=True, verbose=False)
    five = simulated_experiment(name, fast=True, tests=5, verbose=False)
    assert [r.name for r in five.train] == [r.name for r in one.train]
    for a, b in zip(one.train, five.train):
        np.testing.assert_array_equal(a.gyro, b.gyro)
        np.testing.assert_array_equal(a.quat, b.quat)
    assert len(five.test) == 5 and len({r.name for r in five.test}) == 5
    np.testing.assert_array_equal(five.test[0].acc, one.test[0].acc)
    assert not np.allclose(five.test[1].acc[:50], five.test[2].acc[:50])   # independent draws
    with pytest.raises(ValueError, match="at least 1"):
        simulated_experiment(name, fast=True, tests=0, verbose=False)


def test_captions_name_the_data_as_it_was_read():
    from danae_lite.data import experiments, oxiod_motions

    assert experiments.source_of("broad", "real") == "real BROAD data"
    assert experiments.source_of("ucs", "simulated") == "the simulator standing in for UCS"
    assert oxiod_motions.Motions("simulated", {}, "").source == "the simulator standing in for OxIOD"
