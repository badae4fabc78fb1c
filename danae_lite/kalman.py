r"""The paper's linear attitude Kalman filter, exactly as the authors built it.

State, inputs and measurements
------------------------------
The state holds the three Euler angles and a gyro-derived rate bias for each,

.. math::  x = [\phi,\ b_\phi,\ \theta,\ b_\theta,\ \psi,\ b_\psi]^T
           \qquad [\mathrm{rad},\ \mathrm{rad/s},\ \ldots]

and the model is the paper's eqs (1)-(2), :math:`x_t = A x_{t-1} + B u_{t-1} + v`,
:math:`y_t = C x_t + w`, with (``dt`` the step [s])

.. math::
   A = \begin{bmatrix} 1 & -dt \\ 0 & 1 \end{bmatrix}^{\oplus 3},\quad
   B = \begin{bmatrix} dt \\ 0 \end{bmatrix}^{\oplus 3},\quad
   C = \begin{bmatrix} 1 & 0 \end{bmatrix}^{\oplus 3}

(:math:`\oplus 3`: block-diagonal repetition for roll, pitch and yaw). So each angle is
integrated from its Euler rate minus its bias, and each angle is measured directly.

* Input ``u`` = Euler rates (:func:`euler_rates`) from the body gyro (p, q, r) [rad/s],
  evaluated at the **previous KF estimates** :math:`\hat\phi, \hat\theta`.
* Measurement ``y`` = ``[roll_acc, pitch_acc, psi_mag]`` [rad]: tilt from the
  accelerometer (:func:`accel_tilt`) and the tilt-compensated magnetic heading
  (:func:`mag_heading`), the latter again evaluated at the previous :math:`\hat\phi,
  \hat\theta`.

Recursion (paper eqs 3-7), once per sample ``t = 0 .. N-1`` starting from ``x0``, ``P0``:

.. math::
   x'_t = A x_{t-1} + B u_t,\qquad P'_t = A P_{t-1} A^T + Q,\qquad
   K_t = P'_t C^T (C P'_t C^T + R)^{-1},

   x_t = x'_t + K_t (y_t - C x'_t),\qquad P_t = (I - K_t C) P'_t.

Faithfulness notes (see the authors' ``kalman_gyraccmag.py``)
-------------------------------------------------------------
* Default covariances are the paper's *untuned* setting ``P0 = Q = I6``, ``R = I3``.
* The authors hard-coded ``dt = 0.1`` s for both datasets (OxIOD is really sampled at
  100 Hz, i.e. 0.01 s); :meth:`KFConfig.authors` reproduces that, the default
  :class:`KFConfig` uses the recording's true period ``1/fs``.
* ``x0 = 0``, but the authors seeded :math:`\hat\phi, \hat\theta` with the ground truth at
  sample 0 for the step-0 rate and heading formulas only (``init_from_truth=True``).
* **Typo in the authors' A**: its last row is ``[0, 0, 0, 0, 1, 0]`` instead of
  ``[0, 0, 0, 0, 0, 1]``, so their yaw bias is overwritten by the previous yaw,
  :math:`b_\psi \leftarrow \psi_{t-1}`. This module does *not* copy it: the filter always
  uses the correct ``A``. :func:`system_matrices` can return the typo'd matrix
  (``authors_typo=True``) for demonstration only.
* No angle is ever wrapped: neither the innovation nor the state, exactly as in the
  authors' code (``KFConfig(wrap_yaw_innovation=True)`` wraps the yaw innovation to
  [-pi, pi), a fix the paper's setting does not use). The yaw estimate is unbounded (it can leave [-pi, pi)); when the heading
  crosses +-pi the measurement jumps by 2 pi, the innovation ``psi_mag - psi'`` with it,
  and the yaw estimate and its bias go through a large transient.
* The authors' roll formula ``atan2(ay, sqrt(ax^2 + az^2))`` equals the true roll only at
  zero pitch: for a static pose it gives ``asin(sin(phi) cos(theta))``. Pitch is exact.

Speed
-----
``P``/``K`` do not depend on the data, so the gain sequence is computed first and stops as
soon as it has converged to machine precision (about 170 steps for the paper's identities
at dt = 0.1 s, about 1600 at dt = 0.01 s, more for a small ``Q``; cached per setting);
the data loop then runs with plain ``math`` scalars, using ``K_t`` during that transient
and the converged gain afterwards. When ``P0``, ``Q`` are
block-diagonal in the (angle, bias) pairs and ``R`` is diagonal (the default), the three
2-state blocks are filtered independently with 6 gains ("block" path); otherwise the full
6x3 gain is used ("general" path). Both give the result of the plain matrix recursion.
"""
from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field
from collections import OrderedDict
from collections.abc import Iterator
from itertools import chain, repeat
from typing import TYPE_CHECKING, Literal

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:  # pragma: no cover
    from .recording import Recording

__all__ = [
    "AUTHORS_DT",
    "GainSequence",
    "KFConfig",
    "KFResult",
    "KFStep",
    "SteadyState",
    "accel_tilt",
    "euler_rates",
    "gain_sequence",
    "kalman_filter",
    "kf_step",
    "mag_heading",
    "run_kf",
    "steady_state",
    "system_matrices",
]

AUTHORS_DT: float = 0.1
"""Time step [s] hard-coded in the authors' KF for both datasets."""

_BLOCKS = ((0, 1), (2, 3), (4, 5))
"""State indices (angle, bias) of the roll, pitch and yaw blocks."""
PI = math.pi
TWO_PI = 2.0 * math.pi

_REL_TOL = 4.0 * np.finfo(float).eps
"""Relative change below which the gain/covariance recursion counts as converged."""


# --------------------------------------------------------------------------------------
# Measurement and input helpers (vectorised)
# --------------------------------------------------------------------------------------
def accel_tilt(acc: ArrayLike) -> NDArray[np.float64]:
    r"""Roll and pitch from the accelerometer, the authors' formulas.

    .. math::
       \phi_{acc} = \operatorname{atan2}\!\left(a_y, \sqrt{a_x^2 + a_z^2}\right),\qquad
       \theta_{acc} = \operatorname{atan2}\!\left(-a_x, \sqrt{a_y^2 + a_z^2}\right)

    Parameters
    ----------
    acc : array_like, shape (N, 3) or (3,)
        Accelerometer in the body frame [g] (any unit works: only ratios matter), tilt
        convention: at rest ``acc = R^T [0, 0, 1]``.

    Returns
    -------
    ndarray, shape (N, 2)
        ``(roll_acc, pitch_acc)`` [rad]. For a static pose with roll ``phi`` and pitch
        ``theta`` this is ``(asin(sin(phi) cos(theta)), theta)``: roll is exact only at
        zero pitch (the formula is the authors', kept as is).
    """
    a = np.atleast_2d(np.asarray(acc, dtype=float))
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"acc must have shape (N, 3), got {np.shape(acc)}")
    ax, ay, az = a[:, 0], a[:, 1], a[:, 2]
    roll = np.arctan2(ay, np.sqrt(ax * ax + az * az))
    pitch = np.arctan2(-ax, np.sqrt(ay * ay + az * az))
    return np.column_stack((roll, pitch))


def mag_heading(mag: ArrayLike, roll: ArrayLike, pitch: ArrayLike) -> NDArray[np.float64]:
    r"""Tilt-compensated magnetic heading, the authors' formula.

    With :math:`m` normalised to unit norm (no hard/soft-iron calibration),

    .. math::
       \psi_{mag} = \operatorname{atan2}\!\big(-m_y\cos\phi + m_z\sin\phi,\;
       m_x\cos\theta + m_y\sin\theta\sin\phi + m_z\sin\theta\cos\phi\big).

    This de-rotates ``m`` by roll and pitch into the horizontal plane and reads the
    heading there; in a reference frame with x north, y west, z up (field
    ``(B cos I, 0, -B sin I)``) it returns the intrinsic-ZYX yaw exactly when ``roll`` and
    ``pitch`` are the true ones.

    Parameters
    ----------
    mag : array_like, shape (N, 3)
        Magnetic field in the body frame [µT] (only the direction is used).
    roll, pitch : array_like, shape (N,) or scalar
        Roll and pitch [rad] used for the tilt compensation (the KF uses its previous
        estimates).

    Returns
    -------
    ndarray, shape (N,)
        Heading [rad] in (-pi, pi].
    """
    m = np.atleast_2d(np.asarray(mag, dtype=float))
    if m.ndim != 2 or m.shape[1] != 3:
        raise ValueError(f"mag must have shape (N, 3), got {np.shape(mag)}")
    m = _unit_rows(m, "mag")
    sf, cf = np.sin(roll), np.cos(roll)
    sh, ch = np.sin(pitch), np.cos(pitch)
    mx, my, mz = m[:, 0], m[:, 1], m[:, 2]
    return np.arctan2(-my * cf + mz * sf, mx * ch + my * sh * sf + mz * sh * cf)


def euler_rates(gyro: ArrayLike, roll: ArrayLike, pitch: ArrayLike) -> NDArray[np.float64]:
    r"""Euler-angle rates from body angular rates (intrinsic ZYX kinematics).

    .. math::
       \dot\phi = p + \sin\phi\tan\theta\, q + \cos\phi\tan\theta\, r,\quad
       \dot\theta = \cos\phi\, q - \sin\phi\, r,\quad
       \dot\psi = \frac{\sin\phi}{\cos\theta} q + \frac{\cos\phi}{\cos\theta} r

    Parameters
    ----------
    gyro : array_like, shape (N, 3)
        Body angular rates (p, q, r) [rad/s].
    roll, pitch : array_like, shape (N,) or scalar
        Roll and pitch [rad] at which the kinematics are evaluated.

    Returns
    -------
    ndarray, shape (N, 3)
        :math:`(\dot\phi, \dot\theta, \dot\psi)` [rad/s]. Singular at pitch = +-pi/2.
    """
    g = np.atleast_2d(np.asarray(gyro, dtype=float))
    if g.ndim != 2 or g.shape[1] != 3:
        raise ValueError(f"gyro must have shape (N, 3), got {np.shape(gyro)}")
    p, q, r = g[:, 0], g[:, 1], g[:, 2]
    sf, cf = np.sin(roll), np.cos(roll)
    ch, th = np.cos(pitch), np.tan(pitch)
    return np.column_stack((p + sf * th * q + cf * th * r, cf * q - sf * r, sf / ch * q + cf / ch * r))


def _unit_rows(m: NDArray[np.float64], name: str) -> NDArray[np.float64]:
    norm = np.sqrt(np.einsum("ij,ij->i", m, m))
    bad = ~(norm > 0) | ~np.isfinite(norm)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{name} row {i} is {m[i].tolist()}: cannot normalise a zero/non-finite vector")
    return m / norm[:, None]


# --------------------------------------------------------------------------------------
# Model matrices and configuration
# --------------------------------------------------------------------------------------
def system_matrices(
    dt: float, authors_typo: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return ``(A, B, C)`` of the paper's model for step ``dt`` [s].

    ``A`` (6x6) is the identity with ``A[0,1] = A[2,3] = A[4,5] = -dt``; ``B`` (6x3) has
    ``B[0,0] = B[2,1] = B[4,2] = dt``; ``C`` (3x6) selects states 0, 2, 4.

    ``authors_typo=True`` returns the authors' ``A`` whose last row is
    ``[0, 0, 0, 0, 1, 0]`` (so ``b_psi <- psi(t-1)``). It exists only to show the typo;
    :func:`kalman_filter` never uses it.
    """
    _check_dt(dt)
    A = np.eye(6)
    B = np.zeros((6, 3))
    C = np.zeros((3, 6))
    for j, (a, b) in enumerate(_BLOCKS):
        A[a, b] = -dt
        B[a, j] = dt
        C[j, a] = 1.0
    if authors_typo:
        A[5] = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    return A, B, C


def _check_dt(dt: float) -> None:
    if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive finite number of seconds, got {dt!r}")


def _as_cov(value: ArrayLike, n: int, name: str, definite: bool) -> NDArray[np.float64]:
    """Scalar -> value*I, 1-D -> diag, 2-D -> as is; check shape, symmetry, (semi)definiteness."""
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = float(a) * np.eye(n)
    elif a.ndim == 1:
        if a.shape != (n,):
            raise ValueError(f"{name}: a diagonal must have {n} entries, got shape {a.shape}")
        a = np.diag(a)
    if a.shape != (n, n):
        raise ValueError(f"{name} must be a {n}x{n} matrix (or a scalar / {n} diagonal entries), got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} contains non-finite entries")
    scale = max(1.0, float(np.abs(a).max()))
    if not np.allclose(a, a.T, rtol=0.0, atol=1e-12 * scale):
        raise ValueError(f"{name} must be symmetric (max |{name} - {name}^T| = {np.abs(a - a.T).max():.3g})")
    w = np.linalg.eigvalsh(0.5 * (a + a.T))
    if definite and w.min() <= 0:
        raise ValueError(f"{name} must be positive definite (smallest eigenvalue {w.min():.3g})")
    if w.min() < -1e-12 * scale:
        raise ValueError(f"{name} must be positive semi-definite (smallest eigenvalue {w.min():.3g})")
    a = a.copy()
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class KFConfig:
    """Settings of the attitude KF. The defaults are the paper's untuned setting.

    Parameters
    ----------
    P0 : array_like (6, 6), default identity
        Initial a-posteriori covariance of ``x0`` [rad², (rad/s)², mixed off-diagonal].
    Q : array_like (6, 6), default identity
        Process-noise covariance *per step*: variance added to the angle [rad²] and to the
        bias [(rad/s)²] at each prediction. Identity = 1 rad std of angle error added
        every step: no trust in the gyro at all.
    R : array_like (3, 3), default identity
        Measurement-noise covariance of ``(roll_acc, pitch_acc, psi_mag)`` [rad²]. Identity
        = 1 rad (57°) std per measurement; must be positive definite.
    dt : float or None
        Step [s]; ``None`` uses ``1/fs`` of the recording. The authors used 0.1 s for both
        datasets: see :meth:`authors`.
    x0 : array_like (6,), default zeros
        Initial state ``[phi, b_phi, theta, b_theta, psi, b_psi]`` [rad, rad/s, ...].
    init_from_truth : bool, default True
        As in the authors' code: the previous-estimate roll/pitch used by the step-0 rate
        and heading formulas are the ground truth at sample 0, while the state itself
        starts at ``x0``. ``False`` uses ``x0``'s roll and pitch instead.
    wrap_yaw_innovation : bool, default False
        Wrap the yaw innovation ``psi_mag - psi'`` to [-pi, pi) before the update, so that a
        heading crossing +-pi (a 2 pi jump of the measurement) is a small innovation, not a
        2 pi one. The state stays continuous (unwrapped). ``False`` is the paper's filter.

    Covariances may be given as a scalar (times identity) or as the diagonal entries.
    """

    P0: NDArray[np.float64] = field(default_factory=lambda: np.eye(6))
    Q: NDArray[np.float64] = field(default_factory=lambda: np.eye(6))
    R: NDArray[np.float64] = field(default_factory=lambda: np.eye(3))
    dt: float | None = None
    x0: NDArray[np.float64] = field(default_factory=lambda: np.zeros(6))
    init_from_truth: bool = True
    wrap_yaw_innovation: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "P0", _as_cov(self.P0, 6, "P0", definite=False))
        object.__setattr__(self, "Q", _as_cov(self.Q, 6, "Q", definite=False))
        object.__setattr__(self, "R", _as_cov(self.R, 3, "R", definite=True))
        if self.dt is not None:
            _check_dt(self.dt)
            object.__setattr__(self, "dt", float(self.dt))
        x0 = np.asarray(self.x0, dtype=float)
        if x0.shape != (6,) or not np.isfinite(x0).all():
            raise ValueError(f"x0 must be 6 finite numbers [phi, b_phi, theta, b_theta, psi, b_psi], got {x0!r}")
        x0 = x0.copy()
        x0.setflags(write=False)
        object.__setattr__(self, "x0", x0)

    @classmethod
    def authors(cls, **overrides: object) -> "KFConfig":
        """The authors' exact setting: ``P0 = Q = I6``, ``R = I3``, ``x0 = 0``, ``dt = 0.1`` s
        for every dataset, roll/pitch seeded from the ground truth. Keyword arguments
        override single fields."""
        kwargs: dict[str, object] = {"dt": AUTHORS_DT}
        kwargs.update(overrides)
        return cls(**kwargs)  # type: ignore[arg-type]

    @property
    def block_diagonal(self) -> bool:
        """True when ``P0``, ``Q`` are block-diagonal in the (angle, bias) pairs and ``R``
        is diagonal, so the three angles are filtered independently."""
        mask = np.zeros((6, 6), dtype=bool)
        for a, b in _BLOCKS:
            mask[a : b + 1, a : b + 1] = True
        return bool(
            not self.P0[~mask].any() and not self.Q[~mask].any() and not (self.R - np.diag(np.diag(self.R))).any()
        )

    def __repr__(self) -> str:
        def short(m: NDArray[np.float64]) -> str:
            if np.array_equal(m, m[0, 0] * np.eye(len(m))):
                return f"{m[0, 0]:g}*I{len(m)}"
            if not (m - np.diag(np.diag(m))).any():
                return "diag(" + ", ".join(f"{v:g}" for v in np.diag(m)) + ")"
            return f"<{m.shape[0]}x{m.shape[1]} matrix>"

        return (
            f"KFConfig(P0={short(self.P0)}, Q={short(self.Q)}, R={short(self.R)}, dt={self.dt}, "
            f"x0={self.x0.tolist()}, init_from_truth={self.init_from_truth}"
            + (", wrap_yaw_innovation=True)" if self.wrap_yaw_innovation else ")")
        )


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


def kf_step(
    x: ArrayLike,
    P: ArrayLike,
    u: ArrayLike,
    y: ArrayLike,
    A: ArrayLike,
    B: ArrayLike,
    C: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
) -> KFStep:
    """One textbook step of the linear KF, eqs (3)-(7), with every intermediate kept.

    Works for any dimensions: ``x`` (n,), ``P``/``Q`` (n, n), ``u`` (m,), ``B`` (n, m),
    ``y`` (k,), ``C`` (k, n), ``R`` (k, k). Meant for teaching and checking by hand;
    :func:`kalman_filter` is the fast implementation of the same equations.
    """
    x, P, u, y = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (x, P, u, y))
    A, B, C, Q, R = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (A, B, C, Q, R))
    P = np.atleast_2d(P)
    x_prior = A @ x + B @ u
    P_prior = A @ P @ A.T + Q
    S = C @ P_prior @ C.T + R
    K = P_prior @ C.T @ np.linalg.inv(S)
    innovation = y - C @ x_prior
    x_new = x_prior + K @ innovation
    P_new = (np.eye(len(x)) - K @ C) @ P_prior
    return KFStep(x_prior=x_prior, P_prior=P_prior, S=S, K=K, innovation=innovation, x=x_new, P=P_new)


# --------------------------------------------------------------------------------------
# Gain sequence and steady state
# --------------------------------------------------------------------------------------
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
    """

    K: NDArray[np.float64]
    P_post: NDArray[np.float64]
    converged: bool

    def __len__(self) -> int:
        return int(self.K.shape[0])


def _block_gains(
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
        if (
            max(abs(n0 - k0), abs(n1 - k1)) <= tol * max(abs(n0), abs(n1))
            and max(abs(p00 - o00), abs(p01 - o01), abs(p11 - o11)) <= tol * max(abs(p00), abs(p01), abs(p11))
        ):
            return ks, ps, True
        k0, k1 = n0, n1
    return ks, ps, False


def _block_gains_cached(block: tuple[float, ...], dt: float, n_max: int
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """:func:`_block_gains` of ``block`` = (p00, p01, p11, q00, q01, q11, r) as read-only arrays
    (K: (m, 2), P: (m, 3)), remembered for the last :data:`_BLOCK_CACHE_SIZE` blocks.

    A tuning grid repeats blocks: the roll and pitch blocks of every setting share their
    (angle, bias) variances, and every fold of a cross-validation runs the same grid. A
    remembered run serves any ``n_max`` it answers exactly: a run that converged within
    ``n_max`` steps, or the first ``n_max`` steps of a longer one (not converged within them).
    """
    key = (*block, float(dt))
    hit = _BLOCK_CACHE.get(key)
    if hit is not None:
        K, P, converged = hit
        if converged and len(K) <= n_max:
            _BLOCK_CACHE.move_to_end(key)
            return hit
        if len(K) >= n_max:
            _BLOCK_CACHE.move_to_end(key)
            return K[:n_max], P[:n_max], False
    ks, ps, converged = _block_gains(*block, dt, n_max)
    K, P = np.asarray(ks), np.asarray(ps)
    K.setflags(write=False)
    P.setflags(write=False)
    _BLOCK_CACHE[key] = (K, P, converged)
    while len(_BLOCK_CACHE) > _BLOCK_CACHE_SIZE:
        _BLOCK_CACHE.popitem(last=False)
    return K, P, converged


_BLOCK_CACHE: "OrderedDict[tuple[float, ...], tuple[NDArray[np.float64], NDArray[np.float64], bool]]" = OrderedDict()
_BLOCK_CACHE_SIZE = 128
"""Blocks remembered by :func:`_block_gains_cached` (each at most 40 bytes per step)."""


def _block_gain_sequence(
    dt: float, P0: NDArray[np.float64], Q: NDArray[np.float64], R: NDArray[np.float64], n_max: int
) -> GainSequence:
    """The three decoupled blocks, each iterated until it converges, then padded."""
    per_block = [
        _block_gains_cached(tuple(map(float, (P0[a, a], P0[a, b], P0[b, b], Q[a, a], Q[a, b], Q[b, b], R[j, j]))),
                            dt, n_max)
        for j, (a, b) in enumerate(_BLOCKS)
    ]
    m = max(len(ks) for ks, _, _ in per_block)
    K = np.zeros((m, 6, 3))
    P = np.zeros((m, 6, 6))
    for j, ((a, b), (ks, ps, _)) in enumerate(zip(_BLOCKS, per_block)):
        kk = np.asarray(ks)
        pp = np.asarray(ps)
        n = len(kk)
        K[:n, a, j], K[:n, b, j] = kk[:, 0], kk[:, 1]
        K[n:, a, j], K[n:, b, j] = kk[-1, 0], kk[-1, 1]
        P[:n, a, a], P[:n, a, b], P[:n, b, b] = pp[:, 0], pp[:, 1], pp[:, 2]
        P[n:, a, a], P[n:, a, b], P[n:, b, b] = pp[-1, 0], pp[-1, 1], pp[-1, 2]
        P[:, b, a] = P[:, a, b]
    return GainSequence(K=K, P_post=P, converged=all(c for _, _, c in per_block))


def _general_gain_sequence(
    dt: float, P0: NDArray[np.float64], Q: NDArray[np.float64], R: NDArray[np.float64], n_max: int
) -> GainSequence:
    """Plain 6x6 matrix recursion of eqs 4, 5, 7 (same stopping rule)."""
    A, _, C = system_matrices(dt)
    P = np.array(P0, dtype=float)
    Ks: list[NDArray[np.float64]] = []
    Ps: list[NDArray[np.float64]] = []
    K_old = np.full((6, 3), np.nan)
    converged = False
    for _ in range(n_max):
        Pp = A @ P @ A.T + Q
        PCt = Pp[:, 0::2]  # P' C^T: C selects states 0, 2, 4
        K = PCt @ np.linalg.inv(PCt[0::2] + R)  # P' C^T (C P' C^T + R)^-1
        P_old = P
        P = Pp - K @ Pp[0::2]  # (I - K C) P' = P' - K (C P')
        Ks.append(K)
        Ps.append(P)
        if np.abs(K - K_old).max() <= _REL_TOL * np.abs(K).max() and np.abs(P - P_old).max() <= _REL_TOL * np.abs(
            P
        ).max():
            converged = True
            break
        K_old = K
    return GainSequence(K=np.asarray(Ks), P_post=np.asarray(Ps), converged=converged)


def gain_sequence(
    dt: float,
    config: KFConfig | None = None,
    n_max: int = 100_000,
    method: Literal["auto", "block", "general"] = "auto",
) -> GainSequence:
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
        that trusts the gyro) converges slowly: thousands of steps. Results are cached
        (read-only arrays) for the last few settings.
    """
    _check_dt(dt)
    cfg = config or KFConfig()
    if n_max < 1:
        raise ValueError(f"n_max must be >= 1, got {n_max}")
    block = _resolve_method(cfg, method)
    key = (block, float(dt), cfg.P0.tobytes(), cfg.Q.tobytes(), cfg.R.tobytes())
    hit = _GAIN_CACHE.get(key)
    if hit is not None and (hit.converged or len(hit) >= n_max):
        _GAIN_CACHE.move_to_end(key)
        if len(hit) <= n_max:
            return hit
        return GainSequence(K=hit.K[:n_max], P_post=hit.P_post[:n_max], converged=False)
    fn = _block_gain_sequence if block else _general_gain_sequence
    seq = fn(float(dt), cfg.P0, cfg.Q, cfg.R, int(n_max))
    seq.K.setflags(write=False)
    seq.P_post.setflags(write=False)
    _GAIN_CACHE[key] = seq
    while len(_GAIN_CACHE) > _GAIN_CACHE_SIZE:
        _GAIN_CACHE.popitem(last=False)
    return seq


_GAIN_CACHE: "OrderedDict[tuple[object, ...], GainSequence]" = OrderedDict()
_GAIN_CACHE_SIZE = 8


def _resolve_method(cfg: KFConfig, method: str) -> bool:
    if method not in ("auto", "block", "general"):
        raise ValueError(f"method must be 'auto', 'block' or 'general', got {method!r}")
    if method == "block" and not cfg.block_diagonal:
        raise ValueError("method='block' needs block-diagonal P0, Q and a diagonal R")
    return method == "block" or (method == "auto" and cfg.block_diagonal)


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
        ``"block"`` or ``"general"`` (which implementation ran).
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
        out = np.empty((len(self.euler), 6))
        out[:, 0::2] = self.euler
        out[:, 1::2] = self.bias
        return out

    def __len__(self) -> int:
        return int(self.euler.shape[0])


def _block_loop(
    rows: Iterator[tuple[float, ...]],
    gains: Iterator[tuple[float, ...]],
    st: list[float],
    dt: float,
    wrap_yaw: bool = False,
) -> tuple[array, ...]:
    """The data loop for the three decoupled 2-state blocks, plain ``math`` scalars.

    ``st`` = [phi, b_phi, theta, b_theta, psi, b_psi, phi_hat, theta_hat] (initial state and
    the roll/pitch used by the first step's rate and heading formulas); ``gains`` yields
    (K00, K10, K21, K31, K42, K52) per step; ``rows`` yields (p, q, r, roll_acc, pitch_acc,
    mx, my, mz) with m of unit norm. Returns arrays of phi, b_phi, theta, b_theta, psi,
    b_psi, u0, u1, u2, psi_mag. ``wrap_yaw`` wraps the yaw innovation to [-pi, pi).
    """
    sin, cos, atan2 = math.sin, math.cos, math.atan2
    f, bf, h, bh, s, bs, pf, ph = st
    out = tuple(array("d") for _ in range(10))
    o_f, o_bf, o_h, o_bh, o_s, o_bs, o_u0, o_u1, o_u2, o_ym = (a.append for a in out)
    for (p, q, r, ya, yb, mx, my, mz), (kf0, kf1, kh0, kh1, ks0, ks1) in zip(rows, gains):
        sf = sin(pf)
        cf = cos(pf)
        sh = sin(ph)
        ch = cos(ph)
        # inputs: Euler rates at the previous estimates (w = sin(phi) q + cos(phi) r)
        w = sf * q + cf * r
        u0 = p + sh * w / ch
        u1 = cf * q - sf * r
        u2 = w / ch
        # tilt-compensated heading at the previous estimates
        ym = atan2(mz * sf - my * cf, mx * ch + sh * (my * sf + mz * cf))
        # predict x' = A x + B u (bias unchanged) and update x = x' + K (y - C x'), per block
        f = f - dt * bf + dt * u0
        e = ya - f
        f += kf0 * e
        bf += kf1 * e
        h = h - dt * bh + dt * u1
        e = yb - h
        h += kh0 * e
        bh += kh1 * e
        s = s - dt * bs + dt * u2
        e = ym - s
        if wrap_yaw:
            e = (e + PI) % TWO_PI - PI
        s += ks0 * e
        bs += ks1 * e
        pf = f
        ph = h
        o_f(f)
        o_bf(bf)
        o_h(h)
        o_bh(bh)
        o_s(s)
        o_bs(bs)
        o_u0(u0)
        o_u1(u1)
        o_u2(u2)
        o_ym(ym)
    return out


def _general_loop(
    rows: Iterator[tuple[float, ...]],
    gains: Iterator[tuple[float, ...]],
    st: list[float],
    dt: float,
    wrap_yaw: bool = False,
) -> tuple[array, ...]:
    """As :func:`_block_loop` with a full 6x3 gain per step (row-major, 18 numbers).

    Its first lines (inputs and heading at the previous estimates) repeat :func:`_block_loop`'s
    on purpose: both are hot loops of plain scalars, where a helper call per sample would cost
    a third of the loop's time.
    """
    sin, cos, atan2 = math.sin, math.cos, math.atan2
    x0, x1, x2, x3, x4, x5, pf, ph = st
    out = tuple(array("d") for _ in range(10))
    o_f, o_bf, o_h, o_bh, o_s, o_bs, o_u0, o_u1, o_u2, o_ym = (a.append for a in out)
    for (p, q, r, ya, yb, mx, my, mz), k in zip(rows, gains):
        (k00, k01, k02, k10, k11, k12, k20, k21, k22, k30, k31, k32, k40, k41, k42, k50, k51, k52) = k
        sf = sin(pf)
        cf = cos(pf)
        sh = sin(ph)
        ch = cos(ph)
        w = sf * q + cf * r
        u0 = p + sh * w / ch
        u1 = cf * q - sf * r
        u2 = w / ch
        ym = atan2(mz * sf - my * cf, mx * ch + sh * (my * sf + mz * cf))
        x0 = x0 - dt * x1 + dt * u0
        x2 = x2 - dt * x3 + dt * u1
        x4 = x4 - dt * x5 + dt * u2
        e0 = ya - x0
        e1 = yb - x2
        e2 = ym - x4
        if wrap_yaw:
            e2 = (e2 + PI) % TWO_PI - PI
        x0, x1, x2, x3, x4, x5 = (
            x0 + (k00 * e0 + k01 * e1 + k02 * e2),
            x1 + (k10 * e0 + k11 * e1 + k12 * e2),
            x2 + (k20 * e0 + k21 * e1 + k22 * e2),
            x3 + (k30 * e0 + k31 * e1 + k32 * e2),
            x4 + (k40 * e0 + k41 * e1 + k42 * e2),
            x5 + (k50 * e0 + k51 * e1 + k52 * e2),
        )
        pf = x0
        ph = x2
        o_f(x0)
        o_bf(x1)
        o_h(x2)
        o_bh(x3)
        o_s(x4)
        o_bs(x5)
        o_u0(u0)
        o_u1(u1)
        o_u2(u2)
        o_ym(ym)
    return out


def _step(dt: float | None, cfg: KFConfig) -> float:
    """The step [s]: ``dt``, else ``cfg.dt``; ValueError when neither is given or they disagree."""
    if dt is None:
        if cfg.dt is None:
            raise ValueError("dt is not given and config.dt is None: pass the step in seconds")
        dt = cfg.dt
    _check_dt(dt)
    dt = float(dt)
    if cfg.dt is not None and cfg.dt != dt:
        raise ValueError(f"dt={dt} disagrees with config.dt={cfg.dt}")
    return dt


def _sensor_arrays(**named: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """The sensor arrays as finite (N, 3) floats with one N (> 0); ValueError naming the array,
    and the first bad row, otherwise."""
    arrays = {}
    n = None
    for name, value in named.items():
        a = np.asarray(value, dtype=float)
        if a.ndim != 2 or a.shape[1] != 3:
            raise ValueError(f"{name} must have shape (N, 3), got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"{name} contains non-finite values (first at row {int(np.argmax(~np.isfinite(a).all(1)))})")
        n = a.shape[0] if n is None else n
        if a.shape[0] != n:
            raise ValueError(f"{name} has {a.shape[0]} rows, gyro has {n}")
        arrays[name] = a
    if not n:
        raise ValueError("no samples")
    return arrays


def _initial_tilt(init_euler: ArrayLike | None, cfg: KFConfig) -> tuple[float, float]:
    """Roll and pitch [rad] of the step-0 formulas: ``init_euler``'s, else ``cfg.x0``'s."""
    if init_euler is None:
        return float(cfg.x0[0]), float(cfg.x0[2])
    ie = np.asarray(init_euler, dtype=float).ravel()
    if ie.size not in (2, 3) or not np.isfinite(ie).all():
        raise ValueError(f"init_euler must be (roll, pitch[, yaw]) in rad, got {init_euler!r}")
    return float(ie[0]), float(ie[1])


def kalman_filter(
    gyro: ArrayLike,
    acc: ArrayLike,
    mag: ArrayLike,
    dt: float | None = None,
    config: KFConfig | None = None,
    init_euler: ArrayLike | None = None,
    *,
    store_gains: bool = False,
    method: Literal["auto", "block", "general"] = "auto",
) -> KFResult:
    """Run the paper's KF (eqs 3-7) over raw sensor arrays.

    Parameters
    ----------
    gyro : array_like (N, 3)
        Body angular rates (p, q, r) [rad/s].
    acc : array_like (N, 3)
        Accelerometer [g], tilt convention (see :func:`accel_tilt`).
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
        Implementation; ``"auto"`` uses the decoupled block loop when the configuration
        is block-diagonal. All give the same numbers.

    Returns
    -------
    KFResult
    """
    cfg = config or KFConfig()
    dt = _step(dt, cfg)
    arrays = _sensor_arrays(gyro=gyro, acc=acc, mag=mag)
    n = len(arrays["gyro"])
    pf0, ph0 = _initial_tilt(init_euler, cfg)

    block = _resolve_method(cfg, method)
    seq = gain_sequence(dt, cfg, n_max=n, method="block" if block else "general")

    tilt = accel_tilt(arrays["acc"])
    mu = _unit_rows(arrays["mag"], "mag")
    g = arrays["gyro"]
    cols = [g[:, 0], g[:, 1], g[:, 2], tilt[:, 0], tilt[:, 1], mu[:, 0], mu[:, 1], mu[:, 2]]
    rows = zip(*(c.tolist() for c in cols))
    st = [*map(float, cfg.x0), pf0, ph0]

    # gains: K_t during the transient, then the converged gain for every later step
    m = min(n, len(seq))
    if block:
        picked = seq.K[:m, [0, 1, 2, 3, 4, 5], [0, 0, 1, 1, 2, 2]]
        loop = _block_loop
    else:
        picked = seq.K[:m].reshape(m, 18)
        loop = _general_loop
    gains = chain(map(tuple, picked.tolist()), repeat(tuple(picked[-1].tolist())))
    out = loop(rows, gains, st, dt, cfg.wrap_yaw_innovation)

    res = [np.frombuffer(a, dtype=float) for a in out]
    euler = np.column_stack((res[0], res[2], res[4]))
    bias = np.column_stack((res[1], res[3], res[5]))
    rates = np.column_stack(res[6:9])
    meas = np.column_stack((tilt[:, 0], tilt[:, 1], res[9]))
    last = m - 1
    n_tr = min(n, len(seq) - 1 if seq.converged else len(seq))
    stored = None
    if store_gains:
        stored = np.empty((n, 6, 3))
        stored[:m] = seq.K[:m]
        stored[m:] = seq.K[m - 1]
    return KFResult(
        euler=euler,
        bias=bias,
        measurements=meas,
        rates=rates,
        gain=seq.K[last].copy(),
        P=seq.P_post[last].copy(),
        n_transient=n_tr,
        dt=dt,
        config=cfg,
        gains=stored,
        path="block" if block else "general",
    )


def run_kf(
    rec: "Recording",
    config: KFConfig | None = None,
    *,
    store_gains: bool = False,
    method: Literal["auto", "block", "general"] = "auto",
) -> KFResult:
    """Run the paper's KF over a :class:`~danae_lite.recording.Recording`.

    ``dt`` is ``config.dt`` or, if that is ``None``, ``1 / rec.fs``; with
    ``config.init_from_truth`` the step-0 roll/pitch are ``rec.euler[0]`` (as the authors
    did). See :func:`kalman_filter` for the other arguments and :class:`KFResult` for the
    output.
    """
    cfg = config or KFConfig()
    dt = cfg.dt if cfg.dt is not None else rec.dt
    init = rec.euler[0] if cfg.init_from_truth else None
    return kalman_filter(
        rec.gyro, rec.acc, rec.mag, dt, cfg, init_euler=init, store_gains=store_gains, method=method
    )
