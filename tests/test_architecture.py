"""The package's shape: rooms by concept, imports pointing one way (down the package map), no
import circles, every module in the package map, and only the settings module reads the
``DANAE_*`` variables.

Imports are read from the source with :mod:`ast`, including those made inside functions (they
run too, only later). Imports under ``if TYPE_CHECKING:`` are left out: they never run.

A module's room is the first part of its name (``kalman.filter`` -> ``kalman``); :data:`ROOMS`
lists them in the order of the package map, and a room imports only rooms listed before it.
Book maintenance (re-execution, the pages' generated blocks) is not in the package: ``tools/``.
The Kalman-filter chapters (1-2) and the chapters' common ``setup()`` load no torch.
"""
from __future__ import annotations

import ast
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "danae_lite"
SETTINGS = "runtime"
ROOMS = ("_version", "angles", "data", "kalman", "danae", "evaluate", "plots", "paper", "research",
         "runtime", "book", "commands", "cli", "__main__", "__init__")
"""The package's rooms (a folder or a module at the top), in the order data flows through them;
a room imports only rooms listed before it."""


def layer(module: str) -> int:
    """The position of the module's room in :data:`ROOMS` (``kalman.filter`` -> that of ``kalman``)."""
    return ROOMS.index(module.split(".")[0])


def modules(package: Path) -> dict[str, Path]:
    """Module name relative to the package (``kalman.filter``, ``cli``; a folder's ``__init__`` is
    the folder's name) -> its file, for every ``.py`` file under ``package``, recursively."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1] or ("__init__",)
        out[".".join(parts)] = path
    return out


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes inside ``if TYPE_CHECKING:`` blocks."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return skip


def _targets(node: ast.Import | ast.ImportFrom, module: str, is_package: bool, package: str) -> list[str]:
    """The candidate module names (relative to the package) an import statement may load."""
    if isinstance(node, ast.Import):
        return [a.name[len(package) + 1:] for a in node.names if a.name.startswith(package + ".")]
    if node.level:
        here = module.split(".") if is_package else module.split(".")[:-1]
        if module == "__init__":
            here = []
        base = here[: len(here) - (node.level - 1)]
    elif (node.module or "").split(".")[0] == package:
        base = []
    else:
        return []
    mod = (node.module or "").split(".")
    if not node.level:
        mod = mod[1:]
    stem = [*base, *[m for m in mod if m]]
    return [".".join(stem)] + [".".join([*stem, a.name]) for a in node.names]


def package_imports(package: Path) -> dict[str, set[str]]:
    """Module -> the package's modules it imports, anywhere in its source (folders' ``__init__``
    count as modules: importing ``danae_lite.kalman`` runs ``kalman/__init__.py``)."""
    found = modules(package)
    graph: dict[str, set[str]] = {}
    for name, path in found.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        skip = _type_checking_nodes(tree)
        deps: set[str] = set()
        for node in ast.walk(tree):
            if id(node) in skip or not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            deps.update(_targets(node, name, path.name == "__init__.py", package.name))
        graph[name] = {d for d in deps if d in found and d != name}
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles: strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Imports of a room listed later in :data:`ROOMS`, e.g. ``kalman.filter -> research.leaderboard``."""
    return [f"{m} -> {d}" for m, deps in sorted(graph.items()) for d in sorted(deps) if layer(d) > layer(m)]


def _is_environ(node: ast.AST) -> bool:
    text = ast.unparse(node)
    return text in ("os.environ", "environ")


def env_reads(package: Path) -> list[str]:
    """``module:line`` of every read of a ``DANAE_*`` variable (by literal name or by a ``*_ENV``
    constant) through ``os.environ[...]``, ``os.environ.get(...)`` or ``os.getenv(...)``."""
    out = []
    for name, path in modules(package).items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            key = None
            if isinstance(node, ast.Subscript) and _is_environ(node.value):
                key = node.slice
            elif isinstance(node, ast.Call) and node.args:
                f = node.func
                if (isinstance(f, ast.Attribute) and f.attr in ("get", "pop", "setdefault") and _is_environ(f.value)) \
                        or ast.unparse(f) in ("os.getenv", "getenv"):
                    key = node.args[0]
            if key is None:
                continue
            literal = isinstance(key, ast.Constant) and str(key.value).startswith("DANAE_")
            constant = ast.unparse(key).split(".")[-1].endswith("_ENV")
            if literal or constant:
                out.append(f"{name}:{node.lineno}")
    return out


def test_no_import_circles():
    assert circles(package_imports(PACKAGE)) == []


def test_imports_point_down_the_package_map():
    assert upward_imports(package_imports(PACKAGE)) == []


def test_only_the_settings_module_reads_the_environment():
    assert [r for r in env_reads(PACKAGE) if not r.startswith(f"{SETTINGS}:")] == []


def test_every_module_is_in_the_package_map():
    """``danae_lite/__init__.py`` names every module by its full name (the map a newcomer reads
    first) and holds nothing but the map and the version: no names re-exported."""
    text = (PACKAGE / "__init__.py").read_text(encoding="utf-8")
    missing = [name for name, path in modules(PACKAGE).items()
               if path.name != "__init__.py" and not name.split(".")[-1].startswith("_")
               and f"danae_lite.{name}`" not in text]
    assert missing == []
    code = [ast.unparse(n) for n in ast.parse(text).body[1:]]
    assert code == ["from ._version import __version__"]


def test_rooms_are_the_map():
    """Every module sits in a room of :data:`ROOMS`, and the rooms appear in the package map in
    that order; no room is deeper than one sub-folder."""
    names = modules(PACKAGE)
    assert {n.split(".")[0] for n in names} <= set(ROOMS)
    assert all(len(n.split(".")) <= 3 for n in names)
    text = (PACKAGE / "__init__.py").read_text(encoding="utf-8")
    first = {r: m.start() for r in ROOMS for m in [re.search(rf"danae_lite\.{r}[`.]", text)] if m}
    assert sorted(first, key=first.get) == [r for r in ROOMS if r in first]


TORCH_FREE_CHAPTERS = ("01_kalman_filter", "02_sensors_to_estimates")
"""The chapters that run without torch (the Kalman filter and its estimates)."""


def chapter_imports(stem: str) -> list[str]:
    """The import statements of a chapter's code cells (at any depth of a cell), as source lines."""
    tree = ast.parse(chapter_sources()[stem][0])
    return [ast.unparse(n) for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]


def loaded_after(statements: list[str]) -> set[str]:
    """The top-level names in ``sys.modules`` of a fresh interpreter after running ``statements``."""
    probe = "\n".join([*statements, "import sys", "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))"])
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                         cwd=PACKAGE.parent, env={**os.environ, "DANAE_CACHE": "off"})
    return set(run.stdout.split())


@pytest.mark.parametrize("stem", TORCH_FREE_CHAPTERS)
def test_the_kf_chapters_and_setup_load_no_torch(stem: str):
    """Everything chapters 1-2 import, and the common ``setup()``, runs without loading torch."""
    statements = [*chapter_imports(stem), "from danae_lite.book import setup", "setup(verbose=False)"]
    assert any("danae_lite.kalman" in s for s in statements)
    loaded = loaded_after(statements)
    assert "danae_lite" in loaded and "torch" not in loaded


def test_the_torch_probe_sees_torch_when_it_is_loaded():
    """The probe is not vacuous: a chapter that trains loads torch through the same route."""
    assert "torch" in loaded_after(["from danae_lite.danae.train import train"])


@pytest.fixture
def toy_package(tmp_path: Path) -> Path:
    pkg = tmp_path / "danae_lite"
    for folder in (pkg, pkg / "kalman", pkg / "research"):
        folder.mkdir()
        (folder / "__init__.py").write_text("")
    (pkg / "kalman" / "filter.py").write_text("def f():\n    from ..research.leaderboard import g\n")  # kalman -> research, late
    (pkg / "research" / "leaderboard.py").write_text("from .. import cli\n")  # research -> entry
    (pkg / "cli.py").write_text("from danae_lite.kalman.filter import f\n")
    (pkg / "kalman" / "windows.py").write_text(
        "import os\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..cli import x\n"
        "a = os.environ.get('DANAE_FAST')\nb = os.environ[DATA_ENV]\nc = os.getenv('HOME')\n")
    (pkg / "kalman" / "angles.py").write_text("from . import windows\nfrom .windows import a\n")  # same layer
    return pkg


def test_the_checks_find_what_they_look_for(toy_package: Path):
    """The checks are not vacuous: on a toy package they find a circle made by an import inside a
    function, the upward imports (the layer read from the folder), and the two environment reads
    (not HOME, not TYPE_CHECKING); an import within a layer is neither."""
    graph = package_imports(toy_package)
    assert graph["kalman.windows"] == set()  # the TYPE_CHECKING import does not count
    assert graph["kalman.angles"] == {"kalman", "kalman.windows"}
    assert circles(graph) == [["cli", "kalman.filter", "research.leaderboard"]]
    assert upward_imports(graph) == ["kalman.filter -> research.leaderboard", "research.leaderboard -> cli"]
    assert env_reads(toy_package) == ["kalman.windows:5", "kalman.windows:6"]


def _top_level_names(tree: ast.Module) -> tuple[set[str], set[str]]:
    """(names a module defines, names it only imports) at its top level (inside top-level
    ``if``/``try`` blocks too)."""
    defined: set[str] = set()
    imported: set[str] = set()
    todo = list(tree.body)
    while todo:
        node = todo.pop()
        if isinstance(node, (ast.If, ast.Try)):
            if not (isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)):
                todo += [*node.body, *node.orelse, *getattr(node, "finalbody", []),
                         *[s for h in getattr(node, "handlers", []) for s in h.body]]
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
            defined.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            defined.update(n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            imported.update((a.asname or a.name).split(".")[0] for a in node.names)
    return defined, imported - defined


def borrowed_names(sources: dict[str, tuple[str, bool]], package: Path) -> list[str]:
    """``where: module.name`` for every import or ``module.name`` read, in ``sources`` (name ->
    (source, is_package)), of a private name of another module of the package or of a name that
    module only re-exports (imports, not defines)."""
    found = modules(package)
    tops = {name: _top_level_names(ast.parse(path.read_text(encoding="utf-8"))) for name, path in found.items()}
    problems = []
    for where, (source, is_pkg) in sources.items():
        tree = ast.parse(source)
        module_aliases: dict[str, str] = {}
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom):
                continue
            targets = _targets(node, where, is_pkg, package.name)
            if not targets or targets[0] not in found:
                continue
            origin = targets[0]
            for alias in node.names:
                sub = f"{origin}.{alias.name}" if origin != "__init__" else alias.name
                if sub in found:
                    module_aliases[alias.asname or alias.name] = sub
                    continue
                defined, only_imported = tops[origin]
                private = alias.name.startswith("_") and not alias.name.startswith("__")
                if private or alias.name in only_imported:
                    problems.append(f"{where}: {origin}.{alias.name}")
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                    and node.value.id in module_aliases:
                origin = module_aliases[node.value.id]
                private = node.attr.startswith("_") and not node.attr.startswith("__")
                if private or node.attr in tops[origin][1]:
                    problems.append(f"{where}: {origin}.{node.attr}")
    return sorted(set(problems))


def chapter_sources() -> dict[str, tuple[str, bool]]:
    """Each chapter's code cells joined into one source (a module imported in one cell is used in
    the next), as the check reads them."""
    out = {}
    for nb in sorted((PACKAGE.parent / "notebooks").glob("[0-9][0-9]_*.ipynb")):
        cells = []
        for cell in json.loads(nb.read_text(encoding="utf-8"))["cells"]:
            if cell["cell_type"] == "code":
                src = "".join(cell["source"])
                try:
                    ast.parse(src)
                except SyntaxError:  # IPython's %magic and !shell lines
                    src = "\n".join(l for l in src.splitlines() if not l.lstrip().startswith(("%", "!")))
                cells.append(src)
        out[nb.stem] = ("\n".join(cells), False)
    return out


def test_no_private_or_re_exported_name_is_used_across_modules():
    """A module and a chapter import each name from the module that defines it, and never a
    private name (``_x``) of another module: no re-export facades, no private crossings."""
    sources = {name: (path.read_text(encoding="utf-8"), path.name == "__init__.py")
               for name, path in modules(PACKAGE).items()}
    assert borrowed_names({**sources, **chapter_sources()}, PACKAGE) == []


def test_the_borrowed_name_check_finds_what_it_looks_for(toy_package: Path):
    (toy_package / "kalman" / "model.py").write_text("import math\nK = 1\ndef _hidden():\n    pass\n")
    (toy_package / "kalman" / "filter.py").write_text("from .model import K, _hidden\nfrom . import model\n"
                                                      "x = model._hidden\ny = model.math\n")
    (toy_package / "cli.py").write_text("from danae_lite.kalman.filter import K\nfrom danae_lite.kalman.model import K\n")
    sources = {name: (path.read_text(), path.name == "__init__.py") for name, path in modules(toy_package).items()}
    assert borrowed_names(sources, toy_package) == ["cli: kalman.filter.K", "kalman.filter: kalman.model._hidden",
                                                    "kalman.filter: kalman.model.math"]
