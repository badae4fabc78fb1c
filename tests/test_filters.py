"""Library filters and every baseline against independent expectations: a static pose gives its
known tilt, a pure rotation about one axis gives that rotation, a known linear corruption is undone."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal
from scipy.spatial.transform import Rotation

from danae_lite.research import baselines, post_processing
from danae_lite.research.ahrs import filters
from danae_lite.data.alignment import FrameAlignment
from danae_lite.angles import angle_diff
from danae_lite.data.recording import Recording
from danae_lite.data.simulate import MAG_REF

FS = 100.0


def pose_recording(euler_fn, seconds: float, name: str = "pose") -> Recording:
    """Noise-free recording of the orientation ``euler_fn(t) -> (N, 3)`` (roll, pitch, yaw), NWU reference."""
    t = np.arange(int(seconds * FS)) / FS
    e = euler_fn(t)
    rot = Rotation.from_euler("ZYX", e[:, ::-1])
    # body rate from the exact relative rotation between samples (constant over each step)
    rates = (rot[:-1].inv() * rot[1:]).as_rotvec() * FS
    gyro = np.vstack([rates, rates[-1:]])
    acc = rot.inv().apply([0.0, 0.0, 1.0])
    mag = rot.inv().apply(MAG_REF)
    return Recording(name, "test", FS, gyro, acc, mag, rot.as_quat())


STATIC = np.array([0.3, -0.2, 1.0])


def static(t: np.ndarray) -> np.ndarray:
    return np.tile(STATIC, (len(t), 1))


def turning(t: np.ndarray) -> np.ndarray:
    return np.column_stack([np.zeros_like(t), np.zeros_like(t), -2.0 + 0.5 * t])  # 0.5 rad/s about z


@pytest.mark.parametrize("name", list(filters.FILTERS))
def test_static_pose_gives_its_tilt_and_heading(name):
    rec = pose_recording(static, 20.0)
    e = filters.filter_euler(name, rec.gyro, rec.acc, rec.mag, rec.fs)
    tail = e[-200:]  # after the filter settled
    np.testing.assert_allclose(tail[:, :2], np.tile(STATIC[:2], (200, 1)), atol=5e-3)
    if filters.FILTERS[name].has_yaw:
        assert np.abs(angle_diff(tail[:, 2], STATIC[2])).max() < 5e-3
    else:
        assert np.isnan(tail[:, 2]).all()


@pytest.mark.parametrize("name", list(filters.FILTERS))
def test_pure_rotation_about_z_gives_that_rotation(name):
    rec = pose_recording(turning, 30.0)
    e = filters.filter_euler(name, rec.gyro, rec.acc, rec.mag, rec.fs)
    truth = turning(np.arange(len(rec)) / FS)
    tail = slice(1500, None)
    # RIANN is a learned network, not an exact integrator: it holds roll/pitch within 0.6 degrees here
    np.testing.assert_allclose(e[tail, :2], 0.0, atol=1.2e-2 if name == "riann" else 5e-3)
    if filters.FILTERS[name].has_yaw:
        assert np.abs(angle_diff(e[tail, 2], truth[tail, 2])).max() < 1e-2


def test_unknown_filter_and_bad_shapes_are_rejected():
    with pytest.raises(ValueError, match="unknown filter"):
        filters.run_filter("kalman9000", np.zeros((5, 3)), np.zeros((5, 3)), None, 100.0)
    with pytest.raises(ValueError, match=r"acc has 4 rows but gyro has 5"):
        filters.run_filter("vqf", np.zeros((5, 3)), np.ones((4, 3)), None, 100.0)
    with pytest.raises(ValueError, match="fs must be a positive"):
        filters.run_filter("vqf", np.zeros((5, 3)), np.ones((5, 3)), None, 0.0)


def test_a_repeated_run_comes_from_the_memo_unchanged():
    rec = pose_recording(turning, 5.0)
    memo = filters.memo
    first = filters.run_filter("vqf", rec.gyro, rec.acc, rec.mag, rec.fs, tauAcc=2.0)
    hits = memo.hits
    first[:] = 0.0  # the caller's copy: changing it changes nothing stored
    again = filters.run_filter("vqf", rec.gyro.copy(), rec.acc, rec.mag, rec.fs, tauAcc=2.0)
    assert memo.hits == hits + 1
    np.testing.assert_array_equal(again, filters.vqf(rec.gyro, rec.acc, rec.mag, rec.fs, tauAcc=2.0))
    misses = memo.misses
    other = filters.run_filter("vqf", rec.gyro, rec.acc, rec.mag, rec.fs, tauAcc=5.0)
    moved = rec.gyro.copy()
    moved[100, 0] += 1e-9
    filters.run_filter("vqf", moved, rec.acc, rec.mag, rec.fs, tauAcc=2.0)
    assert memo.misses == misses + 2  # other parameters, other data: computed
    np.testing.assert_array_equal(other, filters.vqf(rec.gyro, rec.acc, rec.mag, rec.fs, tauAcc=5.0))


def test_a_grid_run_in_worker_processes_gives_the_same_bits_and_is_stored_here():
    rec = pose_recording(turning, 3.0)
    rng = np.random.default_rng(5)
    acc = rec.acc + 0.05 * rng.normal(size=rec.acc.shape)  # noisy tilt: tauAcc matters
    calls = [("vqf", rec.gyro, acc, rec.mag, rec.fs, {"tauAcc": t}) for t in (1.0, 2.0, 4.0)]
    calls.append(("fusion", rec.gyro, acc, rec.mag, rec.fs, {"gain": 0.2}))
    filters.memo.clear()
    parallel = filters.run_many(calls, jobs=2)        # computed in two workers
    assert filters.memo.hits == 0 and len(parallel) == 4
    with filters.memo.bypassed():
        serial = filters.run_many(calls)               # computed here, one after the other
    for p, s in zip(parallel, serial):
        np.testing.assert_array_equal(p, s)
    assert np.abs(parallel[0] - parallel[2]).max() > 1e-4
    again = filters.run_many(calls, jobs=2)
    assert filters.memo.hits == 4                      # stored in this process
    np.testing.assert_array_equal(again[3], serial[3])


def test_riann_model_file_is_found_explicitly():
    assert filters.riann_model_path().endswith("riann.onnx")


# --- the KF-based and post-processing baselines ------------------------------------------------

def _ctx(recs, **kw):
    return baselines.Context(train=list(recs), clean={r.name: np.ones(len(r), bool) for r in recs},
                             alignment=FrameAlignment.identity(), **kw)


@pytest.mark.parametrize("method", ["paper_kf", "tuned_kf", "butterworth", "moving_average", "linear_map"])
def test_kf_baselines_on_a_static_pose(method):
    recs = [pose_recording(static, 30.0, name=f"s{i}") for i in range(2)]
    m = baselines.make_method(method).fit(_ctx(recs))
    (e,) = m.predict(recs[0])
    tail = e[-500:]
    # the accelerometer roll formula of the paper is exact only at zero pitch: asin(sin(roll) cos(pitch))
    # and the heading is tilt-compensated with that roll: the KF converges to the measurements
    roll_acc = np.arcsin(np.sin(STATIC[0]) * np.cos(STATIC[1]))
    from danae_lite.kalman.model import mag_heading

    yaw_mag = float(mag_heading(recs[0].mag[:1], roll_acc, STATIC[1])[0])
    assert abs(yaw_mag - STATIC[2]) > 1e-3  # the measurement itself is biased by the roll formula
    # the linear map is trained against the truth, so it also removes that constant bias
    expected = STATIC if method == "linear_map" else [roll_acc, STATIC[1], yaw_mag]
    np.testing.assert_allclose(tail, np.tile(expected, (500, 1)), atol=2e-3)


def _total_error_rmse(est_by_name, recs, ctx):
    """Total-rotation RMSE [rad] from quaternion dot products (independent of total_objective)."""
    from danae_lite.angles import euler_to_quat

    angles = []
    for r in recs:
        ok = ctx.clean[r.name]
        dot = np.abs(np.sum(euler_to_quat(est_by_name[r.name][ok]) * r.quat[ok], axis=1))
        angles.append(2.0 * np.arccos(np.clip(dot, 0.0, 1.0)))
    a = np.concatenate(angles)
    return float(np.sqrt(np.mean(a * a)))


def test_tuned_kf_searches_jointly_and_beats_the_paper_kf_on_training_data():
    from danae_lite.data.simulate import simulate

    recs = [simulate("handheld", duration=30.0, seed=s) for s in (1, 2)]
    ctx = _ctx(recs)
    tuned = baselines.make_method("tuned_kf").fit(ctx)
    assert len(tuned.search) == len(baselines.KF_Q_ANGLE) ** 2 * len(baselines.KF_Q_BIAS)
    best = tuned.search.loc[tuned.search["objective"].idxmin()]
    assert tuned.params == {"q_tilt": best.q_tilt, "q_bias": best.q_bias, "q_yaw": best.q_yaw}
    assert tuned.config.wrap_yaw_innovation and np.diag(tuned.config.Q).tolist() == [
        best.q_tilt, best.q_bias, best.q_tilt, best.q_bias, best.q_yaw, best.q_bias]
    paper = baselines.make_method("paper_kf").fit(ctx)
    est = lambda m: {r.name: m.predict(r)[0] for r in recs}  # noqa: E731
    assert _total_error_rmse(est(tuned), recs, ctx) == pytest.approx(best.objective, rel=1e-9)
    assert _total_error_rmse(est(tuned), recs, ctx) < _total_error_rmse(est(paper), recs, ctx)


def test_constant_is_the_training_mean_and_the_smoother_smooths_the_tuned_kf():
    from danae_lite.kalman.filter import run_kf
    from danae_lite.kalman import offline
    from danae_lite.data.simulate import simulate

    recs = [simulate("handheld", duration=30.0, seed=s) for s in (1, 2)]
    ctx = _ctx(recs)
    const = baselines.make_method("constant").fit(ctx)
    e = np.concatenate([r.euler for r in recs])
    np.testing.assert_allclose(const.predict(recs[0])[0][5], [e[:, 0].mean(), e[:, 1].mean(),
                                                              np.angle(np.exp(1j * e[:, 2]).mean())])
    rts = ctx.method("tuned_kf_rts")
    smooth = offline.rts_smooth(run_kf(recs[0], ctx.method("tuned_kf").config))
    got = rts.predict(recs[0])[0]
    np.testing.assert_allclose(got[:, :2], smooth[:, [0, 2]], atol=1e-12)
    assert not rts.causal and const.causal and ctx.method("tuned_kf").causal


def test_butterworth_is_the_digital_filter_with_the_stated_cutoff():
    fs, fc = 100.0, 2.0
    t = np.arange(20000) / fs
    # zero-phase (forward-backward) filtering squares the magnitude: -6.02 dB at the cut-off, DC unchanged
    for f, gain in ((0.0, 1.0), (fc, 0.5)):
        x = np.cos(2 * np.pi * f * t)
        y = post_processing.butterworth_lowpass(x, fc, fs)
        mid = slice(5000, 15000)
        assert np.sqrt(np.mean(y[mid] ** 2) / np.mean(x[mid] ** 2)) == pytest.approx(gain, rel=1e-3)
    b, a = signal.butter(2, fc / (fs / 2))  # the same filter from the normalised frequency
    w, h = signal.freqz(b, a, worN=[fc], fs=fs)
    assert abs(h[0]) == pytest.approx(1 / np.sqrt(2), rel=1e-9)
    with pytest.raises(ValueError, match="Nyquist"):
        post_processing.butterworth_lowpass(t, 60.0, fs)


def test_moving_average_by_hand():
    x = np.array([0.0, 3.0, 6.0, 3.0, 0.0])
    np.testing.assert_allclose(post_processing.moving_average(x, 3), [1.0, 3.0, 4.0, 3.0, 1.0])
    with pytest.raises(ValueError, match="odd"):
        post_processing.moving_average(x, 4)


def test_linear_map_recovers_a_known_linear_corruption_exactly():
    rng = np.random.default_rng(0)
    truth = [np.cumsum(rng.normal(0, 0.05, n)) for n in (500, 700)]
    est = [0.8 * y + 0.1 for y in truth]  # scale and offset: undone exactly by an affine window map
    W = post_processing.fit_linear_map(est, truth)
    for x, y in zip(est, truth):
        np.testing.assert_allclose(post_processing.apply_linear_map(W, x), y, atol=1e-9)
    # masked targets are left out of the fit: corrupting them changes nothing
    bad = [y.copy() for y in truth]
    bad[0][100:110] += 5.0
    mask = [np.ones(len(y), bool) for y in truth]
    mask[0][100:110] = False
    W_masked = post_processing.fit_linear_map(est, bad, masks=mask)
    np.testing.assert_allclose(post_processing.apply_linear_map(W_masked, est[1]), truth[1], atol=1e-9)


@pytest.mark.parametrize("name", ["fusion", "vqf", "madgwick", "mahony"])
def test_every_value_of_each_joint_grid_runs_and_the_minimum_is_chosen(name):
    from danae_lite.data.simulate import simulate

    recs = [simulate("handheld", duration=5.0, seed=1)]
    m = baselines.make_method(name).fit(_ctx(recs))
    grid = filters.FILTERS[name].grid
    assert len(m.search) == int(np.prod([len(v) for v in grid.values()]))
    assert np.isfinite(m.search.objective).all()
    best = m.search.loc[m.search.objective.idxmin()]
    assert m.params == {k: best[k] for k in grid}


def _moving_noisy(seconds: float = 12.0) -> Recording:
    """A recording that turns about every axis, its sensors noisy and biased: the filters'
    corrections, gyro-bias terms and gradient steps are all active."""
    def wobble(t):
        return np.column_stack([0.4 * np.sin(0.7 * t), 0.3 * np.sin(0.5 * t + 1.0), -2.0 + 0.4 * t])
    rec = pose_recording(wobble, seconds)
    rng = np.random.default_rng(11)
    gyro = rec.gyro + 0.01 + 0.02 * rng.normal(size=rec.gyro.shape)
    acc = rec.acc + 0.03 * rng.normal(size=rec.acc.shape)
    mag = rec.mag + 0.02 * rng.normal(size=rec.mag.shape)
    return Recording("noisy", "test", FS, gyro, acc, mag, rec.quat)


@pytest.mark.parametrize("name", ["mahony", "madgwick"])
def test_a_whole_grid_in_one_pass_equals_the_library_run_by_run(name):
    # reference: ahrs's own classes, one run per grid point. The one-pass form evaluates the
    # same equations in the same order but through numpy arrays (sums of 3-4 products may
    # round differently): float64 rounding, 1e-16 per step, stays below 1e-9 over 1,200 steps
    # of these contracting filters
    rec = _moving_noisy()
    grid = [dict(zip(filters.FILTERS[name].grid, v)) for v in
            ([(0.3, 0.003), (3.0, 0.3), (10.0, 0.0003)] if name == "mahony" else [(0.005,), (0.041,), (0.16,)])]
    spec = filters.FILTERS[name]
    one_pass = spec.run_grid(rec.gyro, rec.acc, rec.mag, rec.fs, grid)
    assert one_pass is not None and len(one_pass) == 3
    for params, q in zip(grid, one_pass):
        library = spec.run(rec.gyro, rec.acc, rec.mag, rec.fs, **params)
        assert np.abs(q - library).max() < 1e-9
    assert np.abs(one_pass[0] - one_pass[2]).max() > 1e-3  # the gains matter on this recording


def test_a_grid_without_magnetometer_runs_through_the_library():
    rec = _moving_noisy(3.0)
    calls = [("mahony", rec.gyro, rec.acc, None, rec.fs, {"k_P": k}) for k in (0.3, 3.0)]
    assert filters.FILTERS["mahony"].run_grid(rec.gyro, rec.acc, None, rec.fs, [c[5] for c in calls]) is None
    filters.memo.clear()
    for q, (_, g, a, m, fs, p) in zip(filters.run_many(calls), calls):
        np.testing.assert_array_equal(q, filters.mahony(g, a, m, fs, **p))


def test_run_many_groups_a_grid_by_recording_and_keeps_the_order():
    rec, other = _moving_noisy(3.0), _moving_noisy(2.0)
    calls = [("madgwick", r.gyro, r.acc, r.mag, r.fs, {"gain": b}) for b in (0.01, 0.08) for r in (rec, other)]
    calls.append(calls[0])  # a repeated run: computed once
    filters.memo.clear()
    out = filters.run_many(calls)
    assert filters.memo.misses == 5 and filters.memo.nbytes == sum(q.nbytes for q in out[:4])
    for q, (_, g, a, m, fs, p) in zip(out, calls):
        assert np.abs(q - filters.madgwick(g, a, m, fs, **p)).max() < 1e-9


def test_enu_to_nwu_is_scipys_composition_bit_for_bit():
    # the cache key of a network holds its inputs' bytes: the rotation must give SciPy's bits
    rng = np.random.default_rng(3)
    q = rng.normal(size=(20_000, 4))
    q *= (1 + 1e-9 * rng.normal(size=(20_000, 1))) / np.linalg.norm(q, axis=1, keepdims=True)
    rec = _moving_noisy(5.0)
    q_vqf = filters.vqf(rec.gyro, rec.acc, rec.mag, rec.fs)  # a real filter's output, in NWU
    for x in (q, q_vqf, q * 3.0):
        scipy_way = (filters._ENU_TO_NWU * Rotation.from_quat(x)).as_quat()
        np.testing.assert_array_equal(filters._enu_to_nwu(x), scipy_way)


def test_a_grid_searchs_runs_are_not_kept_a_single_run_is_the_library_path():
    # whether or not a search ran first, run_filter of the chosen setting computes the same
    # bits: the one-pass grid (float64 rounding away from the library) is not reused for it
    rec = _moving_noisy(3.0)
    grid = [{"gain": b} for b in (0.01, 0.041, 0.08)]
    filters.memo.clear()
    searched = filters.run_many([("madgwick", rec.gyro, rec.acc, rec.mag, rec.fs, p) for p in grid],
                                persist=False)
    assert filters.memo.nbytes == 0
    single = filters.run_filter("madgwick", rec.gyro, rec.acc, rec.mag, rec.fs, gain=0.041)
    library = filters.madgwick(rec.gyro, rec.acc, rec.mag, rec.fs, gain=0.041)
    np.testing.assert_array_equal(single, library)
    assert 0 < np.abs(searched[1] - library).max() < 1e-9  # the two paths differ, in rounding only
