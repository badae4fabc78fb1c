"""The two records of a DANAE training run, shared by training and checkpoints.

* :class:`TrainConfig` -- everything that defines a training run (its settings).
* :class:`TrainResult` -- what a training run returns: the network, its loss history, bookkeeping.
* :func:`network_of` -- the network inside a network or a :class:`TrainResult`.

:mod:`danae_lite.danae.train` trains with these and :mod:`danae_lite.danae.checkpoints` writes and reads
them; keeping them apart from both lets each import them without importing the other.
Import them from :mod:`danae_lite.danae.train`, as the chapters do.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any

import pandas as pd

from .base import DanaeBase
from .model import ARCHITECTURES

__all__ = ["LOSSES", "NORMALIZATIONS", "TrainConfig", "TrainResult", "network_of"]

NORMALIZATIONS = ("none", "standard")
LOSSES = ("mse",)


@dataclass
class TrainConfig:
    """Everything that defines a training run.

    Attributes
    ----------
    arch : {"paper", "big", "causal"}
        Network, see :data:`danae_lite.danae.model.ARCHITECTURES`.
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
        for validation (at least ``window`` samples when > 0, see
        :func:`~danae_lite.danae.train.validation_tail`). 0 disables validation.
    val_every : int or None
        Steps between validation checks; ``None`` means ten checks per epoch.
    val_stride : int
        Step between the starts of the validation windows. 1 (the paper's way): every window
        of the validation tail. ``window - loss_start``: the scored positions of the windows
        tile the tail, each validation sample scored once (but the tail's first
        ``loss_start`` samples and a remainder shorter than a stride), where stride-1 windows
        score a sample up to ``window - loss_start`` times over, at as many forward passes.
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
    val_stride: int = 1
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
        for name in ("window", "batch_size", "epochs", "eval_batch_size", "val_stride"):
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
    """What :func:`~danae_lite.danae.train.train` returns.

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
        Windows trained and validated on (masked windows left out).
    device : str
        Torch device of the training.
    stopped_early : bool
        Whether early stopping (``patience``) ended the training.
    metadata : dict
        Further plain values kept with the network (e.g. by a cache: head, seed).
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
        """Optimiser steps per second of wall-clock training time (NaN when untimed)."""
        return self.steps / self.seconds if self.seconds > 0 else float("nan")


def network_of(model_or_result: DanaeBase | TrainResult, kind: type[DanaeBase] = DanaeBase) -> DanaeBase:
    """The network itself, or the one a :class:`TrainResult` holds.

    Parameters
    ----------
    model_or_result : DanaeBase or TrainResult
    kind : type
        The network class required (e.g. :class:`~danae_lite.danae.model.DanaeCausal` for on-line use).

    Raises
    ------
    TypeError
        When there is no network of class ``kind``.
    """
    net = model_or_result.model if isinstance(model_or_result, TrainResult) else model_or_result
    if not isinstance(net, kind):
        hint = (" (the paper's networks see future samples; train with TrainConfig(arch='causal'))"
                if kind is not DanaeBase and isinstance(net, DanaeBase) else "")
        raise TypeError(f"expected a {'DANAE' if kind is DanaeBase else kind.__name__} network or a TrainResult "
                        f"holding one, got {type(net).__name__}{hint}")
    return net
