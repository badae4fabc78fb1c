r"""The paper's linear attitude Kalman filter, exactly as the authors built it.

The model, its settings and measurement formulas are in :mod:`danae_lite.kalman.model`, the
gain sequence and steady state in :mod:`danae_lite.kalman.gains`; this module runs the filter.

Recursion (paper eqs 3-7), once per sample ``t = 0 .. N-1`` starting from ``x0``, ``P0``:

.. math::
   x'_t = A x_{t-1} + B u_t,\qquad P'_t = A P_{t-1} A^T + Q,\qquad
   K_t = P'_t C^T (C P'_t C^T + R)^{-1},

   x_t = x'_t + K_t (y_t - C x'_t),\qquad P_t = (I - K_t C) P'_t.

Speed
-----
``P``/``K`` do not depend on the data, so the gain sequence is computed first and stops as
soon as it has converged to machine precision (about 170 steps for the paper's identities
at dt = 0.1 s, about 1600 at dt = 0.01 s, more for a small ``Q``; its blocks are remembered);
the data loop (:func:`recursion`) then runs with plain ``math`` scalars, using ``K_t``
during that transient and the converged gain afterwards. When ``P0``, ``Q`` are
block-diagonal in the (angle, bias) pairs and ``R`` is diagonal (the default), the gains are
those of the three 2-state blocks iterated alone ("block" path); otherwise of the full 6x6
matrices ("general" path). Both give the gains of the plain matrix recursion to rounding;
the data loop is the same. :mod:`danae_lite.kalman.grid` runs that loop for many settings at
once.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from itertools import chain, repeat
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .gains import GainSequence, gain_sequence
from .model import KFConfig, accel_tilt, check_dt, unit_rows

if TYPE_CHECKING:  # pragma: no cover
    from ..data.recording import Recording

__all__ = ["PI", "TRIG_MATH", "TWO_PI", "KFResult", "KFStep", "initial_tilt", "kalman_filter", "kf_step",
           "measurement_rows", "recursion", "run_kf", "sensor_arrays"]

PI = math.pi
TWO_PI = 2.0 * math.pi


# --------------------------------------------------------------------------------------
# One step by the book
# --------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class KFStep:
    """All intermediate quantities of one step of eqs (3)-(7) (see :func:`kf_step`)."""

    x_prior: NDArray[np.float64]
    """``x' = A x + B u`` (eq 3)."""
    P_prior: NDArray[np.float64]
    """``P' = A P A^T + Q`` (eq 4)."""
    S: NDArray[np.float64]
    """Innovation covariance ``C P' C^T + R``."""
    K: NDArray[np.float64]
    """Gain ``P' C^T S^-1`` (eq 5)."""
    innovation: NDArray[np.float64]
    """``y - C x'``."""
    x: NDArray[np.float64]
    """``x' + K (y - C x')`` (eq 6)."""
    P: NDArray[np.float64]
    """``(I - K C) P'`` (eq 7)."""


def kf_step(x: ArrayLike, P: ArrayLike, u: ArrayLike, y: ArrayLike,
            A: ArrayLike, B: ArrayLike, C: ArrayLike, Q: ArrayLike, R: ArrayLike) -> KFStep:
    """One textbook step of the linear KF, eqs (3)-(7), with every intermediate kept.

    Works for any dimensions: ``x`` (n,), ``P``/``Q`` (n, n), ``u`` (m,), ``B`` (n, m),
    ``y`` (k,), ``C`` (k, n), ``R`` (k, k). Meant for teaching and checking by hand;
    :func:`kalman_filter` is the fast implementation of the same equations.
    """
    x, u, y = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (x, u, y))
    P, A, B, C, Q, R = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (P, A, B, C, Q, R))
    x_prior = A @ x + B @ u  # eq (3)
    P_prior = A @ P @ A.T + Q  # eq (4)
    S = C @ P_prior @ C.T + R
    K = P_prior @ C.T @ np.linalg.inv(S)  # eq (5)
    innovation = y - C @ x_prior
    x_new = x_prior + K @ innovation  # eq (6)
    P_new = (np.eye(len(x)) - K @ C) @ P_prior  # eq (7)
    return KFStep(x_prior=x_prior, P_prior=P_prior, S=S, K=K, innovation=innovation, x=x_new, P=P_new)


# --------------------------------------------------------------------------------------
# The filter
# --------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class KFResult:
    """Output of :func:`kalman_filter` / :func:`run_kf` (N samples).

    Attributes
    ----------
    euler : ndarray (N, 3)
        A-posteriori (roll, pitch, yaw) estimates [rad]; yaw is unbounded (never wrapped).
    bias : ndarray (N, 3)
        A-posteriori rate biases (b_phi, b_theta, b_psi) [rad/s].
    measurements : ndarray (N, 3)
        ``y_t = (roll_acc, pitch_acc, psi_mag)`` [rad] as used by the filter.
    rates : ndarray (N, 3)
        ``u_t = (phi_dot, theta_dot, psi_dot)`` [rad/s] as used by the filter.
    gain : ndarray (6, 3)
        Gain of the last step (the steady-state gain once converged).
    P : ndarray (6, 6)
        A-posteriori covariance after the last step.
    n_transient : int
        Number of steps whose gain differed from the steady gain (the gain is constant
        from this index on; equal to N if it never converged within the recording).
    dt : float
        Step used [s].
    config : KFConfig
        Settings used.
    gains : ndarray (N, 6, 3) or None
        Per-step gains ``K_t``, only with ``store_gains=True``.
    path : str
        ``"block"`` or ``"general"`` (how the gains were computed).
    """

    euler: NDArray[np.float64]
    bias: NDArray[np.float64]
    measurements: NDArray[np.float64]
    rates: NDArray[np.float64]
    gain: NDArray[np.float64]
    P: NDArray[np.float64]
    n_transient: int
    dt: float
    config: KFConfig
    gains: NDArray[np.float64] | None = None
    path: str = "block"

    @property
    def state(self) -> NDArray[np.float64]:
        """Full state ``(N, 6)`` = ``[phi, b_phi, theta, b_theta, psi, b_psi]``."""
        return np.stack((self.euler, self.bias), axis=2).reshape(len(self.euler), 6)  # angle, bias per axis

    def __len__(self) -> int:
        return int(self.euler.shape[0])


TRIG_MATH = (math.sin, math.cos, math.atan2)
"""``sin``, ``cos``, ``atan2`` for one setting of plain floats (:func:`kalman_filter`)."""


def recursion(rows: Iterable[tuple[float, ...]], gains: Iterable[tuple[Any, ...]], start: Sequence[Any], dt: float,
              wrap_yaw: bool = False, trig: tuple[Callable[..., Any], ...] = TRIG_MATH) -> Iterator[tuple[Any, ...]]:
    """Eqs (3), (6) over the samples, with the gains of eqs (4)-(5) computed beforehand.

    One state per setting: floats with :data:`TRIG_MATH` (one setting), or NumPy vectors of
    ``K`` settings with :data:`danae_lite.kalman.grid.TRIG_NUMPY` (a grid); the same lines run both.

    ``rows`` yields ``(p, q, r, roll_acc, pitch_acc, mx, my, mz)`` per sample (rates [rad/s],
    accelerometer tilt [rad], magnetometer of unit norm); ``gains`` the step's 6x3 gain,
    row-major (18 numbers or vectors); ``start`` is ``[phi, b_phi, theta, b_theta, psi, b_psi,
    phi_hat, theta_hat]``: ``x0`` and the roll/pitch the first step's rate and heading formulas
    use. ``wrap_yaw`` wraps the yaw innovation to [-pi, pi). Yields, per sample, the
    a-posteriori state ``(phi, b_phi, theta, b_theta, psi, b_psi)``, the inputs ``u`` [rad/s] and
    the heading ``psi_mag`` [rad]: 10 values. A block-diagonal gain (zeros between the three
    (angle, bias) pairs) gives the same numbers as each pair filtered alone: adding an exact
    zero product changes no bit.
    """
    sin, cos, atan2 = trig
    x0, x1, x2, x3, x4, x5, pf, ph = start
    for (p, q, r, ya, yb, mx, my, mz), k in zip(rows, gains):
        (k00, k01, k02, k10, k11, k12, k20, k21, k22, k30, k31, k32, k40, k41, k42, k50, k51, k52) = k
        sf, cf, sh, ch = sin(pf), cos(pf), sin(ph), cos(ph)
        # inputs u: Euler rates at the previous estimates (w = sin(phi) q + cos(phi) r)
        w = sf * q + cf * r
        u0 = p + sh * w / ch
        u1 = cf * q - sf * r
        u2 = w / ch
        # the tilt-compensated heading at the previous estimates
        ym = atan2(mz * sf - my * cf, mx * ch + sh * (my * sf + mz * cf))
        # eq (3): x' = A x + B u (each angle integrates its rate less its bias; biases unchanged)
        x0 = x0 - dt * x1 + dt * u0
        x2 = x2 - dt * x3 + dt * u1
        x4 = x4 - dt * x5 + dt * u2
        # the innovation y - C x'
        e0 = ya - x0
        e1 = yb - x2
        e2 = ym - x4
        if wrap_yaw:
            e2 = (e2 + PI) % TWO_PI - PI
        # eq (6): x = x' + K (y - C x')
        x0, x1, x2, x3, x4, x5 = (
            x0 + (k00 * e0 + k01 * e1 + k02 * e2),
            x1 + (k10 * e0 + k11 * e1 + k12 * e2),
            x2 + (k20 * e0 + k21 * e1 + k22 * e2),
            x3 + (k30 * e0 + k31 * e1 + k32 * e2),
            x4 + (k40 * e0 + k41 * e1 + k42 * e2),
            x5 + (k50 * e0 + k51 * e1 + k52 * e2),
        )
        pf, ph = x0, x2
        yield x0, x1, x2, x3, x4, x5, u0, u1, u2, ym


def _step(dt: float | None, cfg: KFConfig) -> float:
    """The step [s]: ``dt``, else ``cfg.dt``; ValueError when neither is given or they disagree."""
    if dt is None and cfg.dt is None:
        raise ValueError("dt is not given and config.dt is None: pass the step in seconds")
    dt = cfg.dt if dt is None else dt
    check_dt(dt)
    dt = float(dt)
    if cfg.dt is not None and cfg.dt != dt:
        raise ValueError(f"dt={dt} disagrees with config.dt={cfg.dt}")
    return dt


def sensor_arrays(**named: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """The sensor arrays as finite (N, 3) floats with one N (> 0); ValueError naming the array,
    and the first bad row, otherwise."""
    arrays = {}
    n = None
    for name, value in named.items():
        a = np.asarray(value, dtype=float)
        if a.ndim != 2 or a.shape[1] != 3:
            raise ValueError(f"{name} must have shape (N, 3), got {a.shape}")
        if not np.isfinite(a).all():
            row = int(np.argmax(~np.isfinite(a).all(1)))
            raise ValueError(f"{name} contains non-finite values (first at row {row})")
        n = a.shape[0] if n is None else n
        if a.shape[0] != n:
            raise ValueError(f"{name} has {a.shape[0]} rows, gyro has {n}")
        arrays[name] = a
    if not n:
        raise ValueError("no samples")
    return arrays


def measurement_rows(arrays: dict[str, NDArray[np.float64]]
                     ) -> tuple[NDArray[np.float64], Iterator[tuple[float, ...]]]:
    """The accelerometer tilt ``(N, 2)`` [rad] of :func:`sensor_arrays`' output, and the rows
    :func:`recursion` reads: ``(p, q, r, roll_acc, pitch_acc, mx, my, mz)`` per sample as
    floats (the magnetometer scaled to unit norm)."""
    tilt = accel_tilt(arrays["acc"])
    columns = np.column_stack((arrays["gyro"], tilt, unit_rows(arrays["mag"], "mag"))).T
    return tilt, zip(*columns.tolist())


def initial_tilt(init_euler: ArrayLike | None, cfg: KFConfig) -> tuple[float, float]:
    """Roll and pitch [rad] of the step-0 formulas: ``init_euler``'s, else ``cfg.x0``'s."""
    if init_euler is None:
        return float(cfg.x0[0]), float(cfg.x0[2])
    ie = np.asarray(init_euler, dtype=float).ravel()
    if ie.size not in (2, 3) or not np.isfinite(ie).all():
        raise ValueError(f"init_euler must be (roll, pitch[, yaw]) in rad, got {init_euler!r}")
    return float(ie[0]), float(ie[1])


def _step_gains(seq: GainSequence, n: int) -> Iterator[tuple[float, ...]]:
    """The gains of the data loop's ``n`` steps, each the 6x3 gain row-major: ``K_t`` during the
    transient, then the converged gain for every later step."""
    m = min(n, len(seq))
    picked = seq.K[:m].reshape(m, 18)
    return chain(map(tuple, picked.tolist()), repeat(tuple(picked[-1].tolist())))


def kalman_filter(gyro: ArrayLike, acc: ArrayLike, mag: ArrayLike, dt: float | None = None,
                  config: KFConfig | None = None, init_euler: ArrayLike | None = None, *,
                  store_gains: bool = False, method: Literal["auto", "block", "general"] = "auto") -> KFResult:
    """Run the paper's KF (eqs 3-7) over raw sensor arrays.

    Parameters
    ----------
    gyro : array_like (N, 3)
        Body angular rates (p, q, r) [rad/s].
    acc : array_like (N, 3)
        Accelerometer [g], tilt convention (see :func:`~danae_lite.kalman.model.accel_tilt`).
    mag : array_like (N, 3)
        Magnetometer [µT] (normalised internally).
    dt : float, optional
        Step [s]; defaults to ``config.dt``. One of the two must be given; if both are
        given they must agree.
    config : KFConfig, optional
        Covariances and initial state; default the paper's untuned identities.
    init_euler : array_like (3,) or (2,), optional
        Roll and pitch [rad] (a third entry, yaw, is ignored) used as the "previous
        estimates" by the step-0 rate and heading formulas. ``None``: ``x0``'s roll/pitch.
    store_gains : bool
        Also return the per-step gains ``(N, 6, 3)`` (144 bytes per sample).
    method : {"auto", "block", "general"}
        How the gains are computed; ``"auto"`` iterates the three decoupled blocks when the
        configuration is block-diagonal. All give the same gains to rounding.

    Returns
    -------
    KFResult
    """
    cfg = config or KFConfig()
    dt = _step(dt, cfg)
    arrays = sensor_arrays(gyro=gyro, acc=acc, mag=mag)
    n = len(arrays["gyro"])
    start = [*map(float, cfg.x0), *initial_tilt(init_euler, cfg)]
    seq = gain_sequence(dt, cfg, n_max=n, method=method)
    tilt, rows = measurement_rows(arrays)
    steps = recursion(rows, _step_gains(seq, n), start, dt, cfg.wrap_yaw_innovation)
    # res rows: the a-posteriori state (phi, b_phi, theta, b_theta, psi, b_psi), u (3) and psi_mag
    res = np.fromiter(chain.from_iterable(steps), dtype=float, count=10 * n).reshape(n, 10).T
    last = min(n, len(seq)) - 1  # the step whose gain every later step uses
    return KFResult(euler=np.column_stack((res[0], res[2], res[4])), bias=np.column_stack((res[1], res[3], res[5])),
                    measurements=np.column_stack((tilt[:, 0], tilt[:, 1], res[9])), rates=np.column_stack(res[6:9]),
                    gain=seq.K[last].copy(), P=seq.P_post[last].copy(),
                    n_transient=min(n, len(seq) - 1 if seq.converged else len(seq)), dt=dt, config=cfg,
                    gains=seq.K[np.minimum(np.arange(n), last)] if store_gains else None, path=seq.path)


def run_kf(rec: "Recording", config: KFConfig | None = None, *, store_gains: bool = False,
           method: Literal["auto", "block", "general"] = "auto") -> KFResult:
    """Run the paper's KF over a :class:`~danae_lite.data.recording.Recording`.

    ``dt`` is ``config.dt`` or, if that is ``None``, ``1 / rec.fs``; with
    ``config.init_from_truth`` the step-0 roll/pitch are ``rec.euler[0]`` (as the authors
    did). See :func:`kalman_filter` for the other arguments and :class:`KFResult` for the
    output.
    """
    cfg = config or KFConfig()
    dt = cfg.dt if cfg.dt is not None else rec.dt
    init = rec.euler[0] if cfg.init_from_truth else None
    return kalman_filter(rec.gyro, rec.acc, rec.mag, dt, cfg, init_euler=init, store_gains=store_gains, method=method)
