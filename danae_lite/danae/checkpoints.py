"""Checkpoints: one file per trained DANAE network, with its settings and training record.

* :func:`save` -- write a network or a :class:`~danae_lite.danae.train_types.TrainResult` to one file.
* :func:`load` -- read it back as ``(network, TrainConfig, metadata)``.
* :func:`load_result` -- read a file saved from a training run back into a ``TrainResult``.
* :class:`CheckpointError` -- a file that is not a readable DANAE checkpoint.

A file is ``torch.save`` of a dict of plain values and tensors only (format
:data:`CHECKPOINT_FORMAT`, version :data:`CHECKPOINT_VERSION`), so it is read with torch's
safe loader (``weights_only=True``). The network cache (:mod:`danae_lite.danae.networks`)
keeps the same dict (:func:`checkpoint_dict`, :func:`result_from_checkpoint`) in joblib's store.
Nothing here changes a trained network, so this module is not part of a network's cache key
(:func:`danae_lite.danae.networks.cache_key`).
"""
from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from .._version import __version__
from .base import DanaeBase
from .model import ARCHITECTURES, build_model
from .train_types import TrainConfig, TrainResult, network_of

__all__ = ["CHECKPOINT_FORMAT", "CHECKPOINT_VERSION", "CheckpointError", "checkpoint_dict", "load", "load_result",
           "result_from_checkpoint", "save"]

CHECKPOINT_FORMAT = "danae_lite.checkpoint"
CHECKPOINT_VERSION = 1


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


def checkpoint_dict(
    result_or_model: TrainResult | DanaeBase,
    *,
    config: TrainConfig | None = None,
    metadata: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """A network, its training configuration and metadata as a dict of plain values and tensors:
    ``format``, ``version``, ``arch``, ``kwargs`` (constructor arguments), ``state_dict`` (incl.
    the standardisation buffers), ``config`` (:meth:`TrainConfig.to_dict` or None) and
    ``metadata``. For a :class:`TrainResult` the metadata gets ``history`` (dict of lists),
    ``best_step``, ``best_val_loss``, ``seconds``, ``steps``, window counts and ``device``;
    ``torch_version`` and ``normalization`` are always added. Explicit ``config``/``metadata``
    win."""
    net = network_of(result_or_model)
    meta: dict[str, Any] = {}
    if isinstance(result_or_model, TrainResult):
        r = result_or_model
        config = config or r.config
        meta.update(history=r.history, best_step=r.best_step, best_val_loss=r.best_val_loss, seconds=r.seconds,
                    steps=r.steps, n_train_windows=r.n_train_windows, n_val_windows=r.n_val_windows,
                    device=r.device, stopped_early=r.stopped_early, **r.metadata)
    meta.update(torch_version=torch.__version__, danae_lite_version=__version__, normalization=net.normalization())
    meta.update(metadata or {})
    return dict(format=CHECKPOINT_FORMAT, version=CHECKPOINT_VERSION, arch=net.arch, kwargs=net.constructor_kwargs(),
                state_dict={k: v.detach().cpu().clone() for k, v in net.state_dict().items()},
                config=config.to_dict() if config is not None else None, metadata=_plain(meta))


def save(
    result_or_model: TrainResult | DanaeBase,
    path: str | os.PathLike[str],
    *,
    config: TrainConfig | None = None,
    metadata: dict[str, Any] | None = None,
) -> Path:
    """Write a network, its training configuration and metadata to one file: ``torch.save`` of
    :func:`checkpoint_dict`, which :func:`load` reads with ``weights_only=True``. The file is
    written to a temporary name and renamed, so a crash leaves no half file.

    Returns
    -------
    Path
        The file written.
    """
    ckpt = checkpoint_dict(result_or_model, config=config, metadata=metadata)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # a temporary name of this process and call: two processes (two chapters under pytest's
    # workers) storing the same network at once each replace the file whole, neither fails
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        torch.save(ckpt, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
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
    expect_arch : {"paper", "big", "causal"}, optional
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
    try:
        ckpt = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as err:  # corrupt, truncated, or pickled foreign objects
        msg = str(err).strip().splitlines()[0][:200] if str(err).strip() else ""
        raise CheckpointError(f"{path}: cannot be read as {_EXPECTED}: {type(err).__name__}: {msg}") from err
    return _network(ckpt, str(path), expect_arch, map_location)


_EXPECTED = f"a DANAE checkpoint (torch.save dict with format={CHECKPOINT_FORMAT!r})"


def _network(ckpt: Any, path: str, expect_arch: str | None, map_location: str | torch.device
             ) -> tuple[DanaeBase, TrainConfig | None, dict[str, Any]]:
    """The network, configuration and metadata of a checkpoint dict read from ``path``."""
    expected = _EXPECTED
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
    return _result(*load(path, map_location=map_location), str(path))


def result_from_checkpoint(ckpt: dict[str, Any], where: str) -> TrainResult:
    """The :class:`TrainResult` of a :func:`checkpoint_dict` of a training run (on the CPU);
    :class:`CheckpointError` naming ``where`` when it is not one."""
    return _result(*_network(ckpt, where, None, "cpu"), where)


def _result(net: DanaeBase, config: TrainConfig | None, meta: dict[str, Any], path: str) -> TrainResult:
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
