"""Frame alignment: known rotations recovered on the simulator, the OxIOD specific force checked on real data."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from danae_lite.data.alignment import (FrameAlignment, estimate_alignment, rate_lag,
                                       specific_force)
from danae_lite.data.recording import Recording
from danae_lite.data.simulate import SensorErrors, simulate

TRUE_ROTVEC = np.array([0.05, -0.08, 2.9])  # ~170 degrees, mostly about z, like the OxIOD phone


def _recordings(north_yaw: float = 0.0, lag: int = 0) -> list[Recording]:
    err = SensorErrors.none(misalignment=float(np.linalg.norm(TRUE_ROTVEC)), misalignment_axis=tuple(TRUE_ROTVEC))
    out = []
    for seed in (1, 2):
        rec = simulate("handheld", duration=40.0, seed=seed, errors=err)
        quat = (Rotation.from_euler("z", north_yaw) * Rotation.from_quat(rec.quat)).as_quat()
        if lag:
            quat = np.vstack([np.repeat(quat[:1], lag, axis=0), quat[:-lag]])  # truth delayed by `lag` samples
        out.append(Recording(rec.name, rec.source, rec.fs, rec.gyro, rec.acc, rec.mag, quat, rec.meta))
    return out


def test_recovers_a_known_sensor_to_body_rotation_and_north():
    recs = _recordings(north_yaw=0.7)
    al = estimate_alignment(recs)
    err = (al.rotation * Rotation.from_rotvec(TRUE_ROTVEC).inv()).magnitude()
    assert np.degrees(err) < 0.3
    assert al.north_yaw == pytest.approx(0.7, abs=np.radians(0.3))
    assert np.degrees(al.rate_residual) < 1.0


def test_rate_lag_finds_a_delayed_ground_truth():
    recs = _recordings(lag=4)
    assert [rate_lag(r) for r in recs] == [4, 4]
    al = estimate_alignment(recs)
    assert al.lags == {r.name: 4 for r in recs}
    assert np.degrees((al.rotation * Rotation.from_rotvec(TRUE_ROTVEC).inv()).magnitude()) < 0.5


def test_apply_rotates_sensors_into_the_body_frame():
    rec = _recordings()[0]
    al = FrameAlignment(Rotation.from_rotvec(TRUE_ROTVEC).as_quat(), 0.0)
    body = al.apply(rec)
    np.testing.assert_allclose(body.gyro, rec.meta["true_gyro"], atol=1e-9)
    np.testing.assert_allclose(body.acc, rec.meta["true_acc"], atol=1e-9)
    np.testing.assert_allclose(body.mag, rec.meta["true_mag"], atol=1e-9)
    e = np.array([[0.1, 0.2, 3.0]])
    np.testing.assert_allclose(FrameAlignment(al.sensor_to_body, 0.5).to_truth_frame(e),
                               [[0.1, 0.2, 3.5 - 2 * np.pi]])


def test_clean_masks_must_match():
    recs = _recordings()
    with pytest.raises(ValueError, match="clean mask has shape"):
        estimate_alignment(recs, [np.ones(5, bool), np.ones(len(recs[1]), bool)])
    with pytest.raises(ValueError, match="at least one recording"):
        estimate_alignment([])


def test_oxiod_specific_force_points_up_on_a_static_stretch(oxiod_dir):
    """Sign check on real data: where the phone is still, -(gravity + user_acc) rotated into the
    Vicon body and then into the Vicon world is +z (up), within a few degrees."""
    from danae_lite.data.groundtruth import clean_mask
    from danae_lite.data.oxiod import load_recording

    rec = load_recording(oxiod_dir / "handheld" / "data1" / "syn" / "imu3.csv")
    al = estimate_alignment([rec], [clean_mask(rec)])
    from scipy.ndimage import uniform_filter1d

    # "still": over 0.5 s the rotation rate averages below 0.1 rad/s and the user acceleration below 0.03 g
    rate = uniform_filter1d(np.linalg.norm(rec.gyro, axis=1), 50)
    user = uniform_filter1d(np.linalg.norm(rec.meta["user_acc"], axis=1), 50)
    still = (rate < 0.1) & (user < 0.03)
    assert still.sum() > 100, "expected quiet stretches of at least 1 s in total"
    f = specific_force(rec)[still]
    up = Rotation.from_quat(rec.quat[still]).apply(al.rotation.apply(f / np.linalg.norm(f, axis=1, keepdims=True)))
    assert np.median(up[:, 2]) > np.cos(np.radians(5.0))
    # the authors' gravity - user_acc is not a specific force: its z points the other way
    authors = rec.acc[still]
    assert np.median(np.sign(authors[:, 2]) * np.sign(f[:, 2])) < 0
    # the phone sits turned roughly 170 degrees about z relative to the Vicon body
    assert 150 < np.degrees(al.rotation.magnitude()) < 180
