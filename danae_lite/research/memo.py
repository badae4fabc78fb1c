"""Results of deterministic computations, kept for the rest of the process and, optionally, on disk.

A chapter fits the same library filters, and runs the same trained networks, on the same
recordings in several sections (each split of a cross-validation, each table that uses
them), and several chapters run the same ones again. The results depend only on the code,
the parameters and the input arrays, so each distinct run is computed once:
:func:`~danae_lite.research.ahrs.filters.run_filter` and
:func:`~danae_lite.research.features.run_network` keep theirs in a :class:`RunMemo`, keyed by
what ran, its parameters and a :func:`digest` of the input arrays.

A memo holds its runs in memory; when the entry point hands it a :class:`RunStore`
(:func:`use_store`; the research chapters call :func:`keep_runs` after ``setup()``, which puts it
in ``<cache>/runs/full`` or ``runs/fast``), it
also keeps each run on disk, in joblib's store, for later processes and later re-executions. A
stored run's name hashes its key and the memo's :func:`code_fingerprint`: the code of the module that
computes it and of every module of the package that module imports, the versions of the
libraries they import, and the CPU's vector extensions (numpy and torch round differently on
another CPU). Editing any of that code makes every run of that memo new; editing a chapter,
or code the runs do not import, keeps them. The trained networks themselves are kept by
:mod:`danae_lite.danae.networks`.
"""
from __future__ import annotations

import ast
import functools
import hashlib
import importlib
import importlib.metadata
import importlib.util
import os
import sys
from collections import OrderedDict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, TypeVar

import joblib
import numpy as np
from numpy.typing import NDArray

R = TypeVar("R")

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


@dataclass(frozen=True)
class RunStore:
    """Runs kept on disk in joblib's store (the storage of a :class:`joblib.Memory` in
    ``folder``), capped in size.

    A run is one item of the store, under its name (32 hex digits). joblib writes an item whole
    under a temporary name and then renames it, so processes sharing the folder never read half
    of one; :meth:`prune` is joblib's ``reduce_size``, which removes the least recently used
    items first. A damaged item counts as missing (it is removed and the run computed again)."""

    folder: Path
    """The folder of the :class:`joblib.Memory` (a run is the item ``runs/<name>/output.pkl``)."""
    max_bytes: int | None = None
    """Cap on the total size of the stored runs [bytes]; None: no cap."""

    @functools.cached_property
    def memory(self) -> joblib.Memory:
        """The :class:`joblib.Memory` whose storage holds the runs (it prints nothing)."""
        return joblib.Memory(self.folder, verbose=0)

    def load(self, name: str) -> NDArray[Any] | None:
        """The run stored under ``name``, or None; loading marks it used."""
        item = ["runs", name]
        backend = self.memory.store_backend
        if not backend.contains_item(item):
            return None
        try:
            value = backend.load_item(item, verbose=0)
            os.utime(Path(backend.location, *item, "output.pkl"))  # used now: the last to go
        except FileNotFoundError:  # removed meanwhile by another process sharing the folder
            return None
        except Exception:  # damaged (cut short, unreadable): computed again
            backend.clear_item(item)
            return None
        return value if isinstance(value, np.ndarray) else None

    def save(self, name: str, value: NDArray[Any]) -> None:
        """Store ``value`` under ``name`` (replacing any run stored under it)."""
        self.memory.store_backend.dump_item(["runs", name], np.asarray(value), verbose=0)
        _written[self.folder] = _written.get(self.folder, 0) + value.nbytes
        if self.max_bytes is not None and _written[self.folder] > self.max_bytes // 20:
            self.prune()  # every twentieth of the cap written: a folder scan is not free

    def prune(self) -> None:
        """Remove the least recently used runs until the store is within ``max_bytes``."""
        _written[self.folder] = 0
        if self.max_bytes is not None:
            self.memory.reduce_size(bytes_limit=self.max_bytes)


_written: dict[Path, int] = {}
"""Bytes this process stored in each :class:`RunStore` folder since it last pruned it."""
_store: RunStore | None = None
"""The store every :class:`RunMemo` of this process also uses (:func:`use_store`)."""


def use_store(store: RunStore | None) -> None:
    """Make every :class:`RunMemo` of this process also keep its runs in ``store`` (None: in
    memory only). Set by an entry point; :func:`carrying_store` passes it to worker processes."""
    global _store
    _store = store


class CacheSettings(Protocol):
    """What :func:`keep_runs` reads of the run's settings (:class:`danae_lite.runtime.RunSettings`)."""

    cache_root: Path | None
    fast: bool
    cache_gb: float


def keep_runs(settings: CacheSettings) -> None:
    """:func:`use_store` with this mode's store of the settings' cache: ``<cache_root>/runs/full``
    (or ``runs/fast``), capped at ``cache_gb`` [GB]; no store (runs kept in memory only) when
    the cache is off. What a chapter that runs library filters or networks on recordings calls
    after ``setup()``."""
    if settings.cache_root is None:
        use_store(None)
        return
    folder = settings.cache_root / "runs" / ("fast" if settings.fast else "full")
    use_store(RunStore(folder, int(settings.cache_gb * 1e9)))


def carrying_store(fn: Callable[..., R]) -> Callable[..., R]:
    """``fn`` (a module-level function) wrapped so that, called in a worker process, it first
    uses this process's :class:`RunStore`: what :func:`~danae_lite.danae.networks.in_processes`
    is given where the workers run memoised computations."""
    return functools.partial(_call_with_store, _store, fn)


def _call_with_store(store: RunStore | None, fn: Callable[..., R], *args: Any) -> R:
    use_store(store)
    return fn(*args)


@functools.lru_cache(maxsize=None)
def code_fingerprint(module: str) -> str:
    """32 hex digits over what decides the runs computed by ``module``: the code (without
    docstrings and comments) of ``module`` and of every module of this package it imports,
    directly or not, except this one (which stores and finds runs but computes none); the
    installed versions of the other libraries those import; and the CPU vector extensions
    numpy and torch dispatch to."""
    from ..danae.networks import module_code

    h = hashlib.blake2b(digest_size=16)
    ours, theirs = _import_closure(module)
    for name in sorted(ours - {__name__}):  # this module stores and finds runs, computes none
        h.update(name.encode() + b"\0" + module_code(name))
    dists = importlib.metadata.packages_distributions()
    for top in sorted(theirs):
        for dist in sorted(set(dists.get(top, ()))):
            h.update(f"{dist}=={importlib.metadata.version(dist)}".encode())
    h.update(_cpu_features().encode())
    return h.hexdigest()


def _import_closure(module: str) -> tuple[set[str], set[str]]:
    """The modules of this package that ``module`` imports, directly or not (``module``
    included), and the top-level names of the other non-standard libraries they import."""
    package = __name__.split(".")[0]
    ours: set[str] = set()
    theirs: set[str] = set()
    todo = [module]
    while todo:
        name = todo.pop()
        if name in ours:
            continue
        ours.add(name)
        spec = importlib.util.find_spec(name)
        origin = Path(spec.origin) if spec is not None and spec.origin else None
        if origin is None or origin.suffix != ".py":
            raise ValueError(f"code_fingerprint: no Python source for module {name!r}")
        parent = name if origin.name == "__init__.py" else name.rpartition(".")[0]
        for imported in _imports(ast.parse(origin.read_bytes()), parent):
            if imported.split(".")[0] == package:
                todo.append(imported)
            elif imported.split(".")[0] not in sys.stdlib_module_names:
                theirs.add(imported.split(".")[0])
    return ours, theirs


def _imports(tree: ast.Module, parent: str) -> Iterator[str]:
    """The absolute names of the modules ``tree`` imports (``from x import y``: ``x.y`` when
    that is a module of this package, else ``x``); ``parent`` resolves relative imports."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), parent) \
                if node.level else node.module or ""
            ours = base.split(".")[0] == __name__.split(".")[0]
            for alias in node.names:  # another library's modules are not looked up (that imports them)
                full = f"{base}.{alias.name}"
                yield full if ours and _is_module(full) else base


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def _cpu_features() -> str:
    """The vector extensions numpy and torch use on this CPU (their rounding can differ on another)."""
    import torch
    from numpy._core._multiarray_umath import __cpu_features__  # type: ignore[attr-defined]

    return ",".join(sorted(k for k, v in __cpu_features__.items() if v)) + ";" + torch.backends.cpu.get_cpu_capability()


class RunMemo:
    """Arrays computed earlier, by a key the caller builds (what was run, its parameters, a
    :func:`digest` of its input data): in memory, where the least recently used are dropped
    past ``max_bytes``, and in the :class:`RunStore` of :func:`use_store` when there is one,
    under the key and the :func:`code_fingerprint` of ``code_of`` (the module that computes the
    runs). ``get`` returns a copy, so a caller changing it changes nothing stored.
    Timing a computation needs it done afresh: run it inside :meth:`bypassed`."""

    def __init__(self, max_bytes: int, code_of: str) -> None:
        self.max_bytes = int(max_bytes)
        self.code_of = code_of
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

    def _name(self, key: tuple[Any, ...]) -> str:
        """The file name of ``key``'s run in a :class:`RunStore`."""
        return hashlib.blake2b(f"{code_fingerprint(self.code_of)}{key!r}".encode(), digest_size=16).hexdigest()

    def get(self, key: tuple[Any, ...]) -> Array | None:
        found = None if self._bypass else self._items.get(key)
        if found is not None:
            self._items.move_to_end(key)
        elif not self._bypass and _store is not None:
            found = _store.load(self._name(key))
            if found is not None:
                self._remember(key, found)
        if found is None:
            self.misses += 1
            return None
        self.hits += 1
        return found.copy()

    def put(self, key: tuple[Any, ...], value: Array) -> None:
        """Keep ``value`` under ``key``: in memory, and in the store when there is one."""
        if self._bypass or key in self._items:
            return
        if _store is not None:
            _store.save(self._name(key), value)
        self._remember(key, value.copy())

    def _remember(self, key: tuple[Any, ...], value: Array) -> None:
        if value.nbytes > self.max_bytes:
            return
        self._items[key] = value
        self.nbytes += value.nbytes
        while self.nbytes > self.max_bytes:
            self.nbytes -= self._items.popitem(last=False)[1].nbytes

    def clear(self) -> None:
        self._items.clear()
        self.nbytes = self.hits = self.misses = 0
