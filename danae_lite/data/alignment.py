r"""The constant rotations between the sensors and the ground truth, estimated on training data.

Two constant rotations stand between a filter's output and a ground-truth system such as
Vicon:

* **sensor -> body**, :math:`R_{bs}`: the phone's sensor axes are not the axes of the body
  the ground-truth markers define (OxIOD: turned about 170° about z);
* **magnetic north -> ground-truth x axis**: every filter with a magnetometer reports yaw
  from magnetic north (reference frame x = north, y = west, z = up, NWU), the ground truth
  from its own x axis. With both frames z-up, this is a yaw offset :math:`\psi_N`, the
  heading of magnetic north in the ground-truth frame: ``yaw_truth = yaw_NWU + psi_N``.

How they are estimated (:func:`estimate_alignment`, training recordings only, clean
ground-truth samples only):

1. The specific force :math:`f_s` [g] of the sensor (:func:`specific_force`; for OxIOD the
   real one, :math:`-(g_{iOS} + a_{user})`, not the authors' ``gravity - user_acc``) and the
   gyro :math:`\omega_s` [rad/s] are paired with the same quantities seen by the ground
   truth: the body angular rate from consecutive quaternions,
   :math:`\omega_b = f_s\,\mathrm{rotvec}(R_t^\top R_{t+1})`, against the mean of gyro
   samples t and t+1; and the "up" direction :math:`R_t^\top e_z` against the specific force,
   both averaged over 1 s so that the hand's accelerations average out. The ground truth may
   lag the IMU by a few samples (OxIOD: 0 to 5 samples, 0-50 ms, see :func:`rate_lag`); the
   rate pairs are matched at that delay (the data themselves are never shifted).
2. :math:`R_{bs}` is the rotation that best maps the sensor vectors onto the body vectors in
   the least-squares sense (Wahba's problem, solved by SciPy's ``Rotation.align_vectors``);
   the rate pairs and the gravity pairs get equal total weight. Gravity alone cannot fix
   the rotation about the vertical when the phone is held nearly level; the rates can. The
   fit is repeated three times, each time leaving out the rate pairs whose residual
   :math:`\|R\omega_s - \omega_b\|` exceeds three times the median (ground-truth glitches
   and the sensors' relative delay make a few pairs wildly wrong).
3. :math:`\psi_N` is the circular mean of the heading of the horizontal magnetic field in
   the ground-truth frame, :math:`m_w = R_t R_{bs} m_s`.

:meth:`FrameAlignment.apply` rotates a recording's gyro, specific force and magnetometer into
the body frame (so that every method estimates the orientation of the ground truth's body),
and :meth:`FrameAlignment.to_truth_frame` adds :math:`\psi_N` to a yaw estimate. The same
correction is applied to every method of the leaderboard. On the simulator both are known
(:math:`R_{bs}` is the simulated misalignment, :math:`\psi_N = 0`), which the tests use.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import uniform_filter1d
from scipy.spatial.transform import Rotation

from ..angles import wrap
from .recording import Recording

Array = NDArray[np.float64]

SMOOTH_S = 1.0
"""Averaging window [s] of the gravity pairs."""
TRIM_ROUNDS = 3
"""Fits of the rotation; after each, rate pairs whose residual exceeds
:data:`TRIM_FACTOR` times the median are left out of the next."""
TRIM_FACTOR = 3.0
MAX_LAG_S = 0.3
"""Largest delay between ground truth and gyro searched by :func:`rate_lag` [s]."""


def specific_force(rec: Recording) -> Array:
    """The accelerometer's specific force [g] in the sensor frame (at rest: up, seen from the sensor).

    OxIOD stores gravity and user acceleration separately in the iOS sign convention (gravity
    at rest points down); the specific force is ``-(gravity + user_acc)``. Every other source
    already holds it in ``rec.acc``.
    """
    if rec.source == "oxiod":
        return -(np.asarray(rec.meta["gravity"]) + np.asarray(rec.meta["user_acc"]))
    return np.asarray(rec.acc, dtype=float)


@dataclass(frozen=True)
class FrameAlignment:
    """Constant sensor -> body rotation and heading of magnetic north in the ground-truth frame."""

    sensor_to_body: Array
    """Quaternion ``[x, y, z, w]`` of :math:`R_{bs}` (``v_body = R_bs v_sensor``)."""
    north_yaw: float
    """Heading of magnetic north in the ground-truth frame [rad]."""
    rate_residual: float = float("nan")
    """Median angle between aligned gyro and ground-truth body rates on the training data [rad]."""
    gravity_residual: float = float("nan")
    """Median angle between aligned (1 s averaged) specific force and the ground-truth up [rad]."""
    n_pairs: int = 0
    """Vector pairs used."""
    lags: dict[str, int] = field(default_factory=dict)
    """Delay of the ground truth behind the gyro per training recording [samples] (:func:`rate_lag`);
    used only to pair the rates, the data are not shifted."""

    @classmethod
    def identity(cls) -> "FrameAlignment":
        """No rotation, north = x (the simulator without misalignment)."""
        return cls(np.array([0.0, 0.0, 0.0, 1.0]), 0.0)

    @property
    def rotation(self) -> Rotation:
        return Rotation.from_quat(self.sensor_to_body)

    def apply(self, rec: Recording) -> Recording:
        """The recording with gyro, specific force (as ``acc``, tilt convention) and
        magnetometer rotated into the body frame; ``meta["alignment"]`` records this object."""
        m = self.rotation.as_matrix()
        meta = dict(rec.meta)
        meta["alignment"] = self.summary()
        meta["conventions"] = ("aligned to the ground-truth body frame: gyro [rad/s], acc = specific force [g] "
                               "(tilt convention), mag [µT]; yaw estimates are from magnetic north (NWU)")
        return replace(rec, gyro=rec.gyro @ m.T, acc=specific_force(rec) @ m.T, mag=rec.mag @ m.T, meta=meta)

    def to_truth_frame(self, euler: ArrayLike) -> Array:
        """Euler (N, 3) [rad] from magnetic north (NWU) to the ground-truth frame: yaw + north_yaw,
        wrapped to [-pi, pi); roll and pitch are unchanged (a rotation about the vertical)."""
        e = np.array(euler, dtype=float)
        e[:, 2] = wrap(e[:, 2] + self.north_yaw)
        return e

    def summary(self) -> dict[str, float | list[float]]:
        """Plain numbers: the rotation as a rotation vector [rad] and its angle [deg], north yaw [deg], residuals [deg]."""
        rv = self.rotation.as_rotvec()
        return {
            "sensor_to_body_rotvec_rad": [float(v) for v in rv],
            "sensor_to_body_angle_deg": float(np.degrees(np.linalg.norm(rv))),
            "north_yaw_deg": float(np.degrees(self.north_yaw)),
            "rate_residual_deg": float(np.degrees(self.rate_residual)),
            "gravity_residual_deg": float(np.degrees(self.gravity_residual)),
            "n_pairs": int(self.n_pairs),
            "lags_samples": {k: int(v) for k, v in self.lags.items()},
        }


def _angle(a: Array, b: Array) -> Array:
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    c = np.einsum("ij,ij->i", a, b) / np.maximum(na * nb, 1e-300)
    return np.arccos(np.clip(c, -1.0, 1.0))


def _steps(rec: Recording) -> tuple[Rotation, Array, Array]:
    """The ground truth as rotations, the rotation vector of each of its steps (sample t to
    t + 1, body frame) [rad] and the gyro's mean over each step [rad/s]."""
    rot = Rotation.from_quat(rec.quat)
    return rot, (rot[:-1].inv() * rot[1:]).as_rotvec(), 0.5 * (rec.gyro[:-1] + rec.gyro[1:])


def _lagged(n: int, lag: int) -> tuple[slice, slice]:
    """Slices of two series of length ``n`` that pair element ``t + lag`` of the first with
    element ``t`` of the second."""
    length = max(0, n - abs(lag))
    return slice(max(0, lag), max(0, lag) + length), slice(max(0, -lag), max(0, -lag) + length)


def rate_lag(rec: Recording, clean: ArrayLike | None = None, max_lag_s: float = MAX_LAG_S) -> int:
    """Delay of the ground truth behind the gyro [samples], from the cross-correlation of the
    rotation-rate magnitudes (which do not depend on the frames). Positive: the ground truth
    shows a motion ``lag`` samples after the gyro. Searched within ``±max_lag_s``."""
    _, steps, w_sens = _steps(rec)
    nb = np.linalg.norm(steps, axis=1) * rec.fs
    ns = np.linalg.norm(w_sens, axis=1)
    ok = np.ones(len(nb), dtype=bool) if clean is None else np.asarray(clean)[:-1] & np.asarray(clean)[1:]
    a = np.where(ok, nb, np.median(nb[ok]) if ok.any() else 0.0)
    a, b = a - a.mean(), ns - ns.mean()
    m = int(round(max_lag_s * rec.fs))
    scores = [float(np.dot(a[body], b[sens])) for body, sens in (_lagged(len(a), k) for k in range(-m, m + 1))]
    return int(np.argmax(scores)) - m


def _pairs(rec: Recording, clean: NDArray[np.bool_], min_rate: float, lag: int) -> tuple[Array, Array, Array, Array]:
    """(body rates, gyro rates, body up, sensor specific force) on clean samples; the body
    rate at ``t + lag`` is paired with the gyro at ``t``."""
    rot, steps, w_sens = _steps(rec)
    body, sens = _lagged(len(steps), lag)
    w_body, ok_b, w_sens = steps[body] * rec.fs, (clean[:-1] & clean[1:])[body], w_sens[sens]
    ok = ok_b & (np.linalg.norm(w_sens, axis=1) > min_rate)
    n = max(1, int(round(SMOOTH_S * rec.fs)))
    up_body = uniform_filter1d(rot.inv().apply([0.0, 0.0, 1.0]), n, axis=0, mode="nearest")
    f_sens = uniform_filter1d(specific_force(rec), n, axis=0, mode="nearest")
    # a gravity pair counts only if its whole averaging window is clean
    clean_win = uniform_filter1d(clean.astype(float), n, mode="nearest") > 1.0 - 1e-9
    return w_body[ok], w_sens[ok], up_body[clean_win], f_sens[clean_win]


def estimate_alignment(recs: Sequence[Recording], clean: Sequence[ArrayLike] | None = None, *,
                       min_rate: float = 0.05) -> FrameAlignment:
    """Estimate :class:`FrameAlignment` from recordings with ground truth (see the module docstring).

    Parameters
    ----------
    recs : training recordings (never the test recording).
    clean : one boolean mask (N,) per recording, True = ground truth usable; default all.
    min_rate : gyro samples slower than this [rad/s] carry no direction and are left out.
    """
    if not recs:
        raise ValueError("need at least one recording to estimate the alignment")
    masks = [np.ones(len(r), dtype=bool) for r in recs] if clean is None else [np.asarray(c, dtype=bool) for c in clean]
    for r, m in zip(recs, masks):
        if m.shape != (len(r),):
            raise ValueError(f"{r.name}: clean mask has shape {m.shape}, expected ({len(r)},)")
    lags = {r.name: rate_lag(r, m) for r, m in zip(recs, masks)}
    parts = [_pairs(r, m, min_rate, lags[r.name]) for r, m in zip(recs, masks)]
    wb, ws, ub, fs_ = (np.concatenate(column) for column in zip(*parts))
    if len(wb) < 3 or len(ub) < 3:
        raise ValueError("too few clean, moving samples to estimate the sensor-to-body rotation")
    fs_unit = fs_ / np.linalg.norm(fs_, axis=1, keepdims=True)
    w_rate = np.full(len(wb), 1.0 / (len(wb) * np.mean(np.sum(ws * ws, axis=1))))
    w_grav = np.full(len(ub), 1.0 / len(ub))
    keep = np.ones(len(wb), dtype=bool)
    for _ in range(TRIM_ROUNDS):  # robust: ground-truth rate outliers would dominate a squared loss
        rot, _ = Rotation.align_vectors(np.vstack([wb[keep], ub]), np.vstack([ws[keep], fs_unit]),
                                        weights=np.r_[w_rate[keep] / w_rate[keep].sum() * w_rate.sum(), w_grav])
        res = np.linalg.norm(rot.apply(ws) - wb, axis=1)
        keep = res <= TRIM_FACTOR * np.median(res)
    # heading of the horizontal magnetic field in the ground-truth frame
    mag_truth = np.concatenate([Rotation.from_quat(r.quat[m]).apply(rot.apply(r.mag[m])) for r, m in zip(recs, masks)])
    heading = np.arctan2(mag_truth[:, 1], mag_truth[:, 0])
    north = float(np.arctan2(np.sin(heading).mean(), np.cos(heading).mean()))
    return FrameAlignment(
        sensor_to_body=rot.as_quat(),
        north_yaw=north,
        rate_residual=float(np.median(_angle(rot.apply(ws[keep]), wb[keep]))),
        gravity_residual=float(np.median(_angle(rot.apply(fs_unit), ub))),
        n_pairs=int(keep.sum() + len(ub)),
        lags=lags,
    )
