"""Ground-truth quality: a per-sample mask of the clean samples of an orientation ground truth.

The Vicon ground truth of OxIOD has glitches that the IMU does not show: single-sample
spikes, short excursions that come back, isolated jumps, and frozen stretches (the same
quaternion repeated). :func:`detect_glitches` finds them and returns a :class:`GlitchReport`
whose ``clean`` mask keeps every other sample; the data is never changed.

Rule. Quaternions are (N, 4), scalar-last (x, y, z, w), body -> world; q and -q are the same
rotation, so every angle below is sign-free. ``d[i]`` [rad] is the rotation angle from
sample i to i+1, ``dt = 1 / fs`` [s], ``thr = max_rate * dt`` and ``quiet = quiet_fraction * thr``.

* Big step i -> i+1: ``d[i] - w[i] * dt > thr``, where ``w[i]`` is the mean gyro norm of
  samples i and i+1 [rad/s] (0 without gyro). ``max_rate`` = 20 rad/s (0.2 rad at 100 Hz) is
  far faster than a hand turns; only the gyro's norm is used because its frame may differ
  from the ground-truth body frame (in OxIOD the phone frame is turned ~180° about z), and by
  the triangle inequality the rotation the gyro cannot explain is about at least ``d - w * dt``.
* Frozen run: at least ``min_frozen`` consecutive identical quaternions (up to sign). The
  samples after the first are stale and bad; the sample where it resumes is bad too when the
  resume step is big (that step is then not used as the start of an excursion or a jump).
* Excursion: a big step out at i and the first later big step j with ``j - i <= max_excursion_s
  * fs`` after which the orientation is back, ``angle(q[i], q[j+1]) <= quiet + path``, where
  ``path`` [rad] is the gyro's rotation over samples i..j+1 (a bound on the true motion
  meanwhile; 0 without gyro). Samples i+1..j are bad; a spike is the case j = i + 1. The big
  steps inside are used up. A false pairing only marks bad the samples between two glitches.
* Isolated jump: a big step i that starts no excursion. ``margin`` [s] (``m = ceil(margin *
  fs)`` samples, at least 1) on each side is bad: samples i-m+1..i+m. Which side is offset
  cannot be told, so the mask only cuts the record there.

Measured on OxIOD handheld/data1 (imu2, 3, 4, 7) to choose these. The gyro never exceeds
4.2 rad/s (0.042 rad per sample), so every step above 0.2 rad is a ground-truth glitch and the
gyro term only drops two borderline steps (0.206 rad, gyro 0.009-0.011 rad). Its part in the
return test matters: 9 of the 14 excursions (4-33 samples) come back only to within
0.05-0.33 rad of the start, close to the gyro's rotation over them (0.05-0.35 rad); without
the gyro there would be 31 isolated jumps instead of 9. Steps above 0.05 rad (0.3-0.4 % of
all steps) make up 17-44 % of the steps 1-7 samples from an isolated jump and thin out by 10
samples, hence ``margin`` = 0.1 s (10 samples at 100 Hz).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..angles import quat_angle

if TYPE_CHECKING:
    import pandas as pd

    from .recording import Recording

Index = NDArray[np.int64]


@dataclass(frozen=True)
class GlitchReport:
    """Clean mask and glitches of one ground truth (see the module docstring for the rule).

    Attributes
    ----------
    clean : (N,) bool, True where the ground-truth sample is clean.
    threshold_rad : big-step threshold ``max_rate / fs`` [rad].
    max_step_rad : largest step angle between consecutive samples [rad].
    steps : index i of every big step i -> i+1.
    spikes : sample index of every single-sample spike.
    excursions : (K, 2) bad [start, stop) sample ranges of excursions of 2 or more samples.
    jumps : index i of every isolated jump i -> i+1.
    frozen : (K, 2) frozen runs as (first sample, length).
    """

    clean: NDArray[np.bool_]
    threshold_rad: float
    max_step_rad: float
    steps: Index
    spikes: Index
    excursions: Index
    jumps: Index
    frozen: Index

    @property
    def n_bad(self) -> int:
        """Number of samples that are not clean."""
        return int(self.clean.size - np.count_nonzero(self.clean))

    def summary(self) -> dict[str, int | float]:
        """Counts as plain numbers; ``frozen_samples`` counts the stale samples (run length - 1),
        ``fraction_bad`` is bad samples / samples, in [0, 1]."""
        return {
            "samples": int(self.clean.size),
            "big_steps": int(self.steps.size),
            "spikes": int(self.spikes.size),
            "excursions": int(len(self.excursions)),
            "excursion_samples": int(np.sum(np.diff(self.excursions, axis=1))),
            "jumps": int(self.jumps.size),
            "frozen_runs": int(len(self.frozen)),
            "frozen_samples": int(np.sum(self.frozen[:, 1] - 1)),
            "bad_samples": self.n_bad,
            "fraction_bad": self.n_bad / self.clean.size,
            "max_step_rad": float(self.max_step_rad),
        }


def _checked(quat: ArrayLike, fs: float, gyro: ArrayLike | None) -> tuple[np.ndarray, np.ndarray | None]:
    q = np.asarray(quat, dtype=float)
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] < 1:
        raise ValueError(f"quat must have shape (N, 4) with N >= 1 (x, y, z, w), got {q.shape}")
    if not np.isfinite(q).all():
        raise ValueError(f"quat row {int(np.argwhere(~np.isfinite(q))[0, 0])} is not finite")
    norms = np.linalg.norm(q, axis=1)
    if (norms < 1e-9).any():
        raise ValueError(f"quat row {int(np.argmax(norms < 1e-9))} is zero, expected a non-zero quaternion")
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"sample rate fs must be a positive number of Hz, got {fs!r}")
    if gyro is None:
        return q, None
    g = np.asarray(gyro, dtype=float)
    if g.shape != (q.shape[0], 3) or not np.isfinite(g).all():
        raise ValueError(f"gyro must be a finite ({q.shape[0]}, 3) array [rad/s] like quat, got shape {g.shape}")
    return q, g


def _frozen_runs(q: NDArray[np.float64], big: NDArray[np.bool_], bad: NDArray[np.bool_],
                 min_frozen: int) -> tuple[NDArray[np.int64], set[int]]:
    """The frozen runs, ``(start, length)`` rows of at least ``min_frozen`` identical (or
    opposite) consecutive quaternions, marked in ``bad`` (all but the first sample, and the sample
    after a run that resumes with a ``big`` step); also the steps at which such a run resumes."""
    n = q.shape[0]
    same = np.all(q[1:] == q[:-1], axis=1) | np.all(q[1:] == -q[:-1], axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], same.astype(np.int8), [0]])))
    starts, lengths = edges[::2], edges[1::2] - edges[::2] + 1
    keep = lengths >= min_frozen
    frozen = np.column_stack([starts[keep], lengths[keep]]).astype(np.int64).reshape(-1, 2)
    resumes = set()
    for s, length in frozen:
        bad[s + 1:s + length] = True
        last = s + length - 1
        if last < n - 1 and big[last]:
            bad[last + 1] = True
            resumes.add(int(last))
    return frozen, resumes


def detect_glitches(quat: ArrayLike, fs: float, *, gyro: ArrayLike | None = None, max_rate: float = 20.0,
                    max_excursion_s: float = 1.0, margin: float = 0.1, min_frozen: int = 5,
                    quiet_fraction: float = 0.25) -> GlitchReport:
    """Find the ground-truth glitches and the clean samples (rule: module docstring).

    Parameters
    ----------
    quat : (N, 4) ground-truth quaternions, scalar-last (x, y, z, w), body -> world; any norm.
    fs : sample rate [Hz].
    gyro : optional (N, 3) angular rate [rad/s] in a body frame (only its norm is used).
    max_rate : fastest plausible rotation rate not explained by the gyro [rad/s].
    max_excursion_s : longest excursion that can still come back [s].
    margin : bad time on each side of an isolated jump [s].
    min_frozen : fewest identical consecutive quaternions that make a frozen run.
    quiet_fraction : return tolerance of an excursion, as a fraction of ``max_rate / fs``.

    Raises
    ------
    ValueError
        Wrong shapes, a non-finite or zero quaternion, fs <= 0, or an out-of-range option.
    """
    q, g = _checked(quat, fs, gyro)
    if not (max_rate > 0 and max_excursion_s >= 0 and margin >= 0 and 0 <= quiet_fraction < 1
            and int(min_frozen) == min_frozen and min_frozen >= 2):
        raise ValueError("need max_rate > 0, max_excursion_s >= 0, margin >= 0, 0 <= quiet_fraction < 1 "
                         f"and an integer min_frozen >= 2; got {max_rate!r}, {max_excursion_s!r}, {margin!r}, "
                         f"{quiet_fraction!r}, {min_frozen!r}")
    n, thr = q.shape[0], max_rate / fs
    u = q / np.linalg.norm(q, axis=1, keepdims=True)
    d = quat_angle(u[:-1], u[1:])
    w = np.zeros(n) if g is None else np.linalg.norm(g, axis=1)
    seen = 0.5 * (w[:-1] + w[1:]) / fs           # gyro rotation over each step [rad]
    path = np.concatenate([[0.0], np.cumsum(seen)])
    big = d - seen > thr
    bad = np.zeros(n, dtype=bool)

    frozen, resumes = _frozen_runs(q, big, bad, int(min_frozen))
    events = np.flatnonzero(big)
    reach, quiet = int(math.floor(max_excursion_s * fs + 1e-9)), quiet_fraction * thr
    m = max(1, math.ceil(margin * fs - 1e-9))     # jump margin [samples]
    spikes, excursions, jumps = [], [], []
    a = 0
    while a < events.size:
        i = int(events[a])
        a += 1
        if i in resumes:
            continue
        later = events[a:np.searchsorted(events, i + reach, side="right")]
        back = quat_angle(u[i], u[later + 1]) <= quiet + path[later + 1] - path[i]
        if back.any():
            j = int(later[np.argmax(back)])
            bad[i + 1:j + 1] = True
            if j == i + 1:
                spikes.append(i + 1)
            else:
                excursions.append((i + 1, j + 1))
            a += int(np.argmax(back)) + 1
        else:
            jumps.append(i)
            bad[max(0, i - m + 1):i + m + 1] = True
    return GlitchReport(
        clean=~bad, threshold_rad=float(thr), max_step_rad=float(d.max()) if d.size else 0.0,
        steps=events.astype(np.int64), spikes=np.array(spikes, dtype=np.int64),
        excursions=np.array(excursions, dtype=np.int64).reshape(-1, 2), jumps=np.array(jumps, dtype=np.int64),
        frozen=frozen)


def clean_mask(recording: Recording) -> NDArray[np.bool_]:
    """(N,) bool mask of the clean ground-truth samples of ``recording`` (its quat, fs and gyro)."""
    return detect_glitches(recording.quat, recording.fs, gyro=recording.gyro).clean


def glitch_table(recordings: Iterable[Recording]) -> pd.DataFrame:
    """One row per recording: name, samples, spikes, excursions, jumps, frozen samples, bad samples, bad %.

    Uses each recording's quat, fs and gyro with the default thresholds; ``frozen samples``
    counts the stale samples of frozen runs, ``bad %`` is 100 * bad samples / samples.
    """
    import pandas as pd

    rows = []
    for rec in recordings:
        s = detect_glitches(rec.quat, rec.fs, gyro=rec.gyro).summary()
        rows.append({"name": rec.name, "samples": s["samples"], "spikes": s["spikes"],
                     "excursions": s["excursions"], "jumps": s["jumps"], "frozen samples": s["frozen_samples"],
                     "bad samples": s["bad_samples"], "bad %": round(100.0 * s["fraction_bad"], 3)})
    return pd.DataFrame(rows, columns=["name", "samples", "spikes", "excursions", "jumps", "frozen samples",
                                       "bad samples", "bad %"])
