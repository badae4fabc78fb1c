"""Ground-truth clean mask: each glitch kind on synthetic rotations, sign invariance, inputs, real OxIOD counts."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from danae_lite.data.groundtruth import (GlitchReport, clean_mask, detect_glitches,
                                         glitch_table)
from danae_lite.data.oxiod import load_recording
from danae_lite.data.recording import Recording

FS = 100.0
KICK = Rotation.from_euler("x", 0.5)  # a 0.5 rad glitch: 50 rad/s at 100 Hz


def smooth(n: int = 1000, rate: float = 0.3) -> tuple[Rotation, np.ndarray]:
    """A smooth rotation (yaw at ``rate`` rad/s plus a roll wobble) and its body gyro (N, 3) [rad/s]."""
    t = np.arange(n) / FS
    rot = Rotation.from_euler("ZYX", np.c_[rate * t, 0.1 * np.sin(t), 0.2 * np.sin(0.7 * t)])
    inc = (rot[:-1].inv() * rot[1:]).as_rotvec() * FS
    return rot, np.vstack([inc, inc[-1:]])


def bad_of(quat: np.ndarray, **kw) -> list[int]:
    return np.flatnonzero(~detect_glitches(quat, FS, **kw).clean).tolist()


def test_smooth_rotation_is_all_clean():
    rot, gyro = smooth()
    for g in (None, gyro):
        r = detect_glitches(rot.as_quat(), FS, gyro=g)
        assert r.clean.all() and r.n_bad == 0 and r.summary()["fraction_bad"] == 0.0 and r.summary()["samples"] == 1000
        assert r.steps.size == r.spikes.size == r.jumps.size == len(r.excursions) == len(r.frozen) == 0
        assert r.threshold_rad == pytest.approx(0.2)


def test_single_sample_spike():
    rot, gyro = smooth()
    q = rot.as_quat()
    q[300] = (rot[300] * KICK).as_quat()
    for g in (None, gyro):
        r = detect_glitches(q, FS, gyro=g)
        assert bad_of(q, gyro=g) == [300] and r.spikes.tolist() == [300] and r.steps.tolist() == [299, 300]
        assert r.jumps.size == 0 and len(r.excursions) == 0


def test_seven_sample_excursion():
    rot, gyro = smooth()
    q = rot.as_quat()
    q[400:407] = (rot[400:407] * KICK).as_quat()
    r = detect_glitches(q, FS)
    assert bad_of(q) == list(range(400, 407))
    assert r.excursions.tolist() == [[400, 407]] and r.spikes.size == 0 and r.jumps.size == 0


def test_gyro_lets_an_excursion_during_fast_motion_come_back():
    rot, gyro = smooth(rate=2.0)  # 0.02 rad per sample: 0.16 rad over the excursion, above quiet = 0.05
    q = rot.as_quat()
    q[400:407] = (rot[400:407] * KICK).as_quat()
    assert bad_of(q, gyro=gyro) == list(range(400, 407))
    without = detect_glitches(q, FS)  # no gyro: the return cannot be told from motion, so two jumps
    assert without.jumps.tolist() == [399, 406] and len(without.excursions) == 0


def test_gyro_explains_a_fast_true_rotation():
    rot, gyro = smooth(rate=30.0)  # 0.3 rad per sample, truly turning: seen by the gyro
    assert detect_glitches(rot.as_quat(), FS, gyro=gyro).clean.all()
    assert detect_glitches(rot.as_quat(), FS).steps.size == 999  # without gyro every step is big


def test_isolated_jump_marks_the_margin():
    rot, _ = smooth()
    q = rot.as_quat()
    q[500:] = (rot[500:] * KICK).as_quat()  # offset that persists: step 499 -> 500
    r = detect_glitches(q, FS)
    assert r.jumps.tolist() == [499] and r.spikes.size == 0
    assert bad_of(q) == list(range(490, 510))  # default margin 0.1 s = 10 samples each side
    assert bad_of(q, margin=0.05) == list(range(495, 505))
    assert bad_of(q, margin=0.0) == [499, 500]  # at least one sample each side


def test_jump_at_the_edges_is_clipped():
    rot, _ = smooth(100)
    q = rot.as_quat()
    q[3:] = (rot[3:] * KICK).as_quat()
    assert bad_of(q) == list(range(0, 13))


def test_frozen_run_of_ten():
    rot, _ = smooth()
    q = rot.as_quat()
    q[600:610] = q[600]
    r = detect_glitches(q, FS)
    assert bad_of(q) == list(range(601, 610))  # 9 stale samples; the resume step is small
    assert r.frozen.tolist() == [[600, 10]] and r.summary()["frozen_samples"] == 9
    q[700:704] = q[700]  # 4 identical samples: shorter than min_frozen = 5
    assert bad_of(q) == list(range(601, 610))
    assert bad_of(q, min_frozen=4) == list(range(601, 610)) + [701, 702, 703]


def test_frozen_run_resuming_with_a_big_step():
    rot, _ = smooth(rate=1.5)  # 15 stale samples drift 0.225 rad > 0.2 from the truth
    q = rot.as_quat()
    q[600:616] = q[600]
    r = detect_glitches(q, FS)
    assert r.steps.tolist() == [615] and r.jumps.size == 0  # the resume is not a jump
    assert bad_of(q) == list(range(601, 617))


def test_frozen_run_held_at_a_glitch():
    rot, _ = smooth()
    q = rot.as_quat()
    q[600:610] = (rot[600] * KICK).as_quat()  # out at 599, frozen, back at 609 -> 610
    r = detect_glitches(q, FS)
    assert r.excursions.tolist() == [[600, 610]] and r.jumps.size == 0
    assert bad_of(q) == list(range(600, 611))  # the excursion plus the big resume sample


def test_sign_flips_are_not_glitches():
    rng = np.random.default_rng(1)
    rot, gyro = smooth()
    q = rot.as_quat()
    flip = rng.random(len(q)) < 0.3
    q[flip] *= -1.0
    assert detect_glitches(q, FS).clean.all() and detect_glitches(q, FS, gyro=gyro).clean.all()
    q[600:610] = q[600] * np.where(np.arange(10) % 2, -1.0, 1.0)[:, None]  # frozen up to sign
    assert bad_of(q) == list(range(601, 610))


def combined() -> tuple[np.ndarray, np.ndarray, list[int]]:
    rot, gyro = smooth(2000)
    q = rot.as_quat()
    q[100] = (rot[100] * KICK).as_quat()
    q[300:307] = (rot[300:307] * Rotation.from_euler("y", 2.5)).as_quat()
    q[800:] = (rot[800:] * KICK).as_quat()
    q[1200:1210] = q[1200]
    q[1500] = (rot[1500] * KICK.inv()).as_quat()
    expect = [100] + list(range(300, 307)) + list(range(790, 810)) + list(range(1201, 1210)) + [1500]
    flip = np.random.default_rng(2).random(len(q)) < 0.5
    q[flip] *= -1.0
    return q, gyro, expect


def test_combination_of_every_kind():
    q, gyro, expect = combined()
    for g in (None, gyro):
        r = detect_glitches(q, FS, gyro=g)
        assert np.flatnonzero(~r.clean).tolist() == expect
        s = r.summary()
        assert (s["spikes"], s["excursions"], s["excursion_samples"], s["jumps"], s["frozen_runs"],
                s["frozen_samples"], s["bad_samples"]) == (2, 1, 7, 1, 1, 9, len(expect))
        assert s["fraction_bad"] == pytest.approx(len(expect) / 2000)
        json.dumps(s)
        assert all(type(v) in (int, float) for v in s.values())


def test_large_input_is_fast():
    q, gyro, _ = combined()
    q = np.tile(q, (20, 1))  # 40,000 samples
    t0 = time.perf_counter()
    detect_glitches(q, FS, gyro=np.tile(gyro, (20, 1)))
    assert time.perf_counter() - t0 < 1.0


def report(clean: list[bool]) -> GlitchReport:
    e = np.zeros(0, dtype=np.int64)
    return GlitchReport(clean=np.array(clean), threshold_rad=0.2, max_step_rad=0.0, steps=e, spikes=e,
                        excursions=e.reshape(0, 2), jumps=e, frozen=e.reshape(0, 2))


def test_counts_of_a_hand_built_mask():
    s = report([True, True, False, True, True, True, False, False, True]).summary()
    assert (s["samples"], s["bad_samples"]) == (9, 3) and s["fraction_bad"] == pytest.approx(1 / 3)


@pytest.mark.parametrize("quat, fs, kw, match", [
    (np.ones((10, 3)), FS, {}, r"quat must have shape \(N, 4\)"),
    (np.ones(4), FS, {}, r"quat must have shape \(N, 4\)"),
    (np.zeros((0, 4)), FS, {}, r"quat must have shape \(N, 4\)"),
    (np.r_[np.ones((3, 4)), np.zeros((1, 4))], FS, {}, "quat row 3 is zero"),
    (np.r_[np.ones((3, 4)), [[np.nan, 0, 0, 1]]], FS, {}, "quat row 3 is not finite"),
    (np.ones((10, 4)), 0.0, {}, "fs must be a positive number of Hz"),
    (np.ones((10, 4)), -100.0, {}, "fs must be a positive number of Hz"),
    (np.ones((10, 4)), float("nan"), {}, "fs must be a positive number of Hz"),
    (np.ones((10, 4)), FS, {"gyro": np.ones((9, 3))}, r"gyro must be a finite \(10, 3\) array"),
    (np.ones((10, 4)), FS, {"max_rate": 0.0}, "need max_rate > 0"),
    (np.ones((10, 4)), FS, {"min_frozen": 1}, "integer min_frozen >= 2"),
])
def test_bad_inputs_raise(quat, fs, kw, match):
    with pytest.raises(ValueError, match=match):
        detect_glitches(quat, fs, **kw)


def test_clean_mask_and_table_from_recordings():
    q, gyro, expect = combined()
    n = len(q)
    rec = Recording(name="synthetic", source="test", fs=FS, gyro=gyro, acc=np.ones((n, 3)), mag=np.ones((n, 3)),
                    quat=q)
    assert np.flatnonzero(~clean_mask(rec)).tolist() == expect
    tab = glitch_table([rec, rec.slice(0, 50, name="head")])
    assert list(tab.columns) == ["name", "samples", "spikes", "excursions", "jumps", "frozen samples",
                                 "bad samples", "bad %"]
    assert tab.iloc[0].tolist() == ["synthetic", 2000, 2, 1, 1, 9, len(expect), pytest.approx(100 * len(expect) / n)]
    assert tab.iloc[1].tolist() == ["head", 50, 0, 0, 0, 0, 0, 0.0]


def test_the_same_glitches_without_the_gyro():
    q, _, _ = combined()
    r = detect_glitches(q, FS)  # as for a recording without a usable gyro
    assert r.spikes.tolist() == [100, 1500]
    assert (r.jumps.tolist(), len(r.excursions), r.frozen.tolist()) == ([799], 1, [[1200, 10]])


# measured with the gyro (clean_mask / glitch_table defaults):
# samples, spikes, excursions, jumps, frozen (stale) samples, bad samples
REAL = {
    2: (23_446, 2, 2, 3, 22, 92),
    3: (18_850, 1, 4, 2, 7, 126),
    4: (21_641, 0, 2, 2, 6, 56),
    7: (14_098, 0, 6, 2, 0, 85),
}


@pytest.mark.realdata
def test_real_glitch_counts(oxiod_dir):
    syn = oxiod_dir / "handheld" / "data1" / "syn"
    recs = [load_recording(syn / f"imu{k}.csv") for k in REAL]
    tab = glitch_table(recs)
    for row, (k, want) in zip(tab.itertuples(index=False), REAL.items()):
        assert row.name == f"handheld/data1/imu{k}"
        assert tuple(row[1:7]) == want, (k, tuple(row[1:7]))
        assert row[7] < 1.0  # under 1 % of the samples are lost
    for rec in recs:
        r = detect_glitches(rec.quat, rec.fs, gyro=rec.gyro)
        assert np.array_equal(clean_mask(rec), r.clean)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], r.clean.astype(np.int8), [0]])))
        runs = [b - a for a, b in zip(edges[::2], edges[1::2]) if b - a >= 20]  # clean runs of >= 20 samples
        assert 0 < len(runs) <= 10
        # without the gyro more steps stay unpaired, so more samples are lost
        assert detect_glitches(rec.quat, rec.fs).n_bad >= r.n_bad
