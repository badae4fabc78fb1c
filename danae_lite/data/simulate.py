"""A deterministic IMU/AHRS simulator with exact ground truth.

Two scenarios stand in for the paper's datasets:

``"handheld"`` (OxIOD slow walking, 100 Hz, 180 s)
    A phone held in hand while walking slowly: roll/pitch drift slowly within about
    ±0.3 rad plus a few degrees of sway at the step frequency (~1.8 Hz); yaw follows a
    walking path with turns; the walk adds a vertical bounce of 0.1-0.2 g at the step
    frequency, smaller forward/lateral accelerations and the centripetal term in turns.
``"underwater"`` (UCS AUV survey, 10 Hz, 1950 s)
    Small, slow roll/pitch (about ±0.1 rad), the yaw of a lawnmower-like survey with
    turns, and small surge/heave/centripetal accelerations (a few mg).

Frames and signals. The reference frame has x = magnetic north, y = west, z = up. The
orientation ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` maps body to reference (intrinsic ZYX,
see :mod:`danae_lite.angles`). The Euler angles are smooth analytic functions of time
(random sums of sinusoids and smooth turns), so their rates are exact and the body rate is

    p = φ̇ − ψ̇ sinθ,   q = θ̇ cosφ + ψ̇ cosθ sinφ,   r = −θ̇ sinφ + ψ̇ cosθ cosφ   [rad/s].

The ideal accelerometer reads the specific force in the tilt convention of
:class:`~danae_lite.data.recording.Recording`, ``f_b = R.T @ (a_ref / g + [0, 0, 1])`` [g], and
the ideal magnetometer ``m_b = R.T @ m_ref`` [µT] with ``m_ref = B (cos I, 0, −sin I)``,
B = 48 µT, inclination I = 60° (the field points down, northern hemisphere). At rest the
paper's ``pitch_acc`` and tilt-compensated ``yaw_mag`` are exact; ``roll_acc`` equals the
true roll only when pitch is zero.

Sensor errors (:class:`SensorErrors`) are added in a fixed order: misalignment of the
sensor triad, then soft iron, disturbances, hard iron (magnetometer), biases and white
noise, the DANAE authors' UCS noise, and finally the magnetometer sample hold. Every random
quantity has its own child generator of ``numpy.random.SeedSequence(seed)``, so switching
one source off or changing its size leaves the draws of every other source unchanged.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..angles import G, euler_to_quat
from .recording import Recording

Array = NDArray[np.float64]

FIELD_STRENGTH = 48.0
"""Earth magnetic field strength B [µT]."""
FIELD_INCLINATION = np.deg2rad(60.0)
"""Magnetic inclination I [rad], positive = field pointing below the horizon."""
MAG_REF: Array = FIELD_STRENGTH * np.array([np.cos(FIELD_INCLINATION), 0.0, -np.sin(FIELD_INCLINATION)])
"""Earth field in the reference frame (x north, y west, z up) [µT]."""
AUTHORS_UCS_STD = 0.5
"""Std of the white noise the DANAE authors added to the UCS gyro [rad/s] and acc [m/s²]."""

SCENARIOS: dict[str, tuple[float, float]] = {"handheld": (100.0, 180.0), "underwater": (10.0, 1950.0)}
"""Scenario name -> (default sample rate [Hz], default duration [s])."""

ERROR_SOURCES: tuple[str, ...] = (
    "gyro_noise", "gyro_bias", "gyro_bias_walk", "acc_noise", "acc_bias", "motion", "mag_noise", "hard_iron",
    "soft_iron", "mag_disturbance", "misalignment", "mag_hold", "authors_ucs_noise")
"""Names accepted by :meth:`SensorErrors.only`; each source is named after its main :class:`SensorErrors` field."""
SOURCE_FIELDS: dict[str, tuple[str, ...]] = {source: (source,) for source in ERROR_SOURCES} | {
    "gyro_bias": ("gyro_bias", "gyro_bias_fixed"),
    "acc_bias": ("acc_bias", "acc_bias_fixed"),
    "mag_disturbance": ("mag_disturbance", "mag_disturbance_rate", "mag_disturbance_duration"),
    "misalignment": ("misalignment", "misalignment_axis"),
}
"""Each error source by name: its main field and the fields that go with it."""

_STREAMS = ("trajectory", "gyro_noise", "gyro_bias", "gyro_bias_walk", "acc_noise", "acc_bias",
            "mag_noise", "mag_disturbance", "misalignment", "authors_gyro", "authors_acc")

CONVENTIONS = (
    "simulated: reference x = magnetic north, y = west, z = up; quat scalar-last body->reference, "
    "R = Rz(yaw) Ry(pitch) Rx(roll); gyro [rad/s] body; acc [g] = R.T (a_ref/g + [0,0,1]) (tilt "
    "convention); mag [µT] = R.T m_ref, m_ref = 48 (cos 60°, 0, -sin 60°); true_* in meta are "
    "noise-free body-frame signals (before misalignment); gyro_bias in meta is the bias added [rad/s]"
)


@dataclass(frozen=True)
class SensorErrors:
    """Sensor error model; every field has an "off" default, so ``SensorErrors()`` is error-free.

    White-noise values are standard deviations **per sample** at the recording's rate (to
    convert a datasheet density ND [unit/√Hz]: σ ≈ ND·√(fs/2)). All vectors are per axis
    of the sensor frame.

    Attributes
    ----------
    gyro_noise : gyro white noise std [rad/s] per sample.
    gyro_bias : std [rad/s] of the constant gyro bias, drawn per axis from N(0, σ).
    gyro_bias_fixed : a given constant gyro bias (x, y, z) [rad/s]; overrides ``gyro_bias``.
    gyro_bias_walk : gyro bias random walk [rad/s/√s]; the bias starts at the constant value
        and its variance grows by ``gyro_bias_walk² · t``.
    acc_noise : accelerometer white noise std [g] per sample.
    acc_bias : std [g] of the constant accelerometer bias, drawn per axis.
    acc_bias_fixed : a given accelerometer bias (x, y, z) [g]; overrides ``acc_bias``.
    motion : scale factor of the platform's linear acceleration (0 = only gravity, 1 = the
        scenario's full motion). This is the "accelerometer disturbance from motion".
    mag_noise : magnetometer white noise std [µT] per sample.
    hard_iron : constant magnetometer offset (x, y, z) [µT].
    soft_iron : 3×3 matrix S applied to the field, ``m = S @ m_true`` (identity = off).
    mag_disturbance : peak amplitude [µT] of transient field disturbances: events arrive as a
        Poisson process of ``mag_disturbance_rate`` [1/s]; each adds a sin²-shaped bump of
        ``mag_disturbance_duration`` [s] along a random body-frame direction.
    misalignment : angle [rad] of one rotation between the sensor triad and the body, common
        to gyro, accelerometer and magnetometer (a board mounted askew): the sensors read
        ``Rm.T @ v_body`` with ``Rm = exp(misalignment · axis)``.
    misalignment_axis : axis of that rotation (x, y, z); None = a random unit axis.
    mag_hold : the magnetometer repeats each value for this many samples, as a phone does
        between its slower magnetometer updates (1 = off).
    authors_ucs_noise : add the noise the DANAE authors injected into UCS: each axis of the
        gyro gets N(0, 0.5) [rad/s] and each axis of the accelerometer N(0, 0.5) [m/s²]
        (0.5/9.80665 g), fresh per sample. In the authors' dataset each sample read draws
        new noise and the acc angles come from a second read, so the accelerometer used in
        the measurement is noised independently of the gyro; here the gyro and the acc get
        independent (seeded) draws, the magnetometer none, exactly that net effect.
    """

    gyro_noise: float = 0.0
    gyro_bias: float = 0.0
    gyro_bias_fixed: tuple[float, float, float] | None = None
    gyro_bias_walk: float = 0.0
    acc_noise: float = 0.0
    acc_bias: float = 0.0
    acc_bias_fixed: tuple[float, float, float] | None = None
    motion: float = 0.0
    mag_noise: float = 0.0
    hard_iron: tuple[float, float, float] = (0.0, 0.0, 0.0)
    soft_iron: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    mag_disturbance: float = 0.0
    mag_disturbance_rate: float = 0.0
    mag_disturbance_duration: float = 5.0
    misalignment: float = 0.0
    misalignment_axis: tuple[float, float, float] | None = None
    mag_hold: int = 1
    authors_ucs_noise: bool = False

    def __post_init__(self) -> None:
        for name in ("gyro_bias_fixed", "acc_bias_fixed", "hard_iron", "misalignment_axis"):
            value = getattr(self, name)
            if value is not None:
                vec = tuple(float(v) for v in np.asarray(value, dtype=float).ravel())
                if len(vec) != 3:
                    raise ValueError(f"SensorErrors.{name} must have 3 components, got {value!r}")
                object.__setattr__(self, name, vec)
        s = np.asarray(self.soft_iron, dtype=float)
        if s.shape != (3, 3):
            raise ValueError(f"SensorErrors.soft_iron must be 3x3, got shape {s.shape}")
        object.__setattr__(self, "soft_iron", tuple(tuple(float(v) for v in row) for row in s))
        for name in ("gyro_noise", "gyro_bias", "gyro_bias_walk", "acc_noise", "acc_bias", "motion",
                     "mag_noise", "mag_disturbance", "mag_disturbance_rate", "misalignment"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"SensorErrors.{name} must be a finite number >= 0, got {getattr(self, name)!r}")
        if not self.mag_disturbance_duration > 0:
            raise ValueError("SensorErrors.mag_disturbance_duration must be > 0 s, "
                             f"got {self.mag_disturbance_duration!r}")
        if int(self.mag_hold) != self.mag_hold or self.mag_hold < 1:
            raise ValueError(f"SensorErrors.mag_hold must be an integer >= 1, got {self.mag_hold!r}")
        if self.misalignment_axis is not None and np.linalg.norm(self.misalignment_axis) == 0:
            raise ValueError("SensorErrors.misalignment_axis must be non-zero")

    @classmethod
    def none(cls, **overrides: Any) -> "SensorErrors":
        """No errors and no motion: ideal sensors on a platform that only rotates."""
        return cls(**overrides)

    @classmethod
    def handheld(cls, **overrides: Any) -> "SensorErrors":
        """Smartphone MEMS (InvenSense ICM-20600 class, as in OxIOD's iPhone 7 Plus), 100 Hz.

        gyro: noise 0.003 rad/s, bias σ 0.01 rad/s (0.57 °/s), bias walk 2e-4 rad/s/√s;
        acc: noise 0.002 g, bias σ 0.01 g; full walking motion; mag: noise 0.4 µT, hard iron
        (4, −3, 6) µT, soft iron within ±2 %, disturbances of 10 µT, one per 40 s, 3 s long
        (steel furniture, doors); misalignment 0.01 rad; mag_hold 1 (set e.g. 2-4 to mimic
        a magnetometer slower than the IMU).
        """
        return replace(cls(
            gyro_noise=0.003, gyro_bias=0.01, gyro_bias_walk=2e-4, acc_noise=0.002, acc_bias=0.01,
            motion=1.0, mag_noise=0.4, hard_iron=(4.0, -3.0, 6.0),
            soft_iron=((1.02, 0.01, -0.01), (0.01, 0.98, 0.02), (-0.01, 0.02, 1.01)),
            mag_disturbance=10.0, mag_disturbance_rate=1 / 40, mag_disturbance_duration=3.0,
            misalignment=0.01,
        ), **overrides)

    @classmethod
    def underwater(cls, **overrides: Any) -> "SensorErrors":
        """Tactical-grade MEMS (Analog Devices ADIS16480 class, as on the UCS Sparus AUV), 10 Hz.

        gyro: noise 3e-4 rad/s, bias σ 1e-3 rad/s, bias walk 1e-5 rad/s/√s; acc: noise
        2e-4 g, bias σ 2e-3 g; full survey motion; mag: noise 0.05 µT, vehicle hard iron
        (3, −2, 5) µT, soft iron within ±1 %, disturbances of 4 µT, one per 150 s, 10 s long
        (thruster currents); misalignment 0.005 rad. The authors' UCS noise is off; use
        ``SensorErrors.underwater(authors_ucs_noise=True)`` to reproduce the paper's inputs.
        """
        return replace(cls(
            gyro_noise=3e-4, gyro_bias=1e-3, gyro_bias_walk=1e-5, acc_noise=2e-4, acc_bias=2e-3,
            motion=1.0, mag_noise=0.05, hard_iron=(3.0, -2.0, 5.0),
            soft_iron=((1.01, 0.005, 0.0), (0.005, 0.99, 0.01), (0.0, 0.01, 1.0)),
            mag_disturbance=4.0, mag_disturbance_rate=1 / 150, mag_disturbance_duration=10.0,
            misalignment=0.005,
        ), **overrides)

    def only(self, *sources: str) -> "SensorErrors":
        """A copy with only the named sources (see :data:`ERROR_SOURCES`) kept, all others off."""
        unknown = [s for s in sources if s not in SOURCE_FIELDS]
        if unknown:
            raise ValueError(f"unknown error source {unknown[0]!r}; valid: {', '.join(ERROR_SOURCES)}")
        return replace(SensorErrors(), **{f: getattr(self, f) for s in sources for f in SOURCE_FIELDS[s]})

    def active(self) -> tuple[str, ...]:
        """Names of the sources that are switched on."""
        off = SensorErrors()
        return tuple(s for s, fs in SOURCE_FIELDS.items() if any(getattr(self, f) != getattr(off, f) for f in fs))


def euler_rates_to_body(euler: Array, euler_rate: Array) -> Array:
    """Body angular rate (p, q, r) [rad/s] from (roll, pitch, yaw) [rad] and their rates [rad/s]."""
    phi, theta = euler[:, 0], euler[:, 1]
    dphi, dtheta, dpsi = euler_rate.T
    p = dphi - dpsi * np.sin(theta)
    q = dtheta * np.cos(phi) + dpsi * np.cos(theta) * np.sin(phi)
    r = -dtheta * np.sin(phi) + dpsi * np.cos(theta) * np.cos(phi)
    return np.stack([p, q, r], axis=1)


def rotation_matrices(euler: Array) -> Array:
    """``R = Rz(yaw) Ry(pitch) Rx(roll)`` (body -> reference), shape (N, 3, 3), closed form."""
    cf, sf = np.cos(euler[:, 0]), np.sin(euler[:, 0])
    ct, st = np.cos(euler[:, 1]), np.sin(euler[:, 1])
    cp, sp = np.cos(euler[:, 2]), np.sin(euler[:, 2])
    rows = [[cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
            [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
            [-st, ct * sf, ct * cf]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def _sines(rng: np.random.Generator, t: Array, amplitude: float, f_lo: float, f_hi: float,
           count: int = 4) -> tuple[Array, Array]:
    """A random sum of ``count`` sinusoids, |value| <= amplitude; returns value and derivative."""
    weights = rng.uniform(0.2, 1.0, count)
    amps = amplitude * weights / weights.sum()
    omega = 2 * np.pi * rng.uniform(f_lo, f_hi, count)
    phase = rng.uniform(0, 2 * np.pi, count)
    arg = omega[:, None] * t[None, :] + phase[:, None]
    return amps @ np.sin(arg), (amps * omega) @ np.cos(arg)


def _tone(rng: np.random.Generator, t: Array, amplitude: float, freq: float) -> tuple[Array, Array]:
    """``amplitude · sin(2π f t + random phase)`` and its derivative."""
    omega, phase = 2 * np.pi * freq, rng.uniform(0, 2 * np.pi)
    return amplitude * np.sin(omega * t + phase), amplitude * omega * np.cos(omega * t + phase)


def _turns(rng: np.random.Generator, t: Array, gap: tuple[float, float], turn_rate: tuple[float, float],
           angle: tuple[float, float], alternate: bool) -> tuple[Array, Array]:
    """Heading of straight legs (``gap`` [s]) and smooth C² turns; value [rad] and rate [rad/s].

    Each turn sweeps an angle drawn from ``angle`` [rad] at a mean rate drawn from
    ``turn_rate`` [rad/s] (peak rate 1.875 times the mean), left or right at random or
    alternating (lawnmower).
    """
    psi, rate = rng.uniform(-np.pi, np.pi) + np.zeros_like(t), np.zeros_like(t)
    sign = rng.choice([-1.0, 1.0])
    start = rng.uniform(*gap) / 2
    while start < t[-1]:
        turn, flip = sign * rng.uniform(*angle), rng.choice([-1.0, 1.0])
        dur = abs(turn) / rng.uniform(*turn_rate)
        u = np.clip((t - start) / dur, 0.0, 1.0)
        psi += turn * u**3 * (10 - 15 * u + 6 * u**2)
        rate += turn / dur * 30 * u**2 * (1 - u) ** 2
        sign = -sign if alternate else flip
        start += dur + rng.uniform(*gap)
    return psi, rate


def _trajectory(scenario: str, t: Array, rng: np.random.Generator) -> tuple[Array, Array, Array]:
    """Euler angles (N, 3) [rad], their rates [rad/s] and linear acceleration in the reference frame [m/s²]."""
    zero = np.zeros_like(t)
    if scenario == "handheld":
        f_step = rng.uniform(1.6, 2.0)  # steps per second
        speed = rng.uniform(0.6, 0.9)  # slow walking speed [m/s]
        parts = {
            "roll": [(rng.uniform(-0.1, 0.1) + zero, zero), _sines(rng, t, 0.2, 0.005, 0.05),
                     _tone(rng, t, np.deg2rad(3.0), f_step / 2), _tone(rng, t, np.deg2rad(1.5), f_step)],
            "pitch": [(rng.uniform(-0.1, 0.1) + zero, zero), _sines(rng, t, 0.2, 0.005, 0.05),
                      _tone(rng, t, np.deg2rad(2.0), f_step)],
            "yaw": [_sines(rng, t, 0.1, 0.02, 0.2), _tone(rng, t, np.deg2rad(1.5), f_step / 2)],
        }
        path, path_rate = _turns(rng, t, gap=(8.0, 25.0), turn_rate=(0.3, 0.6), angle=(np.pi / 4, np.pi),
                                  alternate=False)
        # vertical: the walk's bounce at the step frequency and its second harmonic
        vertical = _tone(rng, t, rng.uniform(0.1, 0.2) * G, f_step)[0] + _tone(rng, t, 0.03 * G, 2 * f_step)[0]
        surge = _tone(rng, t, 0.06 * G, f_step)[0]
        sway = _tone(rng, t, 0.04 * G, f_step / 2)[0] + speed * path_rate  # lateral + centripetal
    else:  # "underwater" (simulate checks the name)
        speed = rng.uniform(0.4, 0.7)  # surge speed [m/s]
        parts = {
            "roll": [(rng.uniform(-0.03, 0.03) + zero, zero), _sines(rng, t, 0.08, 0.002, 0.03)],
            "pitch": [(rng.uniform(-0.05, 0.05) + zero, zero), _sines(rng, t, 0.1, 0.002, 0.03)],
            "yaw": [_sines(rng, t, 0.04, 0.005, 0.05)],
        }
        path, path_rate = _turns(rng, t, gap=(60.0, 200.0), turn_rate=(0.05, 0.1), angle=(np.pi / 2, np.pi),
                                  alternate=True)
        speed_change, surge = _sines(rng, t, 0.1, 0.003, 0.03)  # speed variation [m/s] and its derivative
        sway = (speed + speed_change) * path_rate
        vertical = _sines(rng, t, 0.03, 0.005, 0.05)[0]
    parts["yaw"].append((path, path_rate))
    euler = np.stack([sum(v for v, _ in parts[k]) for k in ("roll", "pitch", "yaw")], axis=1)
    rate = np.stack([sum(d for _, d in parts[k]) for k in ("roll", "pitch", "yaw")], axis=1)
    forward = np.stack([np.cos(path), np.sin(path), zero], axis=1)
    left = np.stack([-np.sin(path), np.cos(path), zero], axis=1)
    linear = surge[:, None] * forward + sway[:, None] * left + vertical[:, None] * np.array([0.0, 0.0, 1.0])
    return euler, rate, linear


def _disturbances(rng: np.random.Generator, t: Array, errors: SensorErrors) -> Array:
    """Transient body-frame field bumps [µT], shape (N, 3)."""
    out = np.zeros((t.size, 3))
    if errors.mag_disturbance == 0 or errors.mag_disturbance_rate == 0:
        return out
    start = rng.exponential(1 / errors.mag_disturbance_rate)
    while start < t[-1]:
        direction = rng.standard_normal(3)
        u = (t - start) / errors.mag_disturbance_duration
        bump = np.where((u > 0) & (u < 1), np.sin(np.pi * u) ** 2, 0.0)
        out += errors.mag_disturbance * bump[:, None] * direction / np.linalg.norm(direction)
        start += rng.exponential(1 / errors.mag_disturbance_rate)
    return out


def _constant(rng: np.random.Generator, sigma: float, fixed: tuple[float, float, float] | None) -> Array:
    return np.asarray(fixed, dtype=float) if fixed is not None else sigma * rng.standard_normal(3)


def simulate(scenario: str = "handheld", *, duration: float | None = None, seed: int = 0,
             errors: SensorErrors | None = None, name: str | None = None, fs: float | None = None) -> Recording:
    """Simulate one recording with exact ground truth.

    Parameters
    ----------
    scenario : ``"handheld"`` (default 100 Hz, 180 s) or ``"underwater"`` (10 Hz, 1950 s).
    duration : length [s]; default per scenario. Must give at least 20 samples.
    seed : seeds the trajectory and every error source (same arguments -> identical arrays).
    errors : sensor error model; None -> the scenario preset (:meth:`SensorErrors.handheld`
        or :meth:`SensorErrors.underwater`).
    name : recording name, default ``f"sim-{scenario}-{seed}"``.
    fs : sample rate [Hz]; default per scenario.

    Returns
    -------
    Recording
        gyro [rad/s], acc [g], mag [µT] in the sensor frame and the true quaternion. ``meta``
        holds ``seed``, ``scenario``, ``errors`` (as a dict), the noise-free body-frame
        signals ``true_gyro``/``true_acc``/``true_mag``, the added gyro bias ``gyro_bias``
        (N, 3) [rad/s], ``acc_bias`` (3,) [g], ``linear_acc`` (N, 3) [m/s², reference frame,
        already scaled by ``errors.motion``], ``mag_disturbance`` (N, 3) [µT, body],
        ``misalignment_rotvec`` (3,) [rad], ``mag_ref`` [µT] and ``conventions``.
    """
    fs, n = _rate_and_length(scenario, fs, duration)
    if errors is None:
        errors = SensorErrors.handheld() if scenario == "handheld" else SensorErrors.underwater()
    rng = dict(zip(_STREAMS, (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(len(_STREAMS)))))
    t, dt = np.arange(n) / fs, 1.0 / fs

    euler, euler_rate, linear = _trajectory(scenario, t, rng["trajectory"])
    linear = errors.motion * linear
    rot = rotation_matrices(euler)
    def to_body(v: Array) -> Array:
        return np.einsum("nji,nj->ni", rot, v)  # R.T @ v for every sample

    true_gyro = euler_rates_to_body(euler, euler_rate)
    true_acc = to_body(linear / G + np.array([0.0, 0.0, 1.0]))
    true_mag = to_body(np.broadcast_to(MAG_REF, (n, 3)))

    axis = errors.misalignment_axis  # None: a random unit axis
    if axis is None:
        axis = rng["misalignment"].standard_normal(3)
    rotvec = errors.misalignment * np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    mis = _rotvec_matrix(rotvec)  # sensor -> body; sensors read mis.T @ v_body

    gyro_bias = _constant(rng["gyro_bias"], errors.gyro_bias, errors.gyro_bias_fixed) + np.zeros((n, 3))
    if errors.gyro_bias_walk > 0:
        steps = errors.gyro_bias_walk * np.sqrt(dt) * rng["gyro_bias_walk"].standard_normal((n - 1, 3))
        gyro_bias[1:] += np.cumsum(steps, axis=0)
    gyro = true_gyro @ mis + gyro_bias + _noise(rng["gyro_noise"], errors.gyro_noise, n)

    acc_bias = _constant(rng["acc_bias"], errors.acc_bias, errors.acc_bias_fixed)
    acc = true_acc @ mis + acc_bias + _noise(rng["acc_noise"], errors.acc_noise, n)

    disturbance = _disturbances(rng["mag_disturbance"], t, errors)
    mag = (true_mag @ mis + disturbance) @ np.asarray(errors.soft_iron).T + np.asarray(errors.hard_iron)
    mag = mag + _noise(rng["mag_noise"], errors.mag_noise, n)

    if errors.authors_ucs_noise:
        gyro = gyro + AUTHORS_UCS_STD * rng["authors_gyro"].standard_normal((n, 3))
        acc = acc + AUTHORS_UCS_STD / G * rng["authors_acc"].standard_normal((n, 3))
    if errors.mag_hold > 1:
        mag = mag[(np.arange(n) // int(errors.mag_hold)) * int(errors.mag_hold)]

    meta: dict[str, Any] = {
        "seed": seed, "scenario": scenario, "errors": asdict(errors),
        "true_gyro": true_gyro, "true_acc": true_acc, "true_mag": true_mag,
        "gyro_bias": gyro_bias, "acc_bias": acc_bias, "linear_acc": linear,
        "mag_disturbance": disturbance, "misalignment_rotvec": rotvec, "mag_ref": MAG_REF.copy(),
        "conventions": CONVENTIONS,
    }
    return Recording(name=name or f"sim-{scenario}-{seed}", source=f"simulated:{scenario}", fs=fs,
                     gyro=gyro, acc=acc, mag=mag, quat=euler_to_quat(euler), meta=meta)


def _rate_and_length(scenario: str, fs: float | None, duration: float | None) -> tuple[float, int]:
    """The rate [Hz] and the number of samples of a simulated recording (the scenario's defaults
    where None); ValueError for an unknown scenario, a rate that is not positive or fewer than 20
    samples."""
    if scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario {scenario!r}; valid: {', '.join(SCENARIOS)}")
    fs = float(SCENARIOS[scenario][0] if fs is None else fs)
    duration = float(SCENARIOS[scenario][1] if duration is None else duration)
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"fs must be a positive number of Hz, got {fs!r}")
    n = int(round(duration * fs)) if np.isfinite(duration) else 0
    if n < 20:
        raise ValueError(f"duration {duration!r} s at {fs:g} Hz gives {n} samples; at least 20 are needed")
    return fs, n


def _noise(rng: np.random.Generator, sigma: float, n: int) -> Array:
    """White noise (N, 3) of std ``sigma``, or zeros when the source is off (no draws are made)."""
    return sigma * rng.standard_normal((n, 3)) if sigma > 0 else np.zeros((n, 3))


def _rotvec_matrix(rotvec: Array) -> Array:
    """Rotation matrix of a rotation vector [rad] (Rodrigues' formula)."""
    angle = float(np.linalg.norm(rotvec))
    if angle == 0:
        return np.eye(3)
    k = rotvec / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx
