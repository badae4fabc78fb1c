"""Quaternion frames: the Hamilton product, and body -> ENU (east, north, up: as BROAD stores its
ground truth) to body -> NWU (north, west, up: the package's reference frame) and back.

Quaternions are scalar-last, ``(x, y, z, w)``, as everywhere in the package.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

_S = math.sqrt(0.5)
_ENU_FROM_NWU = np.array([0.0, 0.0, _S, _S])    # Rz(+90°), scalar-last
_NWU_FROM_ENU = np.array([0.0, 0.0, -_S, _S])   # Rz(-90°), scalar-last


def quat_multiply(p: ArrayLike, q: ArrayLike) -> NDArray[np.float64]:
    """Hamilton product ``p * q`` of scalar-last quaternions, row by row.

    ``p`` and ``q`` are (4,) or (N, 4); a single quaternion is applied to every row of the
    other. ``p * q`` rotates by ``q`` first, then by ``p``. NaN rows stay NaN.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    x1, y1, z1, w1 = np.moveaxis(p, -1, 0)
    x2, y2, z2, w2 = np.moveaxis(q, -1, 0)
    return np.stack([
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
    ], axis=-1)


def enu_to_nwu(q_enu: ArrayLike) -> NDArray[np.float64]:
    """Body -> ENU quaternions (scalar-last) to body -> NWU: ``Rz(-90°) * q``."""
    return quat_multiply(_NWU_FROM_ENU, q_enu)


def nwu_to_enu(q_nwu: ArrayLike) -> NDArray[np.float64]:
    """Body -> NWU quaternions (scalar-last) to body -> ENU: ``Rz(+90°) * q``."""
    return quat_multiply(_ENU_FROM_NWU, q_nwu)
