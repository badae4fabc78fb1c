r"""The paper's attitude model: state, inputs, measurements and settings of its Kalman filter
(the filter itself is :mod:`danae_lite.kalman.filter`, its gains :mod:`danae_lite.kalman.gains`).

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
  [-pi, pi), a fix the paper's setting does not use). The yaw estimate is unbounded (it can
  leave [-pi, pi)); when the heading crosses +-pi the measurement jumps by 2 pi, the
  innovation ``psi_mag - psi'`` with it, and the yaw estimate and its bias go through a large
  transient.
* The authors' roll formula ``atan2(ay, sqrt(ax^2 + az^2))`` equals the true roll only at
  zero pitch: for a static pose it gives ``asin(sin(phi) cos(theta))``. Pitch is exact.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["AUTHORS_DT", "BLOCKS", "KFConfig", "accel_tilt", "euler_rates", "mag_heading", "system_matrices"]

AUTHORS_DT: float = 0.1
"""Time step [s] hard-coded in the authors' KF for both datasets."""

BLOCKS = ((0, 1), (2, 3), (4, 5))
"""State indices (angle, bias) of the roll, pitch and yaw blocks."""


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
    ax, ay, az = _rows_of_3(acc, "acc").T
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
    mx, my, mz = unit_rows(_rows_of_3(mag, "mag"), "mag").T
    sf, cf = np.sin(roll), np.cos(roll)
    sh, ch = np.sin(pitch), np.cos(pitch)
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
    p, q, r = _rows_of_3(gyro, "gyro").T
    sf, cf = np.sin(roll), np.cos(roll)
    ch, th = np.cos(pitch), np.tan(pitch)
    return np.column_stack((p + sf * th * q + cf * th * r, cf * q - sf * r, sf / ch * q + cf / ch * r))


def _rows_of_3(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as float rows of 3 (a single (3,) vector is one row); ValueError naming ``name`` otherwise."""
    a = np.atleast_2d(np.asarray(value, dtype=float))
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {np.shape(value)}")
    return a


def unit_rows(m: NDArray[np.float64], name: str) -> NDArray[np.float64]:
    """The rows of ``m`` scaled to unit norm; ValueError naming ``name`` and the row when one is zero
    or not finite."""
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
    :func:`~danae_lite.kalman.filter.kalman_filter` never uses it.
    """
    check_dt(dt)
    A = np.eye(6)
    B = np.zeros((6, 3))
    C = np.zeros((3, 6))
    for j, (a, b) in enumerate(BLOCKS):
        A[a, b] = -dt
        B[a, j] = dt
        C[j, a] = 1.0
    if authors_typo:
        A[5] = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    return A, B, C


def check_dt(dt: float) -> None:
    """ValueError unless ``dt`` is a positive finite number of seconds."""
    if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive finite number of seconds, got {dt!r}")


def _as_cov(value: ArrayLike, n: int, name: str, definite: bool) -> NDArray[np.float64]:
    """Scalar -> value*I, 1-D -> diag, 2-D -> as is; check shape, symmetry, (semi)definiteness."""
    a = np.array(value, dtype=float)  # a copy, made read-only below
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
            check_dt(self.dt)
            object.__setattr__(self, "dt", float(self.dt))
        x0 = np.array(self.x0, dtype=float)
        if x0.shape != (6,) or not np.isfinite(x0).all():
            raise ValueError(f"x0 must be 6 finite numbers [phi, b_phi, theta, b_theta, psi, b_psi], got {x0!r}")
        x0.setflags(write=False)
        object.__setattr__(self, "x0", x0)

    @classmethod
    def authors(cls, **overrides: object) -> "KFConfig":
        """The authors' exact setting: ``P0 = Q = I6``, ``R = I3``, ``x0 = 0``, ``dt = 0.1`` s
        for every dataset, roll/pitch seeded from the ground truth. Keyword arguments
        override single fields."""
        return cls(**{"dt": AUTHORS_DT, **overrides})  # type: ignore[arg-type]

    @property
    def block_diagonal(self) -> bool:
        """True when ``P0``, ``Q`` are block-diagonal in the (angle, bias) pairs and ``R``
        is diagonal, so the three angles are filtered independently."""
        outside = ~np.kron(np.eye(3, dtype=bool), np.ones((2, 2), dtype=bool))  # off the three 2x2 blocks
        return not (self.P0[outside].any() or self.Q[outside].any() or self.R[~np.eye(3, dtype=bool)].any())

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
