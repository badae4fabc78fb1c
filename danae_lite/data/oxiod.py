"""Loader for the Oxford Inertial Odometry Dataset (OxIOD) in its original archive layout.

Layout: ``<root>/<setting>/<dataN>/syn/imuK.csv`` with the Vicon ground truth ``viK.csv``
beside it; no header row; row i of ``imuK`` pairs with row i of ``viK``; 100 Hz. The time
column has only 5 significant digits, so time is taken from the row index (``i / 100`` s).

Columns. ``imuK.csv`` (16): 0 time; 1-3 iOS attitude roll, pitch, yaw [rad]; 4-6 rotation
rate [rad/s]; 7-9 gravity [g]; 10-12 user acceleration [g]; 13-15 magnetic field [µT].
``viK.csv`` (9): 0 time; 1 Vicon frame counter; 2-4 translation [m]; 5-8 quaternion x, y, z, w.

What the loader builds, and why (as the DANAE authors did):

* ``acc = gravity - user_acc`` [g]. iOS reports gravity and user acceleration separately, in
  the iOS sign convention: at rest face up, gravity ≈ (0, 0, -1), the negative of what a
  specific-force accelerometer reads. The real specific force in the phone frame is therefore
  ``-(gravity + user_acc)``; the authors' vector differs from it by an overall sign and by the
  sign of the user acceleration. At rest it equals ``(ux, uy, -uz)``, u being the up direction
  seen from the Vicon body (next point).
* The Vicon body frame is roughly the phone frame turned 180° about z. So the x and y of the
  authors' vector carry the Vicon-signed roll and pitch, while z is flipped; the paper's
  formulas ``roll = atan2(ay, sqrt(ax²+az²))`` and ``pitch = atan2(-ax, sqrt(ay²+az²))`` use z
  only squared, so they give the Vicon roll and pitch.
* gyro and mag stay in the phone frame, as the authors left them.

Measured on handheld/data1 imu2, imu3, imu4, imu7 (all samples, Vicon ``u = R.T @ [0,0,1]``):

* the best rotation taking the iOS gravity direction onto the Vicon "down" (least squares)
  turns 167-169° about an axis within 2.5° of z; after it the two agree to a median 1.1-1.5°;
* median cosine between ``acc * (1, 1, -1)`` (normalised) and u: 0.993 / 0.994 / 0.995 / 0.993;
  without the z flip the median cosine is -0.57 to -0.68;
* median roll from acc vs Vicon: -0.43 vs -0.39 (imu2), -0.50 vs -0.46, -0.49 vs -0.43,
  -0.47 vs -0.41 rad (the phone is held tilted, so a sign error would show as +0.4 rad);
  after a 1 s moving average the acc roll/pitch correlate with the Vicon ones at 0.70-0.77 /
  0.64-0.66 (roll and pitch vary only by a std of 0.03-0.05 rad while walking);
* ``user_acc`` with x, y negated (into the Vicon frame) correlates at -0.79 to -0.91 per axis
  with the acceleration differentiated from the Vicon translation (leaving out 0.3 s around
  each ground-truth glitch): it is minus the kinematic acceleration, as the iOS sign
  convention says.

The ground truth has glitches that the IMU does not show; the loader keeps the data as it is, and
:func:`danae_lite.data.groundtruth.detect_glitches` finds them. Without the gyro, on handheld/data1
(steps above 0.2 rad per sample / spikes / excursions / isolated jumps / frozen runs): imu2
12/2/0/7/2 (13 and 11 samples), imu3 13/1/1/9/1, imu4 8/0/1/6/1, imu7 15/0/3/9/0; the largest
steps are 2.9-3.14 rad. With the gyro (:func:`~danae_lite.data.groundtruth.clean_mask`) more of
these steps pair up into excursions.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .parsing import line_spans, parse_numeric, read_bytes
from .recording import DataError, Recording

FS = 100.0
"""OxIOD sample rate [Hz]."""
MIN_SAMPLES = 20
"""Default minimum length: one DANAE window of 20 samples."""
IMU_NAMES: tuple[str, ...] = (
    "time", "attitude roll", "attitude pitch", "attitude yaw",
    "rotation rate x", "rotation rate y", "rotation rate z", "gravity x", "gravity y", "gravity z",
    "user acceleration x", "user acceleration y", "user acceleration z",
    "magnetic field x", "magnetic field y", "magnetic field z")
"""Column names of ``imuK.csv`` (16 columns)."""
VI_NAMES: tuple[str, ...] = (
    "time", "frame counter", "translation x", "translation y", "translation z",
    "rotation x", "rotation y", "rotation z", "rotation w")
"""Column names of ``viK.csv`` (9 columns)."""
CONVENTIONS = (
    "OxIOD: fs = 100 Hz from the row index; gyro [rad/s] and mag [µT] in the phone (iOS) frame; "
    "acc = gravity - user_acc [g] as the DANAE authors built it: x, y follow the tilt convention "
    "in the Vicon body frame (≈ phone frame turned 180° about z), z is flipped (used only squared); "
    "the real specific force is -(gravity + user_acc) in the phone frame; quat = Vicon "
    "(x, y, z, w), body -> Vicon world.")

_IMU_RE = re.compile(r"imu(\d+)\.csv")


def _default_name(imu_path: Path) -> str:
    if imu_path.parent.name == "syn" and len(imu_path.parents) >= 3:
        return f"{imu_path.parents[2].name}/{imu_path.parents[1].name}/{imu_path.stem}"
    return imu_path.stem


def load_recording(imu_path: str | Path, vi_path: str | Path | None = None, *, name: str | None = None,
                   min_samples: int = MIN_SAMPLES) -> Recording:
    """Load one OxIOD recording.

    Parameters
    ----------
    imu_path : path of ``imuK.csv``.
    vi_path : path of the Vicon file; default ``viK.csv`` in the same folder.
    name : recording name; default ``"<setting>/<dataN>/imuK"`` (e.g. ``"handheld/data1/imu2"``).
    min_samples : fewest rows accepted (default 20, one DANAE window).

    Returns
    -------
    Recording
        ``source="oxiod"``, fs = 100 Hz; gyro [rad/s], acc [g], mag [µT], quat (Vicon). ``meta``:
        ``gravity`` and ``user_acc`` (N, 3) [g], ``phone_euler`` (N, 3) [rad] (iOS attitude),
        ``vicon_position`` (N, 3) [m], ``vicon_frame`` (N,), ``imu_path``, ``vi_path`` and
        ``conventions``.

    Raises
    ------
    DataError
        Missing file, wrong column count, a non-numeric/empty/NaN/inf cell (file, line and
        column named), imu/vi row-count mismatch, or fewer than ``min_samples`` rows.
    """
    imu_path = Path(imu_path)
    if vi_path is None:
        m = _IMU_RE.fullmatch(imu_path.name)
        if m is None:
            raise DataError(f"{imu_path}: cannot infer the ground-truth file; expected a name like imuK.csv "
                            "or an explicit vi_path")
        vi_path = imu_path.with_name(f"vi{m.group(1)}.csv")
    vi_path = Path(vi_path)
    imu_raw = read_bytes(imu_path, "IMU file")
    vi_raw = read_bytes(vi_path, "ground-truth (Vicon) file")
    n_imu, n_vi = line_spans(imu_raw)[0].size, line_spans(vi_raw)[0].size
    if n_imu != n_vi:
        raise DataError(f"{imu_path} has {n_imu} rows but its ground truth {vi_path} has {n_vi}; "
                        "OxIOD pairs them row by row, so the counts must match")
    if n_imu < min_samples:
        raise DataError(f"{imu_path}: {n_imu} rows; at least {min_samples} are needed "
                        "(one DANAE window is 20 samples)")
    imu = parse_numeric(imu_path, imu_raw, len(IMU_NAMES), usecols=range(1, 16), names=IMU_NAMES)
    vi = parse_numeric(vi_path, vi_raw, len(VI_NAMES), usecols=range(1, 9), names=VI_NAMES)
    gravity, user_acc = imu[:, 6:9], imu[:, 9:12]
    quat = vi[:, 4:8]
    norms = np.linalg.norm(quat, axis=1)
    if (norms < 1e-9).any():
        r = int(np.argmax(norms < 1e-9))
        raise DataError(f"{vi_path}: line {r + 1}, columns 6-9 (rotation x, y, z, w): the quaternion is zero")
    return Recording(
        name=name or _default_name(imu_path),
        source="oxiod",
        fs=FS,
        gyro=imu[:, 3:6],
        acc=gravity - user_acc,
        mag=imu[:, 12:15],
        quat=quat,
        meta={
            "gravity": gravity,
            "user_acc": user_acc,
            "phone_euler": imu[:, 0:3],
            "vicon_position": vi[:, 1:4],
            "vicon_frame": vi[:, 0],
            "imu_path": str(imu_path),
            "vi_path": str(vi_path),
            "conventions": CONVENTIONS,
        },
    )

