"""ahrs's Madgwick and Mahony filters (MARG) for a whole grid of gains in one pass over the samples.

``ahrs.filters.Madgwick`` and ``ahrs.filters.Mahony`` update one sample at a time in Python,
about 100 µs per sample, and a grid search runs them once per grid point (6 Madgwick gains,
20 Mahony gain pairs) on the same recording. Here every grid point advances together: the
per-sample work is a few numpy operations on arrays of ``G`` grid points, and what depends only
on the sensors (the unit accelerometer and magnetometer vectors) is computed once for all
samples. The equations are the library's, term by term (the update methods of its two classes,
its Hamilton product and rotation matrix of a unit quaternion, ``w, x, y, z`` order); the first
quaternion is the library's own (``ecompass`` for Madgwick, ``am2q`` for Mahony). The results
agree with the library's to float64 rounding (tests/test_filters.py checks 1e-9 over thousands
of samples), not bit for bit.

Only the MARG form is here, for recordings whose gyro, accelerometer and magnetometer samples
are all non-zero (:func:`supported`); anything else runs through the library
(:func:`danae_lite.research.ahrs.filters.run_many` decides).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

__all__ = ["madgwick_marg", "mahony_marg", "supported"]


def supported(gyr: Array, acc: Array, mag: Array | None) -> bool:
    """Whether the batched MARG updates apply: a magnetometer, and no all-zero sample in any
    sensor (where the library skips the update or falls back to its IMU form)."""
    if mag is None:
        return False
    return bool(all((np.linalg.norm(x, axis=1) > 0).all() for x in (gyr, acc, mag)))


def _unit(v: Array) -> Array:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _product(p: Array, q: Array) -> Array:
    """Hamilton product ``p q`` of quaternions ``(..., 4)``, ``w, x, y, z``."""
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def _dcm(q: Array) -> Array:
    """Rotation matrices ``(G, 3, 3)`` of unit quaternions ``(G, 4)`` (the library's ``to_DCM``)."""
    w, x, y, z = q.T
    return np.stack([np.stack([1.0 - 2.0 * (y**2 + z**2), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)], -1),
                     np.stack([2.0 * (x * y + w * z), 1.0 - 2.0 * (x**2 + z**2), 2.0 * (y * z - w * x)], -1),
                     np.stack([2.0 * (x * z - w * y), 2.0 * (w * x + y * z), 1.0 - 2.0 * (x**2 + y**2)], -1)], 1)


def mahony_marg(gyr: Array, acc: Array, mag: Array, fs: float, k_P: Array, k_I: Array) -> Array:
    """Mahony's filter for ``G`` gain pairs at once: ``(G, N, 4)`` quaternions ``w, x, y, z``.

    gyr [rad/s], acc [m/s²], mag [any unit] : (N, 3), sensor frame, all samples non-zero;
    fs [Hz]; k_P, k_I : (G,) proportional and integral gains (``ahrs.filters.Mahony``'s).
    """
    from ahrs.common.orientation import am2q

    k_P, k_I = np.asarray(k_P, dtype=float)[:, None], np.asarray(k_I, dtype=float)[:, None]
    dt, n, g = 1.0 / fs, len(gyr), len(k_P)
    a_all, m_all = _unit(acc), _unit(mag)
    out = np.empty((g, n, 4))
    q = np.tile(am2q(acc[0], mag[0]), (g, 1))
    out[:, 0] = q
    b = np.zeros((g, 3))
    for t in range(1, n):
        q = _unit(q)
        r = _dcm(q)
        a, m = a_all[t], m_all[t]
        v_a = r[:, 2, :]                                   # R.T @ [0, 0, 1]
        h = r @ m                                          # the field in the Earth frame
        v_m = _unit(r[:, 1, :] * np.hypot(h[:, 0], h[:, 1])[:, None] + r[:, 2, :] * h[:, 2:3])
        omega_mes = np.cross(a, v_a) + np.cross(m, v_m)
        b += (-k_I * omega_mes) * dt
        omega = gyr[t] - b + k_P * omega_mes
        q_dot = 0.5 * _product(q, np.concatenate([np.zeros((g, 1)), omega], axis=1))
        q = _unit(q + q_dot * dt)
        out[:, t] = q
    return out


def madgwick_marg(gyr: Array, acc: Array, mag: Array, fs: float, gain: Array) -> Array:
    """Madgwick's filter for ``G`` gains (beta [rad/s]) at once: ``(G, N, 4)`` quaternions
    ``w, x, y, z``. gyr [rad/s], acc [m/s²], mag [any unit] : (N, 3), all samples non-zero;
    fs [Hz] (``ahrs.filters.Madgwick``'s MARG update)."""
    from ahrs.common.orientation import ecompass

    beta = np.asarray(gain, dtype=float)[:, None]
    dt, n, g = 1.0 / fs, len(gyr), len(beta)
    a_all, m_all = _unit(acc), _unit(mag)
    out = np.empty((g, n, 4))
    q = np.tile(ecompass(acc[0], mag[0], frame="NED", representation="quaternion"), (g, 1))
    out[:, 0] = q
    zeros = np.zeros((g, 1))
    for t in range(1, n):
        q = _unit(q)
        q_dot = 0.5 * _product(q, np.concatenate([zeros, np.tile(gyr[t], (g, 1))], axis=1))
        a, m = a_all[t], m_all[t]
        q_conj = q * np.array([1.0, -1.0, -1.0, -1.0])
        h = _product(q, _product(np.tile(np.concatenate([[0.0], m]), (g, 1)), q_conj))
        bx, bz = np.hypot(h[:, 1], h[:, 2]), h[:, 3]
        qw, qx, qy, qz = _unit(q).T
        f = np.stack([2.0 * (qx * qz - qw * qy) - a[0],
                      2.0 * (qw * qx + qy * qz) - a[1],
                      2.0 * (0.5 - qx**2 - qy**2) - a[2],
                      2.0 * bx * (0.5 - qy**2 - qz**2) + 2.0 * bz * (qx * qz - qw * qy) - m[0],
                      2.0 * bx * (qx * qy - qw * qz) + 2.0 * bz * (qw * qx + qy * qz) - m[1],
                      2.0 * bx * (qw * qy + qx * qz) + 2.0 * bz * (0.5 - qx**2 - qy**2) - m[2]], axis=1)
        zero = np.zeros_like(qw)
        jac = np.stack([
            np.stack([-2.0 * qy, 2.0 * qz, -2.0 * qw, 2.0 * qx], 1),
            np.stack([2.0 * qx, 2.0 * qw, 2.0 * qz, 2.0 * qy], 1),
            np.stack([zero, -4.0 * qx, -4.0 * qy, zero], 1),
            np.stack([-2.0 * bz * qy, 2.0 * bz * qz, -4.0 * bx * qy - 2.0 * bz * qw, -4.0 * bx * qz + 2.0 * bz * qx], 1),
            np.stack([-2.0 * bx * qz + 2.0 * bz * qx, 2.0 * bx * qy + 2.0 * bz * qw, 2.0 * bx * qx + 2.0 * bz * qz,
                      -2.0 * bx * qw + 2.0 * bz * qy], 1),
            np.stack([2.0 * bx * qy, 2.0 * bx * qz - 4.0 * bz * qx, 2.0 * bx * qw - 4.0 * bz * qy, 2.0 * bx * qx], 1),
        ], 1)                                              # (G, 6, 4), the library's eq. 32
        grad = np.einsum("gij,gi->gj", jac, f)
        norm = np.linalg.norm(grad, axis=1, keepdims=True)
        moving = (np.linalg.norm(f, axis=1) > 0)[:, None]  # the library skips the step where f = 0
        q_dot = q_dot - np.where(moving, beta * grad / np.where(norm > 0, norm, 1.0), 0.0)
        q = _unit(q + q_dot * dt)
        out[:, t] = q
    return out
