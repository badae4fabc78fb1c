"""The package's shape: imports run one way (entry points -> research engine -> core), no import
circles, and only the settings module reads the ``DANAE_*`` variables.

Imports are read from the source with :mod:`ast`, including those made inside functions (they
run too, only later). Imports under ``if TYPE_CHECKING:`` are left out: they never run.

Layers (a module not listed is core):

* **entry points**: settings (:mod:`danae_lite.config`), chapter setup and execution
  (:mod:`danae_lite.book`), re-execution (:mod:`danae_lite.execute`), the command line (:mod:`danae_lite.cli`, :mod:`danae_lite.cli_data`, ``__main__``);
* **research engine** (chapters 5 onward): the method protocol and registry, the classical and
  learned methods, the library filters, the BROAD metric and its reference filters, the
  leaderboard, folds, the denoiser, streaming;
* **core** (what chapters 1-4 need): everything else.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "danae_lite"
SETTINGS = "config"
ENTRY = {"config", "book", "execute", "cli", "cli_data", "__main__"}
RESEARCH = {"baselines", "kf_grid", "kf_offline", "methods", "registry", "features", "variants", "leaderboard", "crossval", "denoiser",
            "streaming", "filters", "broad_benchmark"}


def layer(module: str) -> int:
    """0 core, 1 research engine, 2 entry points."""
    return 2 if module in ENTRY else 1 if module in RESEARCH else 0


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes inside ``if TYPE_CHECKING:`` blocks."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return skip


def package_imports(package: Path) -> dict[str, set[str]]:
    """Module (file stem) -> the package's modules it imports, anywhere in its source."""
    modules = {p.stem for p in package.glob("*.py")}
    graph: dict[str, set[str]] = {}
    for path in sorted(package.glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        skip = _type_checking_nodes(tree)
        deps: set[str] = set()
        for node in ast.walk(tree):
            if id(node) in skip or not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                deps.update([node.module.split(".")[0]] if node.module else [a.name for a in node.names])
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith(package.name):
                rest = node.module.split(".")[1:]
                deps.update(rest[:1] if rest else [a.name for a in node.names])
            elif isinstance(node, ast.Import):
                deps.update(a.name.split(".")[1] for a in node.names if a.name.startswith(package.name + "."))
        graph[path.stem] = {d for d in deps if d in modules and d != path.stem}
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
    """Imports from a lower layer into a higher one, e.g. ``core kalman -> research filters``."""
    names = ("core", "research", "entry")
    return [f"{names[layer(m)]} {m} -> {names[layer(d)]} {d}"
            for m, deps in sorted(graph.items()) for d in sorted(deps) if layer(d) > layer(m)]


def _is_environ(node: ast.AST) -> bool:
    text = ast.unparse(node)
    return text in ("os.environ", "environ")


def env_reads(package: Path) -> list[str]:
    """``module:line`` of every read of a ``DANAE_*`` variable (by literal name or by a ``*_ENV``
    constant) through ``os.environ[...]``, ``os.environ.get(...)`` or ``os.getenv(...)``."""
    out = []
    for path in sorted(package.glob("*.py")):
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
                out.append(f"{path.stem}:{node.lineno}")
    return out


def test_no_import_circles():
    assert circles(package_imports(PACKAGE)) == []


def test_imports_run_one_way_entry_research_core():
    assert upward_imports(package_imports(PACKAGE)) == []


def test_only_the_settings_module_reads_the_environment():
    assert [r for r in env_reads(PACKAGE) if not r.startswith(f"{SETTINGS}:")] == []


def test_every_module_is_in_the_package_map():
    """``danae_lite/__init__.py`` names every module (the map a newcomer reads first)."""
    text = (PACKAGE / "__init__.py").read_text(encoding="utf-8")
    missing = [p.stem for p in PACKAGE.glob("*.py")
               if not p.stem.startswith("_") and f"danae_lite.{p.stem}`" not in text]
    assert missing == []


@pytest.fixture
def toy_package(tmp_path: Path) -> Path:
    pkg = tmp_path / "danae_lite"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "kalman.py").write_text("def f():\n    from .leaderboard import g\n")  # core -> research, late
    (pkg / "leaderboard.py").write_text("from . import cli\n")  # research -> entry
    (pkg / "cli.py").write_text("from danae_lite.kalman import f\n")
    (pkg / "windows.py").write_text(
        "import os\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .cli import x\n"
        "a = os.environ.get('DANAE_FAST')\nb = os.environ[DATA_ENV]\nc = os.getenv('HOME')\n")
    return pkg


def test_the_checks_find_what_they_look_for(toy_package: Path):
    """The checks are not vacuous: on a toy package they find a circle made by an import inside a
    function, the upward imports, and the two environment reads (not HOME, not TYPE_CHECKING)."""
    graph = package_imports(toy_package)
    assert graph["windows"] == set()  # the TYPE_CHECKING import does not count
    assert circles(graph) == [["cli", "kalman", "leaderboard"]]
    assert upward_imports(graph) == ["core kalman -> research leaderboard", "research leaderboard -> entry cli"]
    assert env_reads(toy_package) == ["windows:5", "windows:6"]
