"""Established attitude filters from field libraries, behind one call.

Every filter here takes the same inputs and returns the same output, so that the leaderboard
(:mod:`danae_lite.research.leaderboard`) can treat them alike:

* inputs, all in the **body frame**: ``gyro`` (N, 3) [rad/s], ``acc`` (N, 3) the specific
  force [g] (at rest ``R.T @ [0, 0, 1]``, the tilt convention of
  :class:`~danae_lite.data.recording.Recording`), ``mag`` (N, 3) [µT] (only its direction is
  used), and the sample rate ``fs`` [Hz];
* output: quaternions (N, 4), scalar-last ``[x, y, z, w]``, body -> reference with the
  reference frame **x = magnetic north, y = west, z = up** (NWU), the frame of the
  simulator and of the KF's heading (:func:`danae_lite.kalman.model.mag_heading`).

Each library has its own units and frame; the wrappers convert (checked on noise-free
simulated recordings, where every wrapper returns the true orientation to within 0.01 rad):

=========  ==============================  =====================================  ==============
name       library                         units it wants                         its frame
=========  ==============================  =====================================  ==============
fusion     ``imufusion`` (x-io Fusion, C)   gyro deg/s, acc g, mag any             NWU (set)
vqf        ``vqf`` (VQF, C++; causal)       gyro rad/s, acc m/s², mag any          ENU
madgwick   ``ahrs`` ``Madgwick`` (MARG)     gyro rad/s, acc any, mag any           NWU
mahony     ``ahrs`` ``Mahony`` (MARG)       gyro rad/s, acc any, mag any           ENU
riann      ``riann`` (RIANN GRU, ONNX)      gyro rad/s, acc m/s²                   z up, yaw free
=========  ==============================  =====================================  ==============

ENU outputs are turned into NWU by ``Rz(-90°)`` on the left (yaw_NWU = yaw_ENU − π/2).
Every library quaternion is scalar-first ``[w, x, y, z]``; it is reordered. RIANN uses no
magnetometer: its yaw is arbitrary and :func:`filter_euler` returns NaN for it.

All filters run causally (sample by sample, only the past), as they would on-line; VQF's
acausal ``offlineVQF`` is not used. Parameters are the libraries' own names; each filter's
tuning grid (searched on the training recordings by :mod:`danae_lite.research.baselines`) is in
:data:`FILTERS`. ``ahrs``'s two filters update in pure Python, one grid point at a time; a grid
of them on one recording runs in one pass (:mod:`danae_lite.research.ahrs.grid`, equal to the
library's runs to float64 rounding).
"""
from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from ...angles import G, quat_to_euler
from ...danae.networks import in_processes, threads_per_process
from . import grid as ahrs_grid
from ..memo import RunMemo, digest

Array = NDArray[np.float64]

_ENU_TO_NWU = Rotation.from_euler("z", -np.pi / 2)


def _wxyz_to_xyzw(q: ArrayLike) -> Array:
    q = np.asarray(q, dtype=float)
    return np.ascontiguousarray(q[:, [1, 2, 3, 0]])


def _unit_rows(q: Array) -> Array:
    n = np.sqrt(q[:, 0] * q[:, 0] + q[:, 1] * q[:, 1] + q[:, 2] * q[:, 2] + q[:, 3] * q[:, 3])
    return q / n[:, None]


def _enu_to_nwu(q_xyzw: Array) -> Array:
    """``Rz(-90°) q`` for every row: body -> ENU quaternions ``[x, y, z, w]`` as body -> NWU.

    The operations of SciPy's ``Rotation.from_quat(q)`` composed on the left with the constant
    and read back with ``as_quat()``, in the same order (normalise the rows, Hamilton product,
    normalise again), so the same bits (tests/test_filters.py), in a fifth of the time: a
    change of bits would change the cache key of every network trained on these outputs."""
    px, py, pz, pw = _ENU_TO_NWU.as_quat()
    qx, qy, qz, qw = _unit_rows(np.asarray(q_xyzw, dtype=float)).T
    cx, cy, cz = py * qz - pz * qy, pz * qx - px * qz, px * qy - py * qx
    r = np.stack([pw * qx + qw * px + cx, pw * qy + qw * py + cy, pw * qz + qw * pz + cz,
                  pw * qw - (px * qx + py * qy + pz * qz)], axis=1)
    return _unit_rows(r)


def checked_sensors(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float) -> tuple[Array, Array, Array | None]:
    """``gyro``, ``acc`` and ``mag`` as contiguous float arrays, checked: each ``(N, 3)`` with the
    gyro's ``N``, finite, at least one sample, and a positive finite rate ``fs`` [Hz]; ValueError
    naming the array and the row otherwise."""
    g = np.ascontiguousarray(gyro, dtype=float)
    a = np.ascontiguousarray(acc, dtype=float)
    m = None if mag is None else np.ascontiguousarray(mag, dtype=float)
    for name, arr in (("gyro", g), ("acc", a), ("mag", m)):
        if arr is None:
            continue
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise ValueError(f"{name} must have shape (N, 3), got {arr.shape}")
        if arr.shape[0] != g.shape[0]:
            raise ValueError(f"{name} has {arr.shape[0]} rows but gyro has {g.shape[0]}")
        if not np.isfinite(arr).all():
            r = int(np.argwhere(~np.isfinite(arr))[0, 0])
            raise ValueError(f"{name} row {r} is not finite: {arr[r].tolist()}")
    if g.shape[0] < 1:
        raise ValueError("need at least one sample")
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"fs must be a positive number of Hz, got {fs!r}")
    return g, a, m


def fusion(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float, *, gain: float = 0.5,
           acceleration_rejection: float = 10.0, magnetic_rejection: float = 10.0,
           rejection_timeout_s: float = 5.0) -> Array:
    """x-io Fusion AHRS (``imufusion``): complementary filter with rejection of accelerometer
    and magnetometer disturbances.

    ``gain`` is the library's gain (0.5 default); the rejection thresholds are in degrees and
    ``rejection_timeout_s`` in seconds (the library counts it in samples). Returns (N, 4)
    quaternions ``[x, y, z, w]``, body -> NWU.
    """
    import imufusion

    g, a, m = checked_sensors(gyro, acc, mag, fs)
    settings = imufusion.AhrsSettings()
    settings.convention = imufusion.CONVENTION_NWU
    settings.gain = float(gain)
    settings.gyroscope_range = 2000.0
    settings.acceleration_rejection = float(acceleration_rejection)
    settings.magnetic_rejection = float(magnetic_rejection)
    settings.rejection_timeout = int(round(rejection_timeout_s * fs))
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(settings)
    ahrs.set_sample_period(1.0 / fs)
    g_deg = np.degrees(g)
    out = np.empty((len(g), 4))
    for i in range(len(g)):
        if m is None:
            ahrs.update_no_magnetometer(g_deg[i], a[i])
        else:
            ahrs.update(g_deg[i], a[i], m[i])
        out[i] = ahrs.get_quaternion()
    return _wxyz_to_xyzw(out)


def vqf(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float, *, tauAcc: float = 3.0,
        tauMag: float = 9.0, magDistRejectionEnabled: bool = True) -> Array:
    """VQF (``vqf.VQF``, causal): gyro strapdown with accelerometer correction (time constant
    ``tauAcc`` [s]), heading from the magnetometer (``tauMag`` [s]), rest/motion gyro-bias
    estimation and magnetic-disturbance rejection. Returns the 9D quaternion (6D without
    ``mag``), ``[x, y, z, w]``, body -> NWU."""
    import vqf as _vqf

    g, a, m = checked_sensors(gyro, acc, mag, fs)
    f = _vqf.VQF(1.0 / fs, tauAcc=float(tauAcc), tauMag=float(tauMag),
                 magDistRejectionEnabled=bool(magDistRejectionEnabled))
    out = f.updateBatch(g, np.ascontiguousarray(a * G), m)
    q = out["quat9D"] if m is not None else out["quat6D"]
    return _enu_to_nwu(_wxyz_to_xyzw(q))


def madgwick(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float, *, gain: float = 0.041) -> Array:
    """Madgwick's gradient-descent filter (``ahrs.filters.Madgwick``; MARG with ``mag``,
    IMU without). ``gain`` is beta [rad/s] (library default 0.041 MARG). Pure Python: about
    20-40 k samples/s. Returns ``[x, y, z, w]``, body -> NWU."""
    from ahrs.filters import Madgwick

    g, a, m = checked_sensors(gyro, acc, mag, fs)
    f = Madgwick(gyr=g, acc=a * G, mag=m, frequency=float(fs), gain=float(gain))
    return _wxyz_to_xyzw(f.Q)


def mahony(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float, *, k_P: float = 1.0,
           k_I: float = 0.3) -> Array:
    """Mahony's explicit complementary filter (``ahrs.filters.Mahony``), proportional gain
    ``k_P`` and integral gain ``k_I`` (gyro-bias estimation). Returns ``[x, y, z, w]``,
    body -> NWU."""
    from ahrs.filters import Mahony

    g, a, m = checked_sensors(gyro, acc, mag, fs)
    f = Mahony(gyr=g, acc=a * G, mag=m, frequency=float(fs), k_P=float(k_P), k_I=float(k_I))
    q = _wxyz_to_xyzw(f.Q)
    return _enu_to_nwu(q) if m is not None else q


def riann_model_path() -> str:
    """Path of the ONNX model shipped inside the ``riann`` package (riann 0.2.0 does not find
    it by itself from every working directory, so it is always passed explicitly)."""
    import riann

    path = os.path.join(os.path.dirname(riann.__file__), "riann.onnx")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: the riann package does not contain its model file riann.onnx")
    return path


def riann(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float) -> Array:
    """RIANN (``riann``): a trained recurrent network for roll and pitch from gyro and
    accelerometer (no magnetometer, no parameters; ``mag`` is ignored). The GRU runs over
    the recording from its start, causally. Returns ``[x, y, z, w]`` with z up; the yaw is
    arbitrary."""
    from riann import RIANN

    g, a, _ = checked_sensors(gyro, acc, None, fs)
    net = RIANN(riann_model_path())
    q = net.predict(np.ascontiguousarray(a * G, dtype=np.float32), np.ascontiguousarray(g, dtype=np.float32), float(fs))
    return _wxyz_to_xyzw(np.asarray(q, dtype=float))


def _mahony_grid(g: Array, a: Array, m: Array | None, fs: float, params: Sequence[dict[str, Any]]) -> list[Array] | None:
    """:func:`mahony` for every parameter set at once (:func:`~danae_lite.research.ahrs.grid.mahony_marg`)."""
    if not ahrs_grid.supported(g, a, m) or any(set(p) - {"k_P", "k_I"} for p in params):
        return None
    k_p = [float(p.get("k_P", 1.0)) for p in params]
    k_i = [float(p.get("k_I", 0.3)) for p in params]
    return [_enu_to_nwu(_wxyz_to_xyzw(q)) for q in ahrs_grid.mahony_marg(g, a * G, m, fs, k_p, k_i)]


def _madgwick_grid(g: Array, a: Array, m: Array | None, fs: float, params: Sequence[dict[str, Any]]) -> list[Array] | None:
    """:func:`madgwick` for every gain at once (:func:`~danae_lite.research.ahrs.grid.madgwick_marg`)."""
    if not ahrs_grid.supported(g, a, m) or any(set(p) - {"gain"} for p in params):
        return None
    return [_wxyz_to_xyzw(q) for q in ahrs_grid.madgwick_marg(g, a * G, m, fs, [float(p.get("gain", 0.041)) for p in params])]


@dataclass(frozen=True)
class FilterSpec:
    """A library filter: the function, whether its yaw means anything, and its tuning grid."""

    run: Callable[..., Array]
    has_yaw: bool
    grid: dict[str, tuple[Any, ...]] = field(default_factory=dict)
    """Parameter values searched on the training recordings (product of all lists)."""
    run_grid: Callable[..., list[Array] | None] | None = None
    """Several parameter sets on one recording in one pass, ``(gyro, acc, mag, fs, [params, ...])``
    -> outputs as :attr:`run` gives them, or None where it does not apply; None: no such path."""


FILTERS: dict[str, FilterSpec] = {
    "fusion": FilterSpec(fusion, True, {"gain": (0.05, 0.1, 0.2, 0.5, 1.0, 2.0),
                                        "magnetic_rejection": (10.0, 20.0, 45.0, 90.0)}),
    "vqf": FilterSpec(vqf, True, {"tauAcc": (0.5, 1.0, 2.0, 3.0, 5.0, 10.0, 20.0, 40.0),
                                  "tauMag": (3.0, 9.0, 30.0, 100.0)}),
    "madgwick": FilterSpec(madgwick, True, {"gain": (0.005, 0.01, 0.02, 0.041, 0.08, 0.16)}, _madgwick_grid),
    "mahony": FilterSpec(mahony, True, {"k_P": (0.1, 0.3, 1.0, 3.0, 10.0), "k_I": (0.0003, 0.003, 0.03, 0.3)},
                         _mahony_grid),
    "riann": FilterSpec(riann, False, {}),
}
"""The library filters by leaderboard name; each grid (product of its lists) is searched jointly
on the training recordings (:class:`danae_lite.research.baselines.LibraryFilter`): Fusion's gain and
magnetic rejection [deg], VQF's tauAcc and tauMag [s], Madgwick's beta [rad/s], Mahony's k_P
and k_I."""


memo = RunMemo(2 << 30, code_of=__name__)
"""Filter outputs kept by :func:`run_filter` (2 GiB: every distinct run of a chapter's grid searches)."""


def _run_group(name: str, g: Array, a: Array, m: Array | None, fs: float, params: list[dict[str, Any]]) -> list[Array]:
    """One filter on one recording for each parameter set of ``params``: in one pass where the
    filter has one (:attr:`FilterSpec.run_grid`), else run by run. Nothing stored (a worker
    process's part of :func:`run_many`)."""
    spec = FILTERS[name]
    found = spec.run_grid(g, a, m, fs, params) if spec.run_grid is not None and len(params) > 1 else None
    return found if found is not None else [spec.run(g, a, m, fs, **p) for p in params]


def run_many(calls: Sequence[tuple[str, ArrayLike, ArrayLike, ArrayLike | None, float, dict[str, Any]]], *,
             jobs: int = 1, persist: bool = True) -> list[Array]:
    """:func:`run_filter` for each ``(name, gyro, acc, mag, fs, params)`` of ``calls``, in order.

    The runs that :data:`memo` does not hold are grouped by filter and recording: a group is
    one pass over the samples where the filter has one for a whole grid (Madgwick, Mahony:
    :mod:`danae_lite.research.ahrs.grid`). With ``jobs`` > 1 the groups are computed in that
    many worker processes (:func:`~danae_lite.danae.networks.in_processes`, one torch thread
    each) and stored here: a grid search is where the other cores help. ``persist=False``
    returns the computed runs without keeping them (a grid search's many runs, of which one is
    used afterwards): a later :func:`run_filter` of the chosen setting computes it by the one
    path of a single run, so that a filter's output, and any network trained on it, does not
    depend on whether a search ran before it in the process (the one-pass grid agrees with the
    library to float64 rounding, not bit for bit)."""
    for name, *_ in calls:
        if name not in FILTERS:
            raise ValueError(f"unknown filter {name!r}; choose one of {', '.join(FILTERS)}")
    checked = [(name, *checked_sensors(g, a, m, fs), float(fs), dict(params)) for name, g, a, m, fs, params in calls]
    data = [digest(g, a, m) for _, g, a, m, _, _ in checked]
    keys = [(name, fs, tuple(sorted((k, repr(v)) for k, v in params.items())), d)
            for (name, _, _, _, fs, params), d in zip(checked, data)]
    out: list[Array | None] = [memo.get(k) for k in keys]
    groups: dict[tuple[Any, ...], dict[tuple[Any, ...], int]] = {}  # (filter, fs, data) -> {run: a call}
    for i, found in enumerate(out):
        if found is None:
            groups.setdefault((keys[i][0], keys[i][1], data[i]), {}).setdefault(keys[i], i)
    tasks = [(*checked[next(iter(runs.values()))][:5], [checked[i][5] for i in runs.values()]) for runs in groups.values()]
    if jobs > 1 and len(tasks) > 1:
        results = in_processes(_run_group, tasks, processes=jobs, threads=threads_per_process(jobs))
    else:
        results = (_run_group(*t) for t in tasks)
    computed: dict[tuple[Any, ...], Array] = {}
    for runs, qs in zip(groups.values(), results):
        for key, q in zip(runs, qs):
            if persist:
                memo.put(key, q)
            computed[key] = q
    return [found if found is not None else computed[keys[i]] for i, found in enumerate(out)]


def run_filter(name: str, gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float, **params: Any) -> Array:
    """Run library filter ``name`` (see :data:`FILTERS`); returns (N, 4) ``[x, y, z, w]``,
    body -> NWU. A run made before in this process with the same data and parameters is
    returned from :data:`memo` (a copy)."""
    return run_many([(name, gyro, acc, mag, fs, params)])[0]


def to_euler(name: str, q_xyzw: Array) -> Array:
    """Filter ``name``'s quaternions (N, 4) as (N, 3) Euler angles (roll, pitch, yaw) [rad],
    intrinsic ZYX; yaw is NaN for filters without a heading reference (RIANN)."""
    e = quat_to_euler(q_xyzw)
    if not FILTERS[name].has_yaw:
        e[:, 2] = np.nan
    return e


def filter_euler(name: str, gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, fs: float,
                 **params: Any) -> Array:
    """:func:`run_filter` as Euler angles (:func:`to_euler`)."""
    return to_euler(name, run_filter(name, gyro, acc, mag, fs, **params))
