"""The paper's linear KF checked against independent references.

(a) the first two steps computed by hand, (b) the steady state against scipy's DARE and
python-control's dlqe, (c) the measurement helpers at static poses built with scipy's
Rotation, (d) tracking a smooth trajectory from exact sensor signals, (e) the fast block
path, the general path and a naive numpy implementation of eqs 3-7 written here.
"""
from __future__ import annotations

import math

import control
import numpy as np
import pytest
import scipy.linalg
from scipy.spatial.transform import Rotation

from danae_lite.kalman.filter import kalman_filter, kf_step, measurement_rows, recursion, run_kf, sensor_arrays
from danae_lite.kalman.gains import gain_sequence, steady_state
from danae_lite.kalman.grid import TRIG_NUMPY
from danae_lite.kalman.model import (AUTHORS_DT, KFConfig, accel_tilt, euler_rates,
                                     mag_heading, system_matrices)
from danae_lite.data.recording import Recording

from conftest import assert_close_scaled

B_FIELD, INCL = 48.0, math.radians(60.0)
M_REF = B_FIELD * np.array([math.cos(INCL), 0.0, -math.sin(INCL)])  # x north, y west, z up


# ------------------------------------------------------------------ independent reference
def naive_kf(gyro, acc, mag, dt, P0, Q, R, x0, init, authors_typo=False):
    """Eqs 3-7 with plain 6x6 numpy matrices, one step at a time, nothing precomputed."""
    A = np.eye(6)
    A[0, 1] = A[2, 3] = A[4, 5] = -dt
    if authors_typo:
        A[5] = [0, 0, 0, 0, 1, 0]
    B = np.zeros((6, 3))
    B[0, 0] = B[2, 1] = B[4, 2] = dt
    C = np.zeros((3, 6))
    C[0, 0] = C[1, 2] = C[2, 4] = 1.0
    x = np.array(x0, dtype=float)
    P = np.array(P0, dtype=float)
    phi, theta = init
    xs, ys, us, Ks = [], [], [], []
    for t in range(len(gyro)):
        p, q, r = gyro[t]
        u = np.array(
            [
                p + np.sin(phi) * np.tan(theta) * q + np.cos(phi) * np.tan(theta) * r,
                np.cos(phi) * q - np.sin(phi) * r,
                np.sin(phi) / np.cos(theta) * q + np.cos(phi) / np.cos(theta) * r,
            ]
        )
        ax, ay, az = acc[t]
        mx, my, mz = mag[t] / np.linalg.norm(mag[t])
        y = np.array(
            [
                np.arctan2(ay, np.sqrt(ax**2 + az**2)),
                np.arctan2(-ax, np.sqrt(ay**2 + az**2)),
                np.arctan2(
                    -my * np.cos(phi) + mz * np.sin(phi),
                    mx * np.cos(theta) + my * np.sin(theta) * np.sin(phi) + mz * np.sin(theta) * np.cos(phi),
                ),
            ]
        )
        xp = A @ x + B @ u  # eq 3
        Pp = A @ P @ A.T + Q  # eq 4
        K = Pp @ C.T @ np.linalg.inv(C @ Pp @ C.T + R)  # eq 5
        x = xp + K @ (y - C @ xp)  # eq 6
        P = (np.eye(6) - K @ C) @ Pp  # eq 7
        phi, theta = x[0], x[2]
        xs.append(x.copy())
        ys.append(y)
        us.append(u)
        Ks.append(K)
    return np.array(xs), np.array(ys), np.array(us), np.array(Ks), P


def random_inputs(n=400, seed=1):
    rng = np.random.default_rng(seed)
    gyro = rng.normal(0.0, 0.4, (n, 3))
    acc = rng.normal(0.0, 0.15, (n, 3)) + [0.05, -0.1, 1.0]
    mag = rng.normal(0.0, 3.0, (n, 3)) + [20.0, 5.0, -40.0]
    return gyro, acc, mag


TUNED = dict(
    P0=np.diag([0.5, 0.01, 0.4, 0.02, 1.0, 0.03]),
    Q=np.diag([1e-4, 1e-6, 2e-4, 2e-6, 1e-3, 1e-5]),
    R=np.diag([0.01, 0.02, 0.05]),
)
_Qc = np.diag([1e-3, 1e-5, 2e-3, 1e-5, 1e-2, 1e-4])
_Qc[0, 2] = _Qc[2, 0] = 5e-4  # roll/pitch process noise correlated
_Qc[1, 4] = _Qc[4, 1] = 1e-6
_Rc = np.array([[0.02, 0.005, 0.0], [0.005, 0.03, 0.001], [0.0, 0.001, 0.1]])
COUPLED = dict(P0=np.eye(6) + 0.2 * (np.ones((6, 6)) - np.eye(6)) / 5, Q=_Qc, R=_Rc)


# ------------------------------------------------------------------ (a) by hand
def test_first_two_steps_by_hand():
    # dt = 0.1, P0 = Q = I6, R = I3, x0 = 0, previous roll/pitch at step 0 = 0.
    gyro = np.array([[0.2, -0.1, 0.3], [0.1, 0.2, -0.1]])
    acc = np.array([[-0.1, 0.2, 1.0], [0.0, 0.0, 1.0]])
    mag = np.array([[3.0, 4.0, 0.0], [3.0, 4.0, 0.0]])  # unit: (0.6, 0.8, 0)
    res = kalman_filter(gyro, acc, mag, dt=0.1, config=KFConfig(), init_euler=(0.0, 0.0), store_gains=True)

    # Step 0. Every block: P' = A I A^T + I = [[1.01, -0.1], [-0.1, 1]] + I = [[2.01, -0.1], [-0.1, 2]],
    # S = 1 + 2.01 = 3.01, K = (2.01/3.01, -0.1/3.01).
    k0, k1 = 2.01 / 3.01, -0.1 / 3.01
    # u at phi^ = theta^ = 0 is (p, q, r); x' = dt u.
    y0 = [math.atan2(0.2, math.sqrt(1.01)), math.atan2(0.1, math.sqrt(1.04)), math.atan2(-0.8, 0.6)]
    xp0 = [0.1 * 0.2, 0.1 * -0.1, 0.1 * 0.3]
    ang0 = [xp0[j] + k0 * (y0[j] - xp0[j]) for j in range(3)]
    bias0 = [k1 * (y0[j] - xp0[j]) for j in range(3)]
    assert_close_scaled(res.measurements[0], y0, rtol=1e-15)
    assert_close_scaled(res.rates[0], [0.2, -0.1, 0.3], rtol=1e-15)
    assert_close_scaled(res.euler[0], ang0, rtol=1e-15)
    assert_close_scaled(res.bias[0], bias0, rtol=1e-15)
    np.testing.assert_allclose(res.gains[0][[0, 1], 0], [k0, k1], rtol=1e-15)
    # P = (I - K C) P' = [[2.01/3.01, -0.1/3.01], [-0.1/3.01, 2 - 0.01/3.01 = 6.01/3.01]]

    # Step 1. P' = A P A^T + I:
    #   p00' = (2.01 + 2*0.1*0.1 + 0.01*6.01)/3.01 + 1 = 2.0901/3.01 + 1 = 5.1001/3.01
    #   p01' = (-0.1 - 0.1*6.01)/3.01 = -0.701/3.01,  S = 1 + 5.1001/3.01 = 8.1101/3.01
    #   K = (5.1001/8.1101, -0.701/8.1101)
    k0, k1 = 5.1001 / 8.1101, -0.701 / 8.1101
    phi, theta = ang0[0], ang0[1]  # previous estimates
    p, q, r = gyro[1]
    u1 = [
        p + math.sin(phi) * math.tan(theta) * q + math.cos(phi) * math.tan(theta) * r,
        math.cos(phi) * q - math.sin(phi) * r,
        (math.sin(phi) * q + math.cos(phi) * r) / math.cos(theta),
    ]
    y1 = [0.0, 0.0, math.atan2(-0.8 * math.cos(phi), 0.6 * math.cos(theta) + 0.8 * math.sin(theta) * math.sin(phi))]
    xp1 = [ang0[j] - 0.1 * bias0[j] + 0.1 * u1[j] for j in range(3)]
    ang1 = [xp1[j] + k0 * (y1[j] - xp1[j]) for j in range(3)]
    bias1 = [bias0[j] + k1 * (y1[j] - xp1[j]) for j in range(3)]
    assert_close_scaled(res.rates[1], u1, rtol=1e-15)
    assert_close_scaled(res.measurements[1], y1, rtol=1e-15)
    assert_close_scaled(res.euler[1], ang1, rtol=1e-14)
    assert_close_scaled(res.bias[1], bias1, rtol=1e-14)
    np.testing.assert_allclose(res.gains[1][[0, 1], 0], [k0, k1], rtol=1e-14)
    # P after step 1: [[(1-k0) p00', (1-k0) p01'], [., p11' - k1 p01']] with p11' = 9.02/3.01
    p00, p01, p11 = 5.1001 / 3.01, -0.701 / 3.01, 9.02 / 3.01
    P1 = [[(1 - k0) * p00, (1 - k0) * p01], [(1 - k0) * p01, p11 - k1 * p01]]
    np.testing.assert_allclose(res.P[:2, :2], P1, rtol=1e-14)
    assert res.dt == 0.1 and res.n_transient == 2 and res.path == "block"


def test_kf_step_one_block_by_hand():
    # one (angle, bias) block, dt = 0.1, x = 0, P = Q = I, R = 1, u = 0.2 rad/s, y = 0.05 rad
    st = kf_step([0, 0], np.eye(2), [0.2], [0.05], [[1, -0.1], [0, 1]], [[0.1], [0]], [[1, 0]], np.eye(2), [[1.0]])
    np.testing.assert_allclose(st.x_prior, [0.02, 0.0], atol=1e-16)
    np.testing.assert_allclose(st.P_prior, [[2.01, -0.1], [-0.1, 2.0]], rtol=1e-15)
    np.testing.assert_allclose(st.S, [[3.01]], rtol=1e-15)
    np.testing.assert_allclose(st.K[:, 0], [2.01 / 3.01, -0.1 / 3.01], rtol=1e-15)
    np.testing.assert_allclose(st.innovation, [0.03], rtol=1e-14)
    np.testing.assert_allclose(st.x, [0.02 + 0.03 * 2.01 / 3.01, -0.003 / 3.01], rtol=1e-14)
    np.testing.assert_allclose(st.P, [[2.01 / 3.01, -0.1 / 3.01], [-0.1 / 3.01, 6.01 / 3.01]], rtol=1e-14)


def test_authors_typo_is_documented_but_not_used():
    A, B, C = system_matrices(0.1, authors_typo=True)
    np.testing.assert_array_equal(A[5], [0, 0, 0, 0, 1, 0])
    A, B, C = system_matrices(0.1)
    np.testing.assert_array_equal(A[5], [0, 0, 0, 0, 0, 1])
    np.testing.assert_array_equal(A[[0, 2, 4], [1, 3, 5]], [-0.1] * 3)
    np.testing.assert_array_equal(B[[0, 2, 4], [0, 1, 2]], [0.1] * 3)
    np.testing.assert_array_equal(C, np.eye(6)[[0, 2, 4]])
    gyro, acc, mag = random_inputs(50)
    res = kalman_filter(gyro, acc, mag, 0.1, init_euler=(0, 0))
    ok = naive_kf(gyro, acc, mag, 0.1, np.eye(6), np.eye(6), np.eye(3), np.zeros(6), (0, 0))[0]
    typo = naive_kf(gyro, acc, mag, 0.1, np.eye(6), np.eye(6), np.eye(3), np.zeros(6), (0, 0), True)[0]
    assert_close_scaled(res.state, ok, rtol=1e-12)
    assert np.abs(res.state[:, 5] - typo[:, 5]).max() > 0.1


# ------------------------------------------------------------------ (b) steady state
@pytest.mark.parametrize("dt", [0.01, 0.1])
@pytest.mark.parametrize("cov", ["identity", "tuned", "coupled"])
def test_steady_state_matches_dare_dlqe_and_recursion(dt, cov):
    params = {"identity": {}, "tuned": TUNED, "coupled": COUPLED}[cov]
    Q = params.get("Q", np.eye(6))
    R = params.get("R", np.eye(3))
    ss = steady_state(dt, Q, R)
    A, _, C = system_matrices(dt)

    # scipy: the estimation DARE is the control DARE of (A^T, C^T)
    X = scipy.linalg.solve_discrete_are(A.T, C.T, Q, R)
    assert_close_scaled(ss.P_prior, X, rtol=1e-10)
    # the DARE itself: P' = A P' A^T - A P' C^T (C P' C^T + R)^-1 C P' A^T + Q
    res = A @ X @ A.T - A @ X @ C.T @ np.linalg.solve(C @ X @ C.T + R, C @ X @ A.T) + Q - X
    assert np.abs(res).max() < 1e-9 * np.abs(X).max()

    # python-control: dlqe(A, G=I, C, QN, RN) returns the PREDICTOR gain L = A P' C^T S^-1 and P'
    L, P, _ = control.dlqe(A, np.eye(6), C, Q, R)
    assert_close_scaled(P, ss.P_prior, rtol=1e-8)
    assert_close_scaled(L, ss.K_predictor, rtol=1e-8)
    assert_close_scaled(np.linalg.solve(A, L), ss.K_filter, rtol=1e-8)
    assert_close_scaled(A @ ss.K_filter, L, rtol=1e-8)
    # ... and it is not the filter gain: the angle rows differ by -dt * bias-row gain
    np.testing.assert_allclose(L[0, 0] - ss.K_filter[0, 0], -dt * ss.K_filter[1, 0], rtol=1e-8)
    assert np.abs(L - ss.K_filter).max() > 1e-4

    # the recursion of eqs 4, 5, 7 converges to the same fixed point
    cfg = KFConfig(**params)
    seq = gain_sequence(dt, cfg)
    assert seq.converged
    assert_close_scaled(seq.K[-1], ss.K_filter, rtol=1e-8)
    assert_close_scaled(seq.P_post[-1], ss.P_post, rtol=1e-8)
    if cfg.block_diagonal:
        general = gain_sequence(dt, cfg, method="general")
        # (the step at which "converged" is detected depends on ulp-level noise)
        assert general.converged
        m = min(len(general), len(seq))
        assert_close_scaled(general.K[:m], seq.K[:m], rtol=1e-12)
        assert_close_scaled(general.P_post[:m], seq.P_post[:m], rtol=1e-12)


def test_untuned_steady_gain_numbers():
    # Q = R = I, dt = 0.1: one 2-state block has the DARE solution P' with
    # p00 = 1.8816378..., the filter gain K = P' C^T / (p00 + 1) and L = A K.
    ss = steady_state(0.1)
    p00 = ss.P_prior[0, 0]
    np.testing.assert_allclose(ss.K_filter[0, 0], p00 / (p00 + 1), rtol=1e-14)
    np.testing.assert_allclose(ss.K_filter[1, 0], ss.P_prior[1, 0] / (p00 + 1), rtol=1e-14)
    np.testing.assert_allclose([p00, ss.K_filter[0, 0], ss.K_predictor[0, 0]], [1.88163782, 0.65297513, 0.71188394], atol=1e-8)
    # the three blocks are identical and decoupled
    for j, (a, b) in enumerate([(0, 1), (2, 3), (4, 5)]):
        np.testing.assert_allclose(ss.K_filter[[a, b], j], ss.K_filter[[0, 1], 0], rtol=1e-12)
    assert np.count_nonzero(np.abs(ss.K_filter) > 1e-14) == 6


# ------------------------------------------------------------------ (c) static poses
POSES = [(0.0, 0.0, 0.0), (0.3, 0.0, 1.0), (-0.4, 0.2, -2.5), (0.1, -0.6, 3.0), (1.2, 0.7, -0.3), (-2.5, 0.3, 2.0)]


def static_pose(roll, pitch, yaw):
    rot = Rotation.from_euler("ZYX", [yaw, pitch, roll])  # body -> reference
    acc = rot.inv().apply([0.0, 0.0, 1.0])  # tilt convention: R^T up
    mag = rot.inv().apply(M_REF)
    return acc, mag


@pytest.mark.parametrize("roll,pitch,yaw", POSES)
def test_accel_tilt_and_heading_at_static_pose(roll, pitch, yaw):
    acc, mag = static_pose(roll, pitch, yaw)
    tilt = accel_tilt(acc[None])[0]
    # pitch is exact; the authors' roll formula gives asin(sin(roll) cos(pitch))
    assert tilt[1] == pytest.approx(pitch, abs=1e-14)
    assert tilt[0] == pytest.approx(math.asin(math.sin(roll) * math.cos(pitch)), abs=1e-14)
    if pitch == 0.0 and abs(roll) < math.pi / 2:
        assert tilt[0] == pytest.approx(roll, abs=1e-14)
    # tilt-compensated heading with the true roll/pitch = yaw (any field strength)
    psi = mag_heading(3.7 * mag[None], roll, pitch)[0]
    assert math.remainder(psi - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-13)


def test_accel_tilt_closed_forms_by_hand():
    np.testing.assert_allclose(accel_tilt([[0, 0, 1], [0, 1, 0], [-1, 0, 0], [0, 1, 1]]),
                               [[0, 0], [math.pi / 2, 0], [0, math.pi / 2], [math.pi / 4, 0]], atol=1e-15)
    # level, heading north-west: m = (cos I cos45, -cos I sin45, -sin I) rotated... use yaw = +45 deg
    _, mag = static_pose(0.0, 0.0, math.pi / 4)
    assert mag_heading(mag[None], 0.0, 0.0)[0] == pytest.approx(math.pi / 4, abs=1e-14)


@pytest.mark.parametrize("roll,pitch,yaw", POSES[:5])
def test_euler_rates_match_rotation_derivative(roll, pitch, yaw):
    rates = np.array([0.3, -0.2, 0.5])  # (phi_dot, theta_dot, psi_dot) [rad/s]
    h = 1e-5

    def rot(t):
        e = np.array([roll, pitch, yaw]) + rates * t
        return Rotation.from_euler("ZYX", e[::-1])

    omega = (rot(-h).inv() * rot(h)).as_rotvec() / (2 * h)  # body rates, central difference
    np.testing.assert_allclose(euler_rates(omega[None], roll, pitch)[0], rates, atol=1e-8)


# ------------------------------------------------------------------ (d) exact signals
def smooth_trajectory(fs=100.0, duration=60.0):
    t = np.arange(int(fs * duration)) / fs
    e = np.column_stack([0.3 * np.sin(0.5 * t), 0.2 * np.sin(0.3 * t + 1.0), 2.0 * np.sin(0.1 * t)])
    de = np.column_stack([0.15 * np.cos(0.5 * t), 0.06 * np.cos(0.3 * t + 1.0), 0.2 * np.cos(0.1 * t)])
    phi, theta = e[:, 0], e[:, 1]
    gyro = np.column_stack(  # body rates from Euler rates (inverse kinematics)
        [
            de[:, 0] - de[:, 2] * np.sin(theta),
            de[:, 1] * np.cos(phi) + de[:, 2] * np.sin(phi) * np.cos(theta),
            -de[:, 1] * np.sin(phi) + de[:, 2] * np.cos(phi) * np.cos(theta),
        ]
    )
    rot = Rotation.from_euler("ZYX", e[:, ::-1])
    mag = rot.inv().apply(M_REF)
    acc_phys = rot.inv().apply([0.0, 0.0, 1.0])
    # an accelerometer reading for which the authors' tilt formulas are exact:
    # roll_acc = asin(ay), pitch_acc = asin(-ax) for a unit vector
    acc_exact = np.column_stack([-np.sin(theta), np.sin(phi), np.sqrt(1 - np.sin(phi) ** 2 - np.sin(theta) ** 2)])
    rec = Recording("smooth", "test", fs, gyro, acc_exact, mag, rot.as_quat())
    return t, e, rec, acc_phys


@pytest.mark.parametrize(
    "config",
    [
        KFConfig(),  # paper's identities, true dt: follows the measurements
        KFConfig(Q=np.diag([1e-6, 1e-8] * 3), R=np.diag([1e-2] * 3)),  # follows mostly the gyro
    ],
    ids=["identity", "gyro-heavy"],
)
def test_tracks_smooth_trajectory_from_exact_signals(config):
    t, e, rec, _ = smooth_trajectory()
    np.testing.assert_allclose(accel_tilt(rec.acc), e[:, :2], atol=1e-12)
    res = run_kf(rec, config)
    err = np.abs(res.euler - e)[100:].max(axis=0)
    # roll/pitch: only the one-step discretisation of the rates remains (< 1e-3 rad);
    # yaw: the heading is tilt-compensated with the *previous* roll/pitch, which lag the
    # truth by one step (~1.5e-3 rad here), giving a heading error of a few 1e-3 rad.
    assert err[0] < 1e-3 and err[1] < 1e-3 and err[2] < 5e-3
    assert np.abs(res.bias[1000:]).max() < 5e-3
    np.testing.assert_allclose(res.measurements[:, :2], e[:, :2], atol=1e-12)
    assert np.abs(res.measurements[100:, 2] - e[100:, 2]).max() < 5e-3


def test_tracks_with_physical_accelerometer():
    # with the true specific force the roll measurement is asin(sin(roll) cos(pitch)),
    # off by up to 0.3 (1 - cos 0.2) ~ 6e-3 rad here: the roll estimate inherits that, and the
    # heading inherits it through the tilt compensation; pitch stays exact.
    t, e, rec, acc_phys = smooth_trajectory()
    rec2 = Recording("smooth-phys", "test", rec.fs, rec.gyro, acc_phys, rec.mag, rec.quat)
    res = run_kf(rec2)
    formula_err = np.abs(np.arcsin(np.sin(e[:, 0]) * np.cos(e[:, 1])) - e[:, 0]).max()
    assert 5e-3 < formula_err < 7e-3
    err = np.abs(res.euler - e)[100:].max(axis=0)
    assert err[0] < formula_err + 1e-4 and err[1] < 1e-4 and err[2] < 2e-2


def test_authors_setting_and_init_from_truth():
    t, e, rec, _ = smooth_trajectory(duration=5.0)
    cfg = KFConfig.authors()
    assert cfg.dt == AUTHORS_DT == 0.1
    np.testing.assert_array_equal(cfg.P0, np.eye(6))
    np.testing.assert_array_equal(cfg.Q, np.eye(6))
    np.testing.assert_array_equal(cfg.R, np.eye(3))
    np.testing.assert_array_equal(cfg.x0, np.zeros(6))
    assert cfg.init_from_truth
    res = run_kf(rec, cfg)
    assert res.dt == 0.1
    direct = kalman_filter(rec.gyro, rec.acc, rec.mag, 0.1, cfg, init_euler=rec.euler[0])
    np.testing.assert_array_equal(res.state, direct.state)
    # default config uses 1/fs; init_from_truth=False uses x0's roll/pitch for step 0
    assert run_kf(rec).dt == pytest.approx(0.01)
    r0 = run_kf(rec, KFConfig(init_from_truth=False))
    r1 = kalman_filter(rec.gyro, rec.acc, rec.mag, 0.01, KFConfig(), init_euler=(0.0, 0.0))
    np.testing.assert_array_equal(r0.state, r1.state)
    assert not np.array_equal(run_kf(rec).state[0], r0.state[0])


# ------------------------------------------------------------------ (e) paths agree
@pytest.mark.parametrize("params", [{}, TUNED], ids=["identity", "tuned"])
@pytest.mark.parametrize("dt", [0.01, 0.1])
def test_block_general_and_naive_agree(params, dt):
    gyro, acc, mag = random_inputs()
    x0 = np.array([0.1, 0.01, -0.2, -0.02, 1.0, 0.05])
    init = (0.15, -0.1)
    cfg = KFConfig(x0=x0, **params)
    fast = kalman_filter(gyro, acc, mag, dt, cfg, init_euler=init, store_gains=True)
    gen = kalman_filter(gyro, acc, mag, dt, cfg, init_euler=init, store_gains=True, method="general")
    assert fast.path == "block" and gen.path == "general"
    xs, ys, us, Ks, P = naive_kf(gyro, acc, mag, dt, cfg.P0, cfg.Q, cfg.R, x0, init)
    for res in (fast, gen):
        assert_close_scaled(res.state, xs, rtol=1e-12)
        assert_close_scaled(res.measurements, ys, rtol=1e-12)
        assert_close_scaled(res.rates, us, rtol=1e-12)
        assert_close_scaled(res.gains, Ks, rtol=1e-12)
        assert_close_scaled(res.P, P, rtol=1e-12)
        assert_close_scaled(res.gain, Ks[-1], rtol=1e-12)
    assert_close_scaled(fast.state, gen.state, rtol=1e-12)


def _by_kf_step(gyro, acc, mag, dt, cfg, init):
    """The filter written with the textbook kf_step, one sample at a time: states and gains."""
    A, B, C = system_matrices(dt)
    x, P = cfg.x0.copy(), cfg.P0.copy()
    phi, theta = init
    xs, Ks = [], []
    for t in range(len(gyro)):
        u = euler_rates(gyro[t:t + 1], phi, theta)[0]
        roll_acc, pitch_acc = accel_tilt(acc[t:t + 1])[0]
        y = [roll_acc, pitch_acc, mag_heading(mag[t:t + 1], phi, theta)[0]]
        step = kf_step(x, P, u, y, A, B, C, cfg.Q, cfg.R)
        x, P = step.x, step.P
        phi, theta = x[0], x[2]
        xs.append(x)
        Ks.append(step.K)
    return np.array(xs), np.array(Ks)


def test_the_one_loop_equals_kf_step_for_one_setting_and_for_a_batch():
    # recursion() is the filter's only data loop: floats for run_kf, NumPy vectors for the
    # grid; fed kf_step's gains it must give kf_step's states, coupled gains included
    gyro, acc, mag = random_inputs(150, seed=7)
    dt, init = 0.02, (0.1, -0.05)
    configs = [KFConfig(**TUNED), KFConfig(**COUPLED)]
    refs = [_by_kf_step(gyro, acc, mag, dt, cfg, init) for cfg in configs]
    arrays = sensor_arrays(gyro=gyro, acc=acc, mag=mag)
    for cfg, (xs, Ks) in zip(configs, refs):
        start = [*cfg.x0.tolist(), *init]
        steps = recursion(measurement_rows(arrays)[1], map(tuple, Ks.reshape(-1, 18).tolist()), start, dt)
        got = np.array([s[:6] for s in steps])
        assert_close_scaled(got, xs, rtol=1e-12)
    batch_start = [np.array([c.x0[i] for c in configs]) for i in range(6)] + [np.full(2, v) for v in init]
    batch_gains = zip(*(np.stack([K.reshape(-1, 18)[:, j] for _, K in refs], 1) for j in range(18)))
    steps = recursion(measurement_rows(arrays)[1], batch_gains, batch_start, dt, trig=TRIG_NUMPY)
    got = np.array([np.stack(s[:6], axis=1) for s in steps])  # (N, K, 6)
    for k, (xs, _) in enumerate(refs):
        assert_close_scaled(got[:, k], xs, rtol=1e-12)


def test_general_path_with_coupled_covariances_matches_naive():
    gyro, acc, mag = random_inputs(300, seed=4)
    cfg = KFConfig(**COUPLED)
    assert not cfg.block_diagonal
    res = kalman_filter(gyro, acc, mag, 0.05, cfg, init_euler=(0.0, 0.1))
    assert res.path == "general"
    xs, ys, us, Ks, P = naive_kf(gyro, acc, mag, 0.05, cfg.P0, cfg.Q, cfg.R, np.zeros(6), (0.0, 0.1))
    assert_close_scaled(res.state, xs, rtol=1e-12)
    assert_close_scaled(res.measurements, ys, rtol=1e-12)
    assert_close_scaled(res.P, P, rtol=1e-12)
    with pytest.raises(ValueError, match="block-diagonal"):
        kalman_filter(gyro, acc, mag, 0.05, cfg, method="block")


def test_short_recording_without_convergence_matches_naive():
    gyro, acc, mag = random_inputs(5)
    cfg = KFConfig(Q=np.diag([1e-6, 1e-9] * 3))  # slow convergence: every step is transient
    res = kalman_filter(gyro, acc, mag, 0.01, cfg, init_euler=(0, 0), store_gains=True)
    xs, _, _, Ks, P = naive_kf(gyro, acc, mag, 0.01, cfg.P0, cfg.Q, cfg.R, np.zeros(6), (0, 0))
    assert res.n_transient == 5
    assert_close_scaled(res.state, xs, rtol=1e-12)
    assert_close_scaled(res.gains, Ks, rtol=1e-12)
    assert_close_scaled(res.P, P, rtol=1e-12)


def test_simulated_recording_block_equals_naive():
    sim = pytest.importorskip("danae_lite.data.simulate")
    rec = sim.simulate("handheld", duration=3.0, seed=2)
    cfg = KFConfig.authors()
    res = run_kf(rec, cfg)
    xs = naive_kf(rec.gyro, rec.acc, rec.mag, 0.1, np.eye(6), np.eye(6), np.eye(3), np.zeros(6), rec.euler[0, :2])[0]
    assert_close_scaled(res.state, xs, rtol=1e-12)


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(Q=np.eye(5)), "Q must be a 6x6"),
        (dict(R=np.eye(3) - 2 * np.eye(3)), "R must be positive definite"),
        (dict(R=np.zeros((3, 3))), "R must be positive definite"),
        (dict(P0=np.triu(np.ones((6, 6)))), "P0 must be symmetric"),
        (dict(Q=np.diag([1, 1, 1, 1, 1, -1.0])), "Q must be positive semi-definite"),
        (dict(Q=np.full((6, 6), np.nan)), "non-finite"),
        (dict(dt=0.0), "dt must be"),
        (dict(dt=-0.1), "dt must be"),
        (dict(x0=np.zeros(5)), "x0 must be"),
        (dict(P0=np.ones(4)), "P0: a diagonal must have 6"),
    ],
)
def test_config_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        KFConfig(**kwargs)


def test_config_scalar_and_diagonal_forms():
    cfg = KFConfig(Q=0.01, R=[0.1, 0.2, 0.3])
    np.testing.assert_array_equal(cfg.Q, 0.01 * np.eye(6))
    np.testing.assert_array_equal(cfg.R, np.diag([0.1, 0.2, 0.3]))
    assert cfg.block_diagonal
    assert "Q=0.01*I6" in repr(cfg)


def test_filter_input_validation():
    gyro, acc, mag = random_inputs(10)
    with pytest.raises(ValueError, match="dt is not given"):
        kalman_filter(gyro, acc, mag)
    with pytest.raises(ValueError, match="disagrees"):
        kalman_filter(gyro, acc, mag, 0.01, KFConfig.authors())
    with pytest.raises(ValueError, match="rows"):
        kalman_filter(gyro, acc[:5], mag, 0.1)
    with pytest.raises(ValueError, match="shape"):
        kalman_filter(gyro[:, :2], acc, mag, 0.1)
    bad = mag.copy()
    bad[3] = 0.0
    with pytest.raises(ValueError, match="mag row 3"):
        kalman_filter(gyro, acc, bad, 0.1)
    with pytest.raises(ValueError, match="method"):
        kalman_filter(gyro, acc, mag, 0.1, method="fast")


def test_remembered_blocks_give_exactly_the_gains_of_a_fresh_run():
    """The block recursion is remembered per (P0, Q, R, dt) block and serves other lengths:
    every answer must equal, bit for bit, what the recursion gives from scratch."""
    from danae_lite.kalman import gains

    cfg = KFConfig(Q=[1e-4, 1e-6, 1e-4, 1e-6, 1e-3, 1e-6])
    dt = 0.01

    def fresh(n_max):
        gains._BLOCK_CACHE.clear()
        return gains.gain_sequence(dt, cfg, n_max=n_max, method="block")

    full = fresh(100_000)
    assert full.converged and 100 < len(full) < 100_000
    for n_max in (7, len(full) - 1, len(full), len(full) + 50):
        expected = fresh(n_max)
        fresh(100_000)  # remember the blocks of a longer run
        got = gains.gain_sequence(dt, cfg, n_max=n_max, method="block")
        assert got.converged == expected.converged == (n_max >= len(full))
        np.testing.assert_array_equal(got.K, expected.K)
        np.testing.assert_array_equal(got.P_post, expected.P_post)
    # a short run first, then a longer request: computed again, not served from the short one
    fresh(7)
    again = gains.gain_sequence(dt, cfg, n_max=100_000, method="block")
    np.testing.assert_array_equal(again.K, full.K)
