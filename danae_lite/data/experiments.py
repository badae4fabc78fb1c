"""Find the real datasets in the data directory, or let the simulator stand in.

The data directory (an argument; the entry points take it from ``--data-dir`` or ``DANAE_DATA``,
see :mod:`danae_lite.runtime`) holds the datasets in their original layout:

* ``oxiod/handheld/data1/syn/imuK.csv`` + ``viK.csv`` for K = 2, 3, 4, 7: train on imu3, imu4,
  imu7, test on imu2. (The paper used OxIOD's slow-walking set, which is not available here;
  handheld/data1 is the closest set at hand.)
* ``ucs/full_dataset/imu_adis.txt``: first 80 % train, last 20 % test, as the paper.

A missing ``oxiod/`` (or ``ucs/``) folder means "no real data": the simulator
stands in (:func:`danae_lite.data.simulate.simulate`), with the same split shape: four
``"handheld"`` recordings (seeds ``seed + 0..3``, test = the first) or one
``"underwater"`` recording split 80/20. A folder that exists but lacks the expected files raises DataError: whoever put it
there meant real data.

Fast mode (the ``fast`` argument) runs every step on little data, so that a chapter runs in
a minute or two (``make test``) with the same code path as in full mode: it keeps the first
:data:`FAST_SAMPLES` samples of each real OxIOD recording, keeps the real UCS recording whole
(it is only ~20k samples at 10 Hz) and simulates :data:`FAST_DURATION` seconds per recording
instead of the scenario default (180 s handheld, 1950 s underwater). (The research chapters'
datasets, the OxIOD motions and BROAD, are found by :mod:`danae_lite.data.oxiod_motions` and
:mod:`danae_lite.data.broad`, with the same helpers.)
"""
from __future__ import annotations

import os
import textwrap
from dataclasses import dataclass
from pathlib import Path

from . import oxiod, ucs
from .recording import DataError, Recording

OXIOD_FOLDER = ("handheld", "data1")
"""Setting and folder of the OxIOD recordings used."""
OXIOD_TRAIN = (3, 4, 7)
"""OxIOD recordings (K of imuK) used for training."""
OXIOD_TEST = (2,)
"""OxIOD recordings used for testing."""
UCS_RELPATH = Path("full_dataset") / "imu_adis.txt"
"""Location of the ADIS file inside ``<data dir>/ucs``."""
TRAIN_FRACTION = 0.8
"""Share of the UCS recording used for training (the first part)."""
FAST_SAMPLES = 1500
"""Samples kept per real OxIOD recording in fast mode (15 s at 100 Hz)."""
FAST_DURATION = {"handheld": 20.0, "underwater": 300.0}
"""Simulated duration per recording in fast mode [s]."""
NAMES = {"oxiod": "OxIOD", "ucs": "UCS"}
"""The experiments of this module, and how a note names their dataset."""


@dataclass
class Experiment:
    """The recordings of one experiment and where they came from.

    ``name`` is ``"oxiod"``, ``"ucs"`` (here) or ``"broad"`` (:mod:`danae_lite.data.broad`); ``data`` is ``"real"`` or ``"simulated"``;
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

    @property
    def source(self) -> str:
        """The data in a few words, as a caption or a sentence names it (:func:`source_of`)."""
        return source_of(self.name, self.data)


def source_of(name: str, data: str) -> str:
    """How a caption or a sentence names the data of experiment ``name`` (``"oxiod"``, ``"ucs"``,
    ``"broad"``) read as ``data`` (``"real"`` or ``"simulated"``): ``"real OxIOD data"`` or
    ``"the simulator standing in for OxIOD"``."""
    dataset = {**NAMES, "broad": "BROAD"}.get(name, name)
    return f"real {dataset} data" if data == "real" else f"the simulator standing in for {dataset}"


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
    return base / "oxiod" if base is not None and (base / "oxiod").is_dir() else None


DATA_DIR_NAME = "<data dir>"
"""How notes name the data directory ($DANAE_DATA, or the command line's --data-dir): never by
the path it has on the machine that ran them."""


def where(base: Path | None) -> str:
    """How a note names the data directory: ``under <data dir>``, or that none was given."""
    return "(no data directory given)" if base is None else f"under {DATA_DIR_NAME}"


def print_note(note: str) -> None:
    """Print an experiment's note for people, wrapped at 88 characters (a code block's width)."""
    print(textwrap.fill(note, width=88))


def in_data_dir(path: Path, *parts: str) -> str:
    """``path``, a folder of the data directory, as a note writes it: ``<data dir>/<name>``
    followed by ``parts``."""
    return "/".join([DATA_DIR_NAME, path.name, *parts])


def _real_oxiod(root: Path, fast: bool) -> Experiment:
    syn = root.joinpath(*OXIOD_FOLDER, "syn")
    needed = [syn / f"{p}{k}.csv" for k in OXIOD_TEST + OXIOD_TRAIN for p in ("imu", "vi")]
    missing = [str(p) for p in needed if not p.is_file()]
    if missing:
        raise DataError(f"{root} exists but lacks {', '.join(missing)}; expected the original OxIOD layout "
                        "<oxiod>/handheld/data1/syn/imuK.csv + viK.csv")

    train, test = (load_oxiod_files([syn / f"imu{k}.csv" for k in ks], fast) for ks in (OXIOD_TRAIN, OXIOD_TEST))
    cut = fast_note(fast, FAST_SAMPLES)
    note = (f"Real OxIOD from {in_data_dir(root)}: train {', '.join(f'imu{k}' for k in OXIOD_TRAIN)}; test "
            f"{', '.join(f'imu{k}' for k in OXIOD_TEST)} of {'/'.join(OXIOD_FOLDER)}{cut}; the paper's "
            "slow-walking set is not available, so handheld/data1 stands in for it.")
    return Experiment("oxiod", "real", train, test, note)


def _real_ucs(folder: Path) -> Experiment:
    path = folder / UCS_RELPATH
    if not path.is_file():
        raise DataError(f"{folder} exists but lacks {path}; expected the UCS layout "
                        "<ucs>/full_dataset/imu_adis.txt")
    train, test = ucs.split_train_test(ucs.load_recording(path), TRAIN_FRACTION)
    note = (f"Real UCS from {in_data_dir(folder, *UCS_RELPATH.parts)}: first {TRAIN_FRACTION:.0%} ({len(train)} samples) train, "
            f"last {1 - TRAIN_FRACTION:.0%} ({len(test)} samples) test.")
    return Experiment("ucs", "real", [train], [test], note)


def load_oxiod_files(paths: list[Path], fast: bool) -> list[Recording]:
    """OxIOD recordings ``imuK.csv`` (with ``viK.csv`` beside each), cut in fast mode."""
    return fast_cut([oxiod.load_recording(p) for p in paths], fast, FAST_SAMPLES)


def _check_name(name: str) -> None:
    if name not in NAMES:
        raise ValueError(f"unknown experiment {name!r}; valid: {', '.join(NAMES)}")


def load_experiment(name: str = "oxiod", data_dir: str | os.PathLike[str] | None = None, *,
                    fast: bool = False, seed: int = 0, verbose: bool = True) -> Experiment:
    """Load the train/test recordings of ``"oxiod"`` or ``"ucs"``, real if found, else simulated
    (the BROAD benchmark's: :func:`danae_lite.data.broad.load_experiment`).

    Parameters
    ----------
    name : ``"oxiod"`` or ``"ucs"``.
    data_dir : data directory holding ``oxiod/`` and/or ``ucs/``; None: the simulator stands in.
    fast : fast mode (see the module docstring).
    seed : base seed of the simulated stand-in.
    verbose : print the experiment's note.
    """
    _check_name(name)
    base = existing_dir(data_dir)
    folder = base / name if base is not None else None
    if folder is None or not folder.is_dir():
        exp = _simulated(name, f"No real {NAMES[name]} data found {where(base)}: ", fast, seed)
    else:
        exp = _real_oxiod(folder, fast) if name == "oxiod" else _real_ucs(folder)
    if verbose:
        print_note(exp.note)
    return exp


def simulated_experiment(name: str = "oxiod", *, fast: bool = False, seed: int = 0, tests: int = 1,
                         verbose: bool = True) -> Experiment:
    """The simulator's stand-in for ``"oxiod"`` (handheld scenario) or ``"ucs"``
    (underwater), whatever data directory is set: the same recordings :func:`load_experiment`
    falls back to, with ``tests`` independently simulated test recordings instead of one (the
    training recordings, and so every network trained on them, stay the same): handheld, the
    seeds ``seed + 0`` and ``seed + 4 ..``; underwater, the last 20 % of the recordings of seeds
    ``seed + 0 .. seed + tests - 1``."""
    _check_name(name)
    if tests < 1:
        raise ValueError(f"tests must be at least 1, got {tests}")
    exp = _simulated(name, "Simulated: ", fast, seed, tests)
    if verbose:
        print_note(exp.note)
    return exp


def _simulated(name: str, lead: str, fast: bool, seed: int, tests: int = 1) -> Experiment:
    """The simulated stand-in for ``name``, its note starting with ``lead``: four handheld
    recordings (seeds ``seed + 0..3``, test = the first) or one underwater recording split 80/20;
    ``tests`` > 1 adds independent test recordings (:func:`simulated_experiment`)."""
    from .simulate import simulate

    duration = FAST_DURATION["handheld" if name == "oxiod" else "underwater"] if fast else None
    if name == "oxiod":
        recs = [simulate("handheld", duration=duration, seed=seed + i, name=f"sim-handheld-{i}") for i in range(3 + tests)]
        note = (f"{lead}the handheld simulator stands in (train sim-handheld-1..3, test sim-handheld-0"
                f"{f' and 4..{2 + tests}' if tests > 1 else ''}, {recs[0].duration:g} s each).")
        return Experiment("oxiod", "simulated", recs[1:4], [recs[0], *recs[4:]], note)
    parts = [ucs.split_train_test(simulate("underwater", duration=duration, seed=seed + i, name=f"sim-underwater-{i}"),
                                  TRAIN_FRACTION) for i in range(tests)]
    more = "" if tests == 1 else f"; the last {1 - TRAIN_FRACTION:.0%} of {tests - 1} more such recordings test too"
    note = (f"{lead}the underwater simulator stands in ({parts[0][0].duration + parts[0][1].duration:g} s, "
            f"first {TRAIN_FRACTION:.0%} train, last {1 - TRAIN_FRACTION:.0%} test{more}).")
    return Experiment("ucs", "simulated", [parts[0][0]], [test for _, test in parts], note)
