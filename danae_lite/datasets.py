"""Find the real datasets in the data directory, or let the simulator stand in.

The data directory (an argument; the entry points take it from ``--data-dir`` or ``DANAE_DATA``,
see :mod:`danae_lite.config`) holds the datasets in their original layout:

* ``oxiod/handheld/data1/syn/imuK.csv`` + ``viK.csv`` for K = 2, 3, 4, 7: train on imu3, imu4,
  imu7, test on imu2. (The paper used OxIOD's slow-walking set, which is not available here;
  handheld/data1 is the closest set at hand.)
* ``ucs/full_dataset/imu_adis.txt``: first 80 % train, last 20 % test, as the paper.
* ``broad/data_mat/NN_<name>.mat`` (the BROAD benchmark, :mod:`danae_lite.broad`): train on the
  trials of the group ``undisturbed``, test on those of ``disturbed`` (magnets, tapping,
  vibration), so every test trial is a disturbance the methods never saw while fitted.

A missing ``oxiod/`` (or ``broad/``, ``ucs/``) folder means "no real data": the simulator
stands in (:func:`danae_lite.simulate.simulate`), with the same split shape: four
``"handheld"`` recordings (seeds ``seed + 0..3``, test = the first; also for ``broad``) or one
``"underwater"`` recording split 80/20. A folder that exists but lacks the expected files raises DataError: whoever put it
there meant real data.

Fast mode (the ``fast`` argument) runs every step on little data, so that a chapter runs in
a minute or two (``make test``) with the same code path as in full mode: it keeps the first
:data:`FAST_SAMPLES` samples of each real OxIOD recording and at most
:data:`FAST_MOTION_RECORDINGS` recordings per motion (fewer cross-validation folds; still two
training recordings per fold, as in full mode), keeps the real UCS recording whole (it is only
~20k samples at 10 Hz), simulates :data:`FAST_DURATION` seconds per recording instead of the
scenario default (180 s handheld, 1950 s underwater), and keeps the first
:data:`FAST_BROAD_TRIALS` trials of each BROAD group (train, test), cut to their first
:data:`FAST_BROAD_SAMPLES` samples (60 s; every trial moves within them).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from . import broad, oxiod, ucs
from .recording import DataError, Recording

OXIOD_FOLDER = ("handheld", "data1")
"""Setting and folder of the OxIOD recordings used."""
OXIOD_TRAIN = (3, 4, 7)
"""OxIOD recordings (K of imuK) used for training."""
OXIOD_TEST = (2,)
"""OxIOD recordings used for testing."""
PAPER_SPLIT_FOLDER = ("slow walking", "data1")
"""Setting and folder of the paper's own OxIOD split (``--split paper``)."""
PAPER_SPLIT_TRAIN = (2, 3, 4, 5, 6, 7)
"""The paper's training recordings (K of imuK) in :data:`PAPER_SPLIT_FOLDER`."""
PAPER_SPLIT_TEST = (1,)
"""The paper's test recording in :data:`PAPER_SPLIT_FOLDER`."""
UCS_RELPATH = Path("full_dataset") / "imu_adis.txt"
"""Location of the ADIS file inside ``<data dir>/ucs``."""
TRAIN_FRACTION = 0.8
"""Share of the UCS recording used for training (the first part)."""
FAST_SAMPLES = 1500
"""Samples kept per real OxIOD recording in fast mode (15 s at 100 Hz)."""
FAST_MOTION_RECORDINGS = 3
"""Recordings kept per OxIOD motion in fast mode (:func:`load_motions`): leave-one-out folds
then still train on two recordings, as the methods that hold out training recordings need."""
FAST_DURATION = {"handheld": 20.0, "underwater": 300.0}
"""Simulated duration per recording in fast mode [s]."""
FAST_BROAD_SAMPLES = 17143
"""Samples kept per BROAD trial in fast mode (60 s at 285.7 Hz; every trial moves within them,
after resting 27 to 48 s, long enough for the filters' heading to settle)."""
FAST_BROAD_TRIALS = 2
"""BROAD trials kept per group (the training group, the test group) in fast mode."""
BROAD_TRAIN_GROUP = "undisturbed"
"""BROAD trials used for fitting (group of ``trials.json``)."""
BROAD_TEST_GROUP = "disturbed"
"""BROAD trials used for testing."""
NAMES = ("oxiod", "ucs", "broad")
OXIOD_MOTIONS: dict[str, tuple[str, str, tuple[int, ...]]] = {
    "handheld": ("handheld", "data1", (2, 3, 4, 7)),
    "trolley": ("trolley", "data2", (2, 3, 4, 5)),
    "multi users": ("multi users", "user2", (5, 6)),
}
"""OxIOD motions used for cross-validation: motion -> (setting folder, data folder, K of imuK).
Handheld is required; a motion whose folder is absent is left out."""


@dataclass
class Experiment:
    """The recordings of one experiment and where they came from.

    ``name`` is ``"oxiod"``, ``"ucs"`` or ``"broad"``; ``data`` is ``"real"`` or ``"simulated"``;
    ``note`` is one sentence for people saying which data is used. ``aligned`` says that the
    sensor axes already are the ground truth's body axes and its heading is magnetic north (as
    the BROAD benchmark provides them), so the leaderboard estimates no frame alignment.
    """

    name: str
    data: str
    train: list[Recording]
    test: list[Recording]
    note: str
    aligned: bool = False


def existing_dir(path: str | os.PathLike[str] | None) -> Path | None:
    """``path`` resolved, or None for None. A path that is not a directory raises
    ``FileNotFoundError`` naming it: whoever names a data directory means it."""
    if path is None:
        return None
    p = Path(path).expanduser().resolve()
    if not p.is_dir():
        raise FileNotFoundError(f"data directory {p} is not a directory")
    return p


def fast_cut(recs: list[Recording], fast: bool, limit: int) -> list[Recording]:
    """Fast mode: the first ``limit`` samples of each recording (names kept); else ``recs``."""
    return [r.slice(0, limit, name=r.name) if fast and len(r) > limit else r for r in recs]


def fast_note(fast: bool, limit: int) -> str:
    """The phrase a note adds in fast mode, e.g. `` (fast mode: first 6000 samples each)``."""
    return f" (fast mode: first {limit} samples each)" if fast else ""


def oxiod_root(data_dir: str | os.PathLike[str] | None = None) -> Path | None:
    """Return ``<data dir>/oxiod`` if that folder exists, else None."""
    base = existing_dir(data_dir)
    root = base / "oxiod" if base is not None else None
    return root if root is not None and root.is_dir() else None


def ucs_file(data_dir: str | os.PathLike[str] | None = None) -> Path | None:
    """Return ``<data dir>/ucs/full_dataset/imu_adis.txt`` if it exists, else None."""
    base = existing_dir(data_dir)
    path = base / "ucs" / UCS_RELPATH if base is not None else None
    return path if path is not None and path.is_file() else None


def broad_root(data_dir: str | os.PathLike[str] | None = None) -> Path | None:
    """Return ``<data dir>/broad`` if that folder exists, else None."""
    base = existing_dir(data_dir)
    root = base / "broad" if base is not None else None
    return root if root is not None and root.is_dir() else None


def _where(base: Path | None) -> str:
    return "(no data directory given)" if base is None else f"under {base}"


def _real_oxiod(root: Path, fast: bool) -> Experiment:
    syn = root.joinpath(*OXIOD_FOLDER, "syn")
    needed = [syn / f"{p}{k}.csv" for k in OXIOD_TEST + OXIOD_TRAIN for p in ("imu", "vi")]
    missing = [str(p) for p in needed if not p.is_file()]
    if missing:
        raise DataError(f"{root} exists but lacks {', '.join(missing)}; expected the original OxIOD layout "
                        "<oxiod>/handheld/data1/syn/imuK.csv + viK.csv")

    train, test = (load_oxiod_files([syn / f"imu{k}.csv" for k in ks], fast) for ks in (OXIOD_TRAIN, OXIOD_TEST))
    cut = fast_note(fast, FAST_SAMPLES)
    note = (f"Real OxIOD from {root}: train {', '.join(f'imu{k}' for k in OXIOD_TRAIN)}; test "
            f"{', '.join(f'imu{k}' for k in OXIOD_TEST)} of {'/'.join(OXIOD_FOLDER)}{cut}; the paper's "
            "slow-walking set is not available, so handheld/data1 stands in for it.")
    return Experiment("oxiod", "real", train, test, note)


def _real_ucs(path: Path) -> Experiment:
    rec = ucs.load_recording(path)
    train, test = ucs.split_train_test(rec, TRAIN_FRACTION)
    note = (f"Real UCS from {path}: first {TRAIN_FRACTION:.0%} ({len(train)} samples) train, "
            f"last {1 - TRAIN_FRACTION:.0%} ({len(test)} samples) test.")
    return Experiment("ucs", "real", [train], [test], note)


def _real_broad(root: Path, fast: bool) -> Experiment:
    recs = broad.load_trials(root)  # DataError when the folder holds no trials
    keep = FAST_BROAD_TRIALS if fast else None
    train = fast_cut([r for r in recs if BROAD_TRAIN_GROUP in r.meta["groups"]][:keep], fast, FAST_BROAD_SAMPLES)
    test = fast_cut([r for r in recs if BROAD_TEST_GROUP in r.meta["groups"]][:keep], fast, FAST_BROAD_SAMPLES)
    if not train or not test:
        raise DataError(f"{root}: found {len(train)} trial(s) of the group {BROAD_TRAIN_GROUP!r} and {len(test)} of "
                        f"{BROAD_TEST_GROUP!r} (from trials.json); both are needed for the default split")
    cut = (f" (fast mode: the first {FAST_BROAD_TRIALS} trials of each group, first {FAST_BROAD_SAMPLES} samples "
           "each)") if fast else ""
    note = (f"Real BROAD from {root}: train the {len(train)} {BROAD_TRAIN_GROUP} trials, test the {len(test)} "
            f"{BROAD_TEST_GROUP} trials{cut}. BROAD: Laidig, Caruso, Cereatti, Seel, Data 6(7), 2021 (CC BY 4.0).")
    return Experiment("broad", "real", train, test, note, aligned=True)


def load_oxiod_files(paths: list[Path], fast: bool) -> list[Recording]:
    """OxIOD recordings ``imuK.csv`` (with ``viK.csv`` beside each), cut in fast mode."""
    return fast_cut([oxiod.load_recording(p) for p in paths], fast, FAST_SAMPLES)


def load_broad_files(paths: list[Path], fast: bool) -> list[Recording]:
    """BROAD trials ``NN_<name>.mat``, cut in fast mode."""
    return fast_cut([broad.load_trial(p) for p in paths], fast, FAST_BROAD_SAMPLES)


def load_experiment(name: str = "oxiod", data_dir: str | os.PathLike[str] | None = None, *,
                    fast: bool = False, seed: int = 0, verbose: bool = True) -> Experiment:
    """Load the train/test recordings of ``"oxiod"``, ``"ucs"`` or ``"broad"``, real if found, else simulated.

    Parameters
    ----------
    name : ``"oxiod"``, ``"ucs"`` or ``"broad"``.
    data_dir : data directory holding ``oxiod/``, ``ucs/`` and/or ``broad/``; None: the simulator stands in.
    fast : fast mode (see the module docstring).
    seed : base seed of the simulated stand-in.
    verbose : print the experiment's note.
    """
    if name not in NAMES:
        raise ValueError(f"unknown experiment {name!r}; valid: {', '.join(NAMES)}")
    base = existing_dir(data_dir)
    if name == "oxiod":
        root = oxiod_root(base) if base is not None else None
        exp = _real_oxiod(root, fast) if root is not None else _simulated_oxiod(base, fast, seed)
    elif name == "broad":
        root = broad_root(base) if base is not None else None
        exp = _real_broad(root, fast) if root is not None else _simulated_broad(base, fast, seed)
    else:
        folder = base / "ucs" if base is not None else None
        path = ucs_file(base) if base is not None else None
        if folder is not None and folder.is_dir() and path is None:
            raise DataError(f"{folder} exists but lacks {folder / UCS_RELPATH}; expected the UCS layout "
                            "<ucs>/full_dataset/imu_adis.txt")
        exp = _real_ucs(path) if path is not None else _simulated_ucs(base, fast, seed)
    if verbose:
        print(exp.note)
    return exp


def simulated_experiment(name: str = "oxiod", *, fast: bool = False, seed: int = 0,
                         verbose: bool = True) -> Experiment:
    """The simulator's stand-in for ``"oxiod"`` or ``"broad"`` (handheld scenario) or ``"ucs"``
    (underwater), whatever data directory is set: the same recordings :func:`load_experiment`
    falls back to."""
    if name not in NAMES:
        raise ValueError(f"unknown experiment {name!r}; valid: {', '.join(NAMES)}")
    make = {"oxiod": _simulated_oxiod, "broad": _simulated_broad, "ucs": _simulated_ucs}[name]
    exp = make(None, fast, seed)
    for label in ("OxIOD", "BROAD", "UCS"):
        exp.note = exp.note.replace(f"No real {label} data found {_where(None)}: ", "Simulated: ")
    if verbose:
        print(exp.note)
    return exp


def _simulated_oxiod(base: Path | None, fast: bool, seed: int) -> Experiment:
    from .simulate import simulate

    duration = FAST_DURATION["handheld"] if fast else None
    recs = [simulate("handheld", duration=duration, seed=seed + i, name=f"sim-handheld-{i}") for i in range(4)]
    note = (f"No real OxIOD data found {_where(base)}: the handheld simulator stands in "
            f"(train sim-handheld-1..3, test sim-handheld-0, {recs[0].duration:g} s each).")
    return Experiment("oxiod", "simulated", recs[1:], recs[:1], note)


def _simulated_broad(base: Path | None, fast: bool, seed: int) -> Experiment:
    sim = _simulated_oxiod(base, fast, seed)
    note = sim.note.replace("No real OxIOD data found", "No real BROAD data found")
    return Experiment("broad", "simulated", sim.train, sim.test, note)


def _simulated_ucs(base: Path | None, fast: bool, seed: int) -> Experiment:
    from .simulate import simulate

    duration = FAST_DURATION["underwater"] if fast else None
    rec = simulate("underwater", duration=duration, seed=seed, name="sim-underwater-0")
    train, test = ucs.split_train_test(rec, TRAIN_FRACTION)
    note = (f"No real UCS data found {_where(base)}: the underwater simulator stands in "
            f"({rec.duration:g} s, first {TRAIN_FRACTION:.0%} train, last {1 - TRAIN_FRACTION:.0%} test).")
    return Experiment("ucs", "simulated", [train], [test], note)


@dataclass
class Motions:
    """OxIOD recordings grouped by motion, for cross-validation (:mod:`danae_lite.crossval`)."""

    data: str
    """``"real"`` or ``"simulated"``."""
    recordings: dict[str, list[Recording]]
    """motion -> its recordings (names unique across motions, e.g. ``"trolley/data2/imu2"``)."""
    note: str


def load_motions(data_dir: str | os.PathLike[str] | None = None, *, fast: bool = False, seed: int = 0,
                 verbose: bool = True) -> Motions:
    """The OxIOD motions of :data:`OXIOD_MOTIONS` found under ``<data dir>/oxiod`` (fast mode: the
    first :data:`FAST_MOTION_RECORDINGS` of each motion, cut to their first :data:`FAST_SAMPLES`
    samples), or simulated stand-ins when there is no
    ``oxiod/`` folder: the handheld simulator with other seeds for each motion (seeds
    ``seed + 10 m + i``), so that the protocol runs, though the simulator has one motion only.

    A motion folder that exists but lacks one of its files raises
    :class:`~danae_lite.recording.DataError` naming the file.
    """
    base = existing_dir(data_dir)
    root = oxiod_root(base) if base is not None else None
    out: dict[str, list[Recording]] = {}
    keep = FAST_MOTION_RECORDINGS if fast else None
    if root is None:
        from .simulate import simulate

        duration = FAST_DURATION["handheld"] if fast else None
        for m, (motion, (_, _, ks)) in enumerate(OXIOD_MOTIONS.items()):
            out[motion] = [simulate("handheld", duration=duration, seed=seed + 10 * m + i,
                                    name=f"sim-{motion.replace(' ', '-')}-{i}")
                           for i in range(len(ks[:keep]))]
        note = (f"No real OxIOD data found {_where(base)}: the handheld simulator stands in for every motion "
                "(other seeds per motion; the simulator has a single motion).")
        result = Motions("simulated", out, note)
    else:
        for motion, (setting, folder, ks) in OXIOD_MOTIONS.items():
            syn = root / setting / folder / "syn"
            if not (root / setting).is_dir():
                if motion == "handheld":
                    raise DataError(f"{root} lacks {root / setting}; the handheld recordings are needed")
                continue
            ks = ks[:keep]
            needed = [syn / f"{p}{k}.csv" for k in ks for p in ("imu", "vi")]
            missing = [str(x) for x in needed if not x.is_file()]
            if missing:
                raise DataError(f"{root / setting} exists but lacks {', '.join(missing)}; expected the original "
                                f"OxIOD layout <oxiod>/{setting}/{folder}/syn/imuK.csv + viK.csv")
            out[motion] = load_oxiod_files([syn / f"imu{k}.csv" for k in ks], fast)
        cut = (f" (fast mode: at most {FAST_MOTION_RECORDINGS} recordings per motion, first {FAST_SAMPLES} "
               "samples each)") if fast else ""
        note = ("Real OxIOD from " + str(root) + ": " + "; ".join(f"{m} {len(v)} recordings" for m, v in out.items())
                + cut + ".")
        result = Motions("real", out, note)
    if verbose:
        print(result.note)
    return result
