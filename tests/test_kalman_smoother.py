"""The RTS smoother against the batch least-squares solution of the same linear-Gaussian model,
and the wrapped yaw innovation against the unwrapped filter."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from danae_lite.kalman.filter import KFResult, run_kf
from danae_lite.kalman.model import KFConfig, system_matrices
from danae_lite.kalman import offline
from danae_lite.angles import wrap
from danae_lite.data.simulate import simulate


def batch_smoother(res: KFResult) -> np.ndarray:
    """Posterior mean of all states given all measurements, by solving the normal equations.

    States z = [x_-1, x_0, ..., x_{N-1}] (6 each): x_-1 ~ N(x0, P0);
    x_t = A x_{t-1} + B u_t + w_t, w ~ N(0, Q); y_t = C x_t + v_t, v ~ N(0, R).
    """
    cfg, dt = res.config, res.dt
    A, B, C = system_matrices(dt)
    n = len(res.euler)
    dim = 6 * (n + 1)
    H = np.zeros((dim, dim))
    g = np.zeros(dim)
    P0i, Qi, Ri = (np.linalg.inv(M) for M in (cfg.P0, cfg.Q, cfg.R))
    sl = lambda k: slice(6 * k, 6 * k + 6)  # noqa: E731 - state k-1 of the text
    H[sl(0), sl(0)] += P0i
    g[sl(0)] += P0i @ cfg.x0
    for t in range(n):
        i, j = t, t + 1  # x_{t-1}, x_t
        J = np.hstack([-A, np.eye(6)])  # w_t = x_t - A x_{t-1} - B u_t
        idx = np.r_[6 * i: 6 * i + 6, 6 * j: 6 * j + 6]
        H[np.ix_(idx, idx)] += J.T @ Qi @ J
        g[idx] += J.T @ Qi @ (B @ res.rates[t])
        H[sl(j), sl(j)] += C.T @ Ri @ C
        g[sl(j)] += C.T @ Ri @ res.measurements[t]
    z = scipy.linalg.solve(H, g, assume_a="pos")
    return z[6:].reshape(n, 6)


@pytest.mark.parametrize("q", [1.0, 1e-3])
def test_rts_matches_the_batch_least_squares_solution(q):
    rec = simulate("handheld", duration=0.6, seed=3).slice(0, 40)
    cfg = KFConfig(Q=[q, q * 1e-2] * 3, R=[0.5, 0.5, 2.0], init_from_truth=False)
    res = run_kf(rec, cfg)
    smooth = offline.rts_smooth(res)
    ref = batch_smoother(res)
    scale = np.abs(ref).max()
    np.testing.assert_allclose(smooth, ref, atol=1e-9 * scale)
    # the last smoothed state is the filter's own; the smoother differs before it
    np.testing.assert_allclose(smooth[-1], res.state[-1], rtol=0, atol=1e-12)
    assert np.abs(smooth[:-5] - res.state[:-5]).max() > 1e-6


def test_rts_beats_the_filter_on_a_long_recording():
    rec = simulate("handheld", duration=60.0, seed=1)
    res = run_kf(rec, KFConfig(Q=[1e-5, 1e-10] * 3))
    smooth = offline.rts_smooth(res)
    err_f = np.sqrt(np.mean(wrap(res.euler[:, :2] - rec.euler[:, :2]) ** 2))
    err_s = np.sqrt(np.mean(wrap(smooth[:, [0, 2]] - rec.euler[:, :2]) ** 2))
    assert err_s < err_f


def test_wrapped_yaw_innovation_removes_the_2pi_transients():
    rec = simulate("handheld", duration=120.0, seed=0)
    truth_yaw = rec.euler[:, 2]
    assert np.abs(np.diff(truth_yaw)).max() > np.pi  # the heading crosses +-pi
    plain = run_kf(rec, KFConfig(Q=[1e-5, 1e-10] * 3))
    wrapped = run_kf(rec, KFConfig(Q=[1e-5, 1e-10] * 3, wrap_yaw_innovation=True))
    rmse = lambda e: float(np.sqrt(np.mean(wrap(e[:, 2] - truth_yaw) ** 2)))  # noqa: E731
    assert rmse(wrapped.euler) < 0.5 * rmse(plain.euler)
    np.testing.assert_array_equal(wrapped.euler[:, :2], plain.euler[:, :2])  # roll/pitch untouched
    # both implementations agree
    general = run_kf(rec, KFConfig(Q=[1e-5, 1e-10] * 3, wrap_yaw_innovation=True), method="general")
    np.testing.assert_allclose(general.euler, wrapped.euler, atol=1e-9)
    assert "wrap_yaw_innovation=True" in repr(wrapped.config) and "wrap" not in repr(plain.config)
