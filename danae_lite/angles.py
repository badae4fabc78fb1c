"""Angle conventions used everywhere in the book (stated once, here).

* Frames: body frame of the sensor; reference (navigation) frame is the ground-truth
  system's world frame. A quaternion ``q`` (scalar-last ``[x, y, z, w]``, scipy's order)
  rotates body-frame vectors into the reference frame.
* Euler angles: aerospace, intrinsic Z-Y'-X'' (yaw psi, then pitch theta, then roll phi),
  exactly scipy's ``Rotation.as_euler("ZYX")``. Arrays in this package are always ordered
  ``(roll, pitch, yaw)`` in radians, i.e. the reverse of scipy's output.
* Ranges: roll and yaw in [-pi, pi), pitch in [-pi/2, pi/2].
* Angle errors are wrapped to [-pi, pi) with :func:`wrap` unless a caller asks for raw
  (unwrapped) differences.
* Accelerations are in g (standard gravity :data:`G`) everywhere in the package; a loader or
  a library that uses m/s² converts with :data:`G`.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

ANGLES: tuple[str, str, str] = ("roll", "pitch", "yaw")
"""Names of the three Euler angles, in the order used by every array in the package."""

G = 9.80665
"""Standard gravity [m/s²]: 1 g."""

SYMBOLS: dict[str, str] = {"roll": r"$\phi$", "pitch": r"$\theta$", "yaw": r"$\psi$"}
"""LaTeX symbols used by the paper for each angle."""


def wrap(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles [rad] to the half-open interval [-pi, pi).

    >>> float(wrap(np.pi))
    -3.141592653589793
    """
    a = np.asarray(angle, dtype=float)
    w = (a + np.pi) % (2.0 * np.pi) - np.pi
    # rounding can give exactly +pi (e.g. for the float just below -pi): map it to -pi
    return w - 2.0 * np.pi * (w >= np.pi)


def angle_diff(a: ArrayLike, b: ArrayLike, wrapped: bool = True) -> NDArray[np.float64]:
    """Return ``a - b`` [rad], wrapped to [-pi, pi) unless ``wrapped=False``."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    return wrap(d) if wrapped else d


def quat_to_euler(quat_xyzw: ArrayLike) -> NDArray[np.float64]:
    """Convert quaternions ``(N, 4)`` scalar-last to Euler ``(N, 3)`` (roll, pitch, yaw) [rad].

    Uses scipy's ``Rotation.as_euler("ZYX")`` (intrinsic yaw-pitch-roll) and reorders the
    columns to (roll, pitch, yaw); roll and yaw are in [-pi, pi) (scipy's +pi becomes -pi).
    Quaternions need not be unit norm (scipy normalises); a zero quaternion raises
    ``ValueError``.
    """
    q = np.atleast_2d(np.asarray(quat_xyzw, dtype=float))
    rpy = Rotation.from_quat(q).as_euler("ZYX")[:, ::-1].copy()
    # scipy returns roll and yaw in [-pi, pi]; keep the documented half-open [-pi, pi)
    ends = rpy[:, [0, 2]]
    rpy[:, [0, 2]] = np.where(ends >= np.pi, ends - 2.0 * np.pi, ends)
    return rpy


def euler_to_quat(euler_rpy: ArrayLike) -> NDArray[np.float64]:
    """Convert Euler ``(N, 3)`` (roll, pitch, yaw) [rad] to scalar-last quaternions ``(N, 4)``.

    Inverse of :func:`quat_to_euler` (intrinsic ZYX). The sign is chosen with ``w >= 0``.
    """
    e = np.atleast_2d(np.asarray(euler_rpy, dtype=float))
    q = Rotation.from_euler("ZYX", e[:, ::-1]).as_quat()
    q[q[:, 3] < 0] *= -1.0
    return q


def quat_angle(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation angle [rad] between unit quaternions ``a`` and ``b`` (..., 4), in [0, pi], sign-free.

    ``4 atan2(|a - b|, |a + b|)`` (with ``b``'s sign flipped toward ``a``): accurate for small
    angles too, where ``2 acos(a . b)`` loses half the digits.
    """
    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)
    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


def euler_error_angle(euler_rpy: ArrayLike, quat_xyzw: ArrayLike) -> NDArray[np.float64]:
    """Angle [rad] of the rotation ``R(euler) R(quat)^T`` per row: the total attitude error.

    ``euler_rpy`` (..., 3) (roll, pitch, yaw) [rad]; ``quat_xyzw`` (..., 4), normalised here;
    the leading axes broadcast (e.g. (N, K, 3) estimates of K settings against (N, 1, 4) truth).
    The Euler angles become quaternions in closed form, the same numbers as
    :func:`euler_to_quat` to 1e-15 but without SciPy's per-row cost.
    """
    e = np.asarray(euler_rpy, dtype=float)
    q = np.asarray(quat_xyzw, dtype=float)
    cr, sr = np.cos(0.5 * e[..., 0]), np.sin(0.5 * e[..., 0])
    cp, sp = np.cos(0.5 * e[..., 1]), np.sin(0.5 * e[..., 1])
    cy, sy = np.cos(0.5 * e[..., 2]), np.sin(0.5 * e[..., 2])
    est = np.stack((sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                    cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy), axis=-1)
    return quat_angle(est, q / np.linalg.norm(q, axis=-1, keepdims=True))


def unwrap(angle: ArrayLike) -> NDArray[np.float64]:
    """Remove 2*pi jumps along the first axis (numpy ``unwrap``), e.g. for plotting yaw."""
    return np.unwrap(np.asarray(angle, dtype=float), axis=0)
