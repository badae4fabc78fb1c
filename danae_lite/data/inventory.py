"""What a data folder holds, file by file, against the book's reference copies.

The book's stored outputs were computed on one copy of each dataset; the registry
``reference_copies.json`` beside this module lists every file of that copy with its SHA-256,
size [bytes], rows and columns (written by ``python -m tools.data_registry`` from the book's
own copy; checksums and shapes, not data). :func:`check` compares a data folder with it:

* a file whose SHA-256 matches is the book's file: ``ok``;
* a file that differs is read with the book's own loader: one that fails to load is
  ``malformed`` (the loader's message names the file, line and column); one that loads is
  ``differs`` (its rows and columns against the book's): the chapters run, but their numbers
  will not be the book's;
* an absent file is ``missing``.

A dataset is *required* when the chapters' numbers need it (OxIOD handheld); the others are
optional: absent as a whole, the chapters leave them out or let the simulator stand in. A
dataset that is present in part (a file missing) is an error, as it is for the chapters.
UCS has no reference copy here: its file is checked by its loader's format rules only.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

REGISTRY_NAME = "reference_copies.json"
"""The registry's file name, beside this module."""

OXIOD_PAGE = "http://deepio.cs.ox.ac.uk/"
UCS_PAGE = "https://cirs.udg.edu/caves-dataset/"
BROAD_PAGE = "https://github.com/dlaidig/broad"


@dataclass(frozen=True)
class Dataset:
    """One dataset the book reads: its folder inside the data directory and how it is used."""

    name: str
    folder: str
    """Relative to the data directory (``/``-separated)."""
    required: bool
    """Whether the book's numbers need it (a missing required dataset is an error)."""
    when_absent: str
    """What the chapters do without it."""
    source: str
    """Where to get it."""
    reference_copy: bool = True
    """Whether the registry holds the book's copy of its files (UCS: no; its format is checked)."""


DATASETS: tuple[Dataset, ...] = (
    Dataset("oxiod handheld", "oxiod/handheld/data1/syn", True,
            "the chapters run on the simulator instead, and their numbers are not the book's", OXIOD_PAGE),
    Dataset("oxiod trolley", "oxiod/trolley/data2/syn", False,
            "the cross-validation leaves the trolley motion out", OXIOD_PAGE),
    Dataset("oxiod multi users", "oxiod/multi users/user2/syn", False,
            "the cross-validation leaves the multi-users motion out", OXIOD_PAGE),
    Dataset("ucs", "ucs/full_dataset", False,
            "the simulator's underwater scenario stands in (as in the book)", UCS_PAGE, reference_copy=False),
    Dataset("broad", "broad/data_mat", False,
            "the simulator stands in for the BROAD trials", BROAD_PAGE),
)
"""The datasets, in report order."""

EXPERIMENTS: dict[str, tuple[str, ...]] = {
    "oxiod": ("oxiod handheld", "oxiod trolley", "oxiod multi users"),
    "ucs": ("ucs",),
    "broad": ("broad",),
}
"""Experiment name (as ``--experiment`` takes it) -> its datasets."""


@dataclass(frozen=True)
class ReferenceFile:
    """One file of the book's reference copy."""

    dataset: str
    path: str
    """Relative to the data directory (``/``-separated)."""
    sha256: str
    bytes: int
    rows: int
    columns: Any
    """Comma-separated fields per row (CSV), or variable name -> width (``.mat``; rows are
    the samples of ``imu_gyr``), or None (JSON)."""


@dataclass(frozen=True)
class FileReport:
    """The state of one file: ``ok``, ``missing``, ``malformed`` or ``differs``."""

    path: Path
    status: str
    detail: str = ""


@dataclass(frozen=True)
class DatasetReport:
    dataset: Dataset
    files: tuple[FileReport, ...]

    @property
    def absent(self) -> bool:
        """No file of the dataset is there."""
        return all(f.status == "missing" for f in self.files)

    @property
    def failed(self) -> bool:
        """Whether this dataset makes ``data check`` fail: a required one missing, or any file
        malformed, different from the book's, or missing from a dataset present in part."""
        if self.absent:
            return self.dataset.required
        return any(f.status != "ok" for f in self.files)


def registry(path: Path | None = None) -> list[ReferenceFile]:
    """The book's reference files (default: the registry beside this module)."""
    text = (path.read_text(encoding="utf-8") if path is not None
            else resources.files(__package__).joinpath(REGISTRY_NAME).read_text(encoding="utf-8"))
    return [ReferenceFile(**entry) for entry in json.loads(text)["files"]]


def sha256(path: Path) -> str:
    """The hex SHA-256 of the file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def shape_of(path: Path) -> tuple[int, Any]:
    """``(rows, columns)`` of a data file as the registry records them (see :class:`ReferenceFile`).
    Raises DataError (from :mod:`~danae_lite.data.broad`) for an unreadable ``.mat`` file."""
    if path.suffix == ".mat":
        from .broad import read_mat

        data = read_mat(path)
        n = int(data["imu_gyr"].shape[0])
        return n, {k: int(v.shape[1]) for k, v in sorted(data.items())
                   if not k.startswith("__") and getattr(v, "ndim", 0) == 2 and v.shape[0] == n}
    if path.suffix == ".json":
        return 0, None
    lines = path.read_bytes().splitlines()
    return len(lines), (lines[0].count(b",") + 1 if lines else 0)


def load_problem(path: Path) -> str | None:
    """What the book's loader says of ``path`` (None: it loads)."""
    from .recording import DataError

    try:
        if path.suffix == ".mat":
            from .broad import load_trial

            load_trial(path)
        elif path.suffix == ".json":
            json.loads(path.read_text(encoding="utf-8"))
        elif path.name.startswith("vi"):
            from .oxiod import load_recording

            load_recording(path.with_name("imu" + path.name[2:]), path)
        elif path.name.startswith("imu") and path.suffix == ".csv":
            from .oxiod import load_recording

            load_recording(path)
        else:
            from .ucs import load_recording as load_ucs

            load_ucs(path)
    except DataError as err:
        return str(err)
    except (ValueError, OSError) as err:
        return f"{path}: {err}"
    return None


def check_file(root: Path, ref: ReferenceFile) -> FileReport:
    """The state of one reference file in the data folder ``root``."""
    path = root / ref.path
    if not path.is_file():
        return FileReport(path, "missing")
    if path.stat().st_size == ref.bytes and sha256(path) == ref.sha256:
        return FileReport(path, "ok")
    problem = load_problem(path)
    if problem is not None:
        return FileReport(path, "malformed", problem)
    rows, columns = shape_of(path)
    shape = f"{rows} rows, columns {columns}" if ref.columns is not None else f"{path.stat().st_size} bytes"
    book = f"{ref.rows} rows, columns {ref.columns}" if ref.columns is not None else f"{ref.bytes} bytes"
    return FileReport(path, "differs", f"SHA-256 differs from the book's copy ({shape}; the book's: {book})")


def check_ucs(root: Path, dataset: Dataset) -> tuple[FileReport, ...]:
    """The UCS file by its loader's format rules (no reference copy here)."""
    path = root / dataset.folder / "imu_adis.txt"
    if not path.is_file():
        return (FileReport(path, "missing"),)
    problem = load_problem(path)
    if problem is not None:
        return (FileReport(path, "malformed", problem),)
    return (FileReport(path, "ok", "format checked by the loader (no reference copy to compare)"),)


def check(root: Path, experiments: tuple[str, ...] = tuple(EXPERIMENTS),
          reference: list[ReferenceFile] | None = None) -> list[DatasetReport]:
    """One report per dataset of ``experiments`` for the data folder ``root``."""
    reference = registry() if reference is None else reference
    wanted = {name for e in experiments for name in EXPERIMENTS[e]}
    out = []
    for ds in DATASETS:
        if ds.name not in wanted:
            continue
        if not ds.reference_copy:
            files = check_ucs(root, ds)
        else:
            files = tuple(check_file(root, ref) for ref in reference if ref.dataset == ds.name)
        out.append(DatasetReport(ds, files))
    return out
