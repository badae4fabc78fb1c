"""Tests of the IMU/AHRS simulator: ground truth, conventions, error sources, determinism."""
from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from danae_lite.angles import angle_diff, quat_to_euler
from danae_lite.data.simulate import (AUTHORS_UCS_STD, ERROR_SOURCES, G, MAG_REF,
                                      SCENARIOS, SensorErrors, rotation_matrices,
                                      simulate)

UP = np.array([0.0, 0.0, 1.0])
SENSORS = ("gyro", "acc", "mag")


@pytest.fixture(scope="module")
def clean() -> dict:
    """Error-free recordings of both scenarios at their default rate and length."""
    return {sc: simulate(sc, errors=SensorErrors.none()) for sc in SCENARIOS}


def _prefix_product(steps: Rotation) -> Rotation:
    """Cumulative composition steps[0] * steps[1] * ... * steps[k] for every k (doubling scan)."""
    q, shift = steps.as_quat(), 1
    while shift < len(q):
        r = Rotation.from_quat(q)
        q = np.concatenate([q[:shift], (r[:-shift] * r[shift:]).as_quat()])
        shift *= 2
    return Rotation.from_quat(q)


def _integrate(rec, substeps: int = 1) -> Rotation:
    """Integrate the body rates from the true initial attitude (coning-corrected trapezoid)."""
    t = rec.time
    fine = np.linspace(t[0], t[-1], (len(t) - 1) * substeps + 1)
    w = CubicSpline(t, rec.gyro)(fine) if substeps > 1 else rec.gyro
    dt = rec.dt / substeps
    steps = Rotation.from_rotvec(0.5 * (w[:-1] + w[1:]) * dt + np.cross(w[:-1], w[1:]) * dt**2 / 12)
    rots = Rotation.from_quat(rec.quat[0]) * _prefix_product(steps)
    return rots[substeps - 1 :: substeps]


def _attitude_error(rec, substeps: int) -> tuple[float, float]:
    rots = _integrate(rec, substeps)
    truth = Rotation.from_quat(rec.quat[1:])
    angle = (rots.inv() * truth).magnitude().max()
    euler = np.abs(angle_diff(quat_to_euler(rots.as_quat()), rec.euler[1:])).max()
    return float(angle), float(euler)


def test_gyro_integration_reproduces_handheld_truth(clean):
    rec = clean["handheld"]
    coarse, _ = _attitude_error(rec, 1)
    fine, fine_euler = _attitude_error(rec, 2)
    assert fine < 1e-3 and fine_euler < 1e-3
    # Only discretisation error is left: halving the step divides it by ~4 (second order).
    assert 3.0 < coarse / fine < 5.0


def test_gyro_integration_reproduces_underwater_truth(clean):
    angle, euler = _attitude_error(clean["underwater"], 1)
    assert angle < 1e-4 and euler < 1e-4


def test_rotation_matrices_match_quaternion(clean):
    for rec in clean.values():
        np.testing.assert_allclose(rotation_matrices(rec.euler), Rotation.from_quat(rec.quat).as_matrix(), atol=1e-12)


def test_noise_free_acc_and_mag_are_rotated_reference_vectors(clean):
    for sc, rec in clean.items():
        inv = Rotation.from_quat(rec.quat).inv()
        np.testing.assert_allclose(rec.acc, inv.apply(np.tile(UP, (len(rec), 1))), atol=1e-12)
        np.testing.assert_allclose(rec.mag, inv.apply(np.tile(MAG_REF, (len(rec), 1))), atol=1e-10)
        moving = simulate(sc, errors=SensorErrors.none(motion=1.0))
        expected = inv.apply(UP + moving.meta["linear_acc"] / G)
        np.testing.assert_allclose(moving.acc, expected, atol=1e-12)
        np.testing.assert_array_equal(moving.gyro, rec.gyro)
    np.testing.assert_allclose(MAG_REF, [24.0, 0.0, -48 * np.sin(np.pi / 3)], atol=1e-12)


def test_motion_levels():
    hand = simulate("handheld", errors=SensorErrors.none(motion=1.0)).meta["linear_acc"] / G
    assert 0.1 <= np.abs(hand[:, 2]).max() <= 0.25  # vertical bounce [g]
    assert 0.03 < np.abs(hand[:, :2]).max() < 0.2  # step surge/sway and centripetal [g]
    auv = simulate("underwater", errors=SensorErrors.none(motion=1.0)).meta["linear_acc"] / G
    assert 1e-3 < np.abs(auv).max() < 0.03
    half = simulate("handheld", errors=SensorErrors.none(motion=0.5)).meta["linear_acc"] / G
    np.testing.assert_allclose(half, 0.5 * hand, atol=1e-15)


def test_paper_formulas_at_rest(clean):
    for rec in clean.values():
        ax, ay, az = rec.acc.T
        mx, my, mz = (rec.mag / np.linalg.norm(rec.mag, axis=1, keepdims=True)).T
        phi, theta, psi = rec.euler.T
        roll_acc = np.arctan2(ay, np.sqrt(ax**2 + az**2))
        pitch_acc = np.arctan2(-ax, np.sqrt(ay**2 + az**2))
        yaw_mag = np.arctan2(-my * np.cos(phi) + mz * np.sin(phi),
                             mx * np.cos(theta) + my * np.sin(theta) * np.sin(phi) + mz * np.sin(theta) * np.cos(phi))
        level = np.sqrt(np.sin(theta) ** 2 + (np.cos(theta) * np.cos(phi)) ** 2)
        roll_closed = np.arctan2(np.cos(theta) * np.sin(phi), level)
        np.testing.assert_allclose(pitch_acc, theta, atol=1e-12)
        np.testing.assert_allclose(roll_acc, roll_closed, atol=1e-12)
        assert np.abs(angle_diff(yaw_mag, psi)).max() < 1e-10
    # roll_acc is not the roll when pitch is non-zero
    rec = clean["handheld"]
    ax, ay, az = rec.acc.T
    assert np.abs(np.arctan2(ay, np.sqrt(ax**2 + az**2)) - rec.euler[:, 0]).max() > 1e-3


def test_trajectory_shapes(clean):
    hand, auv = clean["handheld"], clean["underwater"]
    assert (hand.fs, len(hand), auv.fs, len(auv)) == (100.0, 18000, 10.0, 19500)
    assert np.abs(hand.euler[:, :2]).max() < 0.45 and np.abs(hand.euler[:, :2]).max() > 0.1
    assert np.abs(auv.euler[:, :2]).max() < 0.2
    for rec in (hand, auv):
        yaw = np.unwrap(rec.euler[:, 2])
        assert np.abs(np.diff(yaw)).sum() > 2 * np.pi  # the path turns
    # step-frequency sway dominates the handheld body rate spectrum
    spec = np.abs(np.fft.rfft(hand.gyro[:, 1] - hand.gyro[:, 1].mean())) ** 2
    freq = np.fft.rfftfreq(len(hand), hand.dt)
    assert 1.5 < freq[np.argmax(spec)] < 2.1


def test_determinism_and_seeds():
    a, b = simulate("handheld", duration=30, seed=3), simulate("handheld", duration=30, seed=3)
    for key in SENSORS + ("quat",):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    for key in ("true_gyro", "gyro_bias", "mag_disturbance"):
        np.testing.assert_array_equal(a.meta[key], b.meta[key])
    c = simulate("handheld", duration=30, seed=4)
    assert np.abs(a.quat - c.quat).max() > 0.1
    noise_a, noise_c = a.gyro - a.meta["true_gyro"], c.gyro - c.meta["true_gyro"]
    assert np.abs(noise_a - noise_c).max() > 1e-3
    assert (a.name, a.source) == ("sim-handheld-3", "simulated:handheld")
    assert (a.meta["seed"], a.meta["scenario"]) == (3, "handheld")
    assert a.meta["errors"] == dataclasses.asdict(SensorErrors.handheld())
    assert simulate("underwater", duration=5, name="x").name == "x"


def test_switching_one_source_off_keeps_other_draws():
    full = SensorErrors.handheld()
    a = simulate("handheld", duration=20, seed=1, errors=full)
    b = simulate("handheld", duration=20, seed=1, errors=dataclasses.replace(full, gyro_bias=0.0))
    np.testing.assert_array_equal(a.acc, b.acc)
    np.testing.assert_array_equal(a.mag, b.mag)
    bias = a.meta["gyro_bias"] - b.meta["gyro_bias"]
    np.testing.assert_allclose(a.gyro - b.gyro, bias, atol=1e-15)
    assert np.abs(bias).max() > 1e-4
    c = simulate("handheld", duration=20, seed=1, errors=dataclasses.replace(full, acc_noise=0.05))
    np.testing.assert_array_equal(a.gyro, c.gyro)
    np.testing.assert_array_equal(a.mag, c.mag)


CHANGES = {
    "gyro_noise": {"gyro"}, "gyro_bias": {"gyro"}, "gyro_bias_walk": {"gyro"},
    "acc_noise": {"acc"}, "acc_bias": {"acc"}, "motion": {"acc"},
    "mag_noise": {"mag"}, "hard_iron": {"mag"}, "soft_iron": {"mag"}, "mag_disturbance": {"mag"},
    "mag_hold": {"mag"}, "misalignment": {"gyro", "acc", "mag"}, "authors_ucs_noise": {"gyro", "acc"},
}


@pytest.mark.parametrize("source", ERROR_SOURCES)
def test_each_source_changes_only_its_sensors(source, clean):
    errors = SensorErrors.handheld(mag_hold=3, authors_ucs_noise=True).only(source)
    assert errors.active() == (source,)
    rec, base = simulate("handheld", errors=errors), clean["handheld"]
    np.testing.assert_array_equal(rec.quat, base.quat)
    for sensor in SENSORS:
        same = np.array_equal(getattr(rec, sensor), getattr(base, sensor))
        assert same == (sensor not in CHANGES[source]), f"{source} -> {sensor}"


def _only(**values) -> SensorErrors:
    return SensorErrors.none(**values)


@pytest.mark.parametrize(("field", "sensor", "true_key", "sigma"), [
    ("gyro_noise", "gyro", "true_gyro", 0.01),
    ("acc_noise", "acc", "true_acc", 0.003),
    ("mag_noise", "mag", "true_mag", 0.4),
])
def test_white_noise_std(field, sensor, true_key, sigma):
    rec = simulate("underwater", seed=2, errors=_only(**{field: sigma}))
    err = getattr(rec, sensor) - rec.meta[true_key]
    np.testing.assert_allclose(err.std(axis=0), sigma, rtol=0.02)
    assert np.abs(err.mean(axis=0)).max() < 4 * sigma / np.sqrt(len(rec))
    assert np.abs(np.corrcoef(err[1:, 0], err[:-1, 0])[0, 1]) < 0.03  # white


def test_authors_ucs_noise():
    rec = simulate("underwater", seed=5, errors=_only(authors_ucs_noise=True))
    g_err, a_err = rec.gyro - rec.meta["true_gyro"], rec.acc - rec.meta["true_acc"]
    np.testing.assert_allclose(g_err.std(axis=0), AUTHORS_UCS_STD, rtol=0.02)
    np.testing.assert_allclose(a_err.std(axis=0) * G, 0.5, rtol=0.02)  # 0.5 m/s² in g
    assert abs(np.corrcoef(g_err[:, 0], a_err[:, 0])[0, 1]) < 0.03  # independent draws
    np.testing.assert_array_equal(rec.mag, rec.meta["true_mag"])
    other = simulate("underwater", seed=6, errors=_only(authors_ucs_noise=True))
    assert np.abs((other.acc - other.meta["true_acc"]) - a_err).max() > 0.01  # seeded per recording


def test_constant_biases():
    draws = np.array([simulate("handheld", duration=0.5, seed=s, errors=_only(gyro_bias=0.02, acc_bias=0.01))
                      .meta["gyro_bias"][0] for s in range(300)])
    np.testing.assert_allclose(draws.std(), 0.02, rtol=0.08)
    rec = simulate("handheld", duration=5, errors=_only(gyro_bias_fixed=(0.1, -0.2, 0.3), acc_bias_fixed=(0.01, 0, 0)))
    np.testing.assert_allclose(rec.gyro - rec.meta["true_gyro"], np.tile([0.1, -0.2, 0.3], (len(rec), 1)), atol=1e-14)
    np.testing.assert_allclose(rec.acc - rec.meta["true_acc"], np.tile([0.01, 0, 0], (len(rec), 1)), atol=1e-14)


def test_bias_random_walk_variance_grows_linearly():
    sigma, fs, duration = 0.01, 100.0, 4.0
    rec = simulate("underwater", errors=_only(gyro_bias_walk=sigma))
    steps = np.diff(rec.meta["gyro_bias"], axis=0)
    np.testing.assert_allclose(steps.std(), sigma * np.sqrt(rec.dt), rtol=0.03)
    walks = np.concatenate([simulate("handheld", duration=duration, fs=fs, seed=s, errors=_only(gyro_bias_walk=sigma))
                            .meta["gyro_bias"] for s in range(400)], axis=1)  # (N, 3*400)
    assert np.all(walks[0] == 0)
    for t in (1.0, 2.0, 3.99):
        np.testing.assert_allclose(walks[int(t * fs)].var(), sigma**2 * t, rtol=0.15)


def test_hard_and_soft_iron(clean):
    base = clean["handheld"]
    rec = simulate("handheld", errors=_only(hard_iron=(5.0, -3.0, 7.0)))
    np.testing.assert_allclose((rec.mag - base.mag).mean(axis=0), [5.0, -3.0, 7.0], atol=1e-12)
    noisy = simulate("handheld", errors=_only(hard_iron=(5.0, -3.0, 7.0), mag_noise=0.5))
    np.testing.assert_allclose((noisy.mag - base.mag).mean(axis=0), [5.0, -3.0, 7.0], atol=4 * 0.5 / np.sqrt(len(base)))
    soft = np.array([[1.1, 0.05, 0.0], [0.05, 0.9, 0.02], [0.0, 0.02, 1.0]])
    rec = simulate("handheld", errors=_only(soft_iron=soft))
    np.testing.assert_allclose(rec.mag, base.mag @ soft.T, atol=1e-12)


def test_magnetic_disturbances():
    amp, rate, dur = 6.0, 0.05, 5.0
    errors = _only(mag_disturbance=amp, mag_disturbance_rate=rate, mag_disturbance_duration=dur)
    rec = simulate("underwater", errors=errors)
    bump = np.linalg.norm(rec.mag - rec.meta["true_mag"], axis=1)
    np.testing.assert_allclose(bump, np.linalg.norm(rec.meta["mag_disturbance"], axis=1), atol=1e-12)
    covered = (bump > 0).mean()
    assert 0.15 < covered < 0.30  # expected 1 - exp(-rate * dur) = 0.22
    assert amp * 0.98 < bump.max() < 2 * amp


def test_misalignment_rotates_every_sensor(clean):
    base = clean["handheld"]
    rec = simulate("handheld", errors=_only(misalignment=0.1, misalignment_axis=(0, 0, 2)))
    inv = Rotation.from_rotvec([0, 0, 0.1]).inv()
    for sensor in SENSORS:
        np.testing.assert_allclose(getattr(rec, sensor), inv.apply(np.array(getattr(base, sensor))), atol=1e-12)
    rec = simulate("handheld", errors=_only(misalignment=0.02))  # random axis
    found, _ = Rotation.align_vectors(np.vstack([base.acc, base.mag]), np.vstack([rec.acc, rec.mag]))
    assert abs(found.magnitude() - 0.02) < 1e-9
    np.testing.assert_allclose(found.as_rotvec(), rec.meta["misalignment_rotvec"], atol=1e-9)


def test_mag_hold(clean):
    base = clean["handheld"]
    rec = simulate("handheld", errors=_only(mag_hold=4))
    np.testing.assert_array_equal(rec.mag[::4], base.mag[::4])
    np.testing.assert_array_equal(rec.mag[1::4], base.mag[::4][: len(rec.mag[1::4])])
    assert not np.array_equal(rec.mag, base.mag)


def test_presets_and_helpers():
    assert SensorErrors() == SensorErrors.none()
    assert SensorErrors.none().active() == ()
    hand = SensorErrors.handheld()
    assert hand.only() == SensorErrors.none()
    assert hand.only("gyro_bias") == SensorErrors(gyro_bias=0.01)
    assert hand.only("gyro_bias", "mag_noise").active() == ("gyro_bias", "mag_noise")
    assert SensorErrors.underwater().gyro_noise < hand.gyro_noise
    assert SensorErrors.underwater(authors_ucs_noise=True).authors_ucs_noise
    with pytest.raises(ValueError, match="gyro_bias"):
        hand.only("gyro_bais")


@pytest.mark.parametrize("kwargs", [
    {"gyro_noise": -1.0}, {"soft_iron": np.eye(2)}, {"hard_iron": (1.0, 2.0)}, {"mag_hold": 0},
    {"mag_hold": 1.5}, {"mag_disturbance_duration": 0.0}, {"misalignment_axis": (0, 0, 0)},
])
def test_invalid_errors(kwargs):
    with pytest.raises(ValueError):
        SensorErrors(**kwargs)


def test_invalid_arguments():
    with pytest.raises(ValueError, match="handheld, underwater"):
        simulate("flying")
    with pytest.raises(ValueError, match="at least 20"):
        simulate("handheld", duration=0.19)
    with pytest.raises(ValueError, match="at least 20"):
        simulate("underwater", duration=1.0)
    assert len(simulate("handheld", duration=0.2)) == 20


def test_speed():
    simulate("handheld", duration=5)
    start = time.perf_counter()
    simulate("handheld")
    assert time.perf_counter() - start < 1.0  # typically ~0.1 s
