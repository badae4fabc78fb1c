"""The leaderboard's method names for the command line's ``--help`` and ``--methods`` check, as a
static table: listing them this way imports none of the methods (no torch, no pandas).
``tests/test_cli.py`` keeps it equal to :data:`danae_lite.research.baselines.METHODS` and
:data:`~danae_lite.research.baselines.DENOISER_FAMILIES`."""
from __future__ import annotations

METHOD_NAMES: tuple[str, ...] = ("constant", "paper_kf", "tuned_kf", "tuned_kf_rts", "butterworth",
                                 "moving_average", "linear_map", "fusion", "vqf", "madgwick", "mahony",
                                 "riann", "danae")
"""The leaderboard's methods, in table order."""
DENOISER_FAMILIES: tuple[str, ...] = ("danae-res", "danae-safe")
"""Learned correctors put behind a filter: ``<family>[<filter>]``."""


def is_method_name(name: str) -> bool:
    """A method of :data:`METHOD_NAMES`, or ``<family>[<filter>]`` for a family of
    :data:`DENOISER_FAMILIES` and a filter of :data:`METHOD_NAMES` other than DANAE."""
    if name in METHOD_NAMES:
        return True
    return any(name.startswith(f"{family}[") and name.endswith("]")
               and name[len(family) + 1:-1] in METHOD_NAMES and not name[len(family) + 1:-1].startswith("danae")
               for family in DENOISER_FAMILIES)
