"""``python -m danae_lite reproduce`` end to end, in fast mode on tiny data: outputs, schema, errors."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import synthetic_oxiod, write_rows, write_ucs
from danae_lite import cli
from danae_lite.commands.reproduce import CSV_COLUMNS
from danae_lite.data import experiments
from danae_lite.evaluate import metrics
from danae_lite.data import oxiod_motions

# tiny runs: one seed, five optimiser steps, one torch thread, CPU
TINY = ["--fast", "--seeds", "0", "--max-steps", "5", "--threads", "1", "--device", "cpu"]
ANGLES = {"oxiod": ["roll", "pitch", "yaw"], "ucs": ["roll", "pitch"]}
FIGURE = {"oxiod": "figure1_roll", "ucs": "figure2_pitch"}
TOP_KEYS = ["experiment", "data", "train", "test", "seeds", "kf", "danae", "paper", "seconds"]
METRIC_KEYS = ["mean_dev", "max_dev", "rmse"]


@pytest.fixture(autouse=True)
def clean_env(monkeypatch: pytest.MonkeyPatch) -> None:
    """No real data, no fast-mode variable, and short simulated recordings."""
    monkeypatch.delenv("DANAE_DATA", raising=False)
    monkeypatch.delenv("DANAE_FAST", raising=False)
    monkeypatch.setitem(experiments.FAST_DURATION, "handheld", 6.0)
    monkeypatch.setitem(experiments.FAST_DURATION, "underwater", 150.0)


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def check_outputs(out: Path, experiment: str, data: str, seeds: list[int]) -> dict:
    """Validate metrics.json (exact shape), metrics.csv (same numbers), the figure and its data."""
    m = json.loads((out / "metrics.json").read_text())
    angles = ANGLES[experiment]
    assert list(m) == TOP_KEYS
    assert m["experiment"] == experiment and m["data"] == data and m["seeds"] == seeds
    for side in ("train", "test"):
        assert isinstance(m[side], list) and m[side] and all(isinstance(n, str) for n in m[side])
    assert set(m["train"]).isdisjoint(m["test"])
    for method, keys in (("kf", METRIC_KEYS), ("danae", METRIC_KEYS + ["rmse_std"])):
        assert list(m[method]) == angles
        for angle in angles:
            vals = m[method][angle]
            assert list(vals) == keys
            one_seed_std = method == "danae" and len(seeds) == 1
            assert all(isinstance(v, float) and math.isfinite(v) and v >= 0 for k, v in vals.items()
                       if not (one_seed_std and k == "rmse_std"))
            assert vals["mean_dev"] <= vals["rmse"] + 1e-12 and vals["rmse"] <= vals["max_dev"] + 1e-12
            assert vals["max_dev"] <= math.pi  # errors are wrapped to [-pi, pi)
        if method == "danae" and len(seeds) == 1:
            assert all(m["danae"][a]["rmse_std"] is None for a in angles)  # no spread from one seed
    assert list(m["paper"]) == ["kf", "danae"]
    for method in ("kf", "danae"):
        assert list(m["paper"][method]) == angles
        for angle in angles:
            assert m["paper"][method][angle] == {k: metrics.PAPER[experiment][method][k][angle] for k in METRIC_KEYS}
    assert list(m["seconds"]) == ["kf", "train", "total"]
    s = m["seconds"]
    assert all(isinstance(v, float) and v >= 0 for v in s.values()) and s["total"] >= s["kf"] + s["train"]

    table = pd.read_csv(out / "metrics.csv")
    assert list(table.columns) == list(CSV_COLUMNS)
    assert list(zip(table.method, table.angle)) == [(me, a) for me in ("kf", "danae") for a in angles]
    for row in table.itertuples():
        ours, paper = m[row.method][row.angle], m["paper"][row.method][row.angle]
        for k in METRIC_KEYS:
            assert getattr(row, k) == pytest.approx(ours[k], rel=1e-12)
            assert getattr(row, f"paper_{k}") == pytest.approx(paper[k], rel=1e-12)
        if row.method == "kf" or ours["rmse_std"] is None:
            assert np.isnan(row.rmse_std)
        else:
            assert row.rmse_std == pytest.approx(ours["rmse_std"], abs=1e-15)

    png = out / f"{FIGURE[experiment]}.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    series = pd.read_csv(out / f"{FIGURE[experiment]}.csv")
    assert list(series.columns) == ["time_s", "ground_truth", "kf", "danae"]
    assert len(series) >= 20 and np.isfinite(series.to_numpy()).all()
    assert (np.diff(series.time_s) > 0).all()
    return m


@pytest.mark.parametrize("experiment", ["oxiod", "ucs"])
def test_simulated(experiment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(["reproduce", "--experiment", experiment, "--out", str(tmp_path), *TINY], capsys)
    assert code == 0, err
    assert "simulator stands in" in out and "data: simulated" in out
    m = check_outputs(tmp_path, experiment, "simulated", [0])
    run_info = json.loads((tmp_path / "run.json").read_text())
    assert run_info["fast"] is True and run_info["train_config"]["max_steps"] == 5
    # validation windows tile the tails (20 samples apart), as in chapters 3 and 4
    assert run_info["train_config"]["val_stride"] == run_info["train_config"]["window"] == 20
    seed_table = pd.read_csv(tmp_path / "seed_table.csv")
    kf_rows = seed_table[seed_table.method == "kf"].set_index("angle")
    for angle in ANGLES[experiment]:  # one test recording: the per-recording rows are the totals
        assert kf_rows.loc[angle, "rmse"] == pytest.approx(m["kf"][angle]["rmse"], rel=1e-12)


@pytest.mark.parametrize(("flags", "seeds"), [(["--fast"], [0]), (["--fast", "--seeds", "2", "5"], [2, 5])])
def test_fast_mode_trains_one_seed_unless_told(flags: list[str], seeds: list[int], tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """README: fast mode trains one seed (0); --seeds still says which when given."""
    argv = ["reproduce", "--out", str(tmp_path), "--max-steps", "5", "--threads", "1", "--device", "cpu", *flags]
    code, out, err = run(argv, capsys)
    assert code == 0, err
    assert f"seeds {' '.join(map(str, seeds))} |" in out
    assert json.loads((tmp_path / "metrics.json").read_text())["seeds"] == seeds


def test_data_dir_flag_reaches_the_run_settings(tmp_oxiod, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """--data-dir is the settings' data directory, over $DANAE_DATA (which points elsewhere here)."""
    (tmp_path / "empty").mkdir()
    monkeypatch.setenv("DANAE_DATA", str(tmp_path / "empty"))
    code, out, err = run(["reproduce", "--data-dir", str(tmp_oxiod.data_dir), "--out", str(tmp_path / "o"), *TINY],
                         capsys)
    assert code == 0, err
    assert "data: real" in out


def test_oxiod_files(tmp_oxiod, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    syn = tmp_oxiod.syn
    out = tmp_path / "out"
    code, stdout, err = run(["reproduce", "--train", str(syn / "imu3.csv"), str(syn / "imu4.csv"),
                             "--test", str(syn / "imu2.csv"), "--out", str(out), "--save-models", *TINY], capsys)
    assert code == 0, err
    m = check_outputs(out, "oxiod", "real", [0])
    assert m["train"] == ["handheld/data1/imu3", "handheld/data1/imu4"] and m["test"] == ["handheld/data1/imu2"]
    # the figure data is the test recording itself (200 samples, shorter than the paper's 25 s)
    series = pd.read_csv(out / "figure1_roll.csv")
    assert len(series) == 200 and series.time_s.iloc[1] == pytest.approx(0.01)
    np.testing.assert_allclose(series.ground_truth, tmp_oxiod.euler[2][:, 0], atol=1e-9)
    assert sorted(p.name for p in (out / "models").iterdir()) == [f"danae_{a}_seed0.pt" for a in ("pitch", "roll", "yaw")]


def test_oxiod_data_dir_defaults(tmp_oxiod, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    code, stdout, err = run(["reproduce", "--data-dir", str(tmp_oxiod.data_dir), "--out", str(out), *TINY], capsys)
    assert code == 0, err
    m = check_outputs(out, "oxiod", "real", [0])
    assert m["train"] == [f"handheld/data1/imu{k}" for k in (3, 4, 7)] and m["test"] == ["handheld/data1/imu2"]


def test_ucs_single_file_is_split(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_ucs(tmp_path / "ucs" / "imu_adis.txt")  # 300 rows
    out = tmp_path / "out"
    code, stdout, err = run(["reproduce", "--experiment", "ucs", "--test", str(path), "--out", str(out), *TINY], capsys)
    assert code == 0, err
    m = check_outputs(out, "ucs", "real", [0])
    samples = json.loads((out / "run.json").read_text())["samples"]
    assert [samples[n] for n in m["train"] + m["test"]] == [240, 60]


def _message(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_missing_test_file(tmp_oxiod, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nowhere" / "imu9.csv"
    code, _, err = run(["reproduce", "--train", str(tmp_oxiod.syn / "imu3.csv"), "--test", str(missing),
                        "--out", str(tmp_path / "out"), *TINY], capsys)
    assert code == 2 and str(missing) in _message(err)
    assert not (tmp_path / "out").exists()


def test_malformed_file(tmp_oxiod, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad"
    imu, vi, _ = synthetic_oxiod(seed=5)
    write_rows(bad / "imu5.csv", imu)
    write_rows(bad / "vi5.csv", vi)
    lines = (bad / "imu5.csv").read_text().splitlines()
    lines[7] = lines[7].rsplit(",", 1)[0]  # 15 columns instead of 16
    (bad / "imu5.csv").write_text("\n".join(lines) + "\n")
    code, _, err = run(["reproduce", "--train", str(tmp_oxiod.syn / "imu3.csv"), "--test", str(bad / "imu5.csv"),
                        "--out", str(tmp_path / "out"), *TINY], capsys)
    msg = _message(err)
    assert code == 2 and str(bad / "imu5.csv") in msg and "line 8" in msg and "15" in msg


@pytest.mark.parametrize("how", ["--test folder", "--data-dir", "incomplete oxiod folder"])
def test_folder_without_recordings(how: str, tmp_oxiod, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    if how == "--test folder":
        argv, named = ["--train", str(tmp_oxiod.syn / "imu3.csv"), "--test", str(empty)], str(empty)
    elif how == "--data-dir":
        argv, named = ["--data-dir", str(empty)], str(empty / "oxiod")
    else:
        (tmp_oxiod.syn / "vi4.csv").unlink()
        argv, named = ["--data-dir", str(tmp_oxiod.data_dir)], str(tmp_oxiod.syn / "vi4.csv")
    code, _, err = run(["reproduce", *argv, "--out", str(tmp_path / "out"), *TINY], capsys)
    assert code == 2 and named in _message(err)


def test_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["reproduce", "--experiment", "aqualoc"], capsys)
    assert code == 2 and "invalid choice" in err
    code, _, err = run(["reproduce", "--data-dir", str(tmp_path / "absent"), *TINY], capsys)
    assert code == 2 and str(tmp_path / "absent") in _message(err)
    code, _, err = run(["reproduce", "--seeds", "1", "1", "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and "--seeds" in _message(err)
    code, _, err = run(["reproduce", "--test", str(tmp_path / "imu2.csv"), *TINY], capsys)
    assert code == 2 and "--train" in _message(err)
    code, _, _ = run([], capsys)
    assert code == 2


def test_help_subprocess() -> None:
    proc = subprocess.run([sys.executable, "-m", "danae_lite", "reproduce", "--help"],
                          capture_output=True, text=True, timeout=120, cwd=Path(__file__).parents[1])
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    for flag in ("--experiment", "--data-dir", "--train", "--test", "--seeds", "--epochs", "--max-steps",
                 "--fast", "--device", "--threads", "--save-models", "--out", "DANAE_DATA", "DANAE_FAST",
                 "80%", "imu3, imu4, imu7", "Default"):
        assert flag in text, flag


def test_leaderboard_folds_simulated(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--folds: leave one recording out within every motion plus handheld -> the other motions."""
    out = tmp_path / "folds"
    code, stdout, err = run(["leaderboard", "--folds", *TINY, "--methods", "constant", "paper_kf", "danae",
                             "--out", str(out)], capsys)
    assert code == 0, err
    rows = pd.read_csv(out / "folds.csv")
    motions = {m: min(len(v[2]), oxiod_motions.FAST_MOTION_RECORDINGS) for m, v in oxiod_motions.OXIOD_MOTIONS.items()}
    in_motion = rows[rows.protocol == "in-motion"]
    assert in_motion.split.nunique() == sum(motions.values())  # one split per held-out recording
    transfer = rows[rows.protocol == "transfer"]
    assert set(transfer.group) == {"trolley", "multi users"}
    assert transfer.test.nunique() == motions["trolley"] + motions["multi users"]
    summary = pd.read_csv(out / "folds_summary.csv")
    assert set(summary.method) == {"constant", "paper_kf", "danae"}
    assert "mean and std over held-out recordings" in stdout
    assert not (out / "no_harm.csv").exists()  # nothing here corrects another method


def test_leaderboard_folds_writes_the_no_harm_table_of_a_denoiser_beside_its_filter(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "nh"
    code, stdout, err = run(["leaderboard", "--folds", "--experiment", "broad", *TINY, "--methods", "paper_kf",
                             "danae-res[paper_kf]", "--out", str(out)], capsys)
    assert code == 0, err
    nh = pd.read_csv(out / "no_harm.csv")
    trials = pd.read_csv(out / "folds_broad.csv").set_index(["test", "method"])
    assert set(nh.quantity) == {"roll RMSE [rad]", "pitch RMSE [rad]", "yaw RMSE [rad]", "total RMSE [deg]",
                                "heading RMSE [deg]", "inclination RMSE [deg]"}
    total = nh[nh.quantity == "total RMSE [deg]"].set_index("test")
    assert len(total) == trials.index.get_level_values("test").nunique()
    for test, r in total.iterrows():  # the benchmark's figure of each held-out trial, both methods
        assert r.filter_value == pytest.approx(trials.loc[(test, "paper_kf"), "total_rmse_deg"], rel=1e-5)
        assert r.corrector_value == pytest.approx(trials.loc[(test, "danae-res[paper_kf]"), "total_rmse_deg"],
                                                  rel=1e-5)
        assert r.change_pct == pytest.approx(100 * (1 - r.corrector_value / r.filter_value), abs=1e-3)  # 6 digits
    assert "No harm?" in stdout and "worse_on" in stdout


def test_folds_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["leaderboard", "--folds", "--experiment", "ucs", *TINY, "--out", str(tmp_path)], capsys)
    assert code == 2 and "nothing to hold out" in err
    code, _, err = run(["leaderboard", "--folds", *TINY, "--test", str(tmp_path), "--out", str(tmp_path)], capsys)
    assert code == 2 and "--train/--test" in err
    code, _, err = run(["leaderboard", "--folds", "--estimates", *TINY, "--out", str(tmp_path)], capsys)
    assert code == 2 and "--estimates" in err


def test_folds_write_the_coverage_of_the_error_bars(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """danae-safe[FILTER] on the BROAD protocol: coverage.csv holds one row per held-out trial and
    angle the filter estimates (RIANN: no yaw), fractions in [0, 1], the 95 % interval covering
    at least what the 68 % one covers."""
    out = tmp_path / "cov"
    code, _, err = run(["leaderboard", "--folds", "--experiment", "broad", *TINY, "--methods", "riann",
                        "danae-safe[riann]", "--out", str(out)], capsys)
    assert code == 0, err
    cov = pd.read_csv(out / "coverage.csv")
    trials = pd.read_csv(out / "folds_broad.csv")
    assert len(cov) == 2 * trials.test.nunique() and set(cov.angle) == {"roll", "pitch"}
    assert cov.cover68.between(0, 1).all() and (cov.cover95 >= cov.cover68).all()
    assert set(pd.read_csv(out / "no_harm.csv").corrector) == {"danae-safe[riann]"}


def test_paper_split_reads_the_slow_walking_files(tmp_path, capsys, monkeypatch):
    """``--split paper``: test slow walking/data1/syn/imu1, train imu2-imu8 as the authors' code, from the data directory."""
    monkeypatch.setenv("DANAE_CACHE", "off")
    syn = tmp_path / "data" / "oxiod" / "slow walking" / "data1" / "syn"
    for k in range(1, 9):
        imu, vi, _ = synthetic_oxiod(seed=10 + k)
        write_rows(syn / f"imu{k}.csv", imu)
        write_rows(syn / f"vi{k}.csv", vi)
    out = tmp_path / "out"
    code, stdout, err = run(["reproduce", "--split", "paper", "--data-dir", str(tmp_path / "data"), *TINY,
                             "--out", str(out)], capsys)
    assert code == 0, err
    info = json.loads((out / "metrics.json").read_text())
    assert info["data"] == "real"
    assert info["train"] == [f"slow walking/data1/imu{k}" for k in range(2, 9)]
    assert info["test"] == ["slow walking/data1/imu1"]
    # a missing file is named; the split does not mix with explicit files or cross-validation
    (syn / "vi5.csv").unlink()
    code, _, err = run(["reproduce", "--split", "paper", "--data-dir", str(tmp_path / "data"), *TINY,
                        "--out", str(out)], capsys)
    assert code == 2 and "vi5.csv" in err and "slow-walking" in err
    code, _, err = run(["reproduce", "--split", "paper", "--train", str(syn / "imu2.csv"), *TINY,
                        "--out", str(out)], capsys)
    assert code == 2 and "leave out --train/--test" in err
    code, _, err = run(["leaderboard", "--folds", "--split", "paper", *TINY, "--out", str(out)], capsys)
    assert code == 2 and "--split" in err
    code, _, err = run(["reproduce", "--experiment", "ucs", "--split", "paper", *TINY, "--out", str(out)], capsys)
    assert code == 2 and "OxIOD's split" in err
