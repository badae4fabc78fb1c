"""Helpers shared by the dataset loaders: reading a file and strict numeric CSV parsing.

Parsing is fast (pandas' C parser) and strict: nothing is dropped or padded. When the fast
parse fails or yields a non-finite value, the offending line and column are located and
reported in a :class:`~danae_lite.data.recording.DataError` that names the file, the 1-based line
number, the 1-based column (and its name when known) and what was expected.
"""
from __future__ import annotations

import io
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .recording import DataError


_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:inf|infinity|nan)", re.I)
"""A plain decimal number (or inf/nan, rejected later as non-finite): what pandas' C parser reads.
Python's ``float`` alone would also take ``1_0`` or non-ASCII digits such as ``'١٢'``."""


def read_bytes(path: Path, what: str = "file") -> bytes:
    """Return the raw content of a file; a missing file raises DataError naming it."""
    if not path.is_file():
        raise DataError(f"{path}: {what} not found")
    return path.read_bytes()


def line_spans(raw: bytes) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Start and end byte offsets of every line (a final newline does not start a new line)."""
    buf = np.frombuffer(raw, dtype=np.uint8)
    newlines = np.flatnonzero(buf == 10)
    ends = newlines if raw.endswith(b"\n") or not raw else np.append(newlines, buf.size)
    starts = np.concatenate([[0], newlines + 1])[: ends.size]
    return starts.astype(np.int64), ends.astype(np.int64)


def _line(raw: bytes, starts: NDArray[np.int64], ends: NDArray[np.int64], i: int) -> str:
    return raw[starts[i]:ends[i]].decode("utf-8", errors="replace").rstrip("\r")


def parse_numeric(path: Path, raw: bytes, ncols: int, *, skip: int = 0, usecols: Sequence[int] | None = None,
                  names: Sequence[str] | None = None) -> NDArray[np.float64]:
    """Parse comma-separated rows that must all have ``ncols`` fields into a float array.

    Parameters
    ----------
    path : file the bytes came from (for messages only).
    raw : the file content.
    ncols : number of comma-separated fields every data line must have.
    skip : number of leading lines that are not data (1 for a header row).
    usecols : 0-based columns to convert (default: all); the others are only counted.
    names : optional name of every column, quoted in messages.

    Returns
    -------
    ndarray, shape (number of data lines, len(usecols)), every value finite.

    Raises
    ------
    DataError
        For an empty line, a line with the wrong number of fields, or a cell of a used column
        that is empty, non-numeric, NaN or infinite. The message names the file, the 1-based
        line number and the 1-based column.
    """
    import pandas as pd  # here, not at the top: the command line's --help loads no pandas

    cols = list(range(ncols)) if usecols is None else list(usecols)
    starts, ends = line_spans(raw)
    starts, ends = starts[skip:], ends[skip:]
    commas = np.concatenate([[0], np.cumsum(np.frombuffer(raw, dtype=np.uint8) == 44)])
    counts = commas[ends] - commas[starts] + 1
    bad = np.flatnonzero(counts != ncols)
    if bad.size:
        i = int(bad[0])
        if not _line(raw, starts, ends, i).strip():
            raise DataError(f"{path}: line {skip + i + 1} is empty; expected {ncols} comma-separated numbers")
        raise DataError(f"{path}: line {skip + i + 1} has {counts[i]} comma-separated columns, expected {ncols}")
    n = starts.size
    try:
        frame = pd.read_csv(io.BytesIO(raw), header=None, skiprows=skip, usecols=cols, dtype=np.float64,
                            skip_blank_lines=False, engine="c")
        values = frame[cols].to_numpy(dtype=np.float64)
    except ValueError:  # pandas' ParserError and EmptyDataError are ValueErrors
        values = None
    if values is not None and values.shape == (n, len(cols)) and np.isfinite(values).all():
        return values
    # The fast parse failed or met a non-finite value: convert cell by cell, stopping at the first bad one.
    out = np.empty((n, len(cols)))
    for r in range(n):
        fields = _line(raw, starts, ends, r).split(",")
        for j, c in enumerate(cols):
            cell = fields[c].strip()
            out[r, j] = float(cell) if _DECIMAL.fullmatch(cell) else np.nan
            if not np.isfinite(out[r, j]):
                label = f" ({names[c]})" if names is not None and c < len(names) else ""
                got = repr(cell) if cell else "an empty cell"
                raise DataError(f"{path}: line {skip + r + 1}, column {c + 1}{label}: expected a finite number, "
                                f"got {got}")
    return out
