"""Conventions: wrapping and Euler/quaternion conversion against independent references."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from danae_lite.angles import angle_diff, euler_to_quat, quat_to_euler, wrap


def test_wrap_hand_values():
    vals = np.array([0.0, math.pi, -math.pi, 3 * math.pi, 2 * math.pi, -0.5, 7.0])
    expected = np.array([0.0, -math.pi, -math.pi, -math.pi, 0.0, -0.5, 7.0 - 2 * math.pi])
    np.testing.assert_allclose(wrap(vals), expected, atol=1e-12)


def test_angle_diff_wraps_across_pi():
    # 179 deg minus -179 deg is -2 deg, not 358 deg
    a, b = math.radians(179), math.radians(-179)
    assert angle_diff(a, b) == pytest.approx(math.radians(-2))
    assert angle_diff(a, b, wrapped=False) == pytest.approx(math.radians(358))


def test_quat_to_euler_matches_closed_form():
    # the ZYX closed form used by the DANAE authors for Vicon quaternions
    rng = np.random.default_rng(1)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x**2 + y**2))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y**2 + z**2))
    np.testing.assert_allclose(quat_to_euler(q), np.c_[roll, pitch, yaw], atol=1e-9)


def test_single_axis_rotations():
    e = quat_to_euler([[math.sin(0.15), 0, 0, math.cos(0.15)]])  # 0.3 rad about x
    np.testing.assert_allclose(e, [[0.3, 0.0, 0.0]], atol=1e-12)
    e = quat_to_euler([[0, 0, math.sin(-1.0), math.cos(-1.0)]])  # -2 rad about z
    np.testing.assert_allclose(e, [[0.0, 0.0, -2.0]], atol=1e-12)


angle = st.floats(-math.pi + 1e-6, math.pi - 1e-6)
pitch = st.floats(-math.pi / 2 + 0.05, math.pi / 2 - 0.05)  # away from gimbal lock


@settings(max_examples=200, deadline=None)
@given(angle, pitch, angle)
def test_euler_quat_round_trip(r, p, y):
    back = quat_to_euler(euler_to_quat([[r, p, y]]))[0]
    np.testing.assert_allclose(wrap(back - np.array([r, p, y])), 0.0, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.floats(-1e4, 1e4))
def test_wrap_invariants(a):
    w = float(wrap(a))
    assert -math.pi <= w < math.pi
    assert math.isclose(math.cos(w), math.cos(a), abs_tol=1e-8)
    assert math.isclose(math.sin(w), math.sin(a), abs_tol=1e-8)
    assert float(wrap(w)) == pytest.approx(w, abs=1e-12)


def test_euler_error_angle_is_scipys_rotation_angle():
    """The closed form against SciPy's rotations (composition, inverse, magnitude), also for
    small angles, where ``2 acos(q1 . q2)`` would lose half the digits, and with broadcasting."""
    from scipy.spatial.transform import Rotation

    from danae_lite.angles import euler_error_angle, euler_to_quat

    rng = np.random.default_rng(0)
    e = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], (1000, 3))
    truth = e + rng.normal(0.0, 1.0, (1000, 1)) * 10.0 ** rng.uniform(-9, 0, (1000, 1)) * rng.normal(size=(1000, 3))
    q = euler_to_quat(truth) * rng.choice([-2.0, 0.5], (1000, 1))  # either sign, not unit norm
    ref = (Rotation.from_euler("ZYX", e[:, ::-1]) * Rotation.from_quat(q).inv()).magnitude()
    got = euler_error_angle(e, q)
    np.testing.assert_allclose(got, ref, rtol=1e-7, atol=1e-15)
    # (N, K, 3) estimates against (N, 1, 4) truths: row by row the same numbers
    many = np.stack([e, e[::-1]], axis=1)
    np.testing.assert_array_equal(euler_error_angle(many, q[:, None, :])[:, 0], got)
