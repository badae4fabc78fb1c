"""The BROAD benchmark's error metric, its two reference filters and the authors' published figures.

BROAD: Laidig, Caruso, Cereatti, Seel, "BROAD—A Benchmark for Robust Inertial Orientation
Estimation", *Data* 6(7):72, 2021 (CC BY 4.0). The trials are loaded by :mod:`danae_lite.data.broad`.
The code below is our own, written after reading the benchmark's paper and example code (the
metric, the filters, the initialisation); nothing is copied from it.

The metric (:func:`error_angles`, :func:`benchmark_rmse`): the error quaternion in the earth
frame, ``q_err = q_est * conj(q_true)``, split into a rotation about the vertical (heading) and
one about a horizontal axis (inclination); RMSE over the movement samples with valid ground
truth. The benchmark removes no heading offset (its code evaluates 9D estimates only); the
inclination error is by construction unaffected by a constant heading offset of the estimate,
which makes it the figure to compare for 6D filters (no magnetometer, arbitrary heading).

The BROAD reference filters (:func:`reference_madgwick`, :func:`reference_mahony`) re-implement what the benchmark ran to make
its published figures: Madgwick's and Mahony's MARG filters as in the x-io reference code,
first-order quaternion integration, initialised from the first accelerometer/magnetometer
sample with the benchmark's formula (:func:`benchmark_initial_quat`). With the published
common parameters (Madgwick beta 0.12; Mahony k_P 0.74, k_I 0.0012) they reproduce the
authors' per-trial total/heading/inclination RMSE to a relative 1.1e-4 or better on all 24
trials we have (the residue is the reference code's single-precision arithmetic: a float32
emulation of its Mahony matched the published figures of two trials to 1e-13). The
``ahrs``-based wrappers of :mod:`danae_lite.research.ahrs.filters` do not: ``ahrs``'s Madgwick uses the
paper's full-size magnetic reference where the reference code predicts half of it (per-trial
total RMSE off by -35 % to +44 %), and ``ahrs``'s Mahony starts from another initial quaternion
(off by -5.5 % to +8.4 %; with the benchmark's initial quaternion it matches to 1e-4).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..data.parsing import read_json
from ..angles import quat_multiply
from ..data.broad import TrialIndex
from ..data.recording import DataError, Recording

Array = NDArray[np.float64]

__all__ = ["BENCHMARK_FILTERS", "METRICS", "PUBLISHED_PARAMS", "BroadRMSE", "Published", "benchmark_initial_quat",
           "benchmark_rmse", "error_angles", "error_quaternion", "evaluate", "group_means", "published",
           "reference_madgwick", "reference_mahony", "run_benchmark_filter"]

METRICS: tuple[str, str, str] = ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg")
"""The benchmark's three figures, as named in its result files."""


# --- the benchmark's metric ----------------------------------------------------------------

def _as_quats(q: ArrayLike, name: str) -> Array:
    arr = np.asarray(q, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ValueError(f"{name} must have shape (N, 4) (scalar-last x, y, z, w), got {arr.shape}")
    return arr


def error_quaternion(q_est: ArrayLike, q_true: ArrayLike) -> Array:
    """The benchmark's error quaternion in the earth frame, scalar-last (N, 4).

    ``q_err = q_est * conj(q_true)`` after normalising both, then normalised: the rotation
    that takes the true orientation onto the estimate, expressed in the reference (earth)
    frame. Both inputs are body -> reference quaternions, scalar-last, in one common frame
    whose z axis is vertical (NWU or ENU alike). NaN rows give NaN rows.
    """
    qe = _as_quats(q_est, "q_est")
    qt = _as_quats(q_true, "q_true")
    if qe.shape != qt.shape:
        raise ValueError(f"q_est has shape {qe.shape} but q_true has {qt.shape}")
    qe = qe / np.linalg.norm(qe, axis=1, keepdims=True)
    qt = qt / np.linalg.norm(qt, axis=1, keepdims=True)
    err = quat_multiply(qe, qt * np.array([-1.0, -1.0, -1.0, 1.0]))
    return err / np.linalg.norm(err, axis=1, keepdims=True)


def error_angles(q_est: ArrayLike, q_true: ArrayLike) -> Array:
    """Per-sample total, heading and inclination errors [rad], shape (N, 3), as BROAD defines them.

    With ``q_err = (x, y, z, w)`` from :func:`error_quaternion`:

    * total error       = 2 * arccos(|w|), the whole rotation angle of q_err, in [0, pi];
    * heading error     = 2 * arctan(|z| / |w|), in [0, pi];
    * inclination error = 2 * arccos(sqrt(w² + z²)), in [0, pi].

    These come from writing ``q_err = q_heading * q_incl``, where ``q_heading`` turns about the
    vertical axis (its angle is the heading error) and ``q_incl`` about a horizontal axis (its
    angle is the inclination error). Because ``q_err`` lives in the earth frame, a constant
    heading offset of the estimate (``q_est -> Rz(a) * q_est``) leaves w² + z² and therefore the
    inclination error unchanged, and a rotation of the common reference frame about z (ENU vs
    NWU) changes none of the three. Deviation from the reference code: arctan2 is used, so
    ``w = z = 0`` (a pure 180° tilt) gives a heading error of 0 where the reference code gets
    0/0 = NaN and drops the sample.
    """
    e = error_quaternion(q_est, q_true)
    w = np.abs(e[:, 3])
    z = np.abs(e[:, 2])
    total = 2.0 * np.arccos(np.clip(w, 0.0, 1.0))
    heading = 2.0 * np.arctan2(z, w)
    incl = 2.0 * np.arccos(np.clip(np.sqrt(w * w + z * z), 0.0, 1.0))
    return np.stack([total, heading, incl], axis=1)


@dataclass(frozen=True)
class BroadRMSE:
    """The benchmark's figures for one trial [deg] and the number of samples they cover."""

    total_rmse_deg: float
    heading_rmse_deg: float
    inclination_rmse_deg: float
    n_samples: int

    def as_dict(self) -> dict[str, float]:
        """The three figures, keyed as in the benchmark's result files (:data:`METRICS`)."""
        return {m: float(getattr(self, m)) for m in METRICS}


def _mask(movement: ArrayLike, n: int, name: str = "movement") -> NDArray[np.bool_]:
    m = np.asarray(movement)
    if m.ndim == 2 and m.shape[1] == 1:
        m = m[:, 0]
    if m.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {m.shape}")
    if m.dtype != bool:
        bad = ~np.isin(m, (0, 1))
        if bad.any():
            r = int(np.argmax(bad))
            raise ValueError(f"{name}[{r}] is {m[r].item()!r}; expected 0/1 or a boolean")
        m = m.astype(bool)
    return m


def benchmark_rmse(q_est: ArrayLike, q_true: ArrayLike, movement: ArrayLike) -> BroadRMSE:
    """Total, heading and inclination RMSE [deg] over the movement phases, as BROAD computes them.

    Per sample, the errors of :func:`error_angles`; then for each of the three
    RMSE = sqrt(mean of error² over the samples where ``movement`` is true and ``q_true`` is
    valid), converted to degrees. Rows of ``q_true`` that are NaN (optical gaps) are left out,
    as the benchmark's ``nanmean`` leaves them out. No heading offset is removed.

    Parameters
    ----------
    q_est : (N, 4) estimated orientation, scalar-last, body -> reference (z up), finite.
    q_true : (N, 4) ground truth in the same frame; all-NaN rows mark missing samples.
    movement : (N,) or (N, 1) boolean or 0/1 mask of the evaluated samples.

    Raises
    ------
    ValueError
        Shapes disagree, ``q_est`` is not finite (the reference code would silently drop such
        rows; here a filter that returns NaN is an error), ``movement`` holds other values than
        0/1, or no sample is both moving and valid.
    """
    qe = _as_quats(q_est, "q_est")
    qt = _as_quats(q_true, "q_true")
    if qe.shape != qt.shape:
        raise ValueError(f"q_est has shape {qe.shape} but q_true has {qt.shape}")
    if not np.isfinite(qe).all():
        r = int(np.argwhere(~np.isfinite(qe))[0, 0])
        raise ValueError(f"q_est row {r} is not finite: {qe[r].tolist()}")
    use = _mask(movement, len(qe)) & np.isfinite(qt).all(axis=1)
    if not use.any():
        raise ValueError("no sample is both in a movement phase and has valid ground truth")
    err = error_angles(qe[use], qt[use])
    rmse = np.degrees(np.sqrt(np.mean(err * err, axis=0)))
    return BroadRMSE(float(rmse[0]), float(rmse[1]), float(rmse[2]), int(use.sum()))


def evaluate(rec: Recording, q_est: ArrayLike) -> BroadRMSE:
    """:func:`benchmark_rmse` of an estimate (scalar-last, body -> NWU) against a loaded trial.

    Uses ``rec.quat`` where ``rec.meta["gt_valid"]`` and ``rec.meta["movement"]`` are both true
    (the benchmark's samples exactly).
    """
    try:
        movement, valid = rec.meta["movement"], rec.meta["gt_valid"]
    except KeyError as exc:
        raise ValueError(f"recording {rec.name!r} has no meta[{exc.args[0]!r}]; load it with "
                         "danae_lite.data.broad.load_trial") from None
    q_true = np.where(np.asarray(valid, dtype=bool)[:, None], rec.quat, np.nan)
    return benchmark_rmse(q_est, q_true, movement)


def group_means(per_trial: Mapping[str, Mapping[str, float]], index: TrialIndex,
                metric: str = "total_rmse_deg") -> dict[str, tuple[float, int]]:
    """Per group, the mean of ``metric`` over its trials present in ``per_trial`` and their count.

    The benchmark's group figure is the plain mean of the per-trial RMSEs (not a pooled RMSE);
    with a subset of the trials the means cover only the trials given. Groups with none of
    them are left out.
    """
    out: dict[str, tuple[float, int]] = {}
    for g, _, _ in index.groups:
        vals = [float(per_trial[t][metric]) for t in index.members(g) if t in per_trial]
        if vals:
            out[g] = (float(np.mean(vals)), len(vals))
    return out


# --- the authors' published figures --------------------------------------------------------

_PARAM_NAMES: dict[str, dict[str, str]] = {"madgwick": {"beta": "beta"}, "mahony": {"Kp": "k_P", "Ki": "k_I"}}


@dataclass(frozen=True)
class Published:
    """The authors' ``results_<filter>_average_rmse.json``.

    ``trials`` / ``groups``: figures with the one parameter set that minimises the mean total
    RMSE over all 39 trials (the benchmark's "TAGP" parameters, ``parameters``);
    ``trials_best`` / ``groups_best``: the per-trial (per-group) minimum over the authors'
    parameter grid. Each figure is a dict keyed by :data:`METRICS` [deg]. ``params`` are the
    TAGP parameters under this module's keyword names (``beta``; ``k_P``, ``k_I``).
    """

    filter: str
    path: Path
    parameters: dict[str, float]
    params: dict[str, float]
    trials: dict[str, dict[str, float]]
    trials_best: dict[str, dict[str, float]]
    groups: dict[str, dict[str, float]]
    groups_best: dict[str, dict[str, float]]


def _figures(path: Path, where: str, entry: Any) -> tuple[dict[str, float], dict[str, float]]:
    out = []
    for kind in ("tagp_parameters", "minimum_value"):
        vals = entry.get(kind) if isinstance(entry, dict) else None
        if not isinstance(vals, dict):
            raise DataError(f"{path}: {where}['{kind}'] is missing; expected an object with {', '.join(METRICS)}")
        fig = {}
        for m in METRICS:
            v = vals.get(m)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or v < 0:
                raise DataError(f"{path}: {where}['{kind}']['{m}'] is {v!r}; expected a non-negative number [deg]")
            fig[m] = float(v)
        out.append(fig)
    return out[0], out[1]


def published(filter_name: str, root: str | Path) -> Published:
    """Load the authors' published figures for ``filter_name`` (``"madgwick"`` or ``"mahony"``).

    ``root`` is the JSON file itself or the folder holding ``results_<filter>_average_rmse.json``
    (the benchmark writes them to ``example_code/out``). Raises DataError naming the file and
    the entry when it is missing or malformed; ValueError for an unknown filter.
    """
    if filter_name not in _PARAM_NAMES:
        raise ValueError(f"unknown filter {filter_name!r}; the benchmark published {', '.join(_PARAM_NAMES)}")
    root = Path(root)
    path = root if root.suffix == ".json" else root / f"results_{filter_name}_average_rmse.json"
    doc = read_json(path, "published BROAD results")
    if not isinstance(doc, dict):
        raise DataError(f"{path}: expected a JSON object")
    for key in ("tagp_parameters", "trials", "groups"):
        if not isinstance(doc.get(key), dict):
            raise DataError(f"{path}: key '{key}' is missing or not an object")
    names = _PARAM_NAMES[filter_name]
    params_raw = doc["tagp_parameters"]
    if set(params_raw) != set(names):
        raise DataError(f"{path}: 'tagp_parameters' has {sorted(params_raw)}; expected {sorted(names)} "
                        f"for {filter_name}")
    for k, v in params_raw.items():
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise DataError(f"{path}: 'tagp_parameters'['{k}'] is {v!r}; expected a number")
    trials, trials_best, groups, groups_best = {}, {}, {}, {}
    for name, entry in doc["trials"].items():
        trials[name], trials_best[name] = _figures(path, f"trials['{name}']", entry)
    for name, entry in doc["groups"].items():
        groups[name], groups_best[name] = _figures(path, f"groups['{name}']", entry)
    return Published(
        filter=filter_name, path=path,
        parameters={k: float(v) for k, v in params_raw.items()},
        params={names[k]: float(v) for k, v in params_raw.items()},
        trials=trials, trials_best=trials_best, groups=groups, groups_best=groups_best)


# --- the benchmark's filters ------------------------------------------------------------------

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
    from .ahrs.filters import _check

    g, a, m = _check(gyro, acc, mag, fs)
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
    x, y, z, w = (float(v) for v in q)
    out = np.empty((len(G_), 4))
    sqrt = math.sqrt
    for i, (gx, gy, gz) in enumerate(G_):
        dw = 0.5 * (-x * gx - y * gy - z * gz)
        dx = 0.5 * (w * gx + y * gz - z * gy)
        dy = 0.5 * (w * gy - x * gz + z * gx)
        dz = 0.5 * (w * gz + x * gy - y * gx)
        ax, ay, az = A_[i]
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
            # magnetometer step written out in both filters, as in the reference code (deliberate:
            # each filter reads top to bottom; a shared helper would cost a call per sample)
            mrow = None if M_ is None else M_[i]
            if mrow is not None and (mrow[0] != 0.0 or mrow[1] != 0.0 or mrow[2] != 0.0):
                mx, my, mz = mrow
                nm = 1.0 / sqrt(mx * mx + my * my + mz * mz)
                mx, my, mz = mx * nm, my * nm, mz * nm
                r11, r12, r13 = 1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)
                r21, r22, r23 = 2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)
                hx, hy = r11 * mx + r12 * my + r13 * mz, r21 * mx + r22 * my + r23 * mz
                hz = r31 * mx + r32 * my + r33 * mz
                bx = 0.5 * sqrt(hx * hx + hy * hy)
                bz = 0.5 * hz
                f4 = r11 * bx + r31 * bz - mx
                f5 = r12 * bx + r32 * bz - my
                f6 = r13 * bx + r33 * bz - mz
                s0 += -2.0 * bz * y * f4 + (2.0 * bz * x - 2.0 * bx * z) * f5 + 2.0 * bx * y * f6
                s1 += 2.0 * bz * z * f4 + (2.0 * bx * y + 2.0 * bz * w) * f5 + (2.0 * bx * z - 4.0 * bz * x) * f6
                s2 += ((-4.0 * bx * y - 2.0 * bz * w) * f4 + (2.0 * bx * x + 2.0 * bz * z) * f5
                       + (2.0 * bx * w - 4.0 * bz * y) * f6)
                s3 += (2.0 * bz * x - 4.0 * bx * z) * f4 + (2.0 * bz * y - 2.0 * bx * w) * f5 + 2.0 * bx * x * f6
            ns = sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
            if ns > 0.0:
                k = beta / ns
                dw -= k * s0
                dx -= k * s1
                dy -= k * s2
                dz -= k * s3
        w, x, y, z = w + dw * dt, x + dx * dt, y + dy * dt, z + dz * dt
        nq = 1.0 / sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w * nq, x * nq, y * nq, z * nq
        out[i] = (x, y, z, w)
    return out


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
    x, y, z, w = (float(v) for v in q)
    ix = iy = iz = 0.0
    out = np.empty((len(G_), 4))
    sqrt = math.sqrt
    for i, (gx, gy, gz) in enumerate(G_):
        ax, ay, az = A_[i]
        if ax != 0.0 or ay != 0.0 or az != 0.0:
            na = 1.0 / sqrt(ax * ax + ay * ay + az * az)
            ax, ay, az = ax * na, ay * na, az * na
            vx = 2.0 * (x * z - w * y)
            vy = 2.0 * (y * z + w * x)
            vz = 1.0 - 2.0 * (x * x + y * y)
            ex = ay * vz - az * vy
            ey = az * vx - ax * vz
            ez = ax * vy - ay * vx
            # magnetometer step written out in both filters, as in the reference code (deliberate:
            # each filter reads top to bottom; a shared helper would cost a call per sample)
            mrow = None if M_ is None else M_[i]
            if mrow is not None and (mrow[0] != 0.0 or mrow[1] != 0.0 or mrow[2] != 0.0):
                mx, my, mz = mrow
                nm = 1.0 / sqrt(mx * mx + my * my + mz * mz)
                mx, my, mz = mx * nm, my * nm, mz * nm
                r11 = 1.0 - 2.0 * (y * y + z * z)
                r12 = 2.0 * (x * y - w * z)
                r13 = 2.0 * (x * z + w * y)
                r21 = 2.0 * (x * y + w * z)
                r22 = 1.0 - 2.0 * (x * x + z * z)
                r23 = 2.0 * (y * z - w * x)
                hx = r11 * mx + r12 * my + r13 * mz
                hy = r21 * mx + r22 * my + r23 * mz
                hz = vx * mx + vy * my + vz * mz
                bx = sqrt(hx * hx + hy * hy)
                ux = r11 * bx + vx * hz
                uy = r12 * bx + vy * hz
                uz = r13 * bx + vz * hz
                ex += my * uz - mz * uy
                ey += mz * ux - mx * uz
                ez += mx * uy - my * ux
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
        w, x, y, z = w * nq, x * nq, y * nq, z * nq
        out[i] = (x, y, z, w)
    return out


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
