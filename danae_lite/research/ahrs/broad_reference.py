"""The BROAD benchmark's two reference filters, as the benchmark ran them to make its published figures.

BROAD: Laidig, Caruso, Cereatti, Seel, "BROAD—A Benchmark for Robust Inertial Orientation
Estimation", *Data* 6(7):72, 2021 (CC BY 4.0). Our own code, written after reading the
benchmark's paper and example code; nothing is copied from it.

:func:`reference_madgwick` and :func:`reference_mahony` are Madgwick's and Mahony's MARG filters
as in the x-io reference code, first-order quaternion integration, initialised from the first
accelerometer/magnetometer sample with the benchmark's formula (:func:`benchmark_initial_quat`).
With the published common parameters (:data:`PUBLISHED_PARAMS`: Madgwick beta 0.12; Mahony k_P
0.74, k_I 0.0012) they reproduce the authors' per-trial total/heading/inclination RMSE to a
relative 1.1e-4 or better on all 24 trials we have (the residue is the reference code's
single-precision arithmetic: a float32 emulation of its Mahony matched the published figures of
two trials to 1e-13). The ``ahrs``-based wrappers of :mod:`danae_lite.research.ahrs.filters`
do not: ``ahrs``'s Madgwick uses the paper's full-size magnetic reference where the reference
code predicts half of it (per-trial total RMSE off by -35 % to +44 %), and ``ahrs``'s Mahony
starts from another initial quaternion (off by -5.5 % to +8.4 %; with the benchmark's initial
quaternion it matches to 1e-4). The vectorised grids of the same two filters are
:mod:`danae_lite.research.ahrs.grid`.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...data.recording import Recording
from .filters import checked_sensors

Array = NDArray[np.float64]

__all__ = ["BENCHMARK_FILTERS", "PUBLISHED_PARAMS", "benchmark_initial_quat", "reference_madgwick",
           "reference_mahony", "run_benchmark_filter"]


def benchmark_initial_quat(acc: ArrayLike, mag: ArrayLike) -> Array:
    """The initial orientation the benchmark gives both filters, from one acc and mag sample.

    Returns a scalar-last quaternion, to be read as body -> NWU like the filters' state. The
    benchmark builds the matrix whose columns are ``x = -(horizontal part of mag)``,
    ``y = up × x`` and ``z = up`` (``up`` = the accelerometer direction), all in body
    coordinates, normalised, and uses the quaternion of that matrix as the state. This is the
    earth-to-body rotation of a south-east-up frame; as a body -> NWU orientation it is right
    only for a level sensor whose x axis points east (NWU yaw -90°); for another heading psi
    it starts at 180° - psi (and mirrors the tilt). Every BROAD trial starts level with x
    within 5° of east, so the initial error is 1-10°, which the filters remove before or during
    the first movement phase; it is reproduced here because Mahony's heading converges slowly
    enough (tens of seconds at k_P = 0.74) for the published figures to depend on it.
    """
    from scipy.spatial.transform import Rotation

    up = np.asarray(acc, dtype=float).reshape(3)
    m = np.asarray(mag, dtype=float).reshape(3)
    x = -(m * np.dot(up, up) - up * np.dot(up, m))   # = (up × -m) × up
    y = np.cross(up, x)
    norms = [float(np.linalg.norm(v)) for v in (x, y, up)]
    if not all(math.isfinite(v) and v > 1e-12 * max(1.0, float(np.linalg.norm(m)) ** 2) for v in norms):
        raise ValueError(f"acc {up.tolist()} and mag {m.tolist()} must be finite, non-zero and not parallel")
    cols = [v / nv for v, nv in zip((x, y, up), norms)]
    q = Rotation.from_matrix(np.column_stack(cols)).as_quat()
    return q if q[3] >= 0 else -q


_Rows = list[list[float]]


def _inputs(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float,
            q0: ArrayLike | None) -> tuple[_Rows, _Rows, _Rows | None, float, Array]:
    g, a, m = checked_sensors(gyro, acc, mag, fs)
    if q0 is None:
        if m is None:
            raise ValueError("without mag, pass the initial orientation q0 (the benchmark's initialisation needs mag)")
        q = benchmark_initial_quat(a[0], m[0])
    else:
        q = np.asarray(q0, dtype=float).reshape(4)
        nq = float(np.linalg.norm(q))
        if not (math.isfinite(nq) and nq > 0):
            raise ValueError(f"q0 must be a non-zero finite quaternion (x, y, z, w), got {q.tolist()}")
        q = q / nq
    return g.tolist(), a.tolist(), (None if m is None else m.tolist()), 1.0 / float(fs), q


def reference_madgwick(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float, *, beta: float = 0.12,
             q0: ArrayLike | None = None) -> Array:
    """Madgwick's gradient-descent filter as BROAD runs it (x-io reference implementation).

    Per sample, with the state q (body -> NWU): the rate ``q_dot = q * (0, gyro) / 2`` minus
    ``beta`` times the normalised gradient of ``|f|²/2``, where f stacks ``R(q).T @ [0,0,1] - a``
    and ``R(q).T @ b - m`` (a, m normalised), ``h = R(q) @ m`` and, as in the reference code,
    ``b = (sqrt(hx² + hy²), 0, hz) / 2``: the predicted field is half the measured one (the
    paper and ``ahrs`` use the full size; this changes the figures by up to 44 % on BROAD).
    Then ``q += q_dot / fs`` and q is normalised. A zero acc row gives no correction; a zero
    mag row (or ``mag=None``) the accelerometer-only gradient. A sample is never skipped (``ahrs``
    skips rows with an exactly zero gyro).

    Parameters
    ----------
    gyro : (N, 3) [rad/s]; acc : (N, 3) any unit (only its direction is used; at rest it points
    up); mag : (N, 3) any unit, or None; fs : [Hz]; beta : gain [rad/s] (BROAD's common best
    0.12); q0 : initial state, scalar-last, body -> NWU; default :func:`benchmark_initial_quat`
    of the first sample. The first output is the state after the first sample, as in the
    benchmark.

    Returns
    -------
    (N, 4) quaternions, scalar-last ``[x, y, z, w]``, body -> NWU (as :mod:`danae_lite.research.ahrs.filters`).
    """
    G_, A_, M_, dt, q = _inputs(gyro, acc, mag, fs, q0)
    beta = float(beta)
    state = tuple(float(v) for v in q)
    out = np.empty((len(G_), 4))
    for i, g in enumerate(G_):
        state = _madgwick_step(state, g, A_[i], None if M_ is None else M_[i], beta, dt)
        out[i] = state
    return out


def _madgwick_step(state: tuple[float, ...], g: list[float], arow: list[float], mrow: list[float] | None,
                   beta: float, dt: float) -> tuple[float, float, float, float]:
    """One sample of :func:`reference_madgwick`: ``(x, y, z, w)`` after gyro ``g``, acc ``arow``
    and mag ``mrow`` (None or zero: no magnetometer term)."""
    x, y, z, w = state
    gx, gy, gz = g
    sqrt = math.sqrt
    dw = 0.5 * (-x * gx - y * gy - z * gz)
    dx = 0.5 * (w * gx + y * gz - z * gy)
    dy = 0.5 * (w * gy - x * gz + z * gx)
    dz = 0.5 * (w * gz + x * gy - y * gx)
    ax, ay, az = arow
    if ax != 0.0 or ay != 0.0 or az != 0.0:
        na = 1.0 / sqrt(ax * ax + ay * ay + az * az)
        ax, ay, az = ax * na, ay * na, az * na
        # third row of R(q) = the up axis seen from the body; residuals of the accelerometer
        r31 = 2.0 * (x * z - w * y)
        r32 = 2.0 * (y * z + w * x)
        r33 = 1.0 - 2.0 * (x * x + y * y)
        f1, f2, f3 = r31 - ax, r32 - ay, r33 - az
        s0 = -2.0 * y * f1 + 2.0 * x * f2
        s1 = 2.0 * z * f1 + 2.0 * w * f2 - 4.0 * x * f3
        s2 = -2.0 * w * f1 + 2.0 * z * f2 - 4.0 * y * f3
        s3 = 2.0 * x * f1 + 2.0 * y * f2
        if mrow is not None and (mrow[0] != 0.0 or mrow[1] != 0.0 or mrow[2] != 0.0):
            m0, m1, m2, m3 = _madgwick_mag_gradient(x, y, z, w, mrow, r31, r32, r33)
            s0, s1, s2, s3 = s0 + m0, s1 + m1, s2 + m2, s3 + m3
        ns = sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
        if ns > 0.0:
            k = beta / ns
            dw -= k * s0
            dx -= k * s1
            dy -= k * s2
            dz -= k * s3
    w, x, y, z = w + dw * dt, x + dx * dt, y + dy * dt, z + dz * dt
    nq = 1.0 / sqrt(w * w + x * x + y * y + z * z)
    return x * nq, y * nq, z * nq, w * nq


def _first_two_rows(x: float, y: float, z: float, w: float) -> tuple[float, float, float, float, float, float]:
    """The first two rows of the rotation matrix R(q) of the unit quaternion ``(x, y, z, w)``."""
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x))


def _madgwick_mag_gradient(x: float, y: float, z: float, w: float, mrow: list[float],
                           r31: float, r32: float, r33: float) -> tuple[float, float, float, float]:
    """The magnetometer's part of Madgwick's gradient, with the reference code's half-size field
    ``b = (sqrt(hx² + hy²), 0, hz) / 2`` (``r3*``: the third row of R(q))."""
    sqrt = math.sqrt
    mx, my, mz = mrow
    nm = 1.0 / sqrt(mx * mx + my * my + mz * mz)
    mx, my, mz = mx * nm, my * nm, mz * nm
    r11, r12, r13, r21, r22, r23 = _first_two_rows(x, y, z, w)
    hx, hy = r11 * mx + r12 * my + r13 * mz, r21 * mx + r22 * my + r23 * mz
    hz = r31 * mx + r32 * my + r33 * mz
    bx = 0.5 * sqrt(hx * hx + hy * hy)
    bz = 0.5 * hz
    f4 = r11 * bx + r31 * bz - mx
    f5 = r12 * bx + r32 * bz - my
    f6 = r13 * bx + r33 * bz - mz
    return (-2.0 * bz * y * f4 + (2.0 * bz * x - 2.0 * bx * z) * f5 + 2.0 * bx * y * f6,
            2.0 * bz * z * f4 + (2.0 * bx * y + 2.0 * bz * w) * f5 + (2.0 * bx * z - 4.0 * bz * x) * f6,
            ((-4.0 * bx * y - 2.0 * bz * w) * f4 + (2.0 * bx * x + 2.0 * bz * z) * f5
             + (2.0 * bx * w - 4.0 * bz * y) * f6),
            (2.0 * bz * x - 4.0 * bx * z) * f4 + (2.0 * bz * y - 2.0 * bx * w) * f5 + 2.0 * bx * x * f6)


def reference_mahony(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float, *, k_P: float = 0.74,
           k_I: float = 0.0012, q0: ArrayLike | None = None) -> Array:
    """Mahony's explicit complementary filter as BROAD runs it (x-io reference implementation).

    Per sample, with the state q (body -> NWU) and a, m normalised: the predicted up axis
    ``v = R(q).T @ [0,0,1]`` and field ``u = R(q).T @ b`` with ``h = R(q) @ m``,
    ``b = (sqrt(hx² + hy²), 0, hz)``; the error ``e = a × v + m × u``; the integral
    ``i += k_I * e / fs`` (kept at 0 when ``k_I = 0``); the corrected rate
    ``omega = gyro + i + k_P * e``; then ``q += q * (0, omega) / (2 fs)`` and q is normalised.
    A zero acc row gives no correction at all (and the integral is neither updated nor
    applied); a zero mag row (or ``mag=None``) uses ``e = a × v``. The gains are those of
    ``ahrs``'s Mahony and of the benchmark's files (``Kp``, ``Ki``); the reference code stores
    ``2 Kp`` and ``2 Ki`` against half-size vectors, which is the same filter.

    Parameters
    ----------
    gyro : (N, 3) [rad/s]; acc, mag : (N, 3) any unit (directions only), mag may be None;
    fs : [Hz]; k_P : proportional gain [rad/s] (BROAD's common best 0.74); k_I : integral gain
    [rad/s²] (0.0012); q0 : initial state, scalar-last, body -> NWU; default
    :func:`benchmark_initial_quat` of the first sample.

    Returns
    -------
    (N, 4) quaternions, scalar-last ``[x, y, z, w]``, body -> NWU.
    """
    G_, A_, M_, dt, q = _inputs(gyro, acc, mag, fs, q0)
    kp, ki = float(k_P), float(k_I)
    state = tuple(float(v) for v in q)
    integral = (0.0, 0.0, 0.0)
    out = np.empty((len(G_), 4))
    for i, g in enumerate(G_):
        state, integral = _mahony_step(state, integral, g, A_[i], None if M_ is None else M_[i], kp, ki, dt)
        out[i] = state
    return out


def _mahony_step(state: tuple[float, ...], integral: tuple[float, float, float], g: list[float],
                 arow: list[float], mrow: list[float] | None, kp: float, ki: float, dt: float
                 ) -> tuple[tuple[float, float, float, float], tuple[float, float, float]]:
    """One sample of :func:`reference_mahony`: ``(x, y, z, w)`` and the integral term after gyro
    ``g``, acc ``arow`` and mag ``mrow`` (None or zero: no magnetometer term)."""
    x, y, z, w = state
    ix, iy, iz = integral
    gx, gy, gz = g
    sqrt = math.sqrt
    ax, ay, az = arow
    if ax != 0.0 or ay != 0.0 or az != 0.0:
        na = 1.0 / sqrt(ax * ax + ay * ay + az * az)
        ax, ay, az = ax * na, ay * na, az * na
        vx = 2.0 * (x * z - w * y)
        vy = 2.0 * (y * z + w * x)
        vz = 1.0 - 2.0 * (x * x + y * y)
        ex = ay * vz - az * vy
        ey = az * vx - ax * vz
        ez = ax * vy - ay * vx
        if mrow is not None and (mrow[0] != 0.0 or mrow[1] != 0.0 or mrow[2] != 0.0):
            mex, mey, mez = _mahony_mag_error(x, y, z, w, mrow, vx, vy, vz)
            ex, ey, ez = ex + mex, ey + mey, ez + mez
        if ki > 0.0:
            ix, iy, iz = ix + ki * ex * dt, iy + ki * ey * dt, iz + ki * ez * dt
            gx, gy, gz = gx + ix, gy + iy, gz + iz
        else:
            ix = iy = iz = 0.0
        gx, gy, gz = gx + kp * ex, gy + kp * ey, gz + kp * ez
    hx_, hy_, hz_ = 0.5 * dt * gx, 0.5 * dt * gy, 0.5 * dt * gz
    w, x, y, z = (w - x * hx_ - y * hy_ - z * hz_,
                  x + w * hx_ + y * hz_ - z * hy_,
                  y + w * hy_ - x * hz_ + z * hx_,
                  z + w * hz_ + x * hy_ - y * hx_)
    nq = 1.0 / sqrt(w * w + x * x + y * y + z * z)
    return (x * nq, y * nq, z * nq, w * nq), (ix, iy, iz)


def _mahony_mag_error(x: float, y: float, z: float, w: float, mrow: list[float],
                      vx: float, vy: float, vz: float) -> tuple[float, float, float]:
    """The magnetometer's part of Mahony's error, ``m × u`` with the predicted field
    ``u = R(q).T @ (sqrt(hx² + hy²), 0, hz)`` (``v``: the predicted up axis)."""
    sqrt = math.sqrt
    mx, my, mz = mrow
    nm = 1.0 / sqrt(mx * mx + my * my + mz * mz)
    mx, my, mz = mx * nm, my * nm, mz * nm
    r11, r12, r13, r21, r22, r23 = _first_two_rows(x, y, z, w)
    hx = r11 * mx + r12 * my + r13 * mz
    hy = r21 * mx + r22 * my + r23 * mz
    hz = vx * mx + vy * my + vz * mz
    bx = sqrt(hx * hx + hy * hy)
    ux = r11 * bx + vx * hz
    uy = r12 * bx + vy * hz
    uz = r13 * bx + vz * hz
    return my * uz - mz * uy, mz * ux - mx * uz, mx * uy - my * ux


BENCHMARK_FILTERS: dict[str, Callable[..., Array]] = {"madgwick": reference_madgwick, "mahony": reference_mahony}
"""The two filters of the benchmark's case study, by name."""
PUBLISHED_PARAMS: dict[str, dict[str, float]] = {
    "madgwick": {"beta": 0.12},
    "mahony": {"k_P": 0.74, "k_I": 0.0012},
}
"""The authors' common ("TAGP") parameters, best mean total RMSE over all 39 trials."""


def run_benchmark_filter(name: str, rec: Recording, *, use_mag: bool = True, **params: Any) -> Array:
    """Run benchmark filter ``name`` on a recording; returns (N, 4) ``[x, y, z, w]``, body -> NWU.

    ``params`` default to :data:`PUBLISHED_PARAMS`; ``use_mag=False`` runs the 6D variant
    (then pass ``q0``; judge it by the inclination RMSE, the heading being unobservable).
    """
    try:
        fn = BENCHMARK_FILTERS[name]
    except KeyError:
        raise ValueError(f"unknown benchmark filter {name!r}; choose one of {', '.join(BENCHMARK_FILTERS)}") from None
    kwargs: dict[str, Any] = {**PUBLISHED_PARAMS[name], **params}
    return fn(rec.gyro, rec.acc, rec.mag if use_mag else None, rec.fs, **kwargs)
