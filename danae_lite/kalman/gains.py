r"""The data-independent half of the paper's Kalman filter: the gain and covariance sequence of
eqs (4), (5), (7), and its steady state from the discrete algebraic Riccati equation.

``P`` and ``K`` depend on the settings and the step, never on the data, so they are computed
once per run before :func:`danae_lite.kalman.filter.kalman_filter` runs its data loop. When
``P0``, ``Q`` are block-diagonal in the (angle, bias) pairs and ``R`` is diagonal, each angle's
2-state block is iterated alone with plain scalars (and remembered for the next run); otherwise
the full 6x6 matrices are.
"""
from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .model import BLOCKS, KFConfig, check_dt, system_matrices

__all__ = ["GainSequence", "SteadyState", "block_gains", "block_settings", "gain_sequence", "steady_state"]

_REL_TOL = 4.0 * np.finfo(float).eps
"""Relative change below which the gain/covariance recursion counts as converged."""


@dataclass(frozen=True, eq=False)
class GainSequence:
    """Data-independent part of the recursion (eqs 4, 5, 7).

    Attributes
    ----------
    K : ndarray (M, 6, 3)
        Gains ``K_0 .. K_{M-1}``; ``K[-1]`` is used for every later step.
    P_post : ndarray (M, 6, 6)
        A-posteriori covariances ``P_0 .. P_{M-1}`` after each update.
    converged : bool
        True if ``K`` and ``P`` stopped changing (relative max-norm change <= 4 eps) by step
        ``M - 1`` (in the block form each block stops on its own and is padded with its
        converged values); False if the sequence was cut at the requested length.
    path : str
        ``"block"`` (three 2-state blocks iterated alone) or ``"general"`` (the 6x6 matrices).
    """

    K: NDArray[np.float64]
    P_post: NDArray[np.float64]
    converged: bool
    path: str

    def __len__(self) -> int:
        return int(self.K.shape[0])


def _block_recursion(
    p00: float, p01: float, p11: float, q00: float, q01: float, q11: float, r: float, dt: float, n_max: int
) -> tuple[list[tuple[float, float]], list[tuple[float, float, float]], bool]:
    """Scalar recursion of one 2-state (angle, bias) block; P is symmetric (3 numbers).

    Returns the gains ``(k_angle, k_bias)`` and posterior ``(p00, p01, p11)`` of each step
    and whether they converged (relative max-norm change <= 4 eps).
    """
    tol = _REL_TOL
    dt2 = dt * dt
    ks: list[tuple[float, float]] = []
    ps: list[tuple[float, float, float]] = []
    k0 = k1 = math.nan
    for _ in range(n_max):
        # P' = A P A^T + Q with A = [[1, -dt], [0, 1]]
        a00 = p00 - dt * p01 - dt * p01 + dt2 * p11 + q00
        a01 = p01 - dt * p11 + q01
        a11 = p11 + q11
        s = r + a00  # S = C P' C^T + R
        n0 = a00 / s  # K = P' C^T S^-1
        n1 = a01 / s
        o00, o01, o11 = p00, p01, p11
        p00 = (1.0 - n0) * a00  # P = (I - K C) P'
        p01 = (1.0 - n0) * a01
        p11 = a11 - n1 * a01
        ks.append((n0, n1))
        ps.append((p00, p01, p11))
        if (max(abs(n0 - k0), abs(n1 - k1)) <= tol * max(abs(n0), abs(n1))
                and max(abs(p00 - o00), abs(p01 - o01), abs(p11 - o11)) <= tol * max(abs(p00), abs(p01), abs(p11))):
            return ks, ps, True
        k0, k1 = n0, n1
    return ks, ps, False


def block_settings(cfg: KFConfig) -> list[tuple[float, ...]]:
    """The roll, pitch and yaw blocks of ``cfg`` as :func:`block_gains` takes them:
    ``(p00, p01, p11, q00, q01, q11, r)`` of each (angle, bias) pair and its measurement."""
    P0, Q, R = cfg.P0, cfg.Q, cfg.R
    return [tuple(map(float, (P0[a, a], P0[a, b], P0[b, b], Q[a, a], Q[a, b], Q[b, b], R[j, j])))
            for j, (a, b) in enumerate(BLOCKS)]


def block_gains(block: tuple[float, ...], dt: float, n_max: int
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """:func:`_block_recursion` of ``block`` (see :func:`block_settings`) as read-only arrays
    (K: (m, 2), P: (m, 3)), remembered for the last :data:`_BLOCK_CACHE_SIZE` blocks.

    A tuning grid repeats blocks: the roll and pitch blocks of every setting share their
    (angle, bias) variances, and every fold of a cross-validation runs the same grid. A
    remembered run serves any ``n_max`` it answers exactly: a run that converged within
    ``n_max`` steps, or the first ``n_max`` steps of a longer one (not converged within them).
    """
    key = (*block, float(dt))
    K, P, converged = _BLOCK_CACHE.pop(key, ((), (), False))
    if not converged and len(K) < n_max:  # nothing remembered, or a shorter run that did not converge
        ks, ps, converged = _block_recursion(*block, dt, n_max)
        K, P = np.asarray(ks), np.asarray(ps)
        K.setflags(write=False)
        P.setflags(write=False)
    _BLOCK_CACHE[key] = (K, P, converged)  # the most recently used last
    if len(_BLOCK_CACHE) > _BLOCK_CACHE_SIZE:
        _BLOCK_CACHE.popitem(last=False)
    if len(K) > n_max:
        return K[:n_max], P[:n_max], False
    return K, P, converged


_BLOCK_CACHE: "OrderedDict[tuple[float, ...], tuple[NDArray[np.float64], NDArray[np.float64], bool]]" = OrderedDict()
_BLOCK_CACHE_SIZE = 128
"""Blocks remembered by :func:`block_gains` (each at most 40 bytes per step)."""


def _block_gain_sequence(dt: float, cfg: KFConfig, n_max: int) -> GainSequence:
    """The three decoupled blocks, each iterated until it converges, then padded."""
    per_block = [block_gains(block, dt, n_max) for block in block_settings(cfg)]
    m = max(len(k) for k, _, _ in per_block)
    K = np.zeros((m, 6, 3))
    P = np.zeros((m, 6, 6))
    for j, ((a, b), (kb, pb, _)) in enumerate(zip(BLOCKS, per_block)):
        pad = np.minimum(np.arange(m), len(kb) - 1)  # a block converged sooner keeps its last values
        K[:, a, j], K[:, b, j] = kb[pad].T
        P[:, a, a], P[:, a, b], P[:, b, b] = pb[pad].T
        P[:, b, a] = P[:, a, b]
    return GainSequence(K=K, P_post=P, converged=all(c for _, _, c in per_block), path="block")


def _general_gain_sequence(dt: float, cfg: KFConfig, n_max: int) -> GainSequence:
    """Plain 6x6 matrix recursion of eqs 4, 5, 7 (same stopping rule)."""
    A = system_matrices(dt)[0]
    P = cfg.P0
    Ks: list[NDArray[np.float64]] = []
    Ps: list[NDArray[np.float64]] = []
    K_old = np.full((6, 3), np.nan)
    converged = False
    for _ in range(n_max):
        Pp = A @ P @ A.T + cfg.Q  # P' = A P A^T + Q
        PCt = Pp[:, 0::2]  # P' C^T: C selects states 0, 2, 4
        K = PCt @ np.linalg.inv(PCt[0::2] + cfg.R)  # P' C^T (C P' C^T + R)^-1
        P_old = P
        P = Pp - K @ Pp[0::2]  # (I - K C) P' = P' - K (C P')
        Ks.append(K)
        Ps.append(P)
        converged = bool(np.abs(K - K_old).max() <= _REL_TOL * np.abs(K).max()
                         and np.abs(P - P_old).max() <= _REL_TOL * np.abs(P).max())
        if converged:
            break
        K_old = K
    return GainSequence(K=np.asarray(Ks), P_post=np.asarray(Ps), converged=converged, path="general")


def gain_sequence(dt: float, config: KFConfig | None = None, n_max: int = 100_000,
                  method: Literal["auto", "block", "general"] = "auto") -> GainSequence:
    """Iterate eqs (4), (5), (7) from ``config.P0`` until ``K`` and ``P`` converge.

    Parameters
    ----------
    dt : float
        Step [s] (``config.dt`` is ignored here).
    config : KFConfig, optional
        Covariances; default the paper's identities.
    n_max : int
        Maximum number of steps (the filter passes its number of samples).
    method : {"auto", "block", "general"}
        ``"block"`` iterates three scalar 2x2 recursions (needs a block-diagonal config),
        ``"general"`` the full 6x6 matrices; ``"auto"`` picks block when possible.

    Returns
    -------
    GainSequence
        Stops at the first step whose ``K`` and ``P`` equal the previous ones to a relative
        4 eps (max-norm); the steady gain is then ``K[-1]``. In the block form each block
        stops on its own and is padded with its converged values. Small ``Q`` (a filter
        that trusts the gyro) converges slowly: thousands of steps. The blocks are
        remembered (:func:`block_gains`) for the next setting that shares them.
    """
    check_dt(dt)
    cfg = config or KFConfig()
    if n_max < 1:
        raise ValueError(f"n_max must be >= 1, got {n_max}")
    if method not in ("auto", "block", "general"):
        raise ValueError(f"method must be 'auto', 'block' or 'general', got {method!r}")
    if method == "block" and not cfg.block_diagonal:
        raise ValueError("method='block' needs block-diagonal P0, Q and a diagonal R")
    if method == "general" or not cfg.block_diagonal:
        return _general_gain_sequence(float(dt), cfg, int(n_max))
    return _block_gain_sequence(float(dt), cfg, int(n_max))


@dataclass(frozen=True, eq=False)
class SteadyState:
    """Steady-state Kalman quantities of the model (see :func:`steady_state`).

    Attributes
    ----------
    K_filter : ndarray (6, 3)
        Filter gain of eq (5), ``K = P' C^T (C P' C^T + R)^-1``: the correction applied to
        the *current* prediction, ``x_t = x'_t + K (y_t - C x'_t)``.
    K_predictor : ndarray (6, 3)
        Predictor (observer) gain ``L = A K_filter`` of
        ``x'_{t+1} = A x'_t + B u + L (y_t - C x'_t)``; this is what python-control's
        ``dlqe`` returns.
    P_prior : ndarray (6, 6)
        Steady a-priori covariance ``P'`` (the DARE solution; ``dlqe``'s ``P``).
    P_post : ndarray (6, 6)
        Steady a-posteriori covariance ``P = (I - K C) P'``.
    """

    K_filter: NDArray[np.float64]
    K_predictor: NDArray[np.float64]
    P_prior: NDArray[np.float64]
    P_post: NDArray[np.float64]


def steady_state(dt: float, Q: ArrayLike | None = None, R: ArrayLike | None = None) -> SteadyState:
    r"""Steady-state gain and covariances from the discrete algebraic Riccati equation.

    The a-priori covariance :math:`P'` of eqs (4)-(7) converges to the solution of

    .. math:: P' = A P' A^T - A P' C^T (C P' C^T + R)^{-1} C P' A^T + Q,

    computed with ``scipy.linalg.solve_discrete_are(A.T, C.T, Q, R)`` (the estimation DARE
    is the control DARE of the transposed system). Then
    :math:`K = P' C^T (C P' C^T + R)^{-1}`, :math:`L = A K`, :math:`P = (I - K C) P'`.

    python-control's ``control.dlqe(A, G, C, QN, RN)`` (matrix form, ``G = I``) returns
    ``L`` — the *predictor* gain — and ``P'``; with a system object it would take the
    noise input matrix from ``sys.B``, which is not what we want. The filter gain of the
    paper is ``K = A^{-1} L`` (``A`` is invertible).

    Parameters
    ----------
    dt : float
        Step [s].
    Q : array_like (6, 6), scalar or diagonal, optional
        Process-noise covariance per step; default identity (the paper).
    R : array_like (3, 3), scalar or diagonal, optional
        Measurement-noise covariance [rad²]; default identity (the paper).
    """
    cfg = KFConfig(Q=np.eye(6) if Q is None else Q, R=np.eye(3) if R is None else R)
    A, _, C = system_matrices(dt)
    P_prior = scipy.linalg.solve_discrete_are(A.T, C.T, cfg.Q, cfg.R)
    P_prior = 0.5 * (P_prior + P_prior.T)
    S = C @ P_prior @ C.T + cfg.R
    K = np.linalg.solve(S.T, (P_prior @ C.T).T).T
    P_post = (np.eye(6) - K @ C) @ P_prior
    return SteadyState(K_filter=K, K_predictor=A @ K, P_prior=P_prior, P_post=P_post)
