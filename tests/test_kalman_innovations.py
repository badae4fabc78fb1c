"""kf_offline.innovations (innovations of a finished run of the paper's KF) checked against independent references.

(a) a plain numpy loop of eqs 3-7 written here, on a short simulator recording (block and
general paths, yaw innovation wrapped or not); (b) the steady-state innovation covariance
``S = C P' C^T + R`` with ``P'`` from scipy's discrete algebraic Riccati equation; (c) the
chi-square property of the NIS on a linear-Gaussian system whose Q and R are the true ones,
and its failure when R is wrong.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
from scipy import stats

from danae_lite.kalman.filter import KFResult, run_kf
from danae_lite.kalman.gains import gain_sequence
from danae_lite.kalman.model import KFConfig, system_matrices
from danae_lite.kalman.offline import Innovations, innovations
from danae_lite.data.simulate import simulate

TUNED = dict(
    P0=np.diag([0.5, 0.01, 0.4, 0.02, 1.0, 0.03]),
    Q=np.diag([1e-4, 1e-7, 2e-4, 1e-7, 1e-3, 1e-6]),
    R=np.diag([0.01, 0.02, 0.05]),
)
_Qc = np.diag([1e-3, 1e-5, 2e-3, 1e-5, 1e-2, 1e-4])
_Qc[0, 2] = _Qc[2, 0] = 5e-4  # roll/pitch process noise correlated: the general path
_Rc = np.array([[0.02, 0.005, 0.0], [0.005, 0.03, 0.001], [0.0, 0.001, 0.1]])
COUPLED = dict(P0=np.eye(6), Q=_Qc, R=_Rc)


def plain_loop(rec, cfg):
    """Eqs 3-7 one step at a time with 6x6 matrices: innovations, S and the states."""
    dt = rec.dt
    A = np.eye(6)
    A[0, 1] = A[2, 3] = A[4, 5] = -dt
    B = np.zeros((6, 3))
    B[0, 0] = B[2, 1] = B[4, 2] = dt
    C = np.zeros((3, 6))
    C[0, 0] = C[1, 2] = C[2, 4] = 1.0
    x, P = np.array(cfg.x0, dtype=float), np.array(cfg.P0, dtype=float)
    phi, theta = rec.euler[0, 0], rec.euler[0, 1]  # init_from_truth, as the authors
    nus, Ss, xs = [], [], []
    for t in range(len(rec)):
        p, q, r = rec.gyro[t]
        sf, cf, th, ch = math.sin(phi), math.cos(phi), math.tan(theta), math.cos(theta)
        u = np.array([p + sf * th * q + cf * th * r, cf * q - sf * r, sf / ch * q + cf / ch * r])
        ax, ay, az = rec.acc[t]
        mx, my, mz = rec.mag[t] / np.linalg.norm(rec.mag[t])
        sh = math.sin(theta)
        y = np.array([
            math.atan2(ay, math.hypot(ax, az)),
            math.atan2(-ax, math.hypot(ay, az)),
            math.atan2(-my * cf + mz * sf, mx * ch + my * sh * sf + mz * sh * cf),
        ])
        xp = A @ x + B @ u
        Pp = A @ P @ A.T + cfg.Q
        S = C @ Pp @ C.T + cfg.R
        nu = y - C @ xp
        if cfg.wrap_yaw_innovation:
            nu[2] = (nu[2] + math.pi) % (2 * math.pi) - math.pi
        K = Pp @ C.T @ np.linalg.inv(S)
        x = xp + K @ nu
        P = (np.eye(6) - K @ C) @ Pp
        phi, theta = x[0], x[2]
        nus.append(nu)
        Ss.append(S)
        xs.append(x.copy())
    return np.array(nus), np.array(Ss), np.array(xs)


@pytest.fixture(scope="module")
def rec():
    """12 s of the handheld simulator at 100 Hz, its magnetic heading crossing ±π."""
    return simulate("handheld", duration=12.0, seed=0)


@pytest.mark.parametrize("settings, wrap", [({}, False), (TUNED, True), (TUNED, False), (COUPLED, True)],
                         ids=["paper", "tuned-wrapped", "tuned", "coupled-general"])
def test_matches_a_plain_loop_of_the_kf_equations(rec, settings, wrap):
    cfg = KFConfig(**settings, wrap_yaw_innovation=wrap)
    res = run_kf(rec, cfg, store_gains=True)
    assert res.path == ("general" if settings is COUPLED else "block")
    nu_ref, S_ref, x_ref = plain_loop(rec, cfg)
    np.testing.assert_allclose(res.state, x_ref, rtol=0, atol=1e-9)  # same filter
    inn = innovations(res)
    assert isinstance(inn, Innovations) and len(inn) == len(rec)
    assert inn.nu.shape == (len(rec), 3) and inn.S.shape == (len(rec), 3, 3) and inn.nis.shape == (len(rec),)
    np.testing.assert_allclose(inn.nu, nu_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(inn.S, S_ref, rtol=1e-9, atol=0)
    nis_ref = np.einsum("ni,nij,nj->n", nu_ref, np.linalg.inv(S_ref), nu_ref)
    np.testing.assert_allclose(inn.nis, nis_ref, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(inn.sigma, np.sqrt(np.diagonal(S_ref, axis1=1, axis2=2)), rtol=1e-9)
    np.testing.assert_allclose(inn.nis_angle, nu_ref**2 / np.diagonal(S_ref, axis1=1, axis2=2), rtol=1e-7,
                               atol=1e-12)
    # the filter's own update is x = x' + K nu with these innovations
    A, B, _ = system_matrices(res.dt)
    x_prior = np.vstack((cfg.x0, res.state[:-1])) @ A.T + res.rates @ B.T
    np.testing.assert_allclose(res.state, x_prior + np.einsum("nij,nj->ni", res.gains, inn.nu), atol=1e-9)
    if wrap:
        assert np.all((inn.nu[:, 2] >= -math.pi) & (inn.nu[:, 2] < math.pi))


def test_unwrapped_yaw_innovation_jumps_by_two_pi_where_the_heading_crosses_pi(rec):
    res = run_kf(rec, KFConfig(**TUNED))
    assert np.abs(np.diff(res.measurements[:, 2])).max() > 6.0  # the magnetic heading crosses ±π
    raw = innovations(res)
    wrapped = innovations(run_kf(rec, KFConfig(**TUNED, wrap_yaw_innovation=True)))
    assert np.abs(raw.nu[:, 2]).max() > 6.0  # unwrapped, the filter sees a 2π innovation
    assert np.abs(wrapped.nu[:, 2]).max() < math.pi
    # the blocks are decoupled: roll and pitch never see the yaw innovation
    np.testing.assert_allclose(raw.nu[:, :2], wrapped.nu[:, :2], rtol=0, atol=0)


@pytest.mark.parametrize("settings", [{}, TUNED], ids=["paper", "tuned"])
def test_steady_state_S_equals_the_riccati_closed_form(settings):
    dt = 0.01
    cfg = KFConfig(**settings, dt=dt)
    seq = gain_sequence(dt, cfg)
    assert seq.converged
    n = len(seq) + 50
    rec = simulate("handheld", duration=n / 100.0, seed=1)
    res = run_kf(rec, cfg)
    inn = innovations(res)
    A, _, C = system_matrices(dt)
    P_prior = scipy.linalg.solve_discrete_are(A.T, C.T, cfg.Q, cfg.R)
    S_ss = C @ P_prior @ C.T + cfg.R
    np.testing.assert_allclose(inn.S[-1], S_ss, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(inn.S[-40:], np.broadcast_to(S_ss, (40, 3, 3)), rtol=1e-8, atol=1e-12)
    # the first step: P' = A P0 A^T + Q
    np.testing.assert_allclose(inn.S[0], C @ (A @ cfg.P0 @ A.T + cfg.Q) @ C.T + cfg.R, rtol=1e-12)


def linear_gaussian_run(Q_true, R_true, Q_filter, R_filter, n=20000, dt=0.01, seed=7):
    """Simulate x_t = A x_{t-1} + B u_t + v, y_t = C x_t + w with v ~ N(0, Q_true),
    w ~ N(0, R_true), filter it with (Q_filter, R_filter) and return the run as a KFResult."""
    rng = np.random.default_rng(seed)
    A, B, C = system_matrices(dt)
    cfg = KFConfig(P0=np.diag(10 * np.diag(Q_true) + 1e-6), Q=Q_filter, R=R_filter, dt=dt)
    x_true = rng.multivariate_normal(np.zeros(6), cfg.P0)
    Lq, Lr = np.linalg.cholesky(Q_true), np.linalg.cholesky(R_true)
    u = 0.3 * np.sin(np.arange(n)[:, None] * dt * np.array([1.0, 0.7, 0.4]))  # known inputs [rad/s]
    ys = np.empty((n, 3))
    for t in range(n):
        x_true = A @ x_true + B @ u[t] + Lq @ rng.standard_normal(6)
        ys[t] = C @ x_true + Lr @ rng.standard_normal(3)
    seq = gain_sequence(dt, cfg, n_max=n)
    x = np.array(cfg.x0)
    xs = np.empty((n, 6))
    for t in range(n):
        xp = A @ x + B @ u[t]
        x = xp + seq.K[min(t, len(seq) - 1)] @ (ys[t] - C @ xp)
        xs[t] = x
    return KFResult(euler=xs[:, 0::2], bias=xs[:, 1::2], measurements=ys, rates=u, gain=seq.K[-1],
                    P=seq.P_post[-1], n_transient=len(seq), dt=dt, config=cfg)


Q_TRUE = np.diag([1e-4, 1e-8, 2e-4, 1e-8, 5e-4, 1e-8])
R_TRUE = np.diag([4e-3, 2e-3, 1e-2])


def test_nis_is_chi_square_with_three_dof_when_q_and_r_are_the_true_ones():
    inn = innovations(linear_gaussian_run(Q_TRUE, R_TRUE, Q_TRUE, R_TRUE))
    n = len(inn)
    # mean of chi2(3) is 3 with variance 6: the standard error of the mean of 20000 white
    # samples is sqrt(6 / 20000) = 0.017; 0.1 is about six of them
    assert abs(inn.nis.mean() - 3.0) < 0.1
    np.testing.assert_allclose(inn.nis_angle.mean(axis=0), 1.0, atol=0.05)
    lo, hi = stats.chi2.ppf([0.025, 0.975], 3)
    outside = np.mean((inn.nis < lo) | (inn.nis > hi))
    assert abs(outside - 0.05) < 0.01  # binomial standard error 0.0015
    # and the distribution itself: Kolmogorov-Smirnov against chi2(3)
    assert stats.kstest(inn.nis, stats.chi2(3).cdf).pvalue > 1e-3
    assert n == 20000


def test_nis_flags_a_wrong_measurement_noise():
    too_large = innovations(linear_gaussian_run(Q_TRUE, R_TRUE, Q_TRUE, 10 * R_TRUE))
    too_small = innovations(linear_gaussian_run(Q_TRUE, R_TRUE, Q_TRUE, 0.1 * R_TRUE))
    assert too_large.nis.mean() < 1.0  # the filter thinks its innovations are larger than they are
    assert too_small.nis.mean() > 9.0
