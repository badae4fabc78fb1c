"""The one in-memory recording type used by every part of the book.

A :class:`Recording` holds time-aligned inertial/magnetic samples and the ground-truth
orientation of one run, whatever its source (OxIOD, Underwater Caves, or the simulator).

Units and frames (see also :mod:`danae_lite.angles`):

========  =========  ======================================================================
field     shape      meaning
========  =========  ======================================================================
fs        scalar     sample rate [Hz]; sample ``i`` is at ``time[i] = i / fs`` [s]
gyro      (N, 3)     angular rate about body x, y, z [rad/s]
acc       (N, 3)     accelerometer vector in the body frame [g] in the *tilt convention*:
                     at rest it equals the reference frame's up axis seen from the body,
                     ``R.T @ [0, 0, 1]``, so the paper's roll = atan2(ay, sqrt(ax²+az²)) and
                     pitch = atan2(-ax, sqrt(ay²+az²)) hold. The simulator produces exactly
                     this specific force; for OxIOD it is the authors' ``gravity - user
                     acceleration`` (see :mod:`danae_lite.data.oxiod`), whose x and y follow the
                     convention in the Vicon body frame
mag       (N, 3)     magnetic field in the body frame [µT]
quat      (N, 4)     ground-truth orientation, scalar-last [x, y, z, w], body -> reference
========  =========  ======================================================================

The reference frame has x towards magnetic north (simulator) or the ground-truth
system's x axis (real data) and z up. ``meta`` holds source-specific extras (e.g. OxIOD's
separate gravity and user acceleration) and a ``"conventions"`` note.

The ground-truth Euler angles (roll, pitch, yaw) [rad] are derived from ``quat`` with
scipy's ``Rotation`` in intrinsic ZYX order (:func:`danae_lite.angles.quat_to_euler`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..angles import quat_to_euler


class DataError(ValueError):
    """Bad input data. The message names the file, the row/column and what was expected."""


@dataclass(frozen=True, eq=False)
class Recording:
    """One run of sensor data with its ground truth. See the module docstring for units."""

    name: str
    source: str
    fs: float
    gyro: NDArray[np.float64]
    acc: NDArray[np.float64]
    mag: NDArray[np.float64]
    quat: NDArray[np.float64]
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        where = f"recording {self.name!r} ({self.source})"
        if not (np.isfinite(self.fs) and self.fs > 0):
            raise DataError(f"{where}: sample rate fs must be a positive number of Hz, got {self.fs!r}")
        n = None
        for key, width in (("gyro", 3), ("acc", 3), ("mag", 3), ("quat", 4)):
            arr = np.asarray(getattr(self, key), dtype=float)
            if arr.ndim != 2 or arr.shape[1] != width:
                raise DataError(f"{where}: {key} must have shape (N, {width}), got {arr.shape}")
            n = arr.shape[0] if n is None else n
            if arr.shape[0] != n:
                raise DataError(f"{where}: {key} has {arr.shape[0]} rows but gyro has {n}")
            bad = ~np.isfinite(arr)
            if bad.any():
                r, c = np.argwhere(bad)[0]
                raise DataError(f"{where}: {key}[{r}, {c}] is {arr[r, c]}, expected a finite number")
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)
        zero = np.flatnonzero(np.linalg.norm(self.quat, axis=1) < 1e-9)
        if zero.size:
            raise DataError(f"{where}: quat row {zero[0]} is zero, expected a non-zero quaternion")

    def __len__(self) -> int:
        return int(self.gyro.shape[0])

    @property
    def dt(self) -> float:
        """Sample period [s]."""
        return 1.0 / self.fs

    @property
    def time(self) -> NDArray[np.float64]:
        """Sample times [s], ``i / fs``."""
        return np.arange(len(self)) / self.fs

    @property
    def duration(self) -> float:
        """Length of the recording [s]."""
        return len(self) / self.fs

    @cached_property
    def euler(self) -> NDArray[np.float64]:
        """Ground-truth (roll, pitch, yaw) [rad], shape (N, 3), intrinsic ZYX from ``quat``."""
        e = quat_to_euler(self.quat)
        e.setflags(write=False)
        return e

    def slice(self, start: int | None = None, stop: int | None = None, name: str | None = None) -> "Recording":
        """Return samples ``start:stop`` as a new recording.

        Per-sample arrays in ``meta`` (ndarrays whose first dimension is ``N``) are sliced too;
        other entries are copied unchanged. ``meta["offset"]`` accumulates the start index
        relative to the original recording.
        """
        n = len(self)
        s = slice(start, stop)
        idx = range(n)[s]
        if not idx:
            raise DataError(f"recording {self.name!r}: slice {start}:{stop} is empty (N={n})")
        meta = {k: v[s] if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n else v
                for k, v in self.meta.items()}
        meta["offset"] = int(self.meta.get("offset", 0)) + idx.start
        return replace(self, name=name or f"{self.name}[{idx.start}:{idx.stop}]", gyro=self.gyro[s], acc=self.acc[s],
                       mag=self.mag[s], quat=self.quat[s], meta=meta)

    def __repr__(self) -> str:
        return f"Recording(name={self.name!r}, source={self.source!r}, n={len(self)}, fs={self.fs:g} Hz)"
