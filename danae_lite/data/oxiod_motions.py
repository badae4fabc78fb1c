"""The OxIOD recordings grouped by motion (handheld, trolley, multi users), for the research
chapters' cross-validation (:mod:`danae_lite.research.crossval`): found in the data directory
with the helpers of :mod:`danae_lite.data.experiments`, or simulated stand-ins when there is no
``oxiod/`` folder.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from . import experiments
from .recording import DataError, Recording

OXIOD_MOTIONS: dict[str, tuple[str, str, tuple[int, ...]]] = {
    "handheld": ("handheld", "data1", (2, 3, 4, 7)),
    "trolley": ("trolley", "data2", (2, 3, 4, 5)),
    "multi users": ("multi users", "user2", (5, 6)),
}
"""OxIOD motions used for cross-validation: motion -> (setting folder, data folder, K of imuK).
Handheld is required; a motion whose folder is absent is left out."""
FAST_MOTION_RECORDINGS = 3
"""Recordings kept per OxIOD motion in fast mode (:func:`load`): leave-one-out folds
then still train on two recordings, as the methods that hold out training recordings need."""


@dataclass
class Motions:
    """OxIOD recordings grouped by motion, for cross-validation (:mod:`danae_lite.research.crossval`)."""

    data: str
    """``"real"`` or ``"simulated"``."""
    recordings: dict[str, list[Recording]]
    """motion -> its recordings (names unique across motions, e.g. ``"trolley/data2/imu2"``)."""
    note: str

    @property
    def source(self) -> str:
        """The data in a few words, as a caption names it (``"real OxIOD data"``, or the simulator)."""
        return experiments.source_of("oxiod", self.data)


def load(data_dir: str | os.PathLike[str] | None = None, *, fast: bool = False, seed: int = 0,
                 verbose: bool = True) -> Motions:
    """The OxIOD motions of :data:`OXIOD_MOTIONS` found under ``<data dir>/oxiod`` (fast mode: the
    first :data:`FAST_MOTION_RECORDINGS` of each motion, cut to their first :data:`~danae_lite.data.experiments.FAST_SAMPLES`
    samples), or simulated stand-ins when there is no
    ``oxiod/`` folder: the handheld simulator with other seeds for each motion (seeds
    ``seed + 10 m + i``), so that the protocol runs, though the simulator has one motion only.

    A motion folder that exists but lacks one of its files raises
    :class:`~danae_lite.data.recording.DataError` naming the file.
    """
    base = experiments.existing_dir(data_dir)
    root = experiments.oxiod_root(base) if base is not None else None
    out: dict[str, list[Recording]] = {}
    keep = FAST_MOTION_RECORDINGS if fast else None
    if root is None:
        from .simulate import simulate

        duration = experiments.FAST_DURATION["handheld"] if fast else None
        for m, (motion, (_, _, ks)) in enumerate(OXIOD_MOTIONS.items()):
            out[motion] = [simulate("handheld", duration=duration, seed=seed + 10 * m + i,
                                    name=f"sim-{motion.replace(' ', '-')}-{i}")
                           for i in range(len(ks[:keep]))]
        note = (f"No real OxIOD data found {experiments.where(base)}: the handheld simulator stands in for every motion "
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
            out[motion] = experiments.load_oxiod_files([syn / f"imu{k}.csv" for k in ks], fast)
        cut = (f" (fast mode: at most {FAST_MOTION_RECORDINGS} recordings per motion, first {experiments.FAST_SAMPLES} "
               "samples each)") if fast else ""
        note = ("Real OxIOD from " + experiments.in_data_dir(root) + ": " + "; ".join(f"{m} {len(v)} recordings" for m, v in out.items())
                + cut + ".")
        result = Motions("real", out, note)
    if verbose:
        experiments.print_note(result.note)
    return result
