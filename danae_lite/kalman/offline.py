r"""The paper's KF after the fact: what a finished run says about itself, and its smoothed
counterpart. Both take a :class:`~danae_lite.kalman.filter.KFResult` and the model of
:mod:`danae_lite.kalman.filter` (eqs 3-7 of the paper, same state, units and frames):

* :func:`innovations`: the innovation of every update, the covariance the filter gave it and
  the normalised innovation squared (NIS), a check of a filter's ``Q`` and ``R`` that needs no
  ground truth (chapter 6).
* :func:`rts_smooth`: the Rauch-Tung-Striebel smoother, each estimate conditioned on all
  samples, past and future (the leaderboard's ``tuned_kf_rts``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .filter import PI, TWO_PI, KFResult
from .gains import gain_sequence
from .model import system_matrices

__all__ = ["Innovations", "innovations", "rts_smooth"]


def rts_smooth(result: KFResult) -> NDArray[np.float64]:
    r"""Rauch-Tung-Striebel smoother over a finished :func:`~danae_lite.kalman.filter.kalman_filter` run: the non-causal
    counterpart of the KF, each estimate conditioned on *all* samples, past and future.

    With the filter's a-posteriori states :math:`x_t`, covariances :math:`P_t`, the known
    inputs :math:`u_t` (``result.rates``) and the model of eqs (3)-(7),

    .. math::

        x'_{t+1} = A x_t + B u_{t+1}, \qquad P'_{t+1} = A P_t A^T + Q, \qquad
        G_t = P_t A^T P'^{-1}_{t+1},

        x^s_{N-1} = x_{N-1}, \qquad x^s_t = x_t + G_t (x^s_{t+1} - x'_{t+1}).

    The inputs (Euler rates at the filter's previous estimates) and the heading measurement
    are taken as the filter used them, so the smoother treats them as given, exactly as a
    linear-Gaussian smoother of the same model would. Yaw stays continuous (unwrapped) like the
    filter's state.

    Returns
    -------
    ndarray (N, 6)
        Smoothed states ``[phi, b_phi, theta, b_theta, psi, b_psi]`` [rad, rad/s, ...].
    """
    cfg, dt = result.config, result.dt
    x = result.state
    n = len(x)
    A, B, _ = system_matrices(dt)
    seq = gain_sequence(dt, cfg, n_max=n, method=result.path)
    # G_t = P_t A^T P'^-1_{t+1} for each distinct P_t (the last one stands for every later step)
    G = [np.linalg.solve((A @ P @ A.T + cfg.Q).T, (P @ A.T).T).T for P in seq.P_post[: n - 1]]
    # one-step predictions of every state from the previous a-posteriori state
    x_prior_next = x[:-1] @ A.T + result.rates[1:] @ B.T
    out = x.copy()
    for t in range(n - 2, -1, -1):
        out[t] = x[t] + G[min(t, len(G) - 1)] @ (out[t + 1] - x_prior_next[t])
    return out


@dataclass(frozen=True, eq=False)
class Innovations:
    r"""Per-step innovations of a finished KF run and the covariance the filter gave them
    (see :func:`innovations`). N samples.

    Attributes
    ----------
    nu : ndarray (N, 3)
        Innovations :math:`\nu_t = y_t - C x'_t` [rad]: the measured (roll_acc, pitch_acc,
        psi_mag) minus the predicted (roll, pitch, yaw), in the frame the filter ran in (the
        recording's sensor axes, its yaw counted from magnetic north; no heading offset is
        added). The yaw entry is wrapped to [-pi, pi) when the run's config wrapped it
        (``wrap_yaw_innovation``), as the filter used it.
    S : ndarray (N, 3, 3)
        Innovation covariance the filter assumed, :math:`S_t = C P'_t C^T + R` [rad²].
    nis : ndarray (N,)
        Normalised innovation squared :math:`\nu_t^T S_t^{-1} \nu_t` (dimensionless).
        When the model and its ``Q``, ``R`` are the true ones it is chi-square distributed
        with 3 degrees of freedom (mean 3), independently from step to step.
    """

    nu: NDArray[np.float64]
    S: NDArray[np.float64]
    nis: NDArray[np.float64]

    @property
    def sigma(self) -> NDArray[np.float64]:
        r"""``(N, 3)`` standard deviation of each innovation the filter assumed,
        :math:`\sqrt{S_{kk}}` [rad]."""
        return np.sqrt(np.einsum("nkk->nk", self.S))

    @property
    def nis_angle(self) -> NDArray[np.float64]:
        r"""``(N, 3)`` NIS of each angle on its own, :math:`\nu_k^2 / S_{kk}`
        (dimensionless; chi-square with 1 degree of freedom, mean 1, under the model)."""
        return self.nu**2 / np.einsum("nkk->nk", self.S)

    def __len__(self) -> int:
        return int(self.nu.shape[0])


def innovations(result: KFResult) -> Innovations:
    r"""Innovations, their covariance and the NIS of every step of a finished KF run.

    :class:`KFResult` keeps the a-posteriori states, the inputs and the measurements but not
    what happened inside each update; this recomputes it from them and the run's config:

    .. math::
       x'_t = A x_{t-1} + B u_t,\qquad \nu_t = y_t - C x'_t,\qquad
       P'_t = A P_{t-1} A^T + Q,\qquad S_t = C P'_t C^T + R,

    with :math:`x_{-1} = x_0`, :math:`P_{-1} = P_0` (``result.config``), the
    a-posteriori covariances of :func:`~danae_lite.kalman.filter.gain_sequence` (the converged one for every step
    after the transient, as the filter did) and the yaw innovation wrapped to [-pi, pi)
    when ``config.wrap_yaw_innovation``. These are exactly the quantities of the filter's
    update ``x_t = x'_t + K_t \nu_t``.

    Parameters
    ----------
    result : KFResult
        Output of :func:`~danae_lite.kalman.filter.kalman_filter` or :func:`~danae_lite.kalman.filter.run_kf`.

    Returns
    -------
    Innovations
        ``nu`` (N, 3) [rad], ``S`` (N, 3, 3) [rad²], ``nis`` (N,) [dimensionless].
    """
    cfg, dt = result.config, result.dt
    n = len(result)
    A, B, C = system_matrices(dt)
    x_prev = np.vstack((cfg.x0[None, :], result.state[:-1]))
    x_prior = x_prev @ A.T + result.rates @ B.T
    nu = result.measurements - x_prior @ C.T
    if cfg.wrap_yaw_innovation:
        nu[:, 2] = (nu[:, 2] + PI) % TWO_PI - PI
    seq = gain_sequence(dt, cfg, n_max=n, method=result.path)
    m = len(seq)
    # the a-posteriori covariance before step t: P0, then P_0 .. P_{m-1} (the last one
    # stands for every later step); only these m + 1 distinct S need computing
    P_before = np.concatenate((cfg.P0[None], seq.P_post))
    P_prior = A @ P_before @ A.T + cfg.Q
    S_distinct = C @ P_prior @ C.T + cfg.R
    S_distinct = 0.5 * (S_distinct + np.swapaxes(S_distinct, 1, 2))
    idx = np.minimum(np.arange(n), m)
    S = S_distinct[idx]
    nis = np.einsum("ni,nij,nj->n", nu, np.linalg.inv(S_distinct)[idx], nu)
    return Innovations(nu=nu, S=S, nis=nis)
