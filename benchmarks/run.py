"""Speed benchmarks of the DANAE book: Kalman filter, peer filters, DANAE training and inference.

Everything runs on one simulated recording (the simulator's hand-held scenario, 1000 s at
100 Hz = 100,000 samples; no real data needed), in one process:

1. **Filters** -- samples/s of the paper's KF (:func:`danae_lite.kalman.filter.run_kf`, authors'
   setting, best of 5) beside the field libraries of :mod:`danae_lite.research.ahrs.filters`: Fusion and
   VQF (C/C++, whole recording, best of 5), Madgwick and Mahony (``ahrs``, pure Python:
   first 20,000 samples, best of 3). Target: KF >= 250,000 samples/s (PASS/MISS is printed;
   a miss never fails the run).
2. **DANAE training** -- steps/s and windows/s of the paper network (window 20) trained on
   the KF roll of the recording, at batch 16 and at batch 256 (only the optimiser steps are
   timed: ``TrainResult.seconds / steps``), on the CPU and, when available, on CUDA.
3. **Training throughput against the physical limit** -- windows/s of the bare network step
   (``DanaePaper`` forward + backward + Adam, batch 16, pre-cut windows, nothing else) beside
   :func:`danae_lite.danae.train.train` with the paper's settings on 50,000 windows, validation
   included (``train_loop_windows_per_s``; their ratio is the loop's overhead), the time of
   that whole paper-settings epoch (``paper_epoch_50k_s``), the arithmetic rate it achieves
   (``train_gflops``: 3x the forward FLOPs per window, counted from the layer shapes) and
   the machine's peak for a 2048x2048 float32 matmul on the same threads (``matmul_gflops``).
4. **DANAE inference** -- whole-recording batched :func:`danae_lite.danae.predict.predict` (ms and
   µs per sample) and the streaming cost per sample: the paper network run once per new
   sample on the latest 20-sample window (batch 1, ``torch.no_grad``, 1 thread) -- this is
   ``danae_infer_ms_per_sample`` -- and, when :mod:`danae_lite.research.streaming` is present, the
   latency of :class:`~danae_lite.research.streaming.StreamingDanae` with a small causal network.
   Both are compared with the 10 ms sample period at 100 Hz.

Usage::

    python benchmarks/run.py [--json FILE] [--quick] [--device cpu|cuda]

``--quick`` shrinks everything to a smoke test (well under 30 s). The device for DANAE is
CUDA when ``torch.cuda.is_available()``, else the CPU; ``--device`` overrides. Torch threads
are the process default (``torch.get_num_threads()``: every physical core unless
``OMP_NUM_THREADS`` says otherwise; ``--threads`` overrides); streaming uses 1 thread.
"""
from __future__ import annotations

import argparse
import copy
import datetime as _dt
import importlib
import json
import math
import os
import platform
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

try:
    import danae_lite  # noqa: F401
except ImportError:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import torch

from danae_lite.research.ahrs import filters
from danae_lite.danae.seeding import default_device
from danae_lite.kalman.filter import run_kf
from danae_lite.kalman.model import KFConfig
from danae_lite.data.simulate import simulate
from danae_lite.danae.model import DanaePaper
from danae_lite.danae.predict import predict
from danae_lite.danae.train import train
from danae_lite.danae.train_types import TrainConfig

KF_TARGET = 250_000.0
"""Samples per second the KF should reach (informative only)."""
FS = 100.0
PERIOD_MS = 1000.0 / FS


# --------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------
def log(msg: str = "") -> None:
    print(msg, flush=True)


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (or platform.processor())."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


#: variables that make oneDNN, ATen's vectorised kernels and MKL use AVX2 code only (they
#: must be set before torch is imported, so the AVX2 path runs in a child process)
AVX2_PATH_ENV = {"ONEDNN_MAX_CPU_ISA": "AVX2", "ATEN_CPU_CAPABILITY": "avx2", "MKL_ENABLE_INSTRUCTIONS": "AVX2"}


def cpu_flags() -> set[str]:
    """The CPU's feature flags from /proc/cpuinfo (empty where there is none)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.lower().startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def cpu_isa() -> dict[str, Any]:
    """The instruction sets the CPU has and the one this process's torch kernels use."""
    flags = cpu_flags()
    has = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "other" if flags else "unknown"
    forced = all(os.environ.get(k) == v for k, v in AVX2_PATH_ENV.items())
    return {"cpu": has, "torch_capability": torch.backends.cpu.get_cpu_capability(),
            "path": "AVX2 (forced)" if forced else "native", "avx2_forced": forced}


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def ram_gib() -> float | None:
    try:
        with open("/proc/meminfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return round(int(line.split()[1]) / 1024**2, 1)
    except (OSError, ValueError, IndexError):
        pass
    return None


def _version(module: str) -> str | None:
    try:
        from importlib.metadata import version

        return version(module)
    except Exception:  # noqa: BLE001 - not installed, or no metadata
        return None


def machine_info() -> dict[str, Any]:
    return {
        "python": platform.python_version(),
        "torch": torch.__version__,
        "numpy": np.__version__,
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "usable_cores": usable_cores(),
        "cpu_model": cpu_model(),
        "isa": cpu_isa(),
        "ram_gib": ram_gib(),
        "torch_threads_default": torch.get_num_threads(),
        "cuda_available": bool(torch.cuda.is_available()),
        "cuda_device": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
        "libraries": {m: _version(m) for m in ("imufusion", "vqf", "AHRS")},
    }


def device_label(device: str) -> str:
    if torch.device(device).type == "cuda":
        return f"cuda ({torch.cuda.get_device_name(torch.device(device))})"
    return f"cpu ({usable_cores()} cores, torch {torch.get_num_threads()} thread(s), {cpu_model()})"


def best_of(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """Best wall-clock and best process-CPU time [s] of ``repeats`` calls."""
    wall = cpu = math.inf
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def clean(obj: Any) -> Any:
    """JSON-safe copy: non-finite floats become None, numpy scalars plain numbers."""
    if isinstance(obj, dict):
        return {str(k): clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def sizes(quick: bool) -> dict[str, Any]:
    """How much work each section does."""
    if quick:
        return dict(duration=100.0, kf_repeats=2, fast_repeats=2, slow_samples=500, slow_repeats=1,
                    steps={16: 10, 256: 3}, predict_samples=2000, stream_n=50, stream_warmup=5,
                    causal_steps=5, causal_hidden=(32,), causal_n=100, causal_warmup=10,
                    bare_steps=20, epoch_windows=2_000, matmul_n=256, predict_100k=2_000)
    return dict(duration=1000.0, kf_repeats=5, fast_repeats=5, slow_samples=20_000, slow_repeats=3,
                steps={16: 300, 256: 40}, predict_samples=None, stream_n=1000, stream_warmup=50,
                causal_steps=50, causal_hidden=(32, 128), causal_n=2000, causal_warmup=100,
                bare_steps=600, epoch_windows=50_000, matmul_n=2048, predict_100k=100_000)


# --------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------
def bench_filters(rec: Any, sz: dict[str, Any]) -> dict[str, Any]:
    """KF samples/s beside the library filters; ratios KF/peer."""
    n = len(rec)
    cfg = KFConfig.authors()
    out: dict[str, Any] = {}
    for method in ("auto", "general"):
        res = run_kf(rec, cfg, method=method)  # warm-up (also fills the gain cache)
        wall, cpu = best_of(lambda: run_kf(rec, cfg, method=method), sz["kf_repeats"])
        key = "kf" if method == "auto" else "kf_general"
        out[key] = dict(samples=n, repeats=sz["kf_repeats"], best_s=wall, samples_per_s=n / wall,
                        cpu_samples_per_s=n / cpu, path=res.path)
        log(f"  {key:<10} {n / wall:12,.0f} samples/s  ({res.path} path, CPU time {n / cpu:,.0f}/s, "
            f"best of {sz['kf_repeats']} on {n:,})")
    peers = [("fusion", n, sz["fast_repeats"]), ("vqf", n, sz["fast_repeats"]),
             ("madgwick", min(n, sz["slow_samples"]), sz["slow_repeats"]),
             ("mahony", min(n, sz["slow_samples"]), sz["slow_repeats"])]
    for name, m, reps in peers:
        g, a, mg = rec.gyro[:m], rec.acc[:m], rec.mag[:m]
        try:  # every repeat computed: not the stored output of the first (filters.memo)
            with filters.memo.bypassed():
                filters.run_filter(name, g[: min(m, 200)], a[: min(m, 200)], mg[: min(m, 200)], rec.fs)  # warm-up
                wall, cpu = best_of(lambda: filters.run_filter(name, g, a, mg, rec.fs), reps)
        except ImportError as exc:  # library not installed: report, do not fail
            out[name] = dict(error=f"{type(exc).__name__}: {exc}")
            log(f"  {name:<10} skipped ({exc})")
            continue
        out[name] = dict(samples=m, repeats=reps, best_s=wall, samples_per_s=m / wall, cpu_samples_per_s=m / cpu)
        log(f"  {name:<10} {m / wall:12,.0f} samples/s  (CPU time {m / cpu:,.0f}/s, best of {reps} on {m:,})")
    kf = out["kf"]["samples_per_s"]
    for name, *_ in peers:
        if "samples_per_s" in out[name]:
            out[name]["kf_ratio"] = kf / out[name]["samples_per_s"]
    out["kf_target"] = KF_TARGET
    out["kf_target_met"] = kf >= KF_TARGET
    return out


def bench_training(x: np.ndarray, y: np.ndarray, devices: Sequence[str], sz: dict[str, Any]) -> tuple[dict[str, Any], Any]:
    """Steps/s and windows/s of the paper network at batch 16 and 256, per device.

    Returns the results and the batch-16 TrainResult of the first device (for inference).
    """
    out: dict[str, Any] = {}
    keep = None
    for device in devices:
        out[device] = {}
        for batch, steps in sz["steps"].items():
            cfg = TrainConfig(arch="paper", window=20, batch_size=batch, max_steps=steps, val_fraction=0.0,
                              device=device)
            t0 = time.perf_counter()
            res = train(x, y, cfg, progress=False)
            total = time.perf_counter() - t0
            sps = res.steps / res.seconds
            out[device][str(batch)] = dict(batch_size=batch, steps=res.steps, seconds=res.seconds,
                                           steps_per_s=sps, windows_per_s=sps * batch,
                                           call_seconds=total, n_train_windows=res.n_train_windows,
                                           threads=torch.get_num_threads() if device == "cpu" else None)
            log(f"  {device:<5} batch {batch:>3}: {sps:8.2f} steps/s  {sps * batch:9,.0f} windows/s  "
                f"({res.steps} steps in {res.seconds:.1f} s; whole call {total:.1f} s)")
            if keep is None and batch == 16:
                keep = res
    return out, keep


def forward_flops(net: Any, window: int) -> int:
    """Floating-point operations of one forward pass over one window (2 per multiply-add),
    counted from the shapes of the (transposed) convolutions."""
    macs = 0

    def hook(m: Any, inp: Any, out: Any) -> None:
        nonlocal macs
        c_in = m.in_channels // m.groups
        macs += out.shape[1] * out.shape[2] * c_in * m.kernel_size[0]

    convs = [m for m in net.modules() if isinstance(m, (torch.nn.Conv1d, torch.nn.ConvTranspose1d))]
    handles = [m.register_forward_hook(hook) for m in convs]
    try:
        with torch.no_grad():
            net(torch.zeros(1, net.in_channels, window))
    finally:
        for h in handles:
            h.remove()
    # a transposed convolution's output sample sums over its kernel taps that land on it; with
    # stride 1 each output sample still takes c_in * k products (edge samples fewer: an upper bound)
    return 2 * macs


def matmul_peak(n: int, device: str, seconds: float = 2.0) -> dict[str, Any]:
    """GFLOP/s of an n x n float32 matmul (best of repeated timings over ``seconds``)."""
    a = torch.randn(n, n, device=device)
    b = torch.randn(n, n, device=device)
    sync = torch.cuda.synchronize if torch.device(device).type == "cuda" else (lambda: None)
    a @ b
    sync()
    best, t_end = math.inf, time.perf_counter() + seconds
    while time.perf_counter() < t_end:
        t0 = time.perf_counter()
        a @ b
        sync()
        best = min(best, time.perf_counter() - t0)
    return dict(n=n, best_s=best, gflops=2 * n**3 / best / 1e9, threads=torch.get_num_threads())


def bench_throughput(x: np.ndarray, y: np.ndarray, device: str, sz: dict[str, Any]) -> dict[str, Any]:
    """The bare network step beside train.train, the achieved GFLOP/s beside the matmul peak."""
    window, batch = 20, 16
    # -- bare step: pre-cut windows, forward + backward + Adam, nothing else
    torch.manual_seed(0)
    net = DanaePaper(window=window).to(device)
    fused = torch.device(device).type in ("cpu", "cuda")
    opt = torch.optim.Adam(net.parameters(), lr=0.002, fused=fused)
    n_win = len(x) - window + 1
    idx_all = np.arange(window)[None, :] + np.arange(n_win)[:, None]
    xw = torch.from_numpy(x.astype(np.float32)[idx_all][:, None, :]).to(device)
    yw = torch.from_numpy(y.astype(np.float32)[idx_all][:, None, :]).to(device)
    gen = torch.Generator().manual_seed(0)
    sync = torch.cuda.synchronize if torch.device(device).type == "cuda" else (lambda: None)

    def steps(n: int) -> None:
        for _ in range(n):
            idx = torch.randint(0, n_win, (batch,), generator=gen).to(device)
            loss = torch.mean((net.forward_net(xw[idx]) - yw[idx]) ** 2)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
        sync()

    steps(max(5, sz["bare_steps"] // 10))  # warm-up
    t0 = time.perf_counter()
    steps(sz["bare_steps"])
    bare_s = time.perf_counter() - t0
    bare_wps = sz["bare_steps"] * batch / bare_s
    log(f"  bare step ({device}, batch {batch}): {sz['bare_steps'] / bare_s:,.1f} steps/s = {bare_wps:,.0f} windows/s")

    # -- train.train, paper settings (validation included) on a block giving epoch_windows windows
    n = sz["epoch_windows"] + window - 1
    while n - max(window, int(round(0.1 * n))) - window + 1 < sz["epoch_windows"]:
        n += 1
    n = min(n, len(x))
    cfg = TrainConfig(device=device)  # the paper's settings + 10 % validation, ten checks per epoch
    t0 = time.perf_counter()
    res = train(x[:n], y[:n], cfg, progress=False)
    epoch_s = time.perf_counter() - t0
    loop_wps = res.n_train_windows / res.seconds
    log(f"  train.train (paper settings, {res.n_train_windows:,} training + {res.n_val_windows:,} validation "
        f"windows, {len(res.history)} checks): {res.steps / res.seconds:,.1f} steps/s = {loop_wps:,.0f} windows/s "
        f"(loop/bare = {loop_wps / bare_wps:.2f}); whole call {epoch_s:.1f} s")

    flops_fwd = forward_flops(net, window)
    train_gflops = 3 * flops_fwd * loop_wps / 1e9
    peak = matmul_peak(sz["matmul_n"], device)
    log(f"  forward {flops_fwd / 1e6:.1f} MFLOP per window; training achieves {train_gflops:,.1f} GFLOP/s "
        f"(bare {3 * flops_fwd * bare_wps / 1e9:,.1f}) vs matmul peak {peak['gflops']:,.1f} GFLOP/s "
        f"on {peak['threads']} thread(s): {train_gflops / peak['gflops']:.2f} of the peak")
    return dict(device=device, batch_size=batch, threads=torch.get_num_threads() if device == "cpu" else None,
                bare_steps=sz["bare_steps"], bare_seconds=bare_s, bare_windows_per_s=bare_wps,
                loop_windows_per_s=loop_wps, loop_over_bare=loop_wps / bare_wps,
                epoch_windows=res.n_train_windows, val_windows=res.n_val_windows, checks=len(res.history),
                epoch_steps=res.steps, epoch_loop_seconds=res.seconds, epoch_call_seconds=epoch_s,
                forward_flops_per_window=flops_fwd, train_gflops=train_gflops,
                bare_gflops=3 * flops_fwd * bare_wps / 1e9, matmul=peak,
                train_over_peak=train_gflops / peak["gflops"])


@torch.no_grad()
def paper_stream(net: Any, x: np.ndarray, n: int, warmup: int) -> dict[str, Any]:
    """Per-sample cost of one forward pass of the paper network over the latest window."""
    net = copy.deepcopy(net).cpu().eval()
    L = net.window
    x = np.asarray(x, dtype=np.float32).reshape(len(x), -1)
    n = min(n, len(x) - L - warmup)
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    times = np.empty(n)
    try:
        for i in range(warmup + n):
            t0 = time.perf_counter()
            w = torch.from_numpy(np.ascontiguousarray(x[i : i + L].T))[None]  # (1, C, L)
            _ = float(net(w)[0, 0, -1])  # newest sample's estimate
            if i >= warmup:
                times[i - warmup] = time.perf_counter() - t0
    finally:
        torch.set_num_threads(old)
    ms = times * 1e3
    med, p99 = float(np.median(ms)), float(np.percentile(ms, 99))
    return dict(n=int(n), num_threads=1, window=L, mean_ms=float(ms.mean()), median_ms=med, p99_ms=p99,
                max_ms=float(ms.max()), period_ms=PERIOD_MS, median_fraction=med / PERIOD_MS,
                p99_fraction=p99 / PERIOD_MS, real_time=bool(p99 < PERIOD_MS),
                delay_samples=L - 1, delay_ms=(L - 1) * PERIOD_MS)


def bench_inference(result: Any, x: np.ndarray, y: np.ndarray, sz: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    # whole recording, batched, on the training device
    xp = x if sz["predict_samples"] is None else x[: sz["predict_samples"]]
    t0 = time.perf_counter()
    predict(result, xp)
    sec = time.perf_counter() - t0
    out["predict"] = dict(samples=len(xp), device=result.device, seconds=sec, ms_total=sec * 1e3,
                          us_per_sample=sec * 1e6 / len(xp), samples_per_s=len(xp) / sec,
                          threads=torch.get_num_threads() if result.device == "cpu" else None)
    log(f"  predict (batched, {result.device}): {sec * 1e3:,.0f} ms for {len(xp):,} samples = "
        f"{sec * 1e6 / len(xp):.1f} µs/sample")

    # predict over a 100k-sample recording (the headline inference time)
    n100 = min(len(x), sz["predict_100k"])
    t0 = time.perf_counter()
    predict(result, x[:n100])
    out["predict_100k"] = dict(samples=n100, seconds=time.perf_counter() - t0, device=result.device)
    log(f"  predict over {n100:,} samples: {out['predict_100k']['seconds']:.2f} s")

    # streaming with the paper network: one 20-sample window per new sample
    ps = paper_stream(result.model, x, sz["stream_n"], sz["stream_warmup"])
    out["paper_stream"] = ps
    log(f"  paper net, one window per sample (cpu, 1 thread): median {ps['median_ms']:.2f} ms, "
        f"p99 {ps['p99_ms']:.2f} ms per sample vs {PERIOD_MS:.0f} ms period "
        f"({100 * ps['median_fraction']:.0f} %); plus {ps['delay_samples']} samples look-ahead delay")

    # streaming with a causal network, when the streaming module offers it
    try:
        streaming = importlib.import_module("danae_lite.research.streaming")
        from danae_lite.danae.model import ARCHITECTURES
        ok = hasattr(streaming, "StreamingDanae") and hasattr(streaming, "measure_latency") and "causal" in ARCHITECTURES
    except ImportError:
        ok = False
    out["causal_stream"] = {}
    if not ok:
        log("  causal streaming: danae_lite.research.streaming (StreamingDanae, measure_latency) not available; skipped")
        return out
    n_fit = min(len(x), 20_000)
    for hidden in sz["causal_hidden"]:
        cfg = TrainConfig(arch="causal", hidden=hidden, max_steps=sz["causal_steps"], val_fraction=0.0, device="cpu")
        res = train(x[:n_fit], y[:n_fit], cfg, progress=False)
        streamer = streaming.StreamingDanae(res, num_threads=1)
        need = sz["causal_warmup"] + sz["causal_n"]
        lat = streaming.measure_latency(streamer, sz["causal_n"], fs=FS, warmup=sz["causal_warmup"],
                                        x=x[:need].reshape(need, -1))
        lat["hidden"] = hidden
        lat["receptive_field"] = int(streamer.receptive_field)
        lat["parameters"] = int(sum(p.numel() for p in res.model.parameters()))
        out["causal_stream"][f"h{hidden}"] = lat
        log(f"  causal net h={hidden} ({lat['parameters']:,} params, RF {lat['receptive_field']}), StreamingDanae "
            f"(cpu, 1 thread): median {lat['median_ms']:.3f} ms, p99 {lat['p99_ms']:.3f} ms per sample vs "
            f"{PERIOD_MS:.0f} ms period; real time: {lat['real_time']}")
    out["denoiser_stream"] = bench_denoiser_stream(sz)
    d = out["denoiser_stream"]
    log(f"  DANAE-res on VQF, one sample at a time (features + causal net + gate, cpu, 1 thread): median "
        f"{d['median_ms']:.3f} ms, p99 {d['p99_ms']:.3f} ms per sample; streamed = batch to {d['max_abs_diff_rad']:.1e} rad")
    return out


def bench_denoiser_stream(sz: dict[str, Any]) -> dict[str, Any]:
    """Per-sample latency of the recommended denoiser (:class:`danae_lite.research.danae_res.DenoiserStream`)
    behind VQF, fitted briefly on simulated recordings: one sample's input features, the causal
    network's step and the gated correction, timed together; and its agreement with the batch output."""
    from danae_lite.data.experiments import Experiment
    from danae_lite.research.danae_res import DanaeRes, DenoiserStream
    from danae_lite.research.leaderboard import run_leaderboard
    from danae_lite.data.simulate import simulate

    recs = [simulate("handheld", duration=60.0, seed=s, name=f"bench-{s}") for s in range(3)]
    method = DanaeRes("vqf")
    board = run_leaderboard(Experiment("oxiod", "simulated", recs[1:], recs[:1], "benchmark"), methods=("vqf",),
                            extra=[method], seeds=(0,), progress=False,
                            train_config=TrainConfig(max_steps=sz["causal_steps"], num_threads=1, device="cpu"))
    n = sz["causal_warmup"] + sz["causal_n"]
    rec = board.alignment.apply(recs[0]).slice(0, n)
    est = method.base.predict(rec)[0]
    stream = DenoiserStream(method, num_threads=1)
    out, ms = np.zeros((n, 3)), np.zeros(n)
    for i in range(n):
        t0 = time.perf_counter()
        out[i] = stream.step(method.features(rec.slice(i, i + 1), est[i:i + 1])[0], est[i])
        ms[i] = 1e3 * (time.perf_counter() - t0)
    ms = ms[sz["causal_warmup"]:]
    diff = np.abs(np.angle(np.exp(1j * (out - method.predict(rec)[0])))).max()
    return {"median_ms": float(np.median(ms)), "p99_ms": float(np.percentile(ms, 99)), "samples": int(len(ms)),
            "max_abs_diff_rad": float(diff), "period_ms": PERIOD_MS}


# --------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------
def summary(r: dict[str, Any]) -> dict[str, Any]:
    """The flat headline numbers (the keys other tools read)."""
    f, tr, inf = r["filters"], r["training"], r["inference"]
    dev = r["danae_device"]
    s: dict[str, Any] = {
        "kf_samples_per_s": f["kf"]["samples_per_s"],
        "kf_general_samples_per_s": f["kf_general"]["samples_per_s"],
    }
    for name in ("fusion", "vqf", "madgwick", "mahony"):
        if "samples_per_s" in f.get(name, {}):
            s[f"{name}_samples_per_s"] = f[name]["samples_per_s"]
            s[f"kf_over_{name}"] = f[name]["kf_ratio"]
    s["kf_target_samples_per_s"] = KF_TARGET
    s["kf_target_met"] = f["kf_target_met"]
    s["danae_train_steps_per_s"] = tr[dev]["16"]["steps_per_s"]
    s["danae_train_windows_per_s"] = tr[dev]["16"]["windows_per_s"]
    s["danae_train_steps_per_s_b256"] = tr[dev]["256"]["steps_per_s"]
    s["danae_train_windows_per_s_b256"] = tr[dev]["256"]["windows_per_s"]
    if "cpu" in tr:
        s["danae_train_steps_per_s_cpu"] = tr["cpu"]["16"]["steps_per_s"]
        s["danae_train_steps_per_s_b256_cpu"] = tr["cpu"]["256"]["steps_per_s"]
    if "cuda" in tr:
        s["danae_train_steps_per_s_cuda"] = tr["cuda"]["16"]["steps_per_s"]
        s["danae_train_steps_per_s_b256_cuda"] = tr["cuda"]["256"]["steps_per_s"]
    th = r["throughput"]
    s["train_bare_windows_per_s"] = th["bare_windows_per_s"]
    s["train_loop_windows_per_s"] = th["loop_windows_per_s"]
    s["train_loop_over_bare"] = th["loop_over_bare"]
    s["train_gflops"] = th["train_gflops"]
    s["matmul_gflops"] = th["matmul"]["gflops"]
    s["train_over_matmul_peak"] = th["train_over_peak"]
    s["paper_epoch_50k_s"] = th["epoch_call_seconds"]
    s["predict_100k_s"] = inf["predict_100k"]["seconds"]
    s["danae_predict_ms_total"] = inf["predict"]["ms_total"]
    s["danae_predict_us_per_sample"] = inf["predict"]["us_per_sample"]
    s["danae_predict_samples"] = inf["predict"]["samples"]
    s["danae_infer_ms_per_sample"] = inf["paper_stream"]["median_ms"]
    s["danae_infer_p99_ms_per_sample"] = inf["paper_stream"]["p99_ms"]
    s["sample_period_ms"] = PERIOD_MS
    for key, lat in inf["causal_stream"].items():
        s[f"causal_{key}_stream_ms_per_sample"] = lat["median_ms"]
        s[f"causal_{key}_stream_p99_ms"] = lat["p99_ms"]
    if "denoiser_stream" in inf:
        s["denoiser_stream_ms_per_sample"] = inf["denoiser_stream"]["median_ms"]
        s["denoiser_stream_p99_ms"] = inf["denoiser_stream"]["p99_ms"]
    return s


def table(r: dict[str, Any]) -> str:
    s, f, tr, inf = r, r["filters"], r["training"], r["inference"]
    rows: list[tuple[str, str, str]] = []
    kf = s["kf_samples_per_s"]
    verdict = "PASS" if kf >= KF_TARGET else "MISS"
    rows.append(("KF (run_kf, authors' setting)", f"{kf:,.0f} samples/s",
                 f"target >= {KF_TARGET:,.0f}: {verdict}"))
    rows.append(("KF, general 6x3-gain path", f"{s['kf_general_samples_per_s']:,.0f} samples/s", ""))
    labels = {"fusion": "Fusion (imufusion, C)", "vqf": "VQF (C++)", "madgwick": "Madgwick (ahrs, Python)",
              "mahony": "Mahony (ahrs, Python)"}
    for name, label in labels.items():
        if f"{name}_samples_per_s" in s:
            rows.append((label, f"{s[f'{name}_samples_per_s']:,.0f} samples/s",
                         f"KF/{name} = {s[f'kf_over_{name}']:.2f}x (on {f[name]['samples']:,} samples)"))
    for device, per_batch in tr.items():
        for batch, t in per_batch.items():
            rows.append((f"DANAE training, batch {batch} ({device})", f"{t['steps_per_s']:.2f} steps/s",
                         f"{t['windows_per_s']:,.0f} windows/s"))
    th = r["throughput"]
    rows.append((f"bare network step, batch 16 ({th['device']})", f"{th['bare_windows_per_s']:,.0f} windows/s",
                 f"{th['bare_gflops']:,.1f} GFLOP/s"))
    rows.append(("train.train, paper settings + validation", f"{th['loop_windows_per_s']:,.0f} windows/s",
                 f"loop/bare = {th['loop_over_bare']:.2f} (target >= 0.8)"))
    rows.append(("training arithmetic rate", f"{th['train_gflops']:,.1f} GFLOP/s",
                 f"matmul peak {th['matmul']['gflops']:,.1f} GFLOP/s: {th['train_over_peak']:.2f} of it"))
    rows.append((f"paper epoch, {th['epoch_windows']:,} windows (validation included)",
                 f"{th['epoch_call_seconds']:.1f} s", f"{th['epoch_steps']} steps, {th['checks']} checks"))
    rows.append((f"predict over {inf['predict_100k']['samples']:,} samples", f"{inf['predict_100k']['seconds']:.2f} s",
                 "every stride-1 window, overlap-averaged"))
    p = inf["predict"]
    rows.append((f"DANAE predict, whole recording ({p['device']})", f"{p['ms_total']:,.0f} ms",
                 f"{p['us_per_sample']:.1f} µs/sample, {p['samples']:,} samples"))
    ps = inf["paper_stream"]
    rows.append(("DANAE streaming, paper net (1 window/sample)", f"{ps['median_ms']:.2f} ms/sample",
                 f"p99 {ps['p99_ms']:.2f} ms; {100 * ps['median_fraction']:.0f} % of the {PERIOD_MS:.0f} ms period"))
    for key, lat in inf["causal_stream"].items():
        rows.append((f"DANAE streaming, causal {key} (StreamingDanae)", f"{lat['median_ms']:.3f} ms/sample",
                     f"p99 {lat['p99_ms']:.3f} ms; {100 * lat['median_fraction']:.1f} % of the period"))
    if "denoiser_stream" in inf:
        d = inf["denoiser_stream"]
        rows.append(("DANAE-res on VQF, streaming (DenoiserStream)", f"{d['median_ms']:.3f} ms/sample",
                     f"p99 {d['p99_ms']:.3f} ms; features + causal net + gate; = batch to {d['max_abs_diff_rad']:.0e} rad"))
    w = [max(len(row[i]) for row in rows) for i in range(3)]
    head = ("benchmark", "result", "notes")
    w = [max(w[i], len(head[i])) for i in range(3)]
    line = "  ".join("-" * wi for wi in w)
    fmt = lambda row: "  ".join(c.ljust(wi) if i != 1 else c.rjust(wi) for i, (c, wi) in enumerate(zip(row, w)))  # noqa: E731
    return "\n".join([fmt(head), line, *(fmt(row) for row in rows)])


#: the figures shown side by side for the native and the AVX2 path: (key, label, format)
HEADLINE = [
    ("matmul_gflops", "float32 matmul peak [GFLOP/s]", "{:,.0f}"),
    ("train_gflops", "paper network training [GFLOP/s]", "{:,.1f}"),
    ("train_over_matmul_peak", "  share of the matmul peak", "{:.2f}"),
    ("train_bare_windows_per_s", "bare training step, batch 16 [windows/s]", "{:,.0f}"),
    ("paper_epoch_50k_s", "paper epoch, 50k windows [s]", "{:.1f}"),
    ("predict_100k_s", "predict over 100k samples [s]", "{:.2f}"),
    ("danae_infer_ms_per_sample", "paper net streaming [ms/sample]", "{:.2f}"),
    ("denoiser_stream_ms_per_sample", "DANAE-res streaming [ms/sample]", "{:.3f}"),
    ("denoiser_stream_p99_ms", "  p99 [ms/sample]", "{:.3f}"),
]


def side_by_side(paths: dict[str, dict[str, Any]]) -> str:
    """The headline figures of each instruction-set path in one column each."""
    names = list(paths)
    rows = [("figure", *names)]
    for key, label, fmt in HEADLINE:
        rows.append((label, *(fmt.format(p[key]) if p.get(key) is not None else "—" for p in paths.values())))
    w = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(wi) if i == 0 else c.rjust(wi) for i, (c, wi) in enumerate(zip(r, w))) for r in rows]
    return "\n".join([lines[0], "  ".join("-" * wi for wi in w), *lines[1:]])


def run_avx2_path(argv: Sequence[str]) -> dict[str, Any]:
    """Run this benchmark again in a child process restricted to AVX2 (:data:`AVX2_PATH_ENV`)."""
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "avx2.json"
        cmd = [sys.executable, str(Path(__file__).resolve()), *argv, "--path", "native", "--json", str(out)]
        subprocess.run(cmd, env={**os.environ, **AVX2_PATH_ENV}, check=True)
        return json.loads(out.read_text(encoding="utf-8"))


def _child_argv(args: argparse.Namespace) -> list[str]:
    argv = ["--quick"] if args.quick else []
    if args.device:
        argv += ["--device", args.device]
    if args.threads is not None:
        argv += ["--threads", str(args.threads)]
    return argv


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--json", metavar="FILE", help="write the results to this JSON file")
    parser.add_argument("--quick", action="store_true", help="tiny sizes: a smoke test of a few seconds")
    parser.add_argument("--device", default=None,
                        help="device for DANAE training/inference (default: cuda when available, else cpu)")
    parser.add_argument("--threads", type=int, default=None,
                        help="torch CPU threads (default: torch's own, every physical core)")
    parser.add_argument("--path", choices=("both", "native"), default="both",
                        help="'both' (default): on a CPU with AVX-512, run everything a second time with the "
                             "AVX2 code paths forced (ONEDNN_MAX_CPU_ISA, ATEN_CPU_CAPABILITY, "
                             "MKL_ENABLE_INSTRUCTIONS) and show the two side by side; 'native': this CPU's own path only")
    args = parser.parse_args(argv)
    if args.threads is not None:
        if args.threads < 1:
            parser.error(f"--threads must be >= 1, got {args.threads}")
        torch.set_num_threads(args.threads)

    t_start = time.perf_counter()
    sz = sizes(args.quick)
    device = default_device(args.device)
    # CPU always (the reference machine has no GPU); CUDA too when present, unless --device chose one
    devices = [device] if args.device else (["cuda", "cpu"] if device == "cuda" else ["cpu"])
    mach = machine_info()
    isa = mach["isa"]
    log(f"DANAE benchmarks{' (quick)' if args.quick else ''}: python {mach['python']}, torch {mach['torch']}, "
        f"{mach['usable_cores']} cores, {mach['cpu_model']}, DANAE device {device_label(device)}")
    log(f"instruction sets: the CPU has {isa['cpu']}; torch kernels use {isa['torch_capability']} "
        f"({isa['path']} path)")

    t0 = time.perf_counter()
    rec = simulate("handheld", duration=sz["duration"], seed=0)
    log(f"\n[recording] simulate('handheld', duration={sz['duration']:g}, seed=0): {len(rec):,} samples at "
        f"{rec.fs:g} Hz ({time.perf_counter() - t0:.1f} s)")

    log("\n[1/4] filters: samples per second")
    t0 = time.perf_counter()
    fres = bench_filters(rec, sz)
    kf = fres["kf"]["samples_per_s"]
    ratios = ", ".join(f"KF/{n} = {fres[n]['kf_ratio']:.2f}x" for n in ("fusion", "vqf", "madgwick", "mahony")
                       if "kf_ratio" in fres.get(n, {}))
    log(f"  {ratios}")
    log(f"  KF target >= {KF_TARGET:,.0f} samples/s: {'PASS' if kf >= KF_TARGET else 'MISS'} "
        f"({kf:,.0f})  [{time.perf_counter() - t0:.1f} s]")

    x = run_kf(rec, KFConfig.authors()).euler[:, 0]  # KF roll: DANAE's input
    y = rec.euler[:, 0]                               # true roll: its target
    log(f"\n[2/4] DANAE training (paper network, window 20, KF roll of the recording): devices {devices}")
    t0 = time.perf_counter()
    tres, result = bench_training(x, y, devices, sz)
    log(f"  [{time.perf_counter() - t0:.1f} s]")

    log(f"\n[3/4] training throughput against the physical limit ({device})")
    t0 = time.perf_counter()
    thres = bench_throughput(x, y, device, sz)
    log(f"  [{time.perf_counter() - t0:.1f} s]")

    log("\n[4/4] DANAE inference")
    t0 = time.perf_counter()
    ires = bench_inference(result, x, y, sz)
    log(f"  [{time.perf_counter() - t0:.1f} s]")

    report: dict[str, Any] = {
        "date": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
        "quick": bool(args.quick),
        "device": device_label(device),
        "danae_device": device,
        "recording": dict(name=rec.name, samples=len(rec), fs_hz=rec.fs, duration_s=len(rec) / rec.fs),
        "machine": mach,
        "filters": fres,
        "training": tres,
        "throughput": thres,
        "inference": ires,
    }
    report.update(summary(report))

    log("\n" + table(report))
    if args.path == "both" and isa["cpu"] == "AVX-512" and not isa["avx2_forced"]:
        log("\n[AVX2 path] the same benchmarks with AVX2 code only (a child process)")
        child = run_avx2_path(_child_argv(args))
        # every flat figure of the child (its summary), so that each row can show both paths
        report["avx2_path"] = {k: v for k, v in child.items() if not isinstance(v, (dict, list))} | {
            "machine": child["machine"]}
    label = "AVX2 (forced)" if isa["avx2_forced"] else f"{isa['torch_capability']} (native)"
    paths = {label: report}
    if "avx2_path" in report:
        paths["AVX2 (forced)"] = report["avx2_path"]
    report["paths"] = {name: {k: p.get(k) for k, *_ in HEADLINE} for name, p in paths.items()}
    log("\n" + side_by_side(report["paths"]))
    report["total_wall_s"] = time.perf_counter() - t_start
    log(f"\ntotal wall time: {report['total_wall_s']:.1f} s")
    out = clean(report)
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
        log(f"results written to {path}")
    return out


if __name__ == "__main__":
    main()
