"""Throughput of the paper's Kalman filter (:func:`danae_lite.kalman.run_kf`).

Builds a 100,000-sample recording (the simulator's hand-held scenario, 1000 s at 100 Hz;
random sensor arrays if the simulator is unavailable), filters it best-of-5 with the
authors' setting and prints samples per second and milliseconds per 100k samples, for the
decoupled block path and the general 6x3-gain path.

Usage: ``python benchmarks/kf_throughput.py [--repeats 5]``
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from danae_lite.kalman import KFConfig, run_kf
from danae_lite.recording import Recording


def make_recording(n: int = 100_000, seed: int = 0) -> Recording:
    """A 100k-sample recording: the simulator's hand-held walk, or random arrays."""
    try:
        from danae_lite.simulate import simulate
    except ImportError:
        simulate = None
    if simulate is not None:
        rec = simulate("handheld", duration=n / 100.0, seed=seed)
        if len(rec) == n:
            return rec
    rng = np.random.default_rng(seed)
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    return Recording(
        name="random",
        source="random",
        fs=100.0,
        gyro=rng.normal(0.0, 0.3, (n, 3)),
        acc=rng.normal(0.0, 0.1, (n, 3)) + [0.0, 0.0, 1.0],
        mag=rng.normal(0.0, 2.0, (n, 3)) + [24.0, 0.0, -41.6],
        quat=quat,
    )


def best_of(fn, repeats: int) -> tuple[float, float]:
    """Best wall-clock time and best process CPU time [s] of ``repeats`` calls.

    The CPU time is less sensitive to other processes competing for the cores.
    """
    wall = cpu = float("inf")
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--samples", type=int, default=100_000)
    args = parser.parse_args()
    rec = make_recording(args.samples)
    cfg = KFConfig.authors()
    print(f"{rec!r}, config {cfg!r}")
    for method in ("block", "general"):
        run_kf(rec, cfg, method=method)  # warm-up
        wall, cpu = best_of(lambda: run_kf(rec, cfg, method=method), args.repeats)
        n = len(rec)
        print(
            f"{method:>7} path: {n / wall:10,.0f} samples/s  {wall * 1e3 * 100_000 / n:7.1f} ms per 100k samples"
            f"  (CPU time: {n / cpu:10,.0f} samples/s)  best of {args.repeats}"
        )


if __name__ == "__main__":
    main()
