"""OxIOD loader: columns and conventions, strict validation, ground-truth glitches, and the real files."""
from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d
from scipy.signal import savgol_filter
from scipy.spatial.transform import Rotation

from danae_lite.data.recording import DataError
from danae_lite.data.groundtruth import detect_glitches
from danae_lite.data.oxiod import load_recording

from conftest import edit_cell, edit_line, synthetic_oxiod, write_rows


def acc_angles(acc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ax, ay, az = acc.T
    return np.arctan2(ay, np.hypot(ax, az)), np.arctan2(-ax, np.hypot(ay, az))


# --- columns and conventions -------------------------------------------------------------

def test_columns_map_as_documented(tmp_oxiod):
    rec = load_recording(tmp_oxiod.syn / "imu2.csv")
    imu, vi = tmp_oxiod.imu[2], tmp_oxiod.vi[2]
    assert (rec.name, rec.source, rec.fs, len(rec)) == ("handheld/data1/imu2", "oxiod", 100.0, 200)
    np.testing.assert_array_equal(rec.gyro, imu[:, 4:7])
    np.testing.assert_array_equal(rec.acc, imu[:, 7:10] - imu[:, 10:13])
    np.testing.assert_array_equal(rec.mag, imu[:, 13:16])
    np.testing.assert_array_equal(rec.quat, vi[:, 5:9])
    np.testing.assert_array_equal(rec.meta["gravity"], imu[:, 7:10])
    np.testing.assert_array_equal(rec.meta["user_acc"], imu[:, 10:13])
    np.testing.assert_array_equal(rec.meta["phone_euler"], imu[:, 1:4])
    np.testing.assert_array_equal(rec.meta["vicon_position"], vi[:, 2:5])
    assert rec.meta["vi_path"] == str(tmp_oxiod.syn / "vi2.csv")
    assert rec.meta["imu_path"] == str(tmp_oxiod.syn / "imu2.csv")
    assert "gravity - user_acc" in rec.meta["conventions"]
    np.testing.assert_allclose(rec.time[[0, 1, 199]], [0.0, 0.01, 1.99])


def test_explicit_vi_path_and_name(tmp_oxiod):
    rec = load_recording(tmp_oxiod.syn / "imu3.csv", tmp_oxiod.syn / "vi3.csv", name="mine")
    assert rec.name == "mine"
    np.testing.assert_array_equal(rec.quat, tmp_oxiod.vi[3][:, 5:9])


def test_gravity_angles_equal_the_generating_vicon_angles(tmp_oxiod):
    """Roll/pitch from the (phone-frame) gravity match the Vicon rotation, hand-computed."""
    rec = load_recording(tmp_oxiod.syn / "imu4.csv")
    roll, pitch, _ = tmp_oxiod.euler[4].T
    r_acc, p_acc = acc_angles(rec.meta["gravity"])
    np.testing.assert_allclose(p_acc, pitch, atol=1e-12)  # exact for any roll
    expected_roll = np.arctan2(np.sin(roll) * np.cos(pitch),
                               np.hypot(np.sin(pitch), np.cos(roll) * np.cos(pitch)))
    np.testing.assert_allclose(r_acc, expected_roll, atol=1e-12)
    np.testing.assert_allclose(rec.euler[:, :2], np.c_[roll, pitch], atol=1e-12)


# --- validation: every bad input names the file and the line/column ------------------------

def test_missing_ground_truth(tmp_oxiod):
    (tmp_oxiod.syn / "vi2.csv").unlink()
    with pytest.raises(DataError, match=r"vi2\.csv: ground-truth \(Vicon\) file not found"):
        load_recording(tmp_oxiod.syn / "imu2.csv")


def test_missing_imu_file(tmp_oxiod):
    with pytest.raises(DataError, match=r"imu9\.csv: IMU file not found"):
        load_recording(tmp_oxiod.syn / "imu9.csv")


def test_vi_path_cannot_be_inferred(tmp_path):
    with pytest.raises(DataError, match=r"phone\.csv: cannot infer the ground-truth file"):
        load_recording(tmp_path / "phone.csv")


def test_imu_wrong_column_count(tmp_oxiod):
    path = tmp_oxiod.syn / "imu2.csv"
    edit_line(path, 5, path.read_text().splitlines()[4] + ",1.0")
    with pytest.raises(DataError, match=r"imu2\.csv: line 5 has 17 comma-separated columns, expected 16"):
        load_recording(path)


def test_vi_wrong_column_count(tmp_oxiod):
    path = tmp_oxiod.syn / "vi3.csv"
    edit_line(path, 7, ",".join(path.read_text().splitlines()[6].split(",")[:8]))
    with pytest.raises(DataError, match=r"vi3\.csv: line 7 has 8 comma-separated columns, expected 9"):
        load_recording(tmp_oxiod.syn / "imu3.csv")


@pytest.mark.parametrize(
    "file, line, col, value, message",
    [
        ("imu2.csv", 12, 8, "abc", r"imu2\.csv: line 12, column 8 \(gravity x\): expected a finite number, got 'abc'"),
        ("vi2.csv", 3, 6, "", r"vi2\.csv: line 3, column 6 \(rotation x\): expected a finite number, got an empty cell"),
        ("imu2.csv", 20, 14, "nan",
         r"imu2\.csv: line 20, column 14 \(magnetic field x\): expected a finite number, got 'nan'"),
        ("vi2.csv", 9, 9, "-inf", r"vi2\.csv: line 9, column 9 \(rotation w\): expected a finite number, got '-inf'"),
    ],
    ids=["non-numeric", "empty", "nan", "inf"],
)
def test_bad_cell_is_named(tmp_oxiod, file, line, col, value, message):
    edit_cell(tmp_oxiod.syn / file, line, col, value)
    with pytest.raises(DataError, match=message):
        load_recording(tmp_oxiod.syn / "imu2.csv")


def test_empty_line_is_not_skipped(tmp_oxiod):
    edit_line(tmp_oxiod.syn / "imu2.csv", 50, "")
    with pytest.raises(DataError, match=r"imu2\.csv: line 50 is empty; expected 16 comma-separated numbers"):
        load_recording(tmp_oxiod.syn / "imu2.csv")


def test_row_count_mismatch(tmp_oxiod):
    edit_line(tmp_oxiod.syn / "vi2.csv", 200, None)
    with pytest.raises(DataError, match=r"imu2\.csv has 200 rows but its ground truth .*vi2\.csv has 199"):
        load_recording(tmp_oxiod.syn / "imu2.csv")


def test_too_short(tmp_path):
    imu, vi, _ = synthetic_oxiod(n=19)
    write_rows(tmp_path / "imu1.csv", imu)
    write_rows(tmp_path / "vi1.csv", vi)
    with pytest.raises(DataError, match=r"imu1\.csv: 19 rows; at least 20 are needed "
                                        r"\(one DANAE window is 20 samples\)"):
        load_recording(tmp_path / "imu1.csv")
    assert len(load_recording(tmp_path / "imu1.csv", min_samples=19)) == 19


def test_zero_quaternion(tmp_oxiod):
    path = tmp_oxiod.syn / "vi2.csv"
    for col in (6, 7, 8, 9):
        edit_cell(path, 4, col, "0")
    with pytest.raises(DataError, match=r"vi2\.csv: line 4, columns 6-9 .*quaternion is zero"):
        load_recording(tmp_oxiod.syn / "imu2.csv")


# --- ground-truth glitches -------------------------------------------------------------------

def glitchy_quats() -> np.ndarray:
    n = 200
    yaw = 1.0 * np.arange(n) / 100.0  # 1 rad/s: 0.01 rad per sample
    rot = Rotation.from_euler("z", yaw[:, None])
    kick = Rotation.from_euler("x", 0.5)
    q = rot.as_quat()
    q[50] = (rot[50] * kick).as_quat()            # single-sample spike
    q[121:] = (rot[121:] * kick).as_quat()        # isolated jump between 120 and 121
    q[150:156] = q[150]                           # frozen for 6 samples
    q[170:174] = q[170]                           # frozen for 4 samples: too short to count
    return q


def test_glitches_of_each_kind():
    r = detect_glitches(glitchy_quats(), 100.0)  # without the gyro, as for an OxIOD ground truth
    assert r.threshold_rad == pytest.approx(0.2)
    assert r.steps.size == 3
    assert r.spikes.tolist() == [50]
    assert r.jumps.tolist() == [120]
    assert r.frozen.tolist() == [[150, 6]]
    assert r.max_step_rad == pytest.approx(0.5, abs=0.011)


def test_glitch_threshold_scales_with_rate():
    r = detect_glitches(glitchy_quats(), 10.0)  # 2 rad per sample: nothing is a glitch
    assert (r.steps.size, r.spikes.size, r.jumps.size) == (0, 0, 0)


def test_synthetic_ground_truth_has_no_glitches(tmp_oxiod):
    rec = load_recording(tmp_oxiod.syn / "imu2.csv")
    r = detect_glitches(rec.quat, rec.fs)
    assert (r.steps.size, len(r.frozen)) == (0, 0)


# --- the real files (DANAE_DATA) ---------------------------------------------------------------

ROWS = {2: 23_446, 3: 18_850, 4: 21_641, 7: 14_098}


@pytest.fixture(scope="module")
def real(oxiod_dir):
    syn = oxiod_dir / "handheld" / "data1" / "syn"
    return {k: load_recording(syn / f"imu{k}.csv") for k in ROWS}


@pytest.mark.realdata
def test_real_rows_rate_and_finite(real, oxiod_dir):
    for k, rec in real.items():
        assert len(rec) == ROWS[k] and rec.fs == 100.0 and rec.name == f"handheld/data1/imu{k}"
        for arr in (rec.gyro, rec.acc, rec.mag, rec.quat):
            assert np.isfinite(arr).all()
        np.testing.assert_allclose(np.linalg.norm(rec.quat, axis=1), 1.0, atol=1e-4)
        assert 0.95 < np.median(np.linalg.norm(rec.meta["gravity"], axis=1)) < 1.05
        assert 30.0 < np.median(np.linalg.norm(rec.mag, axis=1)) < 60.0  # µT, Earth's field indoors


@pytest.mark.realdata
def test_real_acc_xy_follow_vicon_and_z_is_flipped(real):
    for rec in real.values():
        up = Rotation.from_quat(rec.quat).inv().apply([0.0, 0.0, 1.0])
        v = rec.acc * [1.0, 1.0, -1.0]
        cos = np.sum(v * up, axis=1) / np.linalg.norm(v, axis=1)
        assert np.median(cos) > 0.98  # measured 0.993-0.996
        cos_unflipped = np.sum(rec.acc * up, axis=1) / np.linalg.norm(rec.acc, axis=1)
        assert np.median(cos_unflipped) < -0.4  # measured -0.57 to -0.68


@pytest.mark.realdata
def test_real_acc_roll_pitch_agree_in_sign_with_vicon(real):
    for rec in real.values():
        up = Rotation.from_quat(rec.quat).inv().apply([0.0, 0.0, 1.0])
        r_gt, p_gt = acc_angles(up)
        r_acc, p_acc = acc_angles(rec.acc)
        # the phone is held tilted by about -0.4 rad of roll: a sign error would give +0.4
        assert np.median(r_gt) < -0.3
        assert abs(np.median(r_acc) - np.median(r_gt)) < 0.1
        # walking accelerations average out over 1 s; then acc and Vicon angles co-vary
        f = lambda x: uniform_filter1d(x, 100)  # noqa: E731
        assert np.corrcoef(f(r_acc), f(r_gt))[0, 1] > 0.6   # measured 0.70-0.77
        assert np.corrcoef(f(p_acc), f(p_gt))[0, 1] > 0.55  # measured 0.64-0.66


@pytest.mark.realdata
def test_real_user_acc_is_minus_the_kinematic_acceleration(real):
    """user_acc (phone frame, x/y negated into the Vicon frame) vs d²(Vicon position)/dt².

    Samples within 0.3 s of a ground-truth step > 0.05 rad (a glitch) are left out.
    """
    for rec in real.values():
        acc_world = savgol_filter(rec.meta["vicon_position"], 31, 3, deriv=2, delta=rec.dt, axis=0) / 9.80665
        rot = Rotation.from_quat(rec.quat)
        acc_body = rot.inv().apply(acc_world)
        user = rec.meta["user_acc"] * [-1.0, -1.0, 1.0]
        keep = np.ones(len(rec), bool)
        keep[:100] = keep[-100:] = False
        for i in np.flatnonzero((rot[:-1].inv() * rot[1:]).magnitude() > 0.05):
            keep[max(0, i - 30):i + 31] = False
        corr = [np.corrcoef(user[keep, i], acc_body[keep, i])[0, 1] for i in range(3)]
        assert max(corr) < -0.7, corr  # measured -0.79 to -0.91


@pytest.mark.realdata
def test_real_glitch_steps_match_scipy(real):
    for rec in real.values():
        rot = Rotation.from_quat(rec.quat)
        steps = (rot[:-1].inv() * rot[1:]).magnitude()
        r = detect_glitches(rec.quat, rec.fs)
        assert r.steps.size == int((steps > 0.2).sum()) > 0
        assert r.max_step_rad == pytest.approx(steps.max(), abs=1e-6)


@pytest.mark.realdata
def test_real_loading_is_fast(oxiod_dir):
    path = oxiod_dir / "handheld" / "data1" / "syn" / "imu2.csv"
    load_recording(path)
    t0 = time.perf_counter()
    load_recording(path)
    assert time.perf_counter() - t0 < 1.0
