"""Training DANAE: chapter 3's loop, with the options the research needs (predicting:
:mod:`danae_lite.danae.predict`).

The paper trains with Adam (lr 0.002, batch 16) on all stride-1 windows of the training
recordings, minimising the MSE between the network output and the ground-truth angles
(rad); one epoch for each OxIOD setting, 100 for UCS. The authors' code differs in three
settings, all exposed in :class:`~danae_lite.danae.train_types.TrainConfig`:

* ``lr``: the code default was 2e-4; the paper states 2e-3 (our default).
* ``betas``: the code used Adam betas (0.5, 0.999); PyTorch's (0.9, 0.999) is our default.
* ``loss_scale``: the code multiplied the MSE by ``lamb`` = 10 or 100. Adam normalises the
  gradient by its running RMS, so a constant factor changes almost nothing (only the
  relative size of Adam's ``eps``); the default 1.0 is the plain MSE.

:func:`train` is chapter 3's ``fit_danae`` step for step: (1) split each recording into a
training head and a validation tail (:func:`validation_tail`), (2) seed the initial weights
and, on a generator of its own, the shuffling, (3) cut the windows, then repeat Adam steps
on shuffled batches with a validation check every ``val_every`` steps, keeping the best
weights, and restore them at the end. The options beyond the chapter: target masks (windows
holding an unusable target sample are left out), standardised inputs and targets, a loss
that ignores the first samples of a window, early stopping, a step cap, the device, the
thread count and a progress bar. The test recording is never touched. The paper reports no
validation split, so with ``val_fraction=0`` the final state is used, as there.
"""
from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import torch

from .base import DanaeBase
from .model import build_model
from .seeding import default_device, seed_everything
from .train_types import TrainConfig, TrainResult
from .windows import sliding_windows, windows_from_recordings

__all__ = ["HISTORY_COLUMNS", "TorchSettings", "as_2d", "train", "validation_tail"]

HISTORY_COLUMNS = ["step", "epoch", "train_loss", "val_loss"]
"""Columns of :attr:`TrainResult.history`, one row per validation check."""


# ---------------------------------------------------------------------------------------
# torch settings
# ---------------------------------------------------------------------------------------
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


class TorchSettings:
    """Set torch's CPU threads, and optionally deterministic algorithms, for a ``with`` block.

    Both are restored on leaving the block. Entering also lets glibc keep freed memory
    (:func:`_keep_freed_memory`). Used by training, :func:`predict` and
    :func:`danae_lite.research.streaming.predict_causal`.

    Parameters
    ----------
    num_threads : int or None
        Torch intra-op CPU threads inside the block; None leaves the count as it is.
    deterministic : bool
        Turn on ``torch.use_deterministic_algorithms`` (warn only) inside the block: with
        the same seed, data and thread count, a CPU training is then bit-identical.
    """

    def __init__(self, num_threads: int | None, deterministic: bool = False) -> None:
        self.num_threads, self.deterministic = num_threads, deterministic

    def __enter__(self) -> None:
        _keep_freed_memory()
        self.old_threads = torch.get_num_threads()
        self.old_det = torch.are_deterministic_algorithms_enabled()
        self.old_warn = torch.is_deterministic_algorithms_warn_only_enabled()
        if self.num_threads is not None:
            torch.set_num_threads(self.num_threads)
        if self.deterministic:
            torch.use_deterministic_algorithms(True, warn_only=True)

    def __exit__(self, *exc: object) -> None:
        if self.num_threads is not None:
            torch.set_num_threads(self.old_threads)
        if self.deterministic:
            torch.use_deterministic_algorithms(self.old_det, warn_only=self.old_warn)


# ---------------------------------------------------------------------------------------
# inputs, split, windows
# ---------------------------------------------------------------------------------------
def as_2d(x: Any, what: str, channels: int | None = None) -> np.ndarray:
    """One recording as a checked float32 array of shape (N, C).

    Parameters
    ----------
    x : array-like, shape (N,) or (N, C)
        Samples in time order (e.g. a KF angle estimate, rad); a 1-D array is one channel.
    what : str
        The argument's name, for the error messages.
    channels : int, optional
        Required channel count ``C`` (a 1-D array is accepted only when it is 1); None: any.

    Raises
    ------
    ValueError
        Another shape, an empty recording, NaN or inf.
    """
    x = np.asarray(x, dtype=np.float32)
    if x.ndim == 1 and channels in (None, 1):
        x = x[:, None]
    if x.ndim != 2 or (channels is not None and x.shape[1] != channels):
        shape = "(N,) or (N, C)" if channels is None else f"(N, {channels})" + (" or (N,)" if channels == 1 else "")
        raise ValueError(f"{what}: expected shape {shape}, got {x.shape}")
    if len(x) == 0:
        raise ValueError(f"{what}: empty recording")
    if not np.isfinite(x).all():
        raise ValueError(f"{what}: contains NaN or inf")
    return x


def _as_list(a: np.ndarray | Sequence[np.ndarray]) -> list[np.ndarray]:
    return [a] if isinstance(a, np.ndarray) else list(a)


def _checked_inputs(
    inputs: np.ndarray | Sequence[np.ndarray],
    targets: np.ndarray | Sequence[np.ndarray],
    target_masks: np.ndarray | Sequence[np.ndarray] | None,
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray] | None]:
    """Per training recording: input (N_i, C_in) and target (N_i, C_out) as float32, and the
    boolean target mask (N_i,) or None, checked against each other (see :func:`train`)."""
    xs, ys = _as_list(inputs), _as_list(targets)
    if len(xs) == 0 or len(xs) != len(ys):
        raise ValueError(f"need the same positive number of input and target recordings, got {len(xs)} and {len(ys)}")
    xs = [as_2d(x, f"inputs[{i}]") for i, x in enumerate(xs)]
    ys = [as_2d(y, f"targets[{i}]") for i, y in enumerate(ys)]
    for i, (x, y) in enumerate(zip(xs, ys)):
        if len(x) != len(y):
            raise ValueError(f"recording {i}: inputs have {len(x)} samples, targets {len(y)}")
        if x.shape[1] != xs[0].shape[1] or y.shape[1] != ys[0].shape[1]:
            raise ValueError(f"recording {i}: channel count differs from recording 0")
    if target_masks is None:
        return xs, ys, None
    masks = [np.asarray(m) for m in _as_list(target_masks)]  # type: ignore[arg-type]
    if len(masks) != len(xs):
        raise ValueError(f"{len(masks)} target masks for {len(xs)} recordings")
    for i, (m, x) in enumerate(zip(masks, xs)):
        if m.dtype != bool or m.shape != (len(x),):
            raise ValueError(f"target_masks[{i}]: expected a boolean array of shape ({len(x)},), got {m.dtype} {m.shape}")
    return xs, ys, masks


def validation_tail(n_samples: int, window: int, val_fraction: float) -> int:
    """Samples at the end of a training recording that :func:`train` holds out for validation.

    ``max(window, round(val_fraction * n_samples))`` when ``val_fraction > 0`` (so the tail
    holds at least one window), else 0. Training uses the other ``n_samples - tail`` samples.

    Parameters
    ----------
    n_samples : int
        Length of the training recording (samples).
    window : int
        Window length ``L`` (samples), :attr:`TrainConfig.window`.
    val_fraction : float
        :attr:`TrainConfig.val_fraction`.

    Returns
    -------
    int
        Number of validation samples at the end of the recording (0: no validation). It may
        leave fewer than ``window`` training samples: :func:`train` refuses such a recording.
    """
    return 0 if val_fraction == 0 else max(window, int(round(val_fraction * n_samples)))


@dataclass
class _Part:
    """One side of the split, per training recording: inputs (N_i, C_in), targets (N_i, C_out)
    and the target mask (N_i,) or None (float32 arrays)."""

    x: list[np.ndarray]
    y: list[np.ndarray]
    mask: list[np.ndarray] | None


def _split(xs: list[np.ndarray], ys: list[np.ndarray], masks: list[np.ndarray] | None, window: int,
           val_fraction: float) -> tuple[_Part, _Part]:
    """Each recording's head for training and its tail (:func:`validation_tail`) for validation."""
    head, tail = _Part([], [], None if masks is None else []), _Part([], [], None if masks is None else [])
    for i, (x, y) in enumerate(zip(xs, ys)):
        n = len(x)
        n_val = validation_tail(n, window, val_fraction)
        if n - n_val < window:
            raise ValueError(f"recording {i} has N={n} samples: too short for a training block of {window} "
                             f"samples plus a validation block of {n_val}")
        for part, cut in ((head, slice(0, n - n_val)), (tail, slice(n - n_val, n))):
            if cut.stop > cut.start:
                part.x.append(x[cut])
                part.y.append(y[cut])
                if masks is not None and part.mask is not None:
                    part.mask.append(masks[i][cut])
    return head, tail


def _std(a: np.ndarray) -> np.ndarray:
    """Per-channel standard deviation of (N, C) samples (float64), 1 where it is ~0."""
    s = a.std(axis=0, dtype=np.float64)
    return np.where(s > 1e-12, s, 1.0)


def _new_network(cfg: TrainConfig, head: _Part, device: str) -> DanaeBase:
    """A freshly initialised network (drawn from torch's seeded global generator) on ``device``,
    holding the mean and std of the usable training samples when ``cfg.normalize == "standard"``."""
    net = build_model(cfg.arch, in_channels=head.x[0].shape[1], out_channels=head.y[0].shape[1],
                      **cfg.model_kwargs())
    if cfg.normalize == "standard":
        keep = head.mask or [slice(None)] * len(head.x)
        xa = np.concatenate([x[m] for x, m in zip(head.x, keep)])
        ya = np.concatenate([y[m] for y, m in zip(head.y, keep)])
        net.set_normalization(xa.mean(0, dtype=np.float64), _std(xa), ya.mean(0, dtype=np.float64), _std(ya))
    return net.to(device)


def _cut_windows(part: _Part, window: int, stride: int, device: str) -> tuple[torch.Tensor, torch.Tensor]:
    """Windows ``stride`` samples apart of each recording, none across two, as (n, C, L) float32
    inputs and targets; windows holding a masked target sample left out."""
    x, y = (torch.from_numpy(np.ascontiguousarray(windows_from_recordings(r, window, stride=stride)
                                                  .transpose(0, 2, 1))) for r in (part.x, part.y))
    if part.mask is not None:
        keep = torch.from_numpy(np.concatenate([sliding_windows(m, window, stride).all(axis=1) for m in part.mask]))
        x, y = x[keep], y[keep]
    return x.to(device), y.to(device)


@dataclass
class _TrainingWindows:
    """The stride-1 training windows of the heads, not cut out: memory holds the samples once
    (standardised, concatenated), and each batch gathers its windows by their first sample
    (:meth:`batch`) — the same values, in the same (B, C, L) layout, as rows of the cut-out
    windows of :func:`_cut_windows`."""

    x: torch.Tensor
    """Inputs of every head, concatenated, (N, C_in), in the network's standard units."""
    y: torch.Tensor
    """Targets, (N, C_out), in standard units (rad when ``normalize="none"``)."""
    starts: torch.Tensor
    """First sample (a row of ``x``) of each window, in :func:`_cut_windows` order, masked
    windows left out."""
    window: int

    def __len__(self) -> int:
        return len(self.starts)

    def batch(self, idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Windows ``idx`` as contiguous (B, C_in, L) inputs and (B, C_out, L) targets."""
        rows = self.starts[idx, None] + torch.arange(self.window, device=self.starts.device)
        return self.x[rows].transpose(1, 2).contiguous(), self.y[rows].transpose(1, 2).contiguous()


def _training_windows(head: _Part, net: DanaeBase, window: int, device: str) -> _TrainingWindows:
    """The training windows of ``head`` in the network's standard units (:class:`_TrainingWindows`)."""
    offsets = np.cumsum([0] + [len(x) for x in head.x[:-1]])
    starts = np.concatenate([o + np.arange(len(x) - window + 1) for o, x in zip(offsets, head.x)])
    if head.mask is not None:
        starts = starts[np.concatenate([sliding_windows(m, window).all(axis=1) for m in head.mask])]
    x = torch.from_numpy(np.concatenate(head.x)).to(device)
    y = torch.from_numpy(np.concatenate(head.y)).to(device)
    return _TrainingWindows((x - net.in_mean.reshape(-1)) / net.in_std.reshape(-1),
                            (y - net.out_mean.reshape(-1)) / net.out_std.reshape(-1),
                            torch.from_numpy(starts).to(device), window)


@torch.no_grad()
def _mse(net: DanaeBase, x: torch.Tensor, y: torch.Tensor, batch_size: int, start: int = 0) -> float:
    """MSE in raw units over all windows, from window position ``start`` on: evaluation mode,
    batches of ``batch_size`` windows, summed in float64."""
    net.eval()
    total = 0.0
    for i in range(0, len(x), batch_size):
        d = net(x[i: i + batch_size])[..., start:] - y[i: i + batch_size, :, start:]
        total += float((d**2).sum(dtype=torch.float64))
    net.train()
    return total / y[..., start:].numel()


@dataclass
class _Checks:
    """The validation checks of a run: history rows, the best weights so far, early stopping."""

    has_val: bool
    min_delta: float
    patience: int | None
    rows: list[dict[str, float]] = field(default_factory=list)
    best_val: float = math.inf
    best_step: int = 0
    best_state: dict[str, torch.Tensor] | None = None
    since_best: int = 0

    def check(self, net: DanaeBase, step: int, epoch: float, train_loss: float, val_loss: float) -> bool:
        """Log a row; copy the weights aside when they beat the best by more than ``min_delta``;
        True when training should stop early."""
        self.rows.append(dict(step=step, epoch=epoch, train_loss=train_loss, val_loss=val_loss))
        if not self.has_val:
            return False
        if val_loss < self.best_val - self.min_delta:
            self.best_val, self.best_step, self.since_best = val_loss, step, 0
            self.best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        else:
            self.since_best += 1
        return self.patience is not None and self.since_best >= self.patience


def _steps(n_windows: int, cfg: TrainConfig) -> tuple[int, int, int]:
    """Steps per epoch, total steps (``cfg.epochs`` passes, capped at ``cfg.max_steps``) and
    steps between validation checks (``cfg.val_every``, by default ten checks per epoch or run)."""
    per_epoch = math.ceil(n_windows / cfg.batch_size)
    total = per_epoch * cfg.epochs if cfg.max_steps is None else min(per_epoch * cfg.epochs, cfg.max_steps)
    return per_epoch, total, cfg.val_every or max(1, min(per_epoch, total) // 10)


def _fit(net: DanaeBase, train_windows: _TrainingWindows, val_windows: tuple[torch.Tensor, torch.Tensor] | None,
         shuffle: torch.Generator, cfg: TrainConfig, bar: Any) -> tuple[_Checks, int, bool]:
    """Chapter 3's loop: Adam steps on shuffled batches of standardised windows, a validation
    check every ``val_every`` steps. Returns the checks, the steps taken and whether it stopped early."""
    device = train_windows.x.device
    n_windows = len(train_windows)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr, betas=cfg.betas, fused=device.type in ("cpu", "cuda"))
    per_epoch, total, every = _steps(n_windows, cfg)
    checks, start = _Checks(val_windows is not None, cfg.min_delta, cfg.patience), cfg.loss_start
    running, n_running, step = torch.zeros((), device=device), 0, 0
    net.train()
    while step < total:
        perm = torch.randperm(n_windows, generator=shuffle).to(device)  # a new order each epoch
        for i in range(0, n_windows, cfg.batch_size):
            x, y = train_windows.batch(perm[i: i + cfg.batch_size])
            mse = torch.mean((net.forward_net(x)[..., start:] - y[..., start:]) ** 2)
            opt.zero_grad(set_to_none=True)
            (cfg.loss_scale * mse).backward()
            opt.step()
            step += 1
            running, n_running = running + mse.detach(), n_running + 1  # summed on the device
            bar.update(1)
            if step % every == 0 or step == total:  # validation check
                val = float("nan") if val_windows is None else _mse(net, *val_windows, cfg.eval_batch_size, start)
                if checks.check(net, step, step / per_epoch, float(running) / n_running, val):
                    return checks, step, True
                running, n_running = torch.zeros((), device=device), 0
                bar.set_postfix(val=f"{val:.3g}", refresh=False)
            if step == total:
                break
    return checks, step, False


def _progress_bar(progress: bool, total_steps: int, arch: str) -> Any:
    """A tqdm bar over the optimiser steps (disabled when ``progress`` is False)."""
    if progress:  # tqdm.auto picks the notebook widget when it can (and warns when it cannot)
        from tqdm.auto import tqdm
    else:
        from tqdm import tqdm
    return tqdm(total=total_steps, disable=not progress, desc=f"DANAE-{arch}", unit="step")


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
        Show a tqdm bar with the last validation loss.
    target_masks : list of bool ndarray, each (N_i,), optional
        True where the target is usable (e.g. :func:`danae_lite.data.groundtruth.clean_mask`).
        Windows holding any unusable target sample are left out of training and
        validation; the validation block is still the tail of each recording, so the split
        does not depend on the mask. ``n_train_windows``/``n_val_windows`` count the windows kept.

    Returns
    -------
    TrainResult

    Notes
    -----
    Training windows are cut per recording with stride 1 (validation windows with
    ``config.val_stride``) and never span two recordings (nor the border between a
    recording's training and validation blocks). They are shuffled each epoch with a
    ``torch.Generator`` seeded from ``config.seed``; the last batch of an epoch may be
    smaller. On CPU, with the same seed, data and thread count, two runs give bit-identical
    networks (``torch.use_deterministic_algorithms`` is on while training).
    """
    cfg = config or TrainConfig()
    xs, ys, masks = _checked_inputs(inputs, targets, target_masks)
    device = default_device(cfg.device)
    with TorchSettings(cfg.num_threads or max(1, torch.get_num_threads()),
                       deterministic=torch.device(device).type == "cpu"):
        head, tail = _split(xs, ys, masks, cfg.window, cfg.val_fraction)  # 1. split
        seed_everything(cfg.seed)  # 2. seeds: the global one fixes the initial weights ...
        net = _new_network(cfg, head, device)
        shuffle = torch.Generator().manual_seed(cfg.seed)  # ... a generator of its own the shuffling
        train_windows = _training_windows(head, net, cfg.window, device)  # 3. windows, in standard units
        if len(train_windows) == 0:
            raise ValueError("no training window is free of masked target samples")
        val_windows = _cut_windows(tail, cfg.window, cfg.val_stride, device) if tail.x else None
        if val_windows is not None and len(val_windows[0]) == 0:  # every validation window is masked
            val_windows = None
        bar = _progress_bar(progress, _steps(len(train_windows), cfg)[1], cfg.arch)
        t0 = time.perf_counter()
        checks, steps, stopped_early = _fit(net, train_windows, val_windows, shuffle, cfg, bar)
        seconds = time.perf_counter() - t0
        bar.close()
        best = val_windows is not None and cfg.restore_best and checks.best_state is not None
        if best:
            net.load_state_dict(checks.best_state)
        net.eval()
    history = pd.DataFrame(checks.rows, columns=HISTORY_COLUMNS)
    history["step"] = history["step"].astype(int)
    best_step, best_val = (checks.best_step, checks.best_val) if best else (steps, float(history.val_loss.iloc[-1]))
    return TrainResult(model=net, config=cfg, history=history, best_step=int(best_step),
                       best_val_loss=float(best_val) if val_windows is not None else float("nan"), seconds=seconds,
                       steps=steps, n_train_windows=len(train_windows), n_val_windows=0 if val_windows is None else
                       len(val_windows[0]), device=str(device), stopped_early=stopped_early)
