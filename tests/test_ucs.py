"""UCS (ADIS16480) loader: header names, units, accelerometer sign, validation and the 80/20 split."""
from __future__ import annotations


import numpy as np
import pytest

from danae_lite.data.recording import DataError
from danae_lite.data.ucs import HEADER, load_recording, split_train_test

from conftest import T0, UCS_HEADER, G, columns, edit_cell, ucs_signals, write_ucs


@pytest.fixture
def ucs_path(tmp_path):
    return write_ucs(tmp_path / "full_dataset" / "imu_adis.txt")


# --- layout, units and sign -----------------------------------------------------------------

def test_header_is_the_export_layout():
    assert list(HEADER) == UCS_HEADER  # the loader's documented header
    # the DANAE authors' column indices: roll 3, qx 6, mx 11, ax 14, gx 17, bx 20
    first = ("field.roll", "field.qx", "field.mx", "field.ax", "field.gx", "field.bx")
    assert [UCS_HEADER.index(c) for c in first] == [3, 6, 11, 14, 17, 20]


def test_columns_units_and_rate(ucs_path):
    sig = ucs_signals()
    rec = load_recording(ucs_path)
    assert (rec.name, rec.source, len(rec)) == ("ucs/imu_adis", "ucs", 300)
    np.testing.assert_allclose(rec.acc, sig["a"] / G, rtol=1e-15)
    np.testing.assert_allclose(rec.mag, sig["m"] * 100.0, rtol=1e-15)  # gauss -> µT
    np.testing.assert_array_equal(rec.gyro, sig["g"])
    np.testing.assert_array_equal(rec.quat, sig["q"])
    np.testing.assert_array_equal(rec.meta["gyro_bias"], sig["b"])
    euler = np.c_[sig["field.roll"], sig["field.pitch"], sig["field.yaw"]]
    np.testing.assert_array_equal(rec.meta["adis_euler"], euler)
    np.testing.assert_array_equal(rec.meta["timestamps_raw"], sig["%time"])
    assert rec.meta["timestamps_raw"].dtype == np.int64
    assert rec.meta["units"] == {"time": "ns", "acc": "m/s^2", "gyro": "rad/s", "mag": "gauss"}
    assert (rec.meta["acc_sign"], rec.meta["acc_sign_agreement"] > 0.99) == (1, True)
    assert rec.fs == pytest.approx(1e9 / np.median(np.diff(sig["%time"])), rel=1e-9)
    assert rec.fs == pytest.approx(10.2, rel=0.01)
    np.testing.assert_allclose(np.linalg.norm(rec.mag, axis=1), 48.0, rtol=1e-12)


def test_accelerometer_sign_auto_flips_a_ned_style_file(tmp_path):
    sig = ucs_signals()
    sig["a"] = -sig["a"]  # a specific force in an NED-like frame: -R.T @ [0, 0, 1] g at rest
    rec = load_recording(write_ucs(tmp_path / "imu_adis.txt", sig))
    assert rec.meta["acc_sign"] == -1
    np.testing.assert_allclose(rec.acc, sig["up"], atol=0.01)  # tilt convention: R.T @ [0, 0, 1]
    forced = load_recording(tmp_path / "imu_adis.txt", acc_sign=1)
    np.testing.assert_allclose(forced.acc, sig["a"] / G, rtol=1e-15)


def test_accelerometer_sign_ambiguous(tmp_path):
    sig = ucs_signals()
    sig["a"] = np.cross(sig["up"], [1.0, 0.0, 0.0]) * G  # perpendicular to up
    with pytest.raises(DataError, match=r"imu_adis\.txt: cannot tell the accelerometer sign .*acc_sign=\+1 or -1"):
        load_recording(write_ucs(tmp_path / "imu_adis.txt", sig))
    with pytest.raises(DataError, match=r"acc_sign must be \+1, -1 or 'auto', got 2"):
        load_recording(tmp_path / "imu_adis.txt", acc_sign=2)


@pytest.mark.parametrize("unit, factor", [("T", 1e-4), ("mgauss", 1e3), ("uT", 100.0), ("nT", 1e5)])
def test_magnetometer_unit_detection(tmp_path, unit, factor):
    sig = ucs_signals()
    sig["m"] = sig["m"] * factor  # gauss -> unit
    rec = load_recording(write_ucs(tmp_path / "imu_adis.txt", sig))
    assert rec.meta["units"]["mag"] == unit
    np.testing.assert_allclose(np.linalg.norm(rec.mag, axis=1), 48.0, rtol=1e-9)


def test_magnetometer_unit_explicit_and_undetectable(tmp_path):
    sig = ucs_signals()
    sig["m"] = sig["m"] * 10.0  # 4.8 in file units: no unit gives 15-95 µT
    path = write_ucs(tmp_path / "imu_adis.txt", sig)
    with pytest.raises(DataError, match=r"imu_adis\.txt: cannot infer the magnetometer unit .*units=\{'mag': \.\.\.\}"):
        load_recording(path)
    rec = load_recording(path, units={"mag": "uT"})
    np.testing.assert_allclose(np.linalg.norm(rec.mag, axis=1), 4.8, rtol=1e-9)


def test_unknown_unit_names_it_and_the_allowed_ones(ucs_path):
    with pytest.raises(DataError, match=r"imu_adis\.txt: unknown acc unit 'ft/s\^2'; allowed: m/s\^2, m/s2, g"):
        load_recording(ucs_path, units={"acc": "ft/s^2"})
    with pytest.raises(DataError, match=r"unknown quantity 'speed' in units; allowed: time, acc, gyro, mag"):
        load_recording(ucs_path, units={"speed": "m/s"})


def test_other_units(ucs_path):
    sig = ucs_signals()
    rec = load_recording(ucs_path, units={"acc": "g", "gyro": "deg/s", "mag": "gauss"})
    np.testing.assert_allclose(rec.acc, sig["a"], rtol=1e-15)
    np.testing.assert_allclose(rec.gyro, np.radians(sig["g"]), rtol=1e-15)


def test_time_unit_gives_implausible_rate(ucs_path):
    with pytest.raises(DataError, match=r"%time column gives 1\.0\d*e-08 Hz with time unit 's'"):
        load_recording(ucs_path, units={"time": "s"})


# --- reading by header name -----------------------------------------------------------------

def test_header_whitespace_percent_and_order_are_tolerated(tmp_path):
    sig = ucs_signals()
    order = list(UCS_HEADER)
    order[6:10] = order[9:5:-1]  # qw, qz, qy, qx
    header = [f"  {h} " for h in order]
    header[0] = " %time"
    header.insert(3, "field.header.frame_id")
    rec = load_recording(write_ucs(tmp_path / "imu_adis.txt", sig, header=header,
                                   extra={"field.header.frame_id": ["adis"] * 300}))
    np.testing.assert_array_equal(rec.quat, sig["q"])
    np.testing.assert_allclose(rec.acc, sig["a"] / G, rtol=1e-15)


def test_time_column_without_percent(tmp_path):
    header = ["time"] + UCS_HEADER[1:]
    rec = load_recording(write_ucs(tmp_path / "imu_adis.txt", header=header))
    assert rec.fs == pytest.approx(10.2, rel=0.01)


def test_float_seconds_time_column(tmp_path):
    sig = ucs_signals()
    sig["%time"] = (sig["%time"] - T0) / 1e9 + 1.4377e9  # seconds, as floats
    rec = load_recording(write_ucs(tmp_path / "imu_adis.txt", sig), units={"time": "s"})
    assert rec.meta["timestamps_raw"].dtype == np.float64
    assert rec.fs == pytest.approx(1.0 / np.median(np.diff(sig["%time"])), rel=1e-9)


def test_missing_header_columns_are_named(tmp_path):
    header = [h for h in UCS_HEADER if h not in ("field.qw", "field.mx")]
    path = tmp_path / "imu_adis.txt"
    sig_cols = columns(ucs_signals())
    path.write_text(",".join(header) + "\n" + "\n".join(
        ",".join(sig_cols[h][i] for h in header) for i in range(300)) + "\n")
    with pytest.raises(DataError, match=r"imu_adis\.txt: header row lacks column\(s\) field\.qw, field\.mx"):
        load_recording(path)


def test_optional_columns_may_be_absent(tmp_path):
    keep = [h for h in UCS_HEADER if h not in ("field.roll", "field.pitch", "field.yaw", "field.temp", "field.bx",
                                           "field.by", "field.bz", "field.header.stamp")]
    sig_cols = columns(ucs_signals())
    path = tmp_path / "imu_adis.txt"
    rows = (",".join(sig_cols[h][i] for h in keep) for i in range(300))
    path.write_text(",".join(keep) + "\n" + "\n".join(rows) + "\n")
    rec = load_recording(path)
    assert len(rec) == 300 and "gyro_bias" not in rec.meta and "adis_euler" not in rec.meta


# --- validation -----------------------------------------------------------------------------

def test_missing_file(tmp_path):
    with pytest.raises(DataError, match=r"imu_adis\.txt: UCS ADIS file not found"):
        load_recording(tmp_path / "imu_adis.txt")


def test_wrong_column_count_on_a_row(ucs_path):
    lines = ucs_path.read_text().splitlines()
    lines[6] += ",0.5"
    ucs_path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"imu_adis\.txt: line 7 has 24 comma-separated columns, expected 23"):
        load_recording(ucs_path)


@pytest.mark.parametrize(
    "line, col, value, message",
    [
        (10, 16, "x", r"imu_adis\.txt: line 10, column 16 \(field\.ay\): expected a finite number, got 'x'"),
        (33, 8, "NaN", r"imu_adis\.txt: line 33, column 8 \(field\.qy\): expected a finite number, got 'NaN'"),
        (2, 19, "inf", r"imu_adis\.txt: line 2, column 19 \(field\.gy\): expected a finite number, got 'inf'"),
        (301, 12, "", r"imu_adis\.txt: line 301, column 12 \(field\.mx\): expected a finite number, got an empty cell"),
    ],
    ids=["non-numeric", "nan", "inf", "empty"],
)
def test_bad_cell_is_named(ucs_path, line, col, value, message):
    edit_cell(ucs_path, line, col, value)
    with pytest.raises(DataError, match=message):
        load_recording(ucs_path)


def test_unused_column_may_hold_text(ucs_path):
    edit_cell(ucs_path, 5, 2, "n/a")  # field.header.seq is not used
    assert len(load_recording(ucs_path)) == 300


def test_time_must_increase(ucs_path):
    lines = ucs_path.read_text().splitlines()
    lines[40], lines[41] = lines[41], lines[40]  # data rows 40 and 41 (file lines 41, 42)
    ucs_path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"imu_adis\.txt: line 42, column 1 \(%time\): time does not increase"):
        load_recording(ucs_path)


def test_too_short(tmp_path):
    sig = {k: v[:19] for k, v in ucs_signals().items()}
    path = write_ucs(tmp_path / "imu_adis.txt", sig)
    with pytest.raises(DataError, match=r"imu_adis\.txt: 19 data rows; at least 20 are needed \(one DANAE window"):
        load_recording(path)
    assert len(load_recording(path, min_samples=19)) == 19


def test_empty_file(tmp_path):
    path = tmp_path / "imu_adis.txt"
    path.write_text("")
    with pytest.raises(DataError, match=r"imu_adis\.txt: empty file; expected a header row"):
        load_recording(path)


# --- split -----------------------------------------------------------------------------------

def test_split_80_20_loses_no_row(ucs_path):
    rec = load_recording(ucs_path)
    train, test = split_train_test(rec)
    assert (len(train), len(test)) == (240, 60)
    assert (train.name, test.name) == ("ucs/imu_adis[train]", "ucs/imu_adis[test]")
    for key in ("gyro", "acc", "mag", "quat"):
        np.testing.assert_array_equal(np.r_[getattr(train, key), getattr(test, key)], getattr(rec, key))
    np.testing.assert_array_equal(test.meta["timestamps_raw"], rec.meta["timestamps_raw"][240:])
    np.testing.assert_array_equal(train.meta["gyro_bias"], rec.meta["gyro_bias"][:240])
    assert (train.meta["offset"], test.meta["offset"]) == (0, 240)
    assert [len(p) for p in split_train_test(rec, 0.7)] == [210, 90]


def test_split_bad_fraction(ucs_path):
    rec = load_recording(ucs_path)
    for bad in (0.0, 1.0, -0.2, 1.5):
        with pytest.raises(ValueError, match="train_fraction must be in"):
            split_train_test(rec, bad)
    with pytest.raises(DataError, match="cannot be split"):
        split_train_test(rec, 0.001)
