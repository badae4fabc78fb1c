"""Training DANAE, choosing the best state on held-out windows, saving, loading, predicting.

The paper trains with Adam (lr 0.002, batch 16) on all stride-1 windows of the training
recordings, minimising the MSE between the network output and the ground-truth angles
(rad); one epoch for each OxIOD setting, 100 for UCS. The authors' code differs in three
settings, all exposed in :class:`TrainConfig`:

* ``lr``: the code default was 2e-4; the paper states 2e-3 (our default).
* ``betas``: the code used Adam betas (0.5, 0.999); PyTorch's (0.9, 0.999) is our default.
* ``loss_scale``: the code multiplied the MSE by ``lamb`` = 10 or 100. Adam normalises the
  gradient by its running RMS, so a constant factor changes almost nothing (only the
  relative size of Adam's ``eps``); the default 1.0 is the plain MSE.

Model selection: ``val_fraction`` of every *training* recording (a contiguous block at its
end) is held out; the network is evaluated on it every ``val_every`` steps and the best
state is kept (optionally stopping early). The test recording is never touched. The paper
reports no validation split, so with ``val_fraction=0`` the final state is used, as there.
"""
from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from .config import default_device, seed_everything
from .model import ARCHITECTURES, DanaeBase, build_model
from .windows import sliding_windows, stitch_overlap_average, stitch_tiles, tile_windows, windows_from_recordings

__all__ = [
    "CHECKPOINT_FORMAT",
    "CHECKPOINT_VERSION",
    "CheckpointError",
    "TrainConfig",
    "TrainResult",
    "load",
    "predict",
    "save",
    "train",
]

CHECKPOINT_FORMAT = "danae_lite.checkpoint"
CHECKPOINT_VERSION = 1
NORMALIZATIONS = ("none", "standard")
LOSSES = ("mse",)


@dataclass
class TrainConfig:
    """Everything that defines a training run.

    Attributes
    ----------
    arch : {"paper", "big", "causal"}
        Network, see :data:`danae_lite.model.ARCHITECTURES`.
    window : int
        Window length ``L`` in samples (20 in the paper).
    hidden : int
        Channels of every hidden layer (128).
    skip, dilated : bool
        Architecture switches for ablations (both ``True`` in the paper).
    lr : float
        Adam learning rate. Paper: 0.002; authors' code: 2e-4.
    betas : (float, float)
        Adam betas. PyTorch default (0.9, 0.999); authors' code: (0.5, 0.999).
    batch_size : int
        Windows per step (16 in the paper).
    epochs : int
        Passes over the training windows (1 for OxIOD, 100 for UCS in the paper).
    loss : {"mse"}
        Training loss: mean squared error over all samples and channels of a batch.
    loss_scale : float
        Constant factor on the loss (the authors' ``lamb``; nearly a no-op under Adam).
    val_fraction : float
        Fraction of each training recording, taken as a contiguous block at its end, used
        for validation (at least ``window`` samples when > 0). 0 disables validation.
    val_every : int or None
        Steps between validation checks; ``None`` means ten checks per epoch.
    patience : int or None
        Stop after this many validation checks without improvement; ``None``: never stop early.
    min_delta : float
        Improvement (rad^2) a validation loss must make to count as better.
    restore_best : bool
        Return the state with the lowest validation loss (else the last state).
    seed : int
        Seeds python, numpy and torch (initialisation and shuffling).
    device : str or None
        ``"cpu"``, ``"cuda"``, ...; ``None``: CUDA when available, else CPU.
    num_threads : int or None
        CPU threads for torch while training; ``None``: the process's torch setting
        (``torch.get_num_threads()``: every physical core unless ``OMP_NUM_THREADS`` or the
        caller set it lower). Give each of several concurrent trainings its share of the
        cores: more threads than cores make torch's thread pool spin and run ten times slower.
    normalize : {"none", "standard"}
        ``"none"``: raw radians in and out, as the paper. ``"standard"``: per-channel mean
        and std of the training inputs and targets (validation blocks excluded) are stored
        in the network's buffers; it standardises its input and de-standardises its output,
        so callers always see radians.
    max_steps : int or None
        Hard cap on optimiser steps (fast mode); ``None``: no cap.
    eval_batch_size : int
        Windows per forward pass for validation (256: the activations of a batch stay in the
        CPU caches; batches of thousands of windows run several times slower per window).
    loss_start : int
        First window position counted in the training and validation loss (0: all). A causal
        network (``arch="causal"``) sees its full past only from position
        ``receptive_field - 1`` on; counting only those positions trains it as it runs on-line.
    """

    arch: str = "paper"
    window: int = 20
    hidden: int = 128
    skip: bool = True
    dilated: bool = True
    lr: float = 0.002
    betas: tuple[float, float] = (0.9, 0.999)
    batch_size: int = 16
    epochs: int = 1
    loss: str = "mse"
    loss_scale: float = 1.0
    val_fraction: float = 0.1
    val_every: int | None = None
    patience: int | None = None
    min_delta: float = 0.0
    restore_best: bool = True
    seed: int = 0
    device: str | None = None
    num_threads: int | None = None
    normalize: str = "none"
    max_steps: int | None = None
    eval_batch_size: int = 256
    loss_start: int = 0

    def __post_init__(self) -> None:
        self.betas = tuple(float(b) for b in self.betas)  # type: ignore[assignment]
        if self.arch not in ARCHITECTURES:
            raise ValueError(f"arch={self.arch!r}: choose one of {sorted(ARCHITECTURES)}")
        if self.loss not in LOSSES:
            raise ValueError(f"loss={self.loss!r}: choose one of {LOSSES}")
        if self.normalize not in NORMALIZATIONS:
            raise ValueError(f"normalize={self.normalize!r}: choose one of {NORMALIZATIONS}")
        if not 0.0 <= self.val_fraction < 1.0:
            raise ValueError(f"val_fraction={self.val_fraction} must be in [0, 1)")
        if len(self.betas) != 2:
            raise ValueError(f"betas needs two values, got {self.betas}")
        for name in ("window", "batch_size", "epochs", "eval_batch_size"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("val_every", "patience", "max_steps", "num_threads"):
            v = getattr(self, name)
            if v is not None and v < 1:
                raise ValueError(f"{name} must be >= 1 or None, got {v}")
        if not 0 <= self.loss_start < self.window:
            raise ValueError(f"loss_start must be in [0, window={self.window}), got {self.loss_start}")
        if not self.lr > 0 or not self.loss_scale > 0:
            raise ValueError("lr and loss_scale must be positive")

    def model_kwargs(self) -> dict[str, Any]:
        """Architecture keyword arguments (channels are taken from the data)."""
        return dict(hidden=self.hidden, skip=self.skip, dilated=self.dilated, window=self.window)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (lists instead of tuples), safe to store in a checkpoint."""
        d = asdict(self)
        d["betas"] = list(self.betas)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "TrainConfig":
        """Inverse of :meth:`to_dict`; unknown keys are ignored."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


@dataclass
class TrainResult:
    """What :func:`train` returns.

    Attributes
    ----------
    model : DanaeBase
        The trained network (best validation state when ``restore_best``), in eval mode.
    config : TrainConfig
    history : DataFrame
        One row per validation check: ``step``, ``epoch`` (fraction of epochs done),
        ``train_loss`` (mean training MSE since the previous row, in the network's
        standardised units -- rad^2 when ``normalize="none"``), ``val_loss`` (MSE on the
        validation windows, always rad^2; NaN without validation).
    best_step : int
        Step of the returned state.
    best_val_loss : float
        Its validation MSE (rad^2), NaN without validation.
    seconds : float
        Wall-clock training time.
    steps : int
        Optimiser steps taken.
    n_train_windows, n_val_windows : int
    device : str
    stopped_early : bool
    """

    model: DanaeBase
    config: TrainConfig
    history: pd.DataFrame
    best_step: int
    best_val_loss: float
    seconds: float
    steps: int
    n_train_windows: int
    n_val_windows: int
    device: str
    stopped_early: bool = False
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def steps_per_second(self) -> float:
        return self.steps / self.seconds if self.seconds > 0 else float("nan")


# ---------------------------------------------------------------------------------------
# data preparation
# ---------------------------------------------------------------------------------------
def _as_2d(x: np.ndarray, what: str) -> np.ndarray:
    x = np.asarray(x, dtype=np.float32)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f"{what}: expected shape (N,) or (N, C), got {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError(f"{what}: contains NaN or inf")
    return x


def _as_list(a: np.ndarray | Sequence[np.ndarray]) -> list[np.ndarray]:
    return [a] if isinstance(a, np.ndarray) else list(a)


def _split(
    inputs: list[np.ndarray], targets: list[np.ndarray], window: int, val_fraction: float
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Per recording: head block for training, tail block (>= window samples) for validation."""
    xs_tr, ys_tr, xs_va, ys_va = [], [], [], []
    for i, (x, y) in enumerate(zip(inputs, targets)):
        n = len(x)
        n_val = 0 if val_fraction == 0 else max(window, int(round(val_fraction * n)))
        if n - n_val < window:
            raise ValueError(
                f"recording {i} has N={n} samples: too short for a training block of {window} "
                f"samples plus a validation block of {n_val}"
            )
        xs_tr.append(x[: n - n_val])
        ys_tr.append(y[: n - n_val])
        if n_val:
            xs_va.append(x[n - n_val :])
            ys_va.append(y[n - n_val :])
    return xs_tr, ys_tr, xs_va, ys_va


def _valid_windows(masks: list[np.ndarray], window: int) -> np.ndarray:
    """For the stride-1 windows of each recording (in :func:`_to_windows` order): True when
    every target sample in the window is usable."""
    return np.concatenate([sliding_windows(m, window).all(axis=1) for m in masks])


def _to_windows(recs: list[np.ndarray], window: int, device: str) -> torch.Tensor:
    """Stride-1 windows of each recording, as a (n, C, L) float32 tensor."""
    w = windows_from_recordings(recs, window, stride=1)  # (n, L, C)
    return torch.from_numpy(np.ascontiguousarray(w.transpose(0, 2, 1))).to(device)


@torch.no_grad()
def _mse(net: DanaeBase, x: torch.Tensor, y: torch.Tensor, batch_size: int, start: int = 0) -> float:
    """Mean squared error in raw units over all windows, samples ``>= start`` of each window and channels."""
    was_training = net.training
    net.eval()
    total = 0.0
    for i in range(0, len(x), batch_size):
        d = net(x[i : i + batch_size])[..., start:] - y[i : i + batch_size, :, start:]
        total += float((d**2).sum(dtype=torch.float64))
    net.train(was_training)
    return total / y[..., start:].numel()


def _default_threads() -> int:
    """The process's torch thread count (``torch.get_num_threads()``), set by the entry
    points (the book's :func:`~danae_lite.book.setup`, the CLI's ``--threads``) or by
    ``OMP_NUM_THREADS``; torch's own default is every physical core."""
    return max(1, torch.get_num_threads())


def _keep_freed_memory() -> None:
    """Let glibc keep freed blocks of up to 64 MiB for reuse (once per process; no-op elsewhere).

    A forward pass over a batch of windows allocates activations of a few MB. glibc serves
    blocks above its ``M_MMAP_THRESHOLD`` (128 KiB at start) with fresh ``mmap`` pages and
    hands them back on free, so every batch page-faults its activations in again: batched
    inference and validation run about half as fast as they can. Raising the mmap and trim
    thresholds keeps those pages in the heap. The cost is at most 128 MiB of freed memory
    kept by the process.
    """
    global _MALLOC_TUNED
    if _MALLOC_TUNED:
        return
    _MALLOC_TUNED = True
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 64 << 20)  # M_MMAP_THRESHOLD
        libc.mallopt(-1, 128 << 20)  # M_TRIM_THRESHOLD
    except (OSError, AttributeError):  # not glibc (macOS, Windows, musl): nothing to do
        pass


_MALLOC_TUNED = False


class _TorchSettings:
    """Temporarily set torch threads and deterministic algorithms, restoring them after."""

    def __init__(self, num_threads: int, deterministic: bool) -> None:
        self.num_threads, self.deterministic = num_threads, deterministic

    def __enter__(self) -> None:
        _keep_freed_memory()
        self.old_threads = torch.get_num_threads()
        self.old_det = torch.are_deterministic_algorithms_enabled()
        self.old_warn = torch.is_deterministic_algorithms_warn_only_enabled()
        torch.set_num_threads(self.num_threads)
        if self.deterministic:
            torch.use_deterministic_algorithms(True, warn_only=True)

    def __exit__(self, *exc: object) -> None:
        torch.set_num_threads(self.old_threads)
        torch.use_deterministic_algorithms(self.old_det, warn_only=self.old_warn)


# ---------------------------------------------------------------------------------------
# training
# ---------------------------------------------------------------------------------------
def train(
    inputs: np.ndarray | Sequence[np.ndarray],
    targets: np.ndarray | Sequence[np.ndarray],
    config: TrainConfig | None = None,
    *,
    progress: bool = True,
    target_masks: np.ndarray | Sequence[np.ndarray] | None = None,
) -> TrainResult:
    """Train a DANAE network to map noisy angle windows to ground-truth windows.

    Parameters
    ----------
    inputs : list of ndarray, each (N_i,) or (N_i, C_in)
        One array per training recording, e.g. the KF roll estimate (rad). A single array
        is taken as one recording.
    targets : list of ndarray, each (N_i,) or (N_i, C_out)
        Matching ground truth (rad), same ``N_i``.
    config : TrainConfig, optional
        Defaults to ``TrainConfig()`` (the paper's settings plus a 10 % validation block).
    progress : bool
        Show a tqdm bar with the running training loss and the last validation loss.
    target_masks : list of bool ndarray, each (N_i,), optional
        True where the target is usable (e.g. :func:`danae_lite.groundtruth.clean_mask`).
        Windows holding any unusable target sample are left out of training and
        validation; the validation block is still the tail of each recording, so the split
        does not depend on the mask. ``n_train_windows``/``n_val_windows`` count the windows kept.

    Returns
    -------
    TrainResult

    Notes
    -----
    Windows are cut per recording with stride 1 and never span two recordings (nor the
    border between a recording's training and validation blocks). They are shuffled each
    epoch with a ``torch.Generator`` seeded from ``config.seed``; the last batch of an epoch
    may be smaller. On CPU, with the same seed, data and thread count, two runs give
    bit-identical networks (``torch.use_deterministic_algorithms`` is on while training).
    """
    if progress:  # tqdm.auto picks the notebook widget when it can (and warns when it cannot)
        from tqdm.auto import tqdm
    else:
        from tqdm import tqdm

    cfg = config or TrainConfig()
    xs, ys = _as_list(inputs), _as_list(targets)
    if len(xs) == 0 or len(xs) != len(ys):
        raise ValueError(f"need the same positive number of input and target recordings, got {len(xs)} and {len(ys)}")
    xs = [_as_2d(x, f"inputs[{i}]") for i, x in enumerate(xs)]
    ys = [_as_2d(y, f"targets[{i}]") for i, y in enumerate(ys)]
    for i, (x, y) in enumerate(zip(xs, ys)):
        if len(x) != len(y):
            raise ValueError(f"recording {i}: inputs have {len(x)} samples, targets {len(y)}")
        if x.shape[1] != xs[0].shape[1] or y.shape[1] != ys[0].shape[1]:
            raise ValueError(f"recording {i}: channel count differs from recording 0")

    masks: list[np.ndarray] | None = None
    if target_masks is not None:
        masks = [np.asarray(m) for m in _as_list(target_masks)]  # type: ignore[arg-type]
        if len(masks) != len(xs):
            raise ValueError(f"{len(masks)} target masks for {len(xs)} recordings")
        for i, (m, x) in enumerate(zip(masks, xs)):
            if m.dtype != bool or m.shape != (len(x),):
                raise ValueError(f"target_masks[{i}]: expected a boolean array of shape ({len(x)},), got {m.dtype} {m.shape}")

    device = default_device(cfg.device)
    num_threads = cfg.num_threads or _default_threads()
    on_cpu = torch.device(device).type == "cpu"

    with _TorchSettings(num_threads, deterministic=on_cpu):
        seed_everything(cfg.seed)
        xs_tr, ys_tr, xs_va, ys_va = _split(xs, ys, cfg.window, cfg.val_fraction)
        keep_tr = keep_va = None
        if masks is not None:
            _, ms_tr, _, ms_va = _split(xs, masks, cfg.window, cfg.val_fraction)
            keep_tr = torch.from_numpy(_valid_windows(ms_tr, cfg.window))
            keep_va = torch.from_numpy(_valid_windows(ms_va, cfg.window)) if ms_va else None
            if not bool(keep_tr.any()):
                raise ValueError("no training window is free of masked target samples")
            # standardisation statistics from usable samples only
            xs_stat = [x[m] for x, m in zip(xs_tr, ms_tr)]
            ys_stat = [y[m] for y, m in zip(ys_tr, ms_tr)]
        else:
            xs_stat, ys_stat = xs_tr, ys_tr
        net = build_model(cfg.arch, in_channels=xs[0].shape[1], out_channels=ys[0].shape[1], **cfg.model_kwargs())
        if cfg.normalize == "standard":
            xa, ya = np.concatenate(xs_stat), np.concatenate(ys_stat)
            def _std(a: np.ndarray) -> np.ndarray:
                s = a.std(axis=0, dtype=np.float64)
                return np.where(s > 1e-12, s, 1.0)
            net.set_normalization(xa.mean(0, dtype=np.float64), _std(xa), ya.mean(0, dtype=np.float64), _std(ya))
        net = net.to(device)

        x_tr, y_tr = _to_windows(xs_tr, cfg.window, device), _to_windows(ys_tr, cfg.window, device)
        if keep_tr is not None:
            x_tr, y_tr = x_tr[keep_tr.to(device)], y_tr[keep_tr.to(device)]
        # the optimised loss lives in standardised units (identical to rad when normalize="none")
        x_tr_n = (x_tr - net.in_mean) / net.in_std
        y_tr_n = (y_tr - net.out_mean) / net.out_std
        has_val = bool(xs_va)
        if has_val:
            x_va, y_va = _to_windows(xs_va, cfg.window, device), _to_windows(ys_va, cfg.window, device)
            if keep_va is not None:
                x_va, y_va = x_va[keep_va.to(device)], y_va[keep_va.to(device)]
                has_val = len(x_va) > 0
        n_train, n_val = len(x_tr), (len(x_va) if has_val else 0)

        steps_per_epoch = math.ceil(n_train / cfg.batch_size)
        total_steps = steps_per_epoch * cfg.epochs
        if cfg.max_steps is not None:
            total_steps = min(total_steps, cfg.max_steps)
        val_every = cfg.val_every or max(1, min(steps_per_epoch, total_steps) // 10)

        # the fused kernel updates every parameter in one call (same Adam, less overhead)
        fused = torch.device(device).type in ("cpu", "cuda")
        opt = torch.optim.Adam(net.parameters(), lr=cfg.lr, betas=cfg.betas, fused=fused)
        gen = torch.Generator().manual_seed(cfg.seed)

        rows: list[dict[str, float]] = []
        best_val, best_step, best_state = math.inf, 0, None
        checks_since_best, stopped_early = 0, False
        loss_sum, loss_n, step = 0.0, 0, 0
        last_val = float("nan")
        bar = tqdm(total=total_steps, disable=not progress, desc=f"DANAE-{cfg.arch}", unit="step")

        def check() -> bool:
            """Log a history row; return True when training should stop early."""
            nonlocal loss_sum, loss_n, best_val, best_step, best_state, checks_since_best, last_val
            val = _mse(net, x_va, y_va, cfg.eval_batch_size, cfg.loss_start) if has_val else float("nan")
            rows.append(dict(step=step, epoch=step / steps_per_epoch,
                             train_loss=float(loss_sum) / max(loss_n, 1), val_loss=val))
            loss_sum, loss_n, last_val = 0.0, 0, val
            if has_val:
                if val < best_val - cfg.min_delta:
                    best_val, best_step, checks_since_best = val, step, 0
                    best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
                else:
                    checks_since_best += 1
                return cfg.patience is not None and checks_since_best >= cfg.patience
            return False

        t0 = time.perf_counter()
        net.train()
        done = False
        for epoch in range(cfg.epochs):
            perm = torch.randperm(n_train, generator=gen).to(device)
            for i in range(0, n_train, cfg.batch_size):
                idx = perm[i : i + cfg.batch_size]
                out = net.forward_net(x_tr_n[idx])
                mse = torch.mean((out[..., cfg.loss_start :] - y_tr_n[idx][..., cfg.loss_start :]) ** 2)
                opt.zero_grad(set_to_none=True)
                (cfg.loss_scale * mse).backward()
                opt.step()
                step += 1
                loss_sum = loss_sum + mse.detach()  # stays on the device: no sync per step
                loss_n += 1
                bar.update(1)
                if step % 20 == 0 or step == total_steps:
                    bar.set_postfix(loss=f"{float(loss_sum) / max(loss_n, 1):.3g}", val=f"{last_val:.3g}", refresh=False)
                if step % val_every == 0 or step == total_steps:
                    if check():
                        stopped_early = True
                        done = True
                        break
                if step >= total_steps:
                    done = True
                    break
            if done:
                break
        bar.close()
        seconds = time.perf_counter() - t0

        if has_val and cfg.restore_best and best_state is not None:
            net.load_state_dict(best_state)
        else:
            best_step = step
            best_val = rows[-1]["val_loss"] if rows else float("nan")
        net.eval()

    history = pd.DataFrame(rows, columns=["step", "epoch", "train_loss", "val_loss"])
    history["step"] = history["step"].astype(int)
    return TrainResult(
        model=net,
        config=cfg,
        history=history,
        best_step=int(best_step),
        best_val_loss=float(best_val) if has_val else float("nan"),
        seconds=seconds,
        steps=step,
        n_train_windows=n_train,
        n_val_windows=n_val,
        device=str(device),
        stopped_early=stopped_early,
    )


# ---------------------------------------------------------------------------------------
# inference
# ---------------------------------------------------------------------------------------
def _net_of(model_or_result: DanaeBase | TrainResult) -> DanaeBase:
    net = model_or_result.model if isinstance(model_or_result, TrainResult) else model_or_result
    if not isinstance(net, DanaeBase):
        raise TypeError(f"expected a DANAE network or a TrainResult, got {type(model_or_result).__name__}")
    return net


@torch.no_grad()
def predict(
    model_or_result: DanaeBase | TrainResult,
    x: np.ndarray,
    *,
    stitch: str = "overlap",
    batch_size: int = 256,
    window: int | None = None,
    num_threads: int | None = None,
) -> np.ndarray:
    """Denoise one recording window by window and stitch the windows back together.

    Parameters
    ----------
    model_or_result : DanaeBase or TrainResult
    x : ndarray, shape (N,) or (N, C_in)
        Noisy input, e.g. the KF roll estimate of the test recording (rad), ``N >= window``.
    stitch : {"overlap", "tiles"}
        ``"overlap"``: every stride-1 window is predicted and each sample is the mean of the
        predictions covering it (:func:`~danae_lite.windows.stitch_overlap_average`); all
        samples are covered. ``"tiles"``: the paper's non-overlapping windows from sample 0
        (:func:`~danae_lite.windows.stitch_tiles`); the last ``N mod window`` samples are NaN.
    batch_size : int
        Windows per forward pass (256 keeps a batch's activations in the CPU caches).
    window : int, optional
        Window length; default ``net.window`` (the training window).
    num_threads : int, optional
        CPU threads for torch during the call; default ``torch.get_num_threads()``, as in
        :class:`TrainConfig`.

    Returns
    -------
    ndarray of float64, shape (N, C_out)
        Denoised signal (computed in float32), in the units of the training targets.
    """
    net = _net_of(model_or_result)
    window = net.window if window is None else int(window)
    x = _as_2d(x, "x")
    n = len(x)
    if stitch == "overlap":
        wins = sliding_windows(x, window)
    elif stitch == "tiles":
        wins = tile_windows(x, window).windows
    else:
        raise ValueError(f"stitch={stitch!r}: choose 'overlap' or 'tiles'")
    p = next(net.parameters())
    was_training = net.training
    net.eval()
    preds = []
    try:
        with _TorchSettings(num_threads or _default_threads(), deterministic=False):
            for i in range(0, len(wins), batch_size):
                chunk = torch.from_numpy(wins[i : i + batch_size].transpose(0, 2, 1).copy())
                preds.append(net(chunk.to(device=p.device, dtype=p.dtype)).transpose(1, 2).cpu().numpy())
    finally:
        net.train(was_training)
    pred = np.concatenate(preds).astype(np.float64)  # (n_windows, L, C_out)
    return stitch_overlap_average(pred, n) if stitch == "overlap" else stitch_tiles(pred, n)


# ---------------------------------------------------------------------------------------
# checkpoints
# ---------------------------------------------------------------------------------------
class CheckpointError(ValueError):
    """A file is not a readable DANAE checkpoint, or holds a different network than expected."""


def _plain(obj: Any, where: str = "metadata") -> Any:
    """Convert to what ``torch.load(weights_only=True)`` accepts: dicts, lists, scalars, tensors."""
    # exact builtin types only: subclasses (np.float64, torch's TorchVersion) are not
    # accepted by the weights_only unpickler
    if obj is None or isinstance(obj, bool):
        return obj if obj is None else bool(obj)
    if isinstance(obj, np.generic):
        return obj.item()
    for kind in (int, float, str):
        if isinstance(obj, kind):
            return kind(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, torch.Tensor):
        return obj.detach().cpu()
    if isinstance(obj, pd.DataFrame):
        return {str(c): _plain(obj[c].to_numpy(), f"{where}.{c}") for c in obj.columns}
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, dict):
        return {str(k): _plain(v, f"{where}.{k}") for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(obj)]
    raise TypeError(f"{where}: cannot store a {type(obj).__name__} in a checkpoint (use plain values)")


def save(
    result_or_model: TrainResult | DanaeBase,
    path: str | os.PathLike[str],
    *,
    config: TrainConfig | None = None,
    metadata: dict[str, Any] | None = None,
) -> Path:
    """Write a network, its training configuration and metadata to one file.

    The file is ``torch.save`` of a dict holding only plain values and tensors, so
    :func:`load` can read it with ``weights_only=True``: ``format``, ``version``, ``arch``,
    ``kwargs`` (constructor arguments), ``state_dict`` (incl. the standardisation buffers),
    ``config`` (:meth:`TrainConfig.to_dict` or None) and ``metadata``. For a
    :class:`TrainResult` the metadata gets ``history`` (dict of lists), ``best_step``,
    ``best_val_loss``, ``seconds``, ``steps``, window counts and ``device``; ``torch_version``
    and ``normalization`` are always added. Explicit ``config``/``metadata`` win.
    The file is written to a temporary name and renamed, so a crash leaves no half file.

    Returns
    -------
    Path
        The file written.
    """
    net = _net_of(result_or_model)
    meta: dict[str, Any] = {}
    if isinstance(result_or_model, TrainResult):
        r = result_or_model
        config = config or r.config
        meta.update(
            history=r.history,
            best_step=r.best_step,
            best_val_loss=r.best_val_loss,
            seconds=r.seconds,
            steps=r.steps,
            n_train_windows=r.n_train_windows,
            n_val_windows=r.n_val_windows,
            device=r.device,
            stopped_early=r.stopped_early,
            **r.metadata,
        )
    from . import __version__

    meta.update(torch_version=torch.__version__, danae_lite_version=__version__, normalization=net.normalization())
    meta.update(metadata or {})
    ckpt = dict(
        format=CHECKPOINT_FORMAT,
        version=CHECKPOINT_VERSION,
        arch=net.arch,
        kwargs=net.constructor_kwargs(),
        state_dict={k: v.detach().cpu().clone() for k, v in net.state_dict().items()},
        config=config.to_dict() if config is not None else None,
        metadata=_plain(meta),
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    torch.save(ckpt, tmp)
    os.replace(tmp, path)
    return path


def load(
    path: str | os.PathLike[str],
    *,
    expect_arch: str | None = None,
    map_location: str | torch.device = "cpu",
) -> tuple[DanaeBase, TrainConfig | None, dict[str, Any]]:
    """Read a checkpoint written by :func:`save`.

    Parameters
    ----------
    path : path-like
    expect_arch : {"paper", "big"}, optional
        Raise :class:`CheckpointError` if the file holds another architecture.
    map_location : str or torch.device
        Where to put the tensors (default CPU).

    Returns
    -------
    (net, config, metadata)
        The network in eval mode, the :class:`TrainConfig` it was trained with (None if
        none was stored) and the metadata dict.

    Raises
    ------
    FileNotFoundError
        No such file.
    CheckpointError
        Corrupt, truncated or foreign file, unknown format version, or another
        architecture than ``expect_arch``. The message names the file.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no checkpoint file at {path}")
    expected = f"a DANAE checkpoint (torch.save dict with format={CHECKPOINT_FORMAT!r})"
    try:
        ckpt = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as err:  # corrupt, truncated, or pickled foreign objects
        msg = str(err).strip().splitlines()[0][:200] if str(err).strip() else ""
        raise CheckpointError(f"{path}: cannot be read as {expected}: {type(err).__name__}: {msg}") from err
    if not isinstance(ckpt, dict) or ckpt.get("format") != CHECKPOINT_FORMAT:
        found = f"a dict with keys {sorted(map(str, ckpt))[:8]}" if isinstance(ckpt, dict) else f"a {type(ckpt).__name__}"
        raise CheckpointError(f"{path}: expected {expected}, found {found}")
    version = ckpt.get("version")
    if not isinstance(version, int) or version > CHECKPOINT_VERSION:
        raise CheckpointError(f"{path}: checkpoint format version {version!r}; this code reads up to {CHECKPOINT_VERSION}")
    arch = ckpt.get("arch")
    if arch not in ARCHITECTURES:
        raise CheckpointError(f"{path}: unknown architecture {arch!r}; expected one of {sorted(ARCHITECTURES)}")
    if expect_arch is not None and arch != expect_arch:
        raise CheckpointError(f"{path}: holds a {arch!r} network ({ARCHITECTURES[arch].__name__}), expected {expect_arch!r}")
    try:
        net = build_model(arch, **ckpt["kwargs"])
        net.load_state_dict(ckpt["state_dict"], strict=True)
        config = TrainConfig.from_dict(ckpt["config"]) if ckpt.get("config") is not None else None
    except Exception as err:
        raise CheckpointError(f"{path}: damaged {arch!r} checkpoint: {type(err).__name__}: {err}") from err
    net = net.to(map_location).eval()
    return net, config, dict(ckpt.get("metadata") or {})


def load_result(path: str | os.PathLike[str], *, map_location: str | torch.device = "cpu") -> TrainResult:
    """Read a checkpoint written by :func:`save` from a :class:`TrainResult` back into one.

    The network, its configuration, loss history and training bookkeeping are restored, so a
    cached run can stand in for a fresh one. Raises :class:`CheckpointError` when the file
    lacks the training metadata (e.g. it was saved from a bare network).
    """
    net, config, meta = load(path, map_location=map_location)
    needed = ("history", "best_step", "best_val_loss", "seconds", "steps", "n_train_windows", "n_val_windows", "device")
    missing = [k for k in needed if k not in meta]
    if config is None or missing:
        raise CheckpointError(f"{path}: not saved from a training run (missing {missing or ['config']})")
    known = set(needed) | {"stopped_early", "torch_version", "danae_lite_version", "normalization"}
    return TrainResult(
        model=net,
        config=config,
        history=pd.DataFrame(meta["history"]),
        best_step=int(meta["best_step"]),
        best_val_loss=float("nan") if meta["best_val_loss"] is None else float(meta["best_val_loss"]),
        seconds=float(meta["seconds"]),
        steps=int(meta["steps"]),
        n_train_windows=int(meta["n_train_windows"]),
        n_val_windows=int(meta["n_val_windows"]),
        device=str(meta["device"]),
        stopped_early=bool(meta.get("stopped_early", False)),
        metadata={k: v for k, v in meta.items() if k not in known},
    )
