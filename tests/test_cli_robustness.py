"""``python -m danae_lite reproduce`` on bad input: exit status 2, one line on stderr naming the
file or value, no traceback. Complements tests/test_cli.py (which covers a missing --test file,
a malformed row, an empty --data-dir / --test folder, an incomplete oxiod/ folder and
duplicate seeds) and does not repeat those cases.

Checkpoints: the command has no flag that takes a checkpoint. It reads checkpoints only from
the trained-network cache (``DANAE_CACHE``): :mod:`danae_lite.danae.networks` calls
:func:`danae_lite.danae.checkpoints.load_result` on a cached file; a damaged one (``CheckpointError``) is
named in a warning and its network trained again in its place. That path is tested here by
damaging the cache between two runs.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import synthetic_oxiod, ucs_signals, write_rows, write_ucs, network_items
from danae_lite import cli

PREFIX = "python -m danae_lite reproduce: error: "
TINY = ["--fast", "--max-steps", "2", "--epochs", "1", "--seeds", "0", "--threads", "1", "--device", "cpu"]
REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def clean_env(monkeypatch: pytest.MonkeyPatch) -> None:
    """No real data, fast-mode variable or network cache from the caller's environment."""
    for name in ("DANAE_DATA", "DANAE_FAST", "DANAE_CACHE"):
        monkeypatch.delenv(name, raising=False)


def oxiod_pair(folder: Path, k: int, n: int = 200) -> Path:
    """Write imuK.csv + viK.csv with ``n`` rows into ``folder``; return the imu path."""
    imu, vi, _ = synthetic_oxiod(n=n, seed=k)
    write_rows(folder / f"imu{k}.csv", imu)
    write_rows(folder / f"vi{k}.csv", vi)
    return folder / f"imu{k}.csv"


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def error_line(err: str) -> str:
    """The one line the command prints for a data/usage error (its own errors: nothing else)."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith(PREFIX), err
    return lines[0]


def argparse_error_line(err: str) -> str:
    """argparse's errors: the usage block, then one error line (no traceback)."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith(PREFIX)]
    assert len(errors) == 1 and lines[-1] == errors[0], err
    usage = lines[:-1]
    assert usage and usage[0].startswith("usage: ") and all(ln.startswith(" ") for ln in usage[1:]), err
    return errors[0]


# ------------------------------------------------------------------ missing files
@pytest.mark.parametrize("experiment", ["oxiod", "ucs"])
def test_missing_train_file(experiment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nowhere" / ("imu3.csv" if experiment == "oxiod" else "imu_adis.txt")
    other = (oxiod_pair(tmp_path / "data", 2) if experiment == "oxiod"
             else write_ucs(tmp_path / "data" / "imu_adis.txt"))
    out = tmp_path / "out"
    code, _, err = run(["reproduce", "--experiment", experiment, "--train", str(missing), "--test", str(other),
                        "--out", str(out), *TINY], capsys)
    msg = error_line(err)
    assert code == 2 and f"--train {missing}" in msg and "no such file" in msg
    assert not out.exists()


def test_explicit_imu_without_its_ground_truth(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    imu3 = oxiod_pair(tmp_path / "data", 3)
    (tmp_path / "data" / "vi3.csv").unlink()
    code, _, err = run(["reproduce", "--train", str(imu3), "--test", str(oxiod_pair(tmp_path / "data", 2)),
                        "--out", str(tmp_path / "out"), *TINY], capsys)
    assert code == 2 and str(tmp_path / "data" / "vi3.csv") in error_line(err)


def test_train_file_not_named_imuK(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = oxiod_pair(tmp_path / "data", 3).with_name("recording.csv")
    (tmp_path / "data" / "imu3.csv").rename(data)
    code, _, err = run(["reproduce", "--train", str(data), "--test", str(oxiod_pair(tmp_path / "data", 2)),
                        "--out", str(tmp_path / "out"), *TINY], capsys)
    msg = error_line(err)
    assert code == 2 and str(data) in msg and "imuK.csv" in msg


# ------------------------------------------------------------------ data directories without recordings
@pytest.mark.parametrize("layout", ["ucs, empty folder", "empty oxiod/", "empty ucs/", "a file"])
def test_data_dir_without_recordings(layout: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = tmp_path / "data"
    experiment = "ucs" if "ucs" in layout else "oxiod"
    if layout == "a file":
        base.write_text("not a folder\n")
        named = str(base)
    else:
        base.mkdir()
        if layout != "ucs, empty folder":
            (base / experiment).mkdir()
        named = str(base / experiment)
    code, _, err = run(["reproduce", "--experiment", experiment, "--data-dir", str(base),
                        "--out", str(tmp_path / "out"), *TINY], capsys)
    assert code == 2 and named in error_line(err)
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ recordings shorter than a window
def test_test_recording_shorter_than_a_window(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    short = oxiod_pair(tmp_path / "short", 5, n=10)
    code, _, err = run(["reproduce", "--train", str(oxiod_pair(tmp_path / "data", 3)), "--test", str(short),
                        "--out", str(tmp_path / "out"), *TINY], capsys)
    msg = error_line(err)
    assert code == 2 and str(short) in msg and "10 rows" in msg and "20" in msg


def test_train_recording_too_short_to_train_on(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 30 rows load (>= one window) but leave no window after the validation block
    short = oxiod_pair(tmp_path / "short", 6, n=30)
    code, _, err = run(["reproduce", "--train", str(short), "--test", str(oxiod_pair(tmp_path / "data", 2)),
                        "--out", str(tmp_path / "out"), *TINY], capsys)
    msg = error_line(err)
    assert code == 2 and "imu6" in msg and "30 samples" in msg and "40" in msg


@pytest.mark.parametrize("rows, named", [(10, "10 data rows"), (30, "24 samples")])
def test_short_ucs_file(rows: int, named: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_ucs(tmp_path / "ucs" / "imu_adis.txt", ucs_signals(n=rows))
    code, _, err = run(["reproduce", "--experiment", "ucs", "--test", str(path), "--out", str(tmp_path / "out"),
                        *TINY], capsys)
    msg = error_line(err)
    # 10 rows: the loader refuses the file; 30 rows: the 80 % training part (24) is too short
    assert code == 2 and named in msg and ("imu_adis" in msg)


# ------------------------------------------------------------------ damaged checkpoints in the cache
@pytest.mark.parametrize("damage", ["truncated", "garbage", "empty"])
def test_damaged_cached_checkpoint(damage: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    cache = tmp_path / "cache"
    monkeypatch.setenv("DANAE_CACHE", str(cache))
    argv = ["reproduce", "--train", str(oxiod_pair(tmp_path / "data", 3)),
            "--test", str(oxiod_pair(tmp_path / "data", 2)), "--out", str(tmp_path / "out"), *TINY]
    code, _, err = run(argv, capsys)
    assert code == 0, err
    files = network_items(cache / "fast")  # --fast: the fast-mode sub-folder
    assert len(files) == 3  # one network per angle
    for f in files:
        raw = f.read_bytes()
        f.write_bytes({"truncated": raw[: len(raw) // 2], "garbage": b"not a checkpoint\n", "empty": b""}[damage])
    with pytest.warns(UserWarning) as caught:
        code, _, err = run(argv, capsys)
    assert code == 0, err
    named = " ".join(str(w.message) for w in caught)
    assert all(str(f) in named for f in files) and "not a readable network" in named and "trained again" in named
    # each damaged file is replaced by the same network, trained again (training is deterministic)
    assert network_items(cache / "fast") == files
    import joblib
    for f in files:
        assert joblib.load(f)["metadata"]["best_step"] >= 0


def test_cache_path_is_a_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                              capsys: pytest.CaptureFixture[str]) -> None:
    cache = tmp_path / "cache"
    cache.write_text("a file, not a folder\n")
    monkeypatch.setenv("DANAE_CACHE", str(cache))
    code, _, err = run(["reproduce", "--train", str(oxiod_pair(tmp_path / "data", 3)),
                        "--test", str(oxiod_pair(tmp_path / "data", 2)), "--out", str(tmp_path / "out"), *TINY],
                       capsys)
    assert code == 2 and str(cache) in error_line(err)


# ------------------------------------------------------------------ unusable --out
def test_out_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "metrics.json"
    target.write_text("keep me\n")
    code, _, err = run(["reproduce", "--train", str(oxiod_pair(tmp_path / "data", 3)),
                        "--test", str(oxiod_pair(tmp_path / "data", 2)), "--out", str(target), *TINY], capsys)
    msg = error_line(err)
    assert code == 2 and f"--out {target}" in msg and "not a folder" in msg
    assert target.read_text() == "keep me\n"


def test_out_inside_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    parent = tmp_path / "afile"
    parent.write_text("x\n")
    out = parent / "run"
    code, _, err = run(["reproduce", "--train", str(oxiod_pair(tmp_path / "data", 3)),
                        "--test", str(oxiod_pair(tmp_path / "data", 2)), "--out", str(out), *TINY], capsys)
    assert code == 2 and str(out) in error_line(err)
    assert parent.read_text() == "x\n"


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="root may write into a read-only folder")
def test_out_not_writable(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        code, _, err = run(["reproduce", "--train", str(oxiod_pair(tmp_path / "data", 3)),
                            "--test", str(oxiod_pair(tmp_path / "data", 2)), "--out", str(locked / "run"), *TINY],
                           capsys)
    finally:
        locked.chmod(0o755)
    assert code == 2 and str(locked / "run") in error_line(err)


# ------------------------------------------------------------------ bad numbers
@pytest.mark.parametrize("flag, value", [
    ("--seeds", "-1"), ("--seeds", "x"), ("--seeds", "1.5"), ("--seeds", ""),
    ("--epochs", "0"), ("--epochs", "-2"), ("--epochs", "1.5"), ("--epochs", "nan"), ("--epochs", "1e3"),
    ("--epochs", ""), ("--max-steps", "0"), ("--max-steps", "two"), ("--threads", "0"),
])
def test_bad_numbers(flag: str, value: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    code, stdout, err = run(["reproduce", "--out", str(out), *TINY, flag, value], capsys)
    msg = argparse_error_line(err)
    assert code == 2 and f"argument {flag}" in msg
    shown = re.escape(repr(value)) if not re.fullmatch(r"-?\d+", value) else re.escape(value)
    assert re.search(rf"got {shown}$", msg), msg
    assert stdout == "" and not out.exists()


@pytest.mark.parametrize("flag", ["--seeds", "--epochs", "--max-steps", "--threads"])
def test_flag_without_a_number(flag: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["reproduce", flag], capsys)
    assert code == 2 and f"argument {flag}" in argparse_error_line(err)


@pytest.mark.parametrize("seed", [str(2**32), str(2**64)])
def test_seed_beyond_numpy_range(seed: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    code, _, err = run(["reproduce", "--train", str(oxiod_pair(tmp_path / "data", 3)),
                        "--test", str(oxiod_pair(tmp_path / "data", 2)), "--out", str(out), *TINY, "--seeds", seed],
                       capsys)
    assert code == 2 and seed in (argparse_error_line(err) if "usage:" in err else error_line(err))
    assert not out.exists()


def test_largest_seed_numpy_accepts_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The boundary of the fix above: 2**32 - 1 is a valid seed everywhere."""
    code, _, err = run(["reproduce", "--train", str(oxiod_pair(tmp_path / "data", 3)),
                        "--test", str(oxiod_pair(tmp_path / "data", 2)), "--out", str(tmp_path / "out"), *TINY,
                        "--seeds", str(2**32 - 1)], capsys)
    assert code == 0, err


# ------------------------------------------------------------------ a real process
def test_subprocess_short_recording(tmp_path: Path) -> None:
    """The installed entry point: exit status 2 and one stderr line, past the torch imports."""
    short = oxiod_pair(tmp_path / "short", 5, n=10)
    env = {k: v for k, v in os.environ.items() if k not in ("DANAE_DATA", "DANAE_FAST", "DANAE_CACHE")}
    proc = subprocess.run([sys.executable, "-m", "danae_lite", "reproduce", "--train",
                           str(oxiod_pair(tmp_path / "data", 3)), "--test", str(short),
                           "--out", str(tmp_path / "out"), *TINY],
                          capture_output=True, text=True, timeout=300, cwd=REPO, env=env)
    assert proc.returncode == 2, proc.stderr
    msg = error_line(proc.stderr)
    assert str(short) in msg and "10 rows" in msg
    assert not (tmp_path / "out").exists()
