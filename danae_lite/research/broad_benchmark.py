"""The BROAD benchmark's error metric and the authors' published figures.

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

The benchmark's two reference filters, which reproduce its published figures, are
:mod:`danae_lite.research.ahrs.broad_reference`.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..data.broad import TrialIndex, read_json
from ..data.frames import quat_multiply
from ..data.recording import DataError, Recording

Array = NDArray[np.float64]

__all__ = ["METRICS", "BroadRMSE", "Published", "benchmark_rmse", "error_angles", "error_quaternion", "evaluate",
           "group_means", "published"]

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
