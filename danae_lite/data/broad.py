"""The BROAD benchmark's recordings: the loader and the benchmark's train/test split (its error
metric, reference filters and the authors' published figures are in
:mod:`danae_lite.research.broad_benchmark`).

BROAD (Berlin Robust Orientation Estimation Assessment Dataset) is by Daniel Laidig, Marco
Caruso, Andrea Cereatti and Thomas Seel: "BROAD—A Benchmark for Robust Inertial Orientation
Estimation", *Data* 6(7):72, 2021, https://doi.org/10.3390/data6070072. The data is licensed
under Creative Commons Attribution 4.0 (CC BY 4.0): credit that paper wherever it is used.
Nothing of the dataset is shipped with this package; the files are read from the user's data
directory. The code below is our own, written after reading the benchmark's paper and example
code (the metric, the filters, the initialisation); nothing is copied from it.

The split (:func:`load_experiment`): train on the trials of the group ``undisturbed``, test on
those of ``disturbed`` (magnets, tapping, vibration), so every test trial is a disturbance the
methods never saw while fitted; with no ``broad/`` folder in the data directory the handheld
simulator stands in (the recordings of :func:`danae_lite.data.experiments.simulated_experiment`).
Fast mode keeps the first :data:`FAST_TRIALS` trials of each group, cut to their first
:data:`FAST_SAMPLES` samples.

Layout: ``<data dir>/broad/data_mat/NN_<name>.mat`` (one file per trial, ``scipy.io.loadmat``)
with ``trials.json`` beside them (trial descriptions and groups). Keys of a trial file:

=================  =======  ===========================================================================
key                shape    meaning
=================  =======  ===========================================================================
``imu_gyr``        (N, 3)   angular rate, body frame [rad/s]
``imu_acc``        (N, 3)   specific force, body frame [m/s²]; at rest it points *up* (+9.8 on z flat)
``imu_mag``        (N, 3)   magnetic field, body frame [µT]
``opt_quat``       (N, 4)   optical ground truth w, x, y, z, body -> ENU (magnetic east, north, up);
                            rows are all-NaN where the markers were not seen
``opt_pos``        (N, 3)   optical position [m] (NaN where not seen)
``sampling_rate``  (1, 1)   285.714 Hz
``movement``       (N, 1)   1 during the movement phases, where the benchmark evaluates errors
``info``           (1,)     free text
=================  =======  ===========================================================================

What :func:`load_trial` builds (a :class:`~danae_lite.data.recording.Recording`, ``source="broad"``):

* ``gyro`` = ``imu_gyr`` [rad/s]; ``mag`` = ``imu_mag`` [µT];
* ``acc`` = ``imu_acc / 9.80665`` [g]. BROAD's accelerometer reads +g *up* at rest, which is the
  tilt convention of the Recording (``R.T @ [0, 0, 1]``), so no sign changes;
* ``quat`` = the ground truth, scalar-last ``[x, y, z, w]``, body -> **NWU** (x magnetic north,
  y west, z up), i.e. ``Rz(-90°) * opt_quat``: the frame of every filter in
  :mod:`danae_lite.research.ahrs.filters`, so that filter output and ground truth compare directly. The
  benchmark's error metric is the same in ENU and NWU (see :func:`danae_lite.research.broad_benchmark.error_angles`);
* ground-truth gaps (NaN rows of ``opt_quat``: 42-4845 samples per trial, mostly before and
  after the movement, up to 513 inside it) are filled so that ``quat`` is finite everywhere:
  spherical-linear interpolation between the valid neighbours inside a gap, the nearest valid
  sample before the first and after the last. ``meta["gt_valid"]`` is False on every filled
  row and the metric never uses them, exactly as the benchmark's ``nanmean`` ignores them.

``meta``: ``trial`` (int NN or None), ``movement`` (N,) bool, ``gt_valid`` (N,) bool,
``gt_gaps`` (list of (start, length) in the file's sample indices; after
:meth:`~danae_lite.data.recording.Recording.slice` use ``gt_valid``, which is sliced),
``position`` (N, 3) [m] in **ENU** as stored (NaN where missing), ``description`` and
``groups`` (from ``trials.json``; None / () when there is none), ``info``, ``path``,
``conventions``.
"""
from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import experiments
from ..angles import G
from .frames import enu_to_nwu
from .recording import DataError, Recording

Array = NDArray[np.float64]

__all__ = ["CONVENTIONS", "FS", "IN_SAMPLE", "QUAT_NORM_TOL", "TrialIndex", "data_mat_dir", "find_trials",
           "in_sample_label", "load_experiment", "load_files", "load_trial", "load_trials", "root",
           "simulated_experiment", "trial_groups", "trial_index"]

FS = 2000.0 / 7.0
"""BROAD's sample rate, 285.714 Hz (each file stores its own ``sampling_rate``)."""
QUAT_NORM_TOL = 1e-3
"""Largest accepted ``|‖opt_quat‖ - 1|`` (the files hold unit quaternions to 1e-15)."""
CONVENTIONS = (
    "BROAD: fs from sampling_rate (285.714 Hz); gyro [rad/s], mag [µT] and acc [g] "
    "(imu_acc / 9.80665, +g up at rest = tilt convention) in the IMU body frame; "
    "quat = ground truth (x, y, z, w), body -> NWU (x magnetic north, y west, z up) = "
    "Rz(-90°) * opt_quat (ENU, w, x, y, z); rows where opt_quat is NaN are filled (slerp inside "
    "a gap, nearest valid at the ends) and marked False in meta['gt_valid']; meta['movement'] "
    "marks the evaluated samples; meta['position'] is opt_pos [m] in ENU as stored.")

FAST_SAMPLES = 17143
"""Samples kept per BROAD trial in fast mode (60 s at 285.7 Hz; every trial moves within them,
after resting 27 to 48 s, long enough for the filters' heading to settle)."""
FAST_TRIALS = 2
"""BROAD trials kept per group (the training group, the test group) in fast mode."""
TRAIN_GROUP = "undisturbed"
"""BROAD trials used for fitting (group of ``trials.json``)."""
TEST_GROUP = "disturbed"
"""BROAD trials used for testing."""

IN_SAMPLE: tuple[str, ...] = ("riann",)
"""Methods whose published parameters were fitted on data that include most BROAD trials
(RIANN's network): their BROAD figures, and those of any method built on them, are partly
in-sample."""


def in_sample_label(method: str) -> str:
    """``method`` as a BROAD table names it: ``"riann (partly in-sample)"`` for a method of
    :data:`IN_SAMPLE` or one built on it (``"danae-res[riann]"``), else unchanged."""
    inside = any(m == method or f"[{m}]" in method for m in IN_SAMPLE)
    return f"{method} (partly in-sample)" if inside else method


_TRIAL_RE = re.compile(r"(\d+)_(.+)")
_REQUIRED: dict[str, int | None] = {
    "imu_gyr": 3, "imu_acc": 3, "imu_mag": 3, "opt_quat": 4, "movement": None, "sampling_rate": None}


# --- loading -----------------------------------------------------------------------------

def _fill_gaps(q: Array, valid: NDArray[np.bool_]) -> Array:
    """Fill invalid rows of scalar-last unit quaternions: slerp inside gaps, hold at the ends."""
    from scipy.spatial.transform import Rotation, Slerp

    out = q.copy()
    idx = np.flatnonzero(valid)
    first, last = idx[0], idx[-1]
    out[:first] = q[first]
    out[last + 1:] = q[last]
    bad = np.flatnonzero(~valid[first:last + 1]) + first
    if bad.size:
        breaks = np.flatnonzero(np.diff(bad) > 1)
        starts = np.r_[bad[0], bad[breaks + 1]]
        stops = np.r_[bad[breaks], bad[-1]] + 1
        for s, e in zip(starts, stops):
            slerp = Slerp([s - 1, e], Rotation.from_quat(q[[s - 1, e]]))
            out[s:e] = slerp(np.arange(s, e)).as_quat()
    return out


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(start, length) of every run of True."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    return [(int(s), int(e - s)) for s, e in zip(starts, stops)]


def _array(path: Path, data: Mapping[str, Any], key: str, width: int | None, n: int | None) -> Array:
    raw = np.asarray(data[key])
    if raw.dtype.kind not in "biuf":
        raise DataError(f"{path}: key '{key}' holds {raw.dtype} data; expected numbers")
    arr = raw.astype(float)
    if width is not None:
        if arr.ndim != 2 or arr.shape[1] != width or arr.shape[0] < 1:
            raise DataError(f"{path}: key '{key}' has shape {arr.shape}; expected (N, {width}) with N >= 1")
    if n is not None and arr.shape[0] != n:
        raise DataError(f"{path}: key '{key}' has {arr.shape[0]} rows but 'imu_gyr' has {n}; "
                        "every per-sample key must have the same number of rows")
    return arr


def _first_bad(path: Path, key: str, arr: Array, what: str = "a finite number") -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise DataError(f"{path}: key '{key}' row {r}, column {c} is {arr[r, c]}; expected {what}")


def load_trial(path: str | Path, *, index: TrialIndex | None = None) -> Recording:
    """Load one BROAD trial file ``NN_<name>.mat`` as a :class:`Recording` (see the module docstring).

    Parameters
    ----------
    path : the ``.mat`` file.
    index : trial descriptions and groups; default: ``trials.json`` beside the file when there
        is one (then it must list the trial), else none (``meta["groups"] = ()``).

    Raises
    ------
    DataError
        The file is missing or unreadable; a key is missing; a shape is not (N, 3) / (N, 4) /
        (N,) or (N, 1); row counts differ; an IMU value is not finite; an ``opt_quat`` row is
        partly NaN, infinite or not unit norm (``|norm - 1| > QUAT_NORM_TOL``); ``opt_quat`` has
        no valid row; ``movement`` holds other values than 0/1; ``sampling_rate`` is not one
        positive number; ``trials.json`` does not list the trial. Every message names the file,
        the key and, where it applies, the row (0-based) and column.
    """
    path = Path(path)
    data = read_mat(path)
    gyr = _array(path, data, "imu_gyr", 3, None)
    n = gyr.shape[0]
    acc = _array(path, data, "imu_acc", 3, n)
    mag = _array(path, data, "imu_mag", 3, n)
    for key, arr in (("imu_gyr", gyr), ("imu_acc", acc), ("imu_mag", mag)):
        _first_bad(path, key, arr)
    q_xyzw, valid = _ground_truth(path, _array(path, data, "opt_quat", 4, n))
    position = None
    if "opt_pos" in data:
        position = _array(path, data, "opt_pos", 3, n)
        if np.isinf(position).any():
            _first_bad(path, "opt_pos", np.where(np.isnan(position), 0.0, position), "a finite number or NaN")
    info = "\n".join(str(s) for s in np.asarray(data["info"]).ravel()) if "info" in data else None
    m = _TRIAL_RE.fullmatch(path.stem)
    description, groups = _listing(path, index)
    return Recording(
        name=path.stem,
        source="broad",
        fs=_sampling_rate(path, data),
        gyro=gyr,
        acc=acc / G,
        mag=mag,
        quat=enu_to_nwu(_fill_gaps(q_xyzw, valid)),
        meta={
            "trial": int(m.group(1)) if m else None,
            "movement": _movement(path, data, n),
            "gt_valid": valid,
            "gt_gaps": _runs(~valid),
            "position": position,
            "description": description,
            "groups": groups,
            "info": info,
            "path": str(path),
            "conventions": CONVENTIONS,
        },
    )


def read_mat(path: Path) -> dict[str, Any]:
    """The variables of a trial file; DataError when it is missing, unreadable or lacks a key."""
    from scipy.io import loadmat

    if not path.is_file():
        raise DataError(f"{path}: BROAD trial file not found")
    try:
        data = loadmat(str(path))
    except Exception as exc:  # scipy raises several types for a corrupt file
        raise DataError(f"{path}: cannot be read as a MATLAB .mat file ({type(exc).__name__}: {exc})") from exc
    missing = [k for k in _REQUIRED if k not in data]
    if missing:
        have = sorted(k for k in data if not k.startswith("__"))
        raise DataError(f"{path}: missing key(s) {', '.join(repr(k) for k in missing)}; a BROAD trial "
                        f"holds {', '.join(_REQUIRED)} (found: {', '.join(have) or 'nothing'})")
    return data


def read_json(path: Path, what: str = "file") -> object:
    """Parse a JSON file (``trials.json``, the published results); a missing file or invalid JSON
    raises DataError naming the file."""
    if not path.is_file():
        raise DataError(f"{path}: {what} not found")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataError(f"{path}: not valid JSON ({exc})") from exc


def _ground_truth(path: Path, quat_wxyz: Array) -> tuple[Array, NDArray[np.bool_]]:
    """``opt_quat`` (w, x, y, z) checked and normalised to scalar-last, NaN on missing rows; and
    the mask of valid rows."""
    n = len(quat_wxyz)
    nan_rows: NDArray[np.bool_] = np.asarray(np.isnan(quat_wxyz).all(axis=1), dtype=bool)
    partly = ~np.isfinite(quat_wxyz) & ~nan_rows[:, None]
    if partly.any():
        r, c = np.argwhere(partly)[0]
        raise DataError(f"{path}: key 'opt_quat' row {r}, column {c} is {quat_wxyz[r, c]}; expected a finite "
                        "number (a missing ground-truth sample must be NaN in all four columns)")
    valid: NDArray[np.bool_] = np.logical_not(nan_rows)
    if not valid.any():
        raise DataError(f"{path}: key 'opt_quat' has no valid row (all {n} are NaN); expected ground truth")
    norms = np.linalg.norm(np.where(valid[:, None], quat_wxyz, 0.0), axis=1)
    off = valid & (np.abs(norms - 1.0) > QUAT_NORM_TOL)
    if off.any():
        r = int(np.argmax(off))
        raise DataError(f"{path}: key 'opt_quat' row {r} has norm {norms[r]:.6g}; expected a unit "
                        f"quaternion (|norm - 1| <= {QUAT_NORM_TOL:g})")
    q_xyzw = quat_wxyz[:, [1, 2, 3, 0]]
    return np.where(valid[:, None], q_xyzw / np.where(norms > 0, norms, 1.0)[:, None], np.nan), valid


def _movement(path: Path, data: Mapping[str, Any], n: int) -> NDArray[np.bool_]:
    """``movement`` as (n,) bools; DataError unless it holds n values of 0 or 1."""
    mov_raw = np.asarray(data["movement"])
    if mov_raw.ndim == 2 and mov_raw.shape[1] == 1:
        mov_raw = mov_raw[:, 0]
    if mov_raw.shape != (n,):
        raise DataError(f"{path}: key 'movement' has shape {np.shape(data['movement'])}; expected ({n}, 1) or ({n},)")
    if mov_raw.dtype.kind not in "biuf":
        raise DataError(f"{path}: key 'movement' holds {mov_raw.dtype} data; expected 0/1")
    not01 = ~np.isin(mov_raw, (0, 1))
    if not01.any():
        r = int(np.argmax(not01))
        raise DataError(f"{path}: key 'movement' row {r} is {mov_raw[r].item()!r}; expected 0 or 1")
    return mov_raw.astype(bool)


def _sampling_rate(path: Path, data: Mapping[str, Any]) -> float:
    """``sampling_rate`` [Hz]; DataError unless it is one positive number."""
    fs_raw = np.asarray(data["sampling_rate"])
    if fs_raw.size != 1 or fs_raw.dtype.kind not in "biuf":
        raise DataError(f"{path}: key 'sampling_rate' is {fs_raw!r}; expected one number [Hz]")
    fs = float(fs_raw.reshape(()))
    if not (math.isfinite(fs) and fs > 0):
        raise DataError(f"{path}: key 'sampling_rate' is {fs}; expected a positive number of Hz")
    return fs


def _listing(path: Path, index: TrialIndex | None) -> tuple[str | None, tuple[str, ...]]:
    """The trial's description and groups from ``index`` (default: ``trials.json`` beside the
    file, if any); DataError when the index does not list it."""
    if index is None:
        jp = path.parent / "trials.json"
        index = trial_index(jp) if jp.is_file() else None
    if index is None:
        return None, ()
    if path.stem not in index.trials:
        raise DataError(f"{path}: trial {path.stem!r} is not listed in {index.path}; "
                        f"expected one of its {len(index.trials)} trials")
    return index.trials[path.stem]


def data_mat_dir(root: str | Path) -> Path:
    """The folder of the trial files for ``root``: ``<root>/broad/data_mat`` (``root`` is the
    data directory), else ``<root>/data_mat`` (``root`` is the BROAD folder itself).

    Raises DataError naming both candidates when neither is a folder.
    """
    root = Path(root)
    for cand in (root / "broad" / "data_mat", root / "data_mat"):
        if cand.is_dir():
            return cand
    raise DataError(f"{root}: no BROAD folder; expected {root / 'broad' / 'data_mat'} "
                    f"(or {root / 'data_mat'}) holding NN_<name>.mat files")


def find_trials(root: str | Path, names: Iterable[str] | None = None) -> list[Path]:
    """The trial files ``NN_<name>.mat`` under ``root`` (see :func:`data_mat_dir`), sorted by NN.

    ``names`` keeps only these trials: full names (``"02_undisturbed_slow_rotation_B"``) or
    numbers (``"02"``, ``"2"``). Raises DataError when the folder is missing, holds no ``.mat``
    file, holds a ``.mat`` file whose name is not ``NN_<name>.mat``, or a name matches no file.
    """
    folder = data_mat_dir(root)
    mats = [p for p in folder.iterdir() if p.suffix == ".mat" and p.is_file()]
    if not mats:
        raise DataError(f"{folder}: no .mat files; expected the BROAD trials NN_<name>.mat")
    numbered = [(_TRIAL_RE.fullmatch(p.stem), p) for p in mats]
    odd = sorted(p.name for m, p in numbered if m is None)
    if odd:
        raise DataError(f"{folder}: {', '.join(odd)}: not a BROAD trial name; expected NN_<name>.mat")
    paths = [p for _, p in sorted((int(m.group(1)), p) for m, p in numbered if m is not None)]
    if names is None:
        return paths
    chosen: set[Path] = set()
    for w in names:
        w = str(w)
        hit = [p for p in paths if p.stem == w or (w.isdigit() and int(p.stem.split("_", 1)[0]) == int(w))]
        if not hit:
            raise DataError(f"{folder}: no trial {w!r}; found {', '.join(p.stem for p in paths)}")
        chosen.update(hit)
    return [p for p in paths if p in chosen]


def load_trials(root: str | Path, names: Iterable[str] | None = None) -> list[Recording]:
    """Load the trials under ``root`` (see :func:`find_trials`, also for ``names``), sorted by
    trial number, with the groups of ``trials.json`` when it is there."""
    paths = find_trials(root, names)
    jp = paths[0].parent / "trials.json"
    index = trial_index(jp) if jp.is_file() else None
    return [load_trial(p, index=index) for p in paths]


@dataclass(frozen=True)
class TrialIndex:
    """``trials.json``: the groups (name, level, category) in file order and, per trial, its
    description and groups."""

    path: Path
    groups: tuple[tuple[str, int, str], ...]
    trials: dict[str, tuple[str, tuple[str, ...]]] = field(default_factory=dict)

    def members(self, group: str) -> list[str]:
        """Names of the trials in ``group``, in file order (all 39 in the full benchmark)."""
        if group not in {g[0] for g in self.groups}:
            raise KeyError(f"no group {group!r} in {self.path}; groups: {', '.join(g[0] for g in self.groups)}")
        return [t for t, (_, gs) in self.trials.items() if group in gs]


def trial_index(root: str | Path) -> TrialIndex:
    """Read ``trials.json``: ``root`` is the file, its folder, or anything :func:`data_mat_dir` takes.

    Raises DataError naming the file and the entry when it is missing or malformed.
    """
    root = Path(root)
    path = root if root.is_file() else (root / "trials.json" if (root / "trials.json").is_file()
                                        else data_mat_dir(root) / "trials.json")
    doc = read_json(path, "trials.json")
    if not isinstance(doc, dict) or not isinstance(doc.get("groups"), list) or not isinstance(doc.get("trials"), dict):
        raise DataError(f"{path}: expected an object with a 'groups' list and a 'trials' object")
    groups = []
    for i, g in enumerate(doc["groups"]):
        if not isinstance(g, dict) or not isinstance(g.get("name"), str):
            raise DataError(f"{path}: groups[{i}] is {g!r}; expected an object with a 'name'")
        groups.append((g["name"], int(g.get("level", 0)), str(g.get("category", ""))))
    trials: dict[str, tuple[str, tuple[str, ...]]] = {}
    for name, t in doc["trials"].items():
        if not isinstance(t, dict) or not isinstance(t.get("groups"), list):
            raise DataError(f"{path}: trials[{name!r}] is {t!r}; expected an object with a 'groups' list")
        trials[name] = (str(t.get("description", "")), tuple(str(g) for g in t["groups"]))
    return TrialIndex(path=path, groups=tuple(groups), trials=trials)


def trial_groups(root: str | Path) -> dict[str, tuple[str, ...]]:
    """Trial name -> its groups, from ``trials.json`` (see :func:`trial_index` for ``root``)."""
    return {name: gs for name, (_, gs) in trial_index(root).trials.items()}


# --- the benchmark's split ---------------------------------------------------------------

def root(data_dir: str | os.PathLike[str] | None = None) -> Path | None:
    """Return ``<data dir>/broad`` if that folder exists, else None."""
    base = experiments.existing_dir(data_dir)
    folder = base / "broad" if base is not None else None
    return folder if folder is not None and folder.is_dir() else None


def load_files(paths: list[Path], fast: bool) -> list[Recording]:
    """BROAD trials ``NN_<name>.mat``, cut in fast mode."""
    return experiments.fast_cut([load_trial(p) for p in paths], fast, FAST_SAMPLES)


def _real_experiment(folder: Path, fast: bool) -> experiments.Experiment:
    recs = load_trials(folder)  # DataError when the folder holds no trials
    keep = FAST_TRIALS if fast else None
    train = experiments.fast_cut([r for r in recs if TRAIN_GROUP in r.meta["groups"]][:keep], fast, FAST_SAMPLES)
    test = experiments.fast_cut([r for r in recs if TEST_GROUP in r.meta["groups"]][:keep], fast, FAST_SAMPLES)
    if not train or not test:
        raise DataError(f"{folder}: found {len(train)} trial(s) of the group {TRAIN_GROUP!r} and {len(test)} of "
                        f"{TEST_GROUP!r} (from trials.json); both are needed for the default split")
    cut = f" (fast mode: the first {FAST_TRIALS} trials of each group, first {FAST_SAMPLES} samples each)" if fast else ""
    note = (f"Real BROAD from {experiments.in_data_dir(folder)}: train the {len(train)} {TRAIN_GROUP} trials, test the {len(test)} "
            f"{TEST_GROUP} trials{cut}. BROAD: Laidig, Caruso, Cereatti, Seel, Data 6(7), 2021 (CC BY 4.0).")
    return experiments.Experiment("broad", "real", train, test, note, aligned=True)


def simulated_experiment(*, fast: bool = False, seed: int = 0, verbose: bool = True) -> experiments.Experiment:
    """The simulator's stand-in for BROAD: the handheld recordings of
    :func:`danae_lite.data.experiments.simulated_experiment` (``"oxiod"``), whatever data directory is set."""
    sim = experiments.simulated_experiment("oxiod", fast=fast, seed=seed, verbose=False)
    exp = experiments.Experiment("broad", "simulated", sim.train, sim.test, sim.note)
    if verbose:
        experiments.print_note(exp.note)
    return exp


def load_experiment(data_dir: str | os.PathLike[str] | None = None, *, fast: bool = False, seed: int = 0,
                    verbose: bool = True) -> experiments.Experiment:
    """The BROAD split (train :data:`TRAIN_GROUP`, test :data:`TEST_GROUP`) from ``<data dir>/broad``,
    or the simulated stand-in when there is no such folder (see the module docstring).

    Parameters
    ----------
    data_dir : data directory holding ``broad/``; None: the simulator stands in.
    fast : fast mode (see the module docstring).
    seed : base seed of the simulated stand-in.
    verbose : print the experiment's note.
    """
    base = experiments.existing_dir(data_dir)
    folder = root(base) if base is not None else None
    if folder is not None:
        exp = _real_experiment(folder, fast)
    else:
        exp = simulated_experiment(fast=fast, seed=seed, verbose=False)
        exp.note = exp.note.replace("Simulated: ", f"No real BROAD data found {experiments.where(base)}: ", 1)
    if verbose:
        experiments.print_note(exp.note)
    return exp
