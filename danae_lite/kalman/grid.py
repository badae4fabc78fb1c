"""The paper's KF run for many settings at once: the tuned KF's grid search in one pass.

:func:`danae_lite.kalman.filter.run_kf` runs one setting with plain ``math`` scalars. A grid
search runs hundreds of settings over the same recordings; here the same loop,
:func:`danae_lite.kalman.filter.recursion`, steps every setting together, one NumPy vector of
settings per state, so that a sample costs about as much for 324 settings as for a dozen.

Additions, products and quotients are IEEE-exact in both, so the two agree to the rounding of
``sin``, ``cos`` and ``atan2``, whose NumPy versions may differ from ``math``'s by an ulp on
some CPUs (``tests/test_kf_grid.py`` bounds the difference).
"""
from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from itertools import count
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from . import gains as kf_gains, model
from .filter import initial_tilt, measurement_rows, recursion, sensor_arrays
from .model import KFConfig
from ..angles import euler_error_angle, wrap

if TYPE_CHECKING:  # pragma: no cover
    from ..data.recording import Recording

__all__ = ["GridScores", "TRIG_NUMPY", "run_kf_grid", "score_kf_grid"]

TRIG_NUMPY = (np.sin, np.cos, np.arctan2)
"""``sin``, ``cos``, ``atan2`` for a batch of settings held in NumPy vectors
(:data:`danae_lite.kalman.filter.TRIG_MATH` is the same for one setting of plain floats)."""

MAX_GRID_BYTES = 512 * 2**20
"""Largest estimate array [bytes] one pass of :func:`score_kf_grid` holds (24 bytes per sample
and setting); a longer recording runs the grid in several passes."""
_SCORE_ELEMENTS = 4_000_000
"""Samples x settings scored at once (each temporary array: 32 MB)."""


class _Gains:
    """The per-step gains of every setting, stored once per distinct (angle, bias) block.

    A grid repeats blocks (roll and pitch share theirs; 324 tuned-KF settings hold 36 distinct
    blocks), so the gains are kept as ``(m, 2 * B)`` for the ``B`` distinct blocks, each padded
    with its converged gain, and :meth:`steps` gathers step ``t``'s ``(6, K)`` gains
    (K00, K10, K21, K31, K42, K52 per setting) with one ``take``.
    """

    def __init__(self, configs: Sequence[KFConfig], dt: float, n: int) -> None:
        keys: dict[tuple[float, ...], int] = {}
        index = np.empty((6, len(configs)), dtype=np.intp)
        for k, cfg in enumerate(configs):
            for (a, b), block in zip(model.BLOCKS, kf_gains.block_settings(cfg)):
                u = keys.setdefault(block, len(keys))
                index[a, k], index[b, k] = 2 * u, 2 * u + 1
        blocks = [kf_gains.block_gains(key, dt, n)[0] for key in keys]
        self.m = max(len(K) for K in blocks)
        self.table = np.empty((self.m, 2 * len(blocks)))
        for u, K in enumerate(blocks):
            self.table[: len(K), 2 * u: 2 * u + 2] = K
            self.table[len(K):, 2 * u: 2 * u + 2] = K[-1]
        self.index = index
        self.steady = self.table[-1].take(index)

    def steps(self) -> Iterator[tuple[Any, ...]]:
        """Each step's 6x3 gain row-major, as :func:`~danae_lite.kalman.filter.recursion` reads
        it: the ``(K,)`` vectors of the blocks, exact zeros between them; from step ``m`` on
        the converged gains."""
        for t in count():
            k = self.table[t].take(self.index) if t < self.m else self.steady
            yield (k[0], 0.0, 0.0, k[1], 0.0, 0.0, 0.0, k[2], 0.0, 0.0, k[3], 0.0,
                   0.0, 0.0, k[4], 0.0, 0.0, k[5])


def _check(configs: Sequence[KFConfig]) -> tuple[bool, bool]:
    """(init_from_truth, wrap_yaw_innovation) shared by all ``configs``; ValueError otherwise."""
    if not configs:
        raise ValueError("configs is empty: give at least one KFConfig")
    for i, cfg in enumerate(configs):
        if not cfg.block_diagonal:
            raise ValueError(f"configs[{i}] is not block-diagonal (P0, Q in (angle, bias) pairs, R diagonal)")
        for attr in ("dt", "init_from_truth", "wrap_yaw_innovation"):
            if getattr(cfg, attr) != getattr(configs[0], attr):
                raise ValueError(f"configs[{i}].{attr} differs from configs[0].{attr}: one grid shares it")
    return configs[0].init_from_truth, configs[0].wrap_yaw_innovation


def run_kf_grid(rec: "Recording", configs: Sequence[KFConfig]) -> NDArray[np.float64]:
    """Euler estimates ``(K, N, 3)`` [rad] of the KF on ``rec`` for each of ``K`` settings.

    ``euler[k]`` equals ``run_kf(rec, configs[k]).euler`` to the rounding of the
    trigonometric functions (yaw unbounded, as there). Every setting must be block-diagonal
    and share ``dt``, ``init_from_truth`` and ``wrap_yaw_innovation``; ``dt`` is
    ``config.dt`` or ``1 / rec.fs``. Memory: 24 bytes per sample and setting.
    """
    from_truth, wrap_yaw = _check(configs)
    dt = configs[0].dt if configs[0].dt is not None else rec.dt
    model.check_dt(dt)
    dt = float(dt)
    arrays = sensor_arrays(gyro=rec.gyro, acc=rec.acc, mag=rec.mag)
    n, k = len(arrays["gyro"]), len(configs)
    gains = _Gains(configs, dt, n)
    _, rows = measurement_rows(arrays)
    x0 = np.array([cfg.x0 for cfg in configs], dtype=float).T  # (6, K)
    if from_truth:  # the step-0 rate and heading formulas use the true roll/pitch (as run_kf)
        tilt0 = [np.full(k, v) for v in initial_tilt(rec.euler[0], configs[0])]
    else:
        tilt0 = [x0[0].copy(), x0[2].copy()]
    euler = np.empty((n, 3, k))
    steps = recursion(rows, gains.steps(), [*x0, *tilt0], dt, wrap_yaw, TRIG_NUMPY)
    for t, (f, _, h, _, s, *_) in enumerate(steps):
        euler[t, 0], euler[t, 1], euler[t, 2] = f, h, s
    return euler.transpose(2, 0, 1)


@dataclass(frozen=True)
class GridScores:
    """RMSE [rad] of each grid setting on the clean samples of the recordings taken together.

    ``total``: ``(K,)`` angle of ``R(est) R(truth)^T`` (as :func:`danae_lite.research.methods.total_error_rmse`);
    ``per_angle``: ``(K, 3)`` wrapped roll, pitch and yaw errors (as ``train_objective``).
    """

    total: NDArray[np.float64]
    per_angle: NDArray[np.float64]


def _score(euler: NDArray[np.float64], rec: "Recording", ok: NDArray[np.bool_], north_yaw: float
           ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Sums of squared total and per-angle errors ``((K,), (K, 3))`` of estimates ``(n, 3, K)``."""
    k = euler.shape[2]
    tot, ang = np.zeros(k), np.zeros((k, 3))
    truth = rec.euler[ok]
    q_true = rec.quat[ok]
    step = max(1, _SCORE_ELEMENTS // max(1, len(truth)))
    for c in range(0, k, step):
        e = euler[ok, :, c: c + step]  # (n_ok, 3, c)
        yaw = wrap(e[:, 2] + north_yaw)
        for j, est in enumerate((e[:, 0], e[:, 1], yaw)):
            d = wrap(truth[:, j, None] - est)
            ang[c: c + step, j] = np.einsum("ij,ij->j", d, d)
        a = euler_error_angle(np.stack((e[:, 0], e[:, 1], yaw), axis=-1), q_true[:, None, :])
        tot[c: c + step] = np.einsum("ij,ij->j", a, a)
    return tot, ang


def score_kf_grid(configs: Sequence[KFConfig], recordings: Sequence["Recording"],
                  clean: dict[str, NDArray[np.bool_]], north_yaw: float = 0.0,
                  max_bytes: int = MAX_GRID_BYTES) -> GridScores:
    """Run every setting over ``recordings`` and score it on their clean samples.

    ``north_yaw`` [rad] is added to the KF yaw (magnetic north to the ground-truth frame, as
    :meth:`danae_lite.data.alignment.FrameAlignment.to_truth_frame`); ``clean[name]`` masks the samples
    that count. Estimates are scored recording by recording and dropped, so memory stays within
    ``max_bytes`` (plus the scoring's temporaries) however long the recordings are.
    """
    k = len(configs)
    tot, ang, count = np.zeros(k), np.zeros((k, 3)), 0
    for rec in recordings:
        ok = np.asarray(clean[rec.name], dtype=bool)
        if ok.shape != (len(rec),):
            raise ValueError(f"clean[{rec.name!r}] has shape {ok.shape}, expected ({len(rec)},)")
        step = max(1, max_bytes // (24 * len(rec)))
        for c in range(0, k, step):
            euler = run_kf_grid(rec, configs[c: c + step]).transpose(1, 2, 0)  # (n, 3, c) base array
            t, a = _score(euler, rec, ok, north_yaw)
            tot[c: c + step] += t
            ang[c: c + step] += a
        count += int(ok.sum())
    if count == 0:
        raise ValueError("no clean sample in the recordings: nothing to score")
    return GridScores(total=np.sqrt(tot / count), per_angle=np.sqrt(ang / count))
