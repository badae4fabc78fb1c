"""Loader for the Underwater Caves Sonar (UCS) dataset's ADIS16480 file.

Mallios, Vidal, Campos, Carreras, "Underwater caves sonar data set", IJRR 36(12), 2017.
The file ``full_dataset/imu_adis.txt`` is a ``rostopic echo -p`` style CSV export of the
``/imu_adis`` topic (message ``cirs_girona_cala_viuda/Imu``: a header, then ``roll pitch yaw
qx qy qz qw temp mx my mz ax ay az gx gy gz bx by bz``, all float64). One header row, then
one row per message (about 19,965 rows, ~10.2 Hz, 32.6 min)::

    %time,field.header.seq,field.header.stamp,field.roll,field.pitch,field.yaw,
    field.qx,field.qy,field.qz,field.qw,field.temp,field.mx,field.my,field.mz,
    field.ax,field.ay,field.az,field.gx,field.gy,field.gz,field.bx,field.by,field.bz

(one line in the file). Sources: the message definition ``msg/Imu.msg`` of the ROS package
cirs_girona_cala_viuda (github.com/PickNikRobotics/cirs_girona_cala_viuda); public loaders of
this very file that read ``%time``, ``field.roll``, ``field.ax``, ``field.gx``, ``field.bx`` by
name and skip three leading columns (time, seq, stamp) before ``roll``; and the DANAE authors'
``datasets.py`` (github.com/fabidicia/DANAE), whose column indices 3-5, 6-9, 11-13, 14-16,
17-19, 20-22 match this layout. Columns are read here by header name, never by position
(surrounding whitespace and a leading ``%`` are ignored), so extra columns are harmless.

Units. ``%time`` is the ROS time in ns; acc in m/s² (→ g, divided by 9.80665); gyro in
rad/s; the magnetometer's unit is not documented by the export: the ADIS16480 itself reports
gauss (0.1 mgauss/LSB, ±2.5 gauss), while a ROS driver may convert to tesla. The default
``units["mag"] = "auto"`` picks the unit among T, gauss, mgauss, µT, nT that puts the median
field strength between 15 and 95 µT (Earth's field is 22-67 µT; the candidates are a factor
≥ 10 apart, so at most one fits), else raises DataError asking for an explicit unit.

Sample rate. ``fs = 1 / median(diff(t))`` over the ``%time`` column converted to s; the
median ignores the jitter of ROS arrival times. The raw timestamps are kept in
``meta["timestamps_raw"]``; the Recording itself uses the uniform grid ``i / fs``, as the
DANAE authors did (they hard-coded dt = 0.1 s).

Accelerometer sign. If the ADIS16480's attitude refers to an NED navigation frame (body z
down), as aerospace AHRS outputs usually do, a specific-force accelerometer at rest reads
``-R.T @ [0, 0, 1]`` g and needs a flip to the tilt convention of
:class:`~danae_lite.data.recording.Recording` (``acc ≈ R.T @ [0, 0, 1]``). On the other hand, the
DANAE authors used the file's acc unflipped, intended ``a_ref = [0, 0, +1]`` for this dataset
in their EKF, and report a UCS pitch error of at most 0.18 rad while the pitch reaches
0.25 rad in their figure (a flipped sign would make errors of about twice the pitch); so the
export is probably already in the tilt convention. The documentation found does not settle
it, so ``acc_sign="auto"`` decides from the data: ``s = sign(median_i <a_i/|a_i|, R_i.T @
[0, 0, 1]>)`` with R from the file's quaternion, raising DataError when that median lies
within ±0.5 (no clear agreement). Pass ``acc_sign=+1`` or ``-1`` to force it; the choice and
the agreement are stored in ``meta``.
"""
from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .parsing import line_spans, parse_numeric, read_bytes
from ..angles import G
from .recording import DataError, Recording

MIN_SAMPLES = 20
"""Default minimum length: one DANAE window of 20 samples."""
HEADER: tuple[str, ...] = (
    "%time", "field.header.seq", "field.header.stamp", "field.roll", "field.pitch", "field.yaw",
    "field.qx", "field.qy", "field.qz", "field.qw", "field.temp", "field.mx", "field.my", "field.mz",
    "field.ax", "field.ay", "field.az", "field.gx", "field.gy", "field.gz", "field.bx", "field.by", "field.bz")
"""The header row of ``imu_adis.txt`` (23 columns)."""
REQUIRED: dict[str, tuple[str, ...]] = {
    "time": ("%time",),
    "quat": ("field.qx", "field.qy", "field.qz", "field.qw"),
    "mag": ("field.mx", "field.my", "field.mz"),
    "acc": ("field.ax", "field.ay", "field.az"),
    "gyro": ("field.gx", "field.gy", "field.gz"),
}
"""Columns that must be present, by the quantity they make up."""
OPTIONAL: dict[str, tuple[str, ...]] = {
    "adis_euler": ("field.roll", "field.pitch", "field.yaw"),
    "temperature": ("field.temp",),
    "gyro_bias": ("field.bx", "field.by", "field.bz"),
    "stamp": ("field.header.stamp",),
}
"""Columns copied into ``meta`` (unchanged, file units) when present."""
UNITS: dict[str, dict[str, float]] = {
    "time": {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0},
    "acc": {"m/s^2": 1.0 / G, "m/s2": 1.0 / G, "g": 1.0},
    "gyro": {"rad/s": 1.0, "deg/s": np.pi / 180.0},
    "mag": {"T": 1e6, "gauss": 100.0, "mgauss": 0.1, "uT": 1.0, "µT": 1.0, "nT": 1e-3},
}
"""Accepted unit strings and their factor to s, g, rad/s and µT."""
DEFAULT_UNITS: dict[str, str] = {"time": "ns", "acc": "m/s^2", "gyro": "rad/s", "mag": "auto"}
"""Units assumed for the file (see the module docstring)."""
FIELD_RANGE_UT = (15.0, 95.0)
"""Median field strength [µT] accepted by the magnetometer unit detection."""


def _key(name: str) -> str:
    return name.strip().lstrip("%").strip()


def _resolve_units(path: Path, units: Mapping[str, str] | None) -> dict[str, str]:
    out = dict(DEFAULT_UNITS)
    for quantity, unit in (units or {}).items():
        if quantity not in UNITS:
            raise DataError(f"{path}: unknown quantity {quantity!r} in units; allowed: {', '.join(UNITS)}")
        allowed = list(UNITS[quantity]) + (["auto"] if quantity == "mag" else [])
        if unit not in allowed:
            raise DataError(f"{path}: unknown {quantity} unit {unit!r}; allowed: {', '.join(allowed)}")
        out[quantity] = unit
    return out


def _mag_unit(path: Path, mag: np.ndarray) -> str:
    strength = float(np.median(np.linalg.norm(mag, axis=1)))
    lo, hi = FIELD_RANGE_UT
    fits = [u for u, f in UNITS["mag"].items() if u != "µT" and lo <= strength * f <= hi]
    if len(fits) != 1:
        raise DataError(f"{path}: cannot infer the magnetometer unit (median |m| = {strength:g} in file units); "
                        f"pass units={{'mag': ...}} with one of {', '.join(UNITS['mag'])}")
    return fits[0]


def _acc_sign(path: Path, acc: np.ndarray, quat: np.ndarray) -> tuple[int, float]:
    from scipy.spatial.transform import Rotation  # here: the command line's --help loads no SciPy

    up = Rotation.from_quat(quat).inv().apply([0.0, 0.0, 1.0])
    norm = np.linalg.norm(acc, axis=1)
    cos = np.sum(acc * up, axis=1)[norm > 0] / norm[norm > 0]
    agreement = float(np.median(cos)) if cos.size else 0.0
    if abs(agreement) < 0.5:
        raise DataError(f"{path}: cannot tell the accelerometer sign (median cosine between acc and the "
                        f"quaternion's up axis = {agreement:.2f}); pass acc_sign=+1 or -1")
    return (1 if agreement > 0 else -1), abs(agreement)


def _stamps(raw: bytes, col: int, parsed: np.ndarray) -> np.ndarray:
    """The time column as int64 when every value is an integer (ns stamps exceed float64's 2**53),
    else ``parsed`` (the column as float64)."""
    import pandas as pd  # here, not at the top: the command line's --help loads no pandas

    try:
        frame = pd.read_csv(io.BytesIO(raw), usecols=[col], dtype=np.int64, engine="c")
    except (ValueError, OverflowError):  # pandas' ParserError is a ValueError
        return parsed
    values = frame.iloc[:, 0].to_numpy()
    return values if values.shape == parsed.shape else parsed


def load_recording(path: str | Path, *, name: str | None = None, units: Mapping[str, str] | None = None,
                   acc_sign: int | str = "auto", min_samples: int = MIN_SAMPLES) -> Recording:
    """Load ``imu_adis.txt`` as one Recording.

    Parameters
    ----------
    path : the ADIS file.
    name : recording name; default ``"ucs/<file stem>"``.
    units : file units per quantity, overriding :data:`DEFAULT_UNITS`; keys ``time``, ``acc``,
        ``gyro``, ``mag``; values from :data:`UNITS` (``mag`` also ``"auto"``).
    acc_sign : +1, -1 or ``"auto"`` (see the module docstring).
    min_samples : fewest data rows accepted (default 20, one DANAE window).

    Returns
    -------
    Recording
        ``source="ucs"``; gyro [rad/s], acc [g] (tilt convention), mag [µT], quat = (qx, qy, qz,
        qw). ``meta``: ``timestamps_raw`` (file values; int64 when all are integers), ``time`` [s from the first row],
        ``units``, ``acc_sign``, ``acc_sign_agreement``, ``path``, ``conventions``, and when
        present ``adis_euler``, ``temperature``, ``gyro_bias``, ``stamp`` (file units).

    Raises
    ------
    DataError
        Missing file, missing header names (all listed), a row with the wrong column count, a
        non-numeric/empty/NaN/inf cell (line and column named), non-increasing time, an unknown
        unit, or fewer than ``min_samples`` rows.
    """
    path = Path(path)
    unit = _resolve_units(path, units)
    raw = read_bytes(path, "UCS ADIS file")
    wanted, get = _columns(path, raw, min_samples)
    stamps, t, fs = _timeline(path, raw, wanted, get, unit["time"])
    if unit["mag"] == "auto":
        unit["mag"] = _mag_unit(path, get["mag"])
    acc = get["acc"] * UNITS["acc"][unit["acc"]]
    quat = get["quat"]
    if acc_sign == "auto":
        sign, agreement = _acc_sign(path, acc, quat)
    elif acc_sign in (1, -1):
        sign, agreement = int(acc_sign), float("nan")
    else:
        raise DataError(f"{path}: acc_sign must be +1, -1 or 'auto', got {acc_sign!r}")
    meta: dict[str, object] = {
        "timestamps_raw": stamps, "time": t, "units": unit, "acc_sign": sign, "acc_sign_agreement": agreement,
        "path": str(path),
        "conventions": ("UCS ADIS16480: fs from the median %time step; gyro [rad/s], acc [g] (times acc_sign, "
                        "tilt convention), mag [µT] in the ADIS body frame; quat = ADIS (qx, qy, qz, qw)."),
    }
    meta |= {k: get[k] if get[k].shape[1] > 1 else get[k][:, 0] for k in OPTIONAL if k in get}
    return Recording(name=name or f"ucs/{path.stem}", source="ucs", fs=fs,
                     gyro=get["gyro"] * UNITS["gyro"][unit["gyro"]], acc=sign * acc,
                     mag=get["mag"] * UNITS["mag"][unit["mag"]], quat=quat, meta=meta)


def _columns(path: Path, raw: bytes, min_samples: int) -> tuple[dict[str, list[int]], dict[str, np.ndarray]]:
    """The file's column indices per quantity (:data:`REQUIRED`, and :data:`OPTIONAL` where the
    header has them) and their values, one ``(n, k)`` array per quantity; DataError for an empty
    file, missing header names, too few rows or a malformed cell."""
    starts, ends = line_spans(raw)
    if starts.size == 0:
        raise DataError(f"{path}: empty file; expected a header row ({','.join(HEADER[:4])},...)")
    header = raw[starts[0]:ends[0]].decode("utf-8-sig", errors="replace").rstrip("\r").split(",")
    index = {}
    for i, h in enumerate(header):
        index.setdefault(_key(h), i)
    missing = [c for cols in REQUIRED.values() for c in cols if _key(c) not in index]
    if missing:
        raise DataError(f"{path}: header row lacks column(s) {', '.join(missing)}; expected the "
                        f"rostopic export header ({','.join(HEADER)})")
    wanted = {k: [index[_key(c)] for c in cols] for k, cols in (REQUIRED | OPTIONAL).items()
              if all(_key(c) in index for c in cols)}
    n = starts.size - 1
    if n < min_samples:
        raise DataError(f"{path}: {n} data rows; at least {min_samples} are needed (one DANAE window is 20 samples)")
    usecols = sorted({c for cols in wanted.values() for c in cols})
    table = parse_numeric(path, raw, len(header), skip=1, usecols=usecols, names=[h.strip() for h in header])
    pos = {c: j for j, c in enumerate(usecols)}
    return wanted, {k: table[:, [pos[c] for c in cols]] for k, cols in wanted.items()}


def _timeline(path: Path, raw: bytes, wanted: dict[str, list[int]], get: dict[str, np.ndarray],
              time_unit: str) -> tuple[np.ndarray, np.ndarray, float]:
    """The raw stamps, the time [s from the first row] and the rate [Hz] from the median step;
    DataError for time that does not increase or a rate outside 0.5-1000 Hz."""
    stamps = _stamps(raw, wanted["time"][0], get["time"][:, 0])
    t = (stamps - stamps[0]) * UNITS["time"][time_unit]
    steps = np.diff(t)
    if (steps <= 0).any():
        r = int(np.argmax(steps <= 0))
        raise DataError(f"{path}: line {r + 3}, column {wanted['time'][0] + 1} (%time): time does not increase "
                        f"({stamps[r + 1]!r} after {stamps[r]!r})")
    fs = 1.0 / float(np.median(steps))
    if not 0.5 <= fs <= 1000.0:
        raise DataError(f"{path}: the %time column gives {fs:g} Hz with time unit {time_unit!r}; "
                        f"pass units={{'time': ...}} with one of {', '.join(UNITS['time'])}")
    return stamps, t, fs


def split_train_test(rec: Recording, train_fraction: float = 0.8) -> tuple[Recording, Recording]:
    """Split into the first ``floor(N * train_fraction)`` samples and the rest, as the paper.

    Per-sample ``meta`` arrays are split too. The DANAE authors split the text file with
    ``head``/``tail`` and their reader then popped the first line of each part as a header,
    so their test part lost its first data row; here no row is lost:
    ``len(train) + len(test) == len(rec)``.
    """
    if not 0.0 < train_fraction < 1.0:
        raise ValueError(f"train_fraction must be in (0, 1), got {train_fraction!r}")
    cut = int(np.floor(len(rec) * train_fraction))
    if cut < 1 or cut >= len(rec):
        raise DataError(f"recording {rec.name!r}: {len(rec)} samples cannot be split at {train_fraction}")
    return (rec.slice(0, cut, name=f"{rec.name}[train]"),
            rec.slice(cut, None, name=f"{rec.name}[test]"))
