"""Results of deterministic computations kept in memory for the rest of the process.

A chapter fits the same library filters, and runs the same trained networks, on the same
recordings in several sections (each split of a cross-validation, each table that uses
them). The results depend only on the code, the parameters and the input arrays, so each
distinct run is computed once per process: :func:`~danae_lite.research.filters.run_filter`
and :func:`~danae_lite.research.features.run_network` keep theirs in a :class:`RunMemo`,
keyed by what ran, its parameters and a :func:`digest` of the input arrays. Nothing is
written to disk (the trained networks themselves are kept by :mod:`danae_lite.core.networks`).
"""
from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def digest(*arrays: NDArray[Any] | None) -> str:
    """32 hex digits of a BLAKE2b over the dtype, shape and bytes of each array (None counts
    as its own value): equal for equal arrays, wherever they are in memory."""
    h = hashlib.blake2b(digest_size=16)
    for arr in arrays:
        if arr is None:
            h.update(b"none")
            continue
        a = np.ascontiguousarray(arr)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


class RunMemo:
    """Arrays computed earlier in this process, by a key the caller builds (what was run, its
    parameters, a :func:`digest` of its input data); the least recently used are dropped past
    ``max_bytes``. ``get`` returns a copy, so a caller changing it changes nothing stored.
    Timing a computation needs it done afresh: run it inside :meth:`bypassed`."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = int(max_bytes)
        self._items: OrderedDict[tuple[Any, ...], Array] = OrderedDict()
        self.nbytes = self.hits = self.misses = 0
        self._bypass = 0

    @contextmanager
    def bypassed(self) -> Iterator[None]:
        """Inside the block nothing is found and nothing stored: every run is computed, as
        a timing must (what is stored stays for after the block)."""
        self._bypass += 1
        try:
            yield
        finally:
            self._bypass -= 1

    def get(self, key: tuple[Any, ...]) -> Array | None:
        found = None if self._bypass else self._items.get(key)
        if found is None:
            self.misses += 1
            return None
        self._items.move_to_end(key)
        self.hits += 1
        return found.copy()

    def put(self, key: tuple[Any, ...], value: Array) -> None:
        if self._bypass or key in self._items or value.nbytes > self.max_bytes:
            return
        self._items[key] = value.copy()
        self.nbytes += value.nbytes
        while self.nbytes > self.max_bytes:
            self.nbytes -= self._items.popitem(last=False)[1].nbytes

    def clear(self) -> None:
        self._items.clear()
        self.nbytes = self.hits = self.misses = 0
