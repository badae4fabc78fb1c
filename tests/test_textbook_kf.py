"""The Kalman step that chapter 1 writes out in plain NumPy is the package's filter.

The chapter's cell tagged ``textbook-kf-step`` defines ``kf_step_by_hand(x, P, u, y, A, B, C,
Q, R) -> (x, P, K)``. These tests execute that cell's source on its own (it may import numpy and
nothing else) and compare the function with :func:`danae_lite.kalman.filter.kf_step` on random
problems and with :func:`danae_lite.kalman.filter.run_kf` over a whole simulated recording, so the
page cannot show a step that differs from the filter the book runs.
"""
import ast
import json
from pathlib import Path

import numpy as np
import pytest

from danae_lite.kalman.filter import kf_step, run_kf
from danae_lite.kalman.model import (KFConfig, accel_tilt, euler_rates, mag_heading,
                                     system_matrices)
from danae_lite.data.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
CHAPTER = ROOT / "notebooks" / "01_kalman_filter.ipynb"
TAG = "textbook-kf-step"
RTOL = 1e-12


def tagged_source(path: Path = CHAPTER, tag: str = TAG) -> str:
    cells = [c for c in json.loads(path.read_text())["cells"] if tag in c.get("metadata", {}).get("tags", [])]
    assert len(cells) == 1, f"{path.name}: expected one cell tagged {tag!r}, found {len(cells)}"
    assert cells[0]["cell_type"] == "code", f"the cell tagged {tag!r} must be a code cell"
    src = cells[0]["source"]
    return src if isinstance(src, str) else "".join(src)


@pytest.fixture(scope="module")
def step():
    """``kf_step_by_hand`` from the chapter's cell, executed in a fresh namespace."""
    namespace: dict = {"__name__": "textbook_kf_step"}
    exec(compile(tagged_source(), f"{CHAPTER.name}[{TAG}]", "exec"), namespace)
    fn = namespace.get("kf_step_by_hand")
    assert callable(fn), f"the cell tagged {TAG!r} must define kf_step_by_hand"
    return fn


def rel_diff(a, b) -> float:
    """max |a - b| relative to max(1, max |b|)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.abs(a - b).max() / max(1.0, float(np.abs(b).max())))


def spd(rng: np.random.Generator, n: int) -> np.ndarray:
    m = rng.normal(size=(n, n))
    return m @ m.T + 0.1 * np.eye(n)


def random_mismatch(fn, n_trials: int = 25, seed: int = 20201) -> float:
    """Largest relative difference of ``fn`` from ``kf_step`` over seeded random problems of
    several sizes (x, P and K compared)."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for trial in range(n_trials):
        n, m, k = [(2, 1, 1), (6, 3, 3), (4, 2, 3), (5, 1, 2)][trial % 4]
        x, u, y = rng.normal(size=n), rng.normal(size=m), rng.normal(size=k)
        A, B, C = rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.normal(size=(k, n))
        P, Q, R = spd(rng, n), spd(rng, n), spd(rng, k)
        ref = kf_step(x, P, u, y, A, B, C, Q, R)
        x1, P1, K1 = fn(x, P, u, y, A, B, C, Q, R)
        assert np.shape(x1) == (n,) and np.shape(P1) == (n, n) and np.shape(K1) == (n, k)
        worst = max(worst, rel_diff(x1, ref.x), rel_diff(P1, ref.P), rel_diff(K1, ref.K))
    return worst


def run_by_hand(fn, rec, config: KFConfig):
    """``fn`` over a recording exactly as ``run_kf`` feeds its equations: input and heading at
    the previous roll/pitch estimates (the truth at step 0, ``init_from_truth``)."""
    A, B, C = system_matrices(config.dt or rec.dt)
    x, P = config.x0.copy(), config.P0.copy()
    roll, pitch = rec.euler[0, :2] if config.init_from_truth else x[[0, 2]]
    tilt = accel_tilt(rec.acc)
    states = np.empty((len(rec), 6))
    K = None
    for t in range(len(rec)):
        u = euler_rates(rec.gyro[t], roll, pitch)[0]
        y = np.array([tilt[t, 0], tilt[t, 1], mag_heading(rec.mag[t], roll, pitch)[0]])
        x, P, K = fn(x, P, u, y, A, B, C, config.Q, config.R)
        states[t] = x
        roll, pitch = x[0], x[2]
    return states, P, K


@pytest.fixture(scope="module")
def recording():
    return simulate("handheld", duration=20.0, seed=7)


def run_mismatch(fn, rec, config=None) -> float:
    config = config or KFConfig()
    ref = run_kf(rec, config)
    states, P, K = run_by_hand(fn, rec, config)
    return max(rel_diff(states, ref.state), rel_diff(P, ref.P), rel_diff(K, ref.gain))


def test_the_cell_is_self_contained_numpy():
    tree = ast.parse(tagged_source())
    imported = {a.name.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.Import) for a in node.names}
    imported |= {node.module.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert imported == {"numpy"}, f"the textbook step may import numpy only, imports {sorted(imported)}"
    defined = [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert defined == ["kf_step_by_hand"], defined


def test_step_equals_kf_step_on_random_problems(step):
    assert random_mismatch(step) <= RTOL


def test_step_over_a_simulated_recording_equals_run_kf(step, recording):
    assert run_mismatch(step, recording) <= RTOL


def test_step_equals_run_kf_with_other_covariances_and_the_authors_dt(step, recording):
    config = KFConfig.authors(Q=np.diag([1e-3, 1e-4] * 3), R=np.diag([0.05, 0.05, 0.2]))
    assert run_mismatch(step, recording, config) <= RTOL


def test_a_perturbed_step_is_detected(step, recording):
    def nudged(*args):  # the state off by 1e-9 rad: far below anything a plot would show
        x, P, K = step(*args)
        return x + 1e-9, P, K

    def forgets_q(x, P, u, y, A, B, C, Q, R):  # a plausible slip: predict without Q
        return step(x, P, u, y, A, B, C, np.zeros_like(Q), R)

    assert random_mismatch(nudged) > 100 * RTOL
    assert random_mismatch(forgets_q) > 1e-3
    assert run_mismatch(nudged, recording) > 100 * RTOL
    assert run_mismatch(forgets_q, recording) > 1e-3


def test_a_missing_or_duplicated_tag_is_reported(tmp_path):
    nb = json.loads(CHAPTER.read_text())
    for c in nb["cells"]:
        c.get("metadata", {}).pop("tags", None)
    probe = tmp_path / "probe.ipynb"
    probe.write_text(json.dumps(nb))
    with pytest.raises(AssertionError, match="found 0"):
        tagged_source(probe)
