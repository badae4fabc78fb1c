"""The command line's data flags -> recordings: ``--experiment``, ``--data-dir``, ``--train`` /
``--test`` and ``--split`` resolved to a :class:`~danae_lite.data.experiments.Experiment` (used by
both subcommands; every mistake is a :class:`UsageError` naming the flag and the file)."""
from __future__ import annotations

import argparse
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..runtime import DATA_ENV
from ..data.experiments import FAST_SAMPLES
from ..data import broad as broad_data

if TYPE_CHECKING:
    from ..runtime import RunSettings

__all__ = ["PAPER_SPLIT_FOLDER", "PAPER_SPLIT_TEST", "PAPER_SPLIT_TRAIN", "UsageError", "load_data"]

PAPER_SPLIT_FOLDER = ("slow walking", "data1")
"""Setting and folder of the paper's own OxIOD split (``--split paper``)."""
PAPER_SPLIT_TRAIN = (2, 3, 4, 5, 6, 7, 8)
"""The training recordings (K of imuK) in :data:`PAPER_SPLIT_FOLDER`: the paper names none; the
authors' code trains on imu2-imu8 (its instructions mention imu2-imu7)."""
PAPER_SPLIT_TEST = (1,)
"""The paper's test recording in :data:`PAPER_SPLIT_FOLDER`."""

_IMU_RE = re.compile(r"imu(\d+)\.csv")


class UsageError(Exception):
    """A mistake in the command line; reported as one line, exit status 2."""


def _oxiod_files(items: Sequence[str], flag: str) -> list[Path]:
    """Expand ``--train``/``--test`` items: a file stays, a folder gives its imuK.csv files by K."""
    out: list[Path] = []
    for item in items:
        p = Path(item).expanduser()
        if p.is_dir():
            found = sorted((int(m.group(1)), q) for q in p.iterdir() if (m := _IMU_RE.fullmatch(q.name)))
            if not found:
                raise UsageError(f"{flag} {p}: folder holds no OxIOD recordings (imuK.csv with viK.csv beside it)")
            out.extend(q for _, q in found)
        elif not p.is_file():
            raise UsageError(f"{flag} {p}: no such file")
        else:
            out.append(p)
    return out


def _ucs_path(items: Sequence[str], flag: str) -> list[Path]:
    out = []
    for item in items:
        p = Path(item).expanduser()
        if p.is_dir():
            raise UsageError(f"{flag} {p}: is a folder; give the UCS file itself (full_dataset/imu_adis.txt)")
        if not p.is_file():
            raise UsageError(f"{flag} {p}: no such file")
        out.append(p)
    return out


def _unique_names(train: list[Any], test: list[Any]) -> tuple[list[Any], list[Any]]:
    """Give distinct recordings distinct names (the KF estimates are keyed by name)."""
    seen: dict[str, Any] = {}
    out: list[list[Any]] = [[], []]
    for side, recs in enumerate((train, test)):
        for rec in recs:
            other = seen.get(rec.name)
            if other is not None and other is not rec:
                path = rec.meta.get("imu_path") or rec.meta.get("path")
                rec = rec.slice(None, None, name=f"{rec.name} ({path or len(seen)})")
            seen[rec.name] = rec
            out[side].append(rec)
    return out[0], out[1]


def _paper_split(args: argparse.Namespace, name: str, base: Path | None) -> argparse.Namespace:
    """``--split paper``: the arguments with ``--train``/``--test`` set to the paper's files."""
    from ..data import experiments

    if name != "oxiod":
        raise UsageError(f"--split paper is OxIOD's split; --experiment is {name}")
    if args.train is not None or args.test is not None:
        raise UsageError("--split paper chooses the recordings itself; leave out --train/--test")
    root = experiments.oxiod_root(base) if base is not None else None
    if root is None:
        where = f"{base}/oxiod" if base is not None else f"a data directory (--data-dir or ${DATA_ENV})"
        raise UsageError(f"--split paper needs OxIOD's slow-walking set; no oxiod/ folder in {where}")
    syn = root.joinpath(*PAPER_SPLIT_FOLDER, "syn")
    missing = [str(syn / f"{p}{k}.csv") for k in PAPER_SPLIT_TEST + PAPER_SPLIT_TRAIN for p in ("imu", "vi")
               if not (syn / f"{p}{k}.csv").is_file()]
    if missing:
        raise UsageError(f"--split paper: missing {', '.join(missing)} (OxIOD's slow-walking set, original layout)")
    return argparse.Namespace(**{**vars(args), "train": [str(syn / f"imu{k}.csv") for k in PAPER_SPLIT_TRAIN],
                                 "test": [str(syn / f"imu{k}.csv") for k in PAPER_SPLIT_TEST]})


def load_data(args: argparse.Namespace, settings: RunSettings) -> Any:
    """Resolve the experiment's recordings from the arguments; returns an experiments.Experiment."""
    from ..data import experiments

    name, fast = args.experiment, settings.fast
    base = settings.data_dir  # --data-dir, else $DANAE_DATA (resolved, checked) or None
    if getattr(args, "split", "default") == "paper":
        args = _paper_split(args, name, base)
    if args.data_dir is not None and args.train is None and args.test is None:
        folder = base / name
        if not folder.is_dir():
            expected = {"oxiod": folder / "handheld" / "data1" / "syn" / "imuK.csv", "ucs": folder / experiments.UCS_RELPATH,
                        "broad": folder / "data_mat" / "NN_<name>.mat"}[name]
            raise UsageError(f"--data-dir {base}: no {name}/ folder with recordings (expected {expected}); "
                             "omit --data-dir to let the simulator stand in")
    if args.train is None and args.test is None:
        if name == "broad":
            return broad_data.load_experiment(base, fast=fast, verbose=False)
        return experiments.load_experiment(name, base, fast=fast, verbose=False)
    if name == "broad":
        return _broad_files(args, base, fast)

    if name == "ucs":
        return _ucs_files(args)
    return _oxiod_files_experiment(args, base, fast)


def _ucs_files(args: argparse.Namespace) -> Any:
    """The UCS experiment of ``--train``/``--test`` files: one file split 80/20, or each side whole."""
    from ..data import experiments, ucs

    train_p = _ucs_path(args.train, "--train") if args.train else []
    test_p = _ucs_path(args.test, "--test") if args.test else []
    single = {p.resolve() for p in train_p + test_p}
    if len(single) == 1 and (not train_p or not test_p or len(train_p) == len(test_p) == 1):
        path = train_p[0] if train_p else test_p[0]
        tr, te = ucs.split_train_test(ucs.load_recording(path), experiments.TRAIN_FRACTION)
        note = (f"UCS file {path}: first {experiments.TRAIN_FRACTION:.0%} ({len(tr)} samples) train, "
                f"last {1 - experiments.TRAIN_FRACTION:.0%} ({len(te)} samples) test.")
        return experiments.Experiment("ucs", "real", [tr], [te], note)
    if not train_p or not test_p:
        flag = "--train" if train_p else "--test"
        raise UsageError(f"{flag} names {len(train_p or test_p)} UCS files but the other side is missing; "
                         "give one file (split 80/20) or both --train and --test")
    train = [ucs.load_recording(p, name=f"ucs/{p.parent.name}/{p.stem}") for p in train_p]
    test = [ucs.load_recording(p, name=f"ucs/{p.parent.name}/{p.stem}") for p in test_p]
    train, test = _unique_names(train, test)
    note = f"UCS files: train {', '.join(map(str, train_p))}; test {', '.join(map(str, test_p))} (each used whole)."
    return experiments.Experiment("ucs", "real", train, test, note)


def _oxiod_files_experiment(args: argparse.Namespace, base: Path | None, fast: bool) -> Any:
    """The OxIOD experiment of ``--train``/``--test`` files; a side left out comes from the data
    directory's default recordings."""
    from ..data import experiments

    syn = None
    if args.train is None or args.test is None:
        syn = _default_root(args, base, "oxiod", "recordings").joinpath(*experiments.OXIOD_FOLDER, "syn")
    train_p = (_oxiod_files(args.train, "--train") if args.train is not None
               else [syn / f"imu{k}.csv" for k in experiments.OXIOD_TRAIN])
    test_p = (_oxiod_files(args.test, "--test") if args.test is not None
              else [syn / f"imu{k}.csv" for k in experiments.OXIOD_TEST])
    train, test = _unique_names(experiments.load_oxiod_files(train_p, fast), experiments.load_oxiod_files(test_p, fast))
    cut = experiments.fast_note(fast, FAST_SAMPLES)
    note = (f"OxIOD files: train {', '.join(r.name for r in train)}; test {', '.join(r.name for r in test)}{cut}.")
    overlap = {p.resolve() for p in train_p} & {p.resolve() for p in test_p}
    if overlap:
        note += f" Warning: {', '.join(map(str, sorted(overlap)))} is used for training and testing."
    return experiments.Experiment("oxiod", "real", train, test, note)


def _default_root(args: argparse.Namespace, base: Path | None, name: str, what: str) -> Path:
    """``<data dir>/<name>`` for the side of ``--train``/``--test`` left out; UsageError when absent."""
    from ..data import experiments

    root = {"oxiod": experiments.oxiod_root, "broad": broad_data.root}[name](base) if base is not None else None
    if root is None:
        given, missing = ("--test", "--train") if args.train is None else ("--train", "--test")
        where = f"{base}/{name}" if base is not None else f"a data directory (--data-dir or ${DATA_ENV})"
        raise UsageError(f"{given} given without {missing}, and no default {what} found in {where}")
    return root


def _broad_trial_files(items: Sequence[str], flag: str) -> list[Path]:
    """Expand ``--train``/``--test`` items for BROAD: a .mat file stays, a folder gives its trials."""
    out: list[Path] = []
    for item in items:
        p = Path(item).expanduser()
        if p.is_dir():
            found = broad_data.find_trials(p)  # DataError naming the folder when it holds none
            out.extend(found)
        elif not p.is_file():
            raise UsageError(f"{flag} {p}: no such file")
        elif p.suffix != ".mat":
            raise UsageError(f"{flag} {p}: not a BROAD trial (expected NN_<name>.mat)")
        else:
            out.append(p)
    return out


def _broad_files(args: argparse.Namespace, base: Path | None, fast: bool) -> Any:
    """BROAD trials named by ``--train``/``--test``; a side left out takes the data directory's default."""
    from ..data import experiments

    default = None
    if args.train is None or args.test is None:
        _default_root(args, base, "broad", "trials")
        default = broad_data.load_experiment(base, fast=fast, verbose=False)

    def load(items: Sequence[str] | None, flag: str, fallback: list[Any]) -> tuple[list[Path], list[Any]]:
        if items is None:
            return [], fallback
        paths = _broad_trial_files(items, flag)
        return paths, broad_data.load_files(paths, fast)

    train_p, train = load(args.train, "--train", default.train if default else [])
    test_p, test = load(args.test, "--test", default.test if default else [])
    train, test = _unique_names(train, test)
    cut = experiments.fast_note(fast, broad_data.FAST_SAMPLES)
    note = f"BROAD trials: train {', '.join(r.name for r in train)}; test {', '.join(r.name for r in test)}{cut}."
    overlap = {p.resolve() for p in train_p} & {p.resolve() for p in test_p}
    if overlap:
        note += f" Warning: {', '.join(map(str, sorted(overlap)))} is used for training and testing."
    return experiments.Experiment("broad", "real", train, test, note, aligned=True)

