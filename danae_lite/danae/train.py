"""Training DANAE and choosing the best state on held-out windows (predicting: :mod:`danae_lite.danae.predict`).

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
end, :func:`validation_tail`) is held out; the network is evaluated on it every
``val_every`` steps and the best state is kept (optionally stopping early). The test
recording is never touched. The paper reports no validation split, so with
``val_fraction=0`` the final state is used, as there.

:func:`train` reads as chapter 3's plain loop: check the inputs, split each recording into
a training head and a validation tail, build the network, cut the windows, then repeat
:func:`_optimisation_step` and, every ``val_every`` steps, a validation check
(:class:`_ModelSelection`). :class:`TrainConfig` and :class:`TrainResult` live in
:mod:`danae_lite.danae.train_types`, :func:`save` and :func:`load` in :mod:`danae_lite.danae.checkpoints`;
all four are importable from here.
"""
from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import torch

from .checkpoints import load, save  # chapter 3 imports them from here (danae_lite.danae.train)
from .model import DanaeBase, build_model
from .seeding import default_device, seed_everything
from .train_types import TrainConfig, TrainResult
from .windows import sliding_windows, windows_from_recordings

__all__ = ["TrainConfig", "TrainResult", "load", "save", "train", "validation_tail"]

HISTORY_COLUMNS = ["step", "epoch", "train_loss", "val_loss"]
"""Columns of :attr:`TrainResult.history`, one row per validation check."""


# ---------------------------------------------------------------------------------------
# torch settings
# ---------------------------------------------------------------------------------------
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
# inputs: recordings, training and validation blocks, windows
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


def _split(
    inputs: list[np.ndarray], targets: list[np.ndarray], window: int, val_fraction: float
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Per recording: head block for training, tail block (:func:`validation_tail`) for validation."""
    xs_tr, ys_tr, xs_va, ys_va = [], [], [], []
    for i, (x, y) in enumerate(zip(inputs, targets)):
        n = len(x)
        n_val = validation_tail(n, window, val_fraction)
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


def _valid_windows(masks: list[np.ndarray], window: int, stride: int = 1) -> np.ndarray:
    """For the windows of each recording, ``stride`` samples apart (in :func:`_to_windows`
    order): True when every target sample in the window is usable."""
    return np.concatenate([sliding_windows(m, window, stride).all(axis=1) for m in masks])


@dataclass
class _Blocks:
    """The training recordings split into training heads and validation tails (float32 arrays)."""

    x_train: list[np.ndarray]
    """Input head of each recording, (N_i - tail_i, C_in)."""
    y_train: list[np.ndarray]
    """Target head of each recording, (N_i - tail_i, C_out)."""
    x_val: list[np.ndarray]
    """Input tail of each recording, (tail_i, C_in); empty without validation."""
    y_val: list[np.ndarray]
    """Target tail of each recording, (tail_i, C_out)."""
    keep_train: torch.Tensor | None = None
    """Per training window (:func:`_to_windows` order): free of masked targets. None: all are."""
    keep_val: torch.Tensor | None = None
    """The same for the validation windows."""
    x_stat: list[np.ndarray] = field(default_factory=list)
    """Input samples the standardisation statistics come from (usable training samples)."""
    y_stat: list[np.ndarray] = field(default_factory=list)
    """Target samples the standardisation statistics come from."""


def _split_blocks(xs: list[np.ndarray], ys: list[np.ndarray], masks: list[np.ndarray] | None,
                  window: int, val_fraction: float, val_stride: int = 1) -> _Blocks:
    """Split every recording (and its mask) into a training head and a validation tail
    (validation windows ``val_stride`` samples apart)."""
    xs_tr, ys_tr, xs_va, ys_va = _split(xs, ys, window, val_fraction)
    if masks is None:
        return _Blocks(xs_tr, ys_tr, xs_va, ys_va, x_stat=xs_tr, y_stat=ys_tr)
    _, ms_tr, _, ms_va = _split(xs, masks, window, val_fraction)
    keep_tr = torch.from_numpy(_valid_windows(ms_tr, window))
    keep_va = torch.from_numpy(_valid_windows(ms_va, window, val_stride)) if ms_va else None
    if not bool(keep_tr.any()):
        raise ValueError("no training window is free of masked target samples")
    # standardisation statistics from usable samples only
    return _Blocks(xs_tr, ys_tr, xs_va, ys_va, keep_tr, keep_va,
                   x_stat=[x[m] for x, m in zip(xs_tr, ms_tr)], y_stat=[y[m] for y, m in zip(ys_tr, ms_tr)])


def _std(a: np.ndarray) -> np.ndarray:
    """Per-channel standard deviation of (N, C) samples (float64), 1 where it is ~0."""
    s = a.std(axis=0, dtype=np.float64)
    return np.where(s > 1e-12, s, 1.0)


def _new_network(cfg: TrainConfig, blocks: _Blocks, c_in: int, c_out: int, device: str) -> DanaeBase:
    """A freshly initialised network (drawn from torch's seeded global generator) on ``device``,
    holding the mean and std of the training samples when ``cfg.normalize == "standard"``."""
    net = build_model(cfg.arch, in_channels=c_in, out_channels=c_out, **cfg.model_kwargs())
    if cfg.normalize == "standard":
        xa, ya = np.concatenate(blocks.x_stat), np.concatenate(blocks.y_stat)
        net.set_normalization(xa.mean(0, dtype=np.float64), _std(xa), ya.mean(0, dtype=np.float64), _std(ya))
    return net.to(device)


def _to_windows(recs: list[np.ndarray], window: int, device: str, stride: int = 1) -> torch.Tensor:
    """Windows of each recording, ``stride`` samples apart, as a (n, C, L) float32 tensor."""
    w = windows_from_recordings(recs, window, stride=stride)  # (n, L, C)
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


@dataclass
class _Windows:
    """The windows a run trains and validates on. Training windows are not cut out: each batch
    gathers its windows from the standardised samples by their first sample (:meth:`batch`),
    so memory holds the samples once, not every window of ``L`` samples; validation windows,
    far fewer, are cut out as (n, C, L) float32 tensors."""

    x_train: torch.Tensor
    """Training inputs of every training head, concatenated, (N, C_in), standardised by the
    network's input statistics."""
    y_train: torch.Tensor
    """Training targets, (N, C_out), standardised: the loss is optimised in these units (rad
    when ``normalize="none"``)."""
    starts: torch.Tensor
    """First sample (a row of ``x_train``) of each training window, in :func:`_to_windows`
    order, masked windows left out."""
    x_val: torch.Tensor | None
    """Validation inputs in raw units (rad); None when there is no validation window."""
    y_val: torch.Tensor | None
    """Validation targets in raw units (rad)."""
    window: int = 20

    @property
    def has_val(self) -> bool:
        return self.x_val is not None

    @property
    def n_train(self) -> int:
        return len(self.starts)

    @property
    def n_val(self) -> int:
        return len(self.x_val) if self.x_val is not None else 0

    def batch(self, idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Training windows ``idx`` as contiguous (B, C_in, L) inputs and (B, C_out, L) targets:
        the same values, in the same layout, as rows of the cut-out windows."""
        rows = self.starts[idx, None] + torch.arange(self.window, device=self.starts.device)
        return (self.x_train[rows].transpose(1, 2).contiguous(),
                self.y_train[rows].transpose(1, 2).contiguous())

    def val_loss(self, net: DanaeBase, cfg: TrainConfig) -> float:
        """The network's validation MSE (rad^2) from window position ``cfg.loss_start`` on; NaN without validation."""
        if self.x_val is None or self.y_val is None:
            return float("nan")
        return _mse(net, self.x_val, self.y_val, cfg.eval_batch_size, cfg.loss_start)


def _window_starts(recs: list[np.ndarray], window: int) -> np.ndarray:
    """First sample of every stride-1 window of each recording, as rows of the recordings
    concatenated (in :func:`_to_windows` order)."""
    offsets = np.cumsum([0] + [len(r) for r in recs[:-1]])
    return np.concatenate([o + np.arange(len(r) - window + 1) for o, r in zip(offsets, recs)])


def _cut_windows(blocks: _Blocks, net: DanaeBase, window: int, device: str, val_stride: int = 1) -> _Windows:
    """Stride-1 windows of the training heads (standardised; as starts into their samples) and
    windows ``val_stride`` apart of the validation tails, masked windows left out."""
    starts = torch.from_numpy(_window_starts(blocks.x_train, window)).to(device)
    if blocks.keep_train is not None:
        starts = starts[blocks.keep_train.to(device)]
    # the optimised loss lives in standardised units (identical to rad when normalize="none")
    x_tr = torch.from_numpy(np.concatenate(blocks.x_train)).to(device)
    y_tr = torch.from_numpy(np.concatenate(blocks.y_train)).to(device)
    x_tr_n = (x_tr - net.in_mean.reshape(-1)) / net.in_std.reshape(-1)
    y_tr_n = (y_tr - net.out_mean.reshape(-1)) / net.out_std.reshape(-1)
    x_va = y_va = None
    if blocks.x_val:
        x_va = _to_windows(blocks.x_val, window, device, val_stride)
        y_va = _to_windows(blocks.y_val, window, device, val_stride)
        if blocks.keep_val is not None:
            x_va, y_va = x_va[blocks.keep_val.to(device)], y_va[blocks.keep_val.to(device)]
        if len(x_va) == 0:  # every validation window holds a masked target
            x_va = y_va = None
    return _Windows(x_tr_n, y_tr_n, starts, x_va, y_va, window)


# ---------------------------------------------------------------------------------------
# training
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Schedule:
    """How many optimiser steps a run takes and after which ones it validates."""

    steps_per_epoch: int
    total_steps: int
    val_every: int

    @classmethod
    def of(cls, n_train: int, cfg: TrainConfig) -> "_Schedule":
        """``cfg.epochs`` passes over ``n_train`` windows (capped at ``cfg.max_steps``);
        ``cfg.val_every`` steps between checks, by default ten checks per epoch."""
        steps_per_epoch = math.ceil(n_train / cfg.batch_size)
        total_steps = steps_per_epoch * cfg.epochs
        if cfg.max_steps is not None:
            total_steps = min(total_steps, cfg.max_steps)
        val_every = cfg.val_every or max(1, min(steps_per_epoch, total_steps) // 10)
        return cls(steps_per_epoch, total_steps, val_every)

    def validates_at(self, step: int) -> bool:
        """Whether a validation check follows optimiser step ``step`` (always after the last)."""
        return step % self.val_every == 0 or step == self.total_steps


def _batches(n_train: int, batch_size: int, epochs: int, seed: int, device: str) -> Iterator[torch.Tensor]:
    """Window indices of each optimiser step: every epoch a fresh shuffle (a ``torch.Generator``
    seeded with ``seed``, apart from the global one) cut into batches; the last may be smaller."""
    gen = torch.Generator().manual_seed(seed)
    for _ in range(epochs):
        perm = torch.randperm(n_train, generator=gen).to(device)
        for i in range(0, n_train, batch_size):
            yield perm[i : i + batch_size]


def _optimisation_step(net: DanaeBase, opt: torch.optim.Optimizer, x: torch.Tensor, y: torch.Tensor,
                       cfg: TrainConfig) -> torch.Tensor:
    """One Adam step on a batch of standardised windows ``x`` (B, C_in, L) -> ``y`` (B, C_out, L).

    Returns the batch's MSE from window position ``cfg.loss_start`` on (before the step,
    unscaled, detached; left on the device so that no step waits for it).
    """
    out = net.forward_net(x)
    mse = torch.mean((out[..., cfg.loss_start :] - y[..., cfg.loss_start :]) ** 2)
    opt.zero_grad(set_to_none=True)
    (cfg.loss_scale * mse).backward()
    opt.step()
    return mse.detach()


class _RunningLoss:
    """Mean training loss since the last validation check, summed on the device."""

    def __init__(self) -> None:
        self.total: float | torch.Tensor = 0.0
        self.n = 0

    def add(self, mse: torch.Tensor) -> None:
        self.total = self.total + mse  # stays on the device: no sync per step
        self.n += 1

    def mean(self) -> float:
        return float(self.total) / max(self.n, 1)

    def pop(self) -> float:
        """The mean, starting a new sum."""
        mean = self.mean()
        self.total, self.n = 0.0, 0
        return mean


@dataclass
class _ModelSelection:
    """The validation checks of a run: history rows, the best state so far, early stopping."""

    has_val: bool
    min_delta: float
    patience: int | None
    rows: list[dict[str, float]] = field(default_factory=list)
    best_val: float = math.inf
    best_step: int = 0
    best_state: dict[str, torch.Tensor] | None = None
    checks_since_best: int = 0

    @property
    def last_val(self) -> float:
        """Validation loss of the latest check (rad^2; NaN before the first)."""
        return self.rows[-1]["val_loss"] if self.rows else float("nan")

    def check(self, net: DanaeBase, step: int, epoch: float, train_loss: float, val_loss: float) -> bool:
        """Log a history row, keep a copy of the state when it improved on the best by more
        than ``min_delta``; return True when training should stop early."""
        self.rows.append(dict(step=step, epoch=epoch, train_loss=train_loss, val_loss=val_loss))
        if not self.has_val:
            return False
        if val_loss < self.best_val - self.min_delta:
            self.best_val, self.best_step, self.checks_since_best = val_loss, step, 0
            self.best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        else:
            self.checks_since_best += 1
        return self.patience is not None and self.checks_since_best >= self.patience

    def finish(self, net: DanaeBase, restore_best: bool, last_step: int) -> tuple[int, float]:
        """Load the best state into ``net`` when asked (else keep the last), put it in eval
        mode; return the step and validation loss (rad^2) of the state it holds."""
        if self.has_val and restore_best and self.best_state is not None:
            net.load_state_dict(self.best_state)
            best = self.best_step, self.best_val
        else:
            best = last_step, self.last_val
        net.eval()
        return best


def _fit(net: DanaeBase, data: _Windows, cfg: TrainConfig, schedule: _Schedule, bar: Any,
         device: str) -> tuple[_ModelSelection, int, bool]:
    """The training loop: Adam steps on shuffled batches, a validation check every
    ``schedule.val_every`` steps. Returns the checks, the steps taken and whether it stopped early."""
    # the fused kernel updates every parameter in one call (same Adam, less overhead)
    fused = torch.device(device).type in ("cpu", "cuda")
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr, betas=cfg.betas, fused=fused)
    selection = _ModelSelection(data.has_val, cfg.min_delta, cfg.patience)
    running = _RunningLoss()
    step, stopped_early = 0, False
    net.train()
    for idx in _batches(data.n_train, cfg.batch_size, cfg.epochs, cfg.seed, device):
        running.add(_optimisation_step(net, opt, *data.batch(idx), cfg))
        step += 1
        bar.update(1)
        if step % 20 == 0 or step == schedule.total_steps:
            bar.set_postfix(loss=f"{running.mean():.3g}", val=f"{selection.last_val:.3g}", refresh=False)
        if schedule.validates_at(step):
            val_loss = data.val_loss(net, cfg)
            if selection.check(net, step, step / schedule.steps_per_epoch, running.pop(), val_loss):
                stopped_early = True
                break
        if step >= schedule.total_steps:
            break
    return selection, step, stopped_early


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
        Show a tqdm bar with the running training loss and the last validation loss.
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
    recording's training and validation blocks). They are shuffled each
    epoch with a ``torch.Generator`` seeded from ``config.seed``; the last batch of an epoch
    may be smaller. On CPU, with the same seed, data and thread count, two runs give
    bit-identical networks (``torch.use_deterministic_algorithms`` is on while training).
    """
    cfg = config or TrainConfig()
    xs, ys, masks = _checked_inputs(inputs, targets, target_masks)
    device = default_device(cfg.device)
    on_cpu = torch.device(device).type == "cpu"
    with TorchSettings(cfg.num_threads or _default_threads(), deterministic=on_cpu):
        seed_everything(cfg.seed)
        blocks = _split_blocks(xs, ys, masks, cfg.window, cfg.val_fraction, cfg.val_stride)
        net = _new_network(cfg, blocks, xs[0].shape[1], ys[0].shape[1], device)
        data = _cut_windows(blocks, net, cfg.window, device, cfg.val_stride)
        schedule = _Schedule.of(data.n_train, cfg)
        bar = _progress_bar(progress, schedule.total_steps, cfg.arch)
        t0 = time.perf_counter()
        selection, steps, stopped_early = _fit(net, data, cfg, schedule, bar, device)
        bar.close()
        seconds = time.perf_counter() - t0
        best_step, best_val = selection.finish(net, cfg.restore_best, steps)
    history = pd.DataFrame(selection.rows, columns=HISTORY_COLUMNS)
    history["step"] = history["step"].astype(int)
    return TrainResult(model=net, config=cfg, history=history, best_step=int(best_step),
                       best_val_loss=float(best_val) if data.has_val else float("nan"), seconds=seconds,
                       steps=steps, n_train_windows=data.n_train, n_val_windows=data.n_val, device=str(device),
                       stopped_early=stopped_early)
