"""Under which conditions a run's numbers hold: the CPU, the instruction set oneDNN runs on,
torch's thread count, the worker processes and the machine's load.

A network trained on one thread gives the same bits on every machine whose oneDNN runs the
same instruction set (the same torch version); the thread count and the instruction set change
the summation order of float32 arithmetic, and the load changes the run's timings.
:func:`probe` asks a child process with the kernels' environment, so that what it records is
what the chapters' kernels ran under (``OMP_NUM_THREADS``, ``ONEDNN_MAX_CPU_ISA``, ...).
"""
from __future__ import annotations

import os
import platform
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from danae_lite.runtime import JOBS_ENV

_PROBE = """
import torch
x, w = torch.zeros(16, 128, 40), torch.zeros(128, 128, 3)
torch.nn.functional.conv1d(x, w, padding=1)   # a convolution of the paper's size runs in oneDNN
print("torch_threads", torch.get_num_threads())
"""


def cpu_model(cpuinfo: str | None = None) -> str:
    """The CPU's model name (``/proc/cpuinfo``; ``cpuinfo`` is its text, for tests), else what
    :func:`platform.processor` says, else ``"unknown CPU"``."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace")
        except OSError:
            cpuinfo = ""
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "model name" and value.strip():
            return value.strip()
    return platform.processor() or "unknown CPU"


def parse_probe(output: str) -> dict[str, Any]:
    """``onednn_isa`` and ``torch_threads`` from what the probe printed with ``ONEDNN_VERBOSE=1``
    (oneDNN's line ``onednn_verbose,...,info,cpu,isa:Intel AVX2``); ValueError when either
    is missing."""
    isa = threads = None
    for line in output.splitlines():
        if line.startswith("onednn_verbose") and ",cpu,isa:" in line:
            isa = line.split(",cpu,isa:", 1)[1].strip()
        elif line.startswith("torch_threads "):
            threads = int(line.split()[1])
    if isa is None or threads is None:
        raise ValueError(f"the oneDNN probe printed no instruction set or thread count:\n{output[-500:]}")
    return {"onednn_isa": isa, "torch_threads": threads}


def probe(env: Mapping[str, str]) -> dict[str, Any]:
    """The conditions a kernel with environment ``env`` runs under: ``cpu`` (model), ``cores``,
    ``onednn_isa`` (e.g. ``"Intel AVX2"``), ``torch_threads`` (torch's default in that
    environment), ``jobs`` (``DANAE_JOBS``, worker processes for the trainings)."""
    run = subprocess.run([sys.executable, "-c", _PROBE], env={**env, "ONEDNN_VERBOSE": "1"},
                         capture_output=True, text=True, check=True, timeout=300)
    return {"cpu": cpu_model(), "cores": os.cpu_count() or 1, **parse_probe(run.stdout),
            "jobs": int(env.get(JOBS_ENV, "1") or 1)}


def load() -> float:
    """The machine's load: runnable processes averaged over the last minute (0 where the system
    does not say)."""
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return 0.0
