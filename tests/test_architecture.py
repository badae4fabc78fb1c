"""The package's shape: imports run one way (entry points -> research engine -> core), no import
circles, every module in the package map, and only the settings module reads the ``DANAE_*``
variables.

Imports are read from the source with :mod:`ast`, including those made inside functions (they
run too, only later). Imports under ``if TYPE_CHECKING:`` are left out: they never run.

A module's layer is its folder, so a new file cannot sit in the wrong layer by accident:

* ``danae_lite/core/``: what chapters 1-4 need (layer 0);
* ``danae_lite/research/``: the research engine of chapters 5 onward (layer 1);
* ``danae_lite/`` itself: the entry points, settings (:mod:`danae_lite.config`), chapter setup
  (:mod:`danae_lite.book`) and the command line (:mod:`danae_lite.cli`, ``__main__``) (layer 2).

Book maintenance (re-execution, the pages' generated blocks) is not in the package: ``tools/``.
The Kalman-filter chapters (1-2) and the chapters' common ``setup()`` load no torch.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "danae_lite"
SETTINGS = "config"
LAYERS = ("core", "research")
"""The layer folders, lowest first; modules directly in the package are the entry points."""


def layer(module: str) -> int:
    """0 core, 1 research engine, 2 entry points, from the module's folder (``core.kalman`` -> 0)."""
    folder = module.split(".")[0]
    return LAYERS.index(folder) if folder in LAYERS else 2


def modules(package: Path) -> dict[str, Path]:
    """Module name relative to the package (``core.kalman``, ``cli``; a folder's ``__init__`` is
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
    count as modules: importing ``danae_lite.core`` runs ``core/__init__.py``)."""
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
    """Imports from a lower layer into a higher one, e.g. ``core kalman -> research filters``."""
    names = (*LAYERS, "entry")
    return [f"{names[layer(m)]} {m} -> {names[layer(d)]} {d}"
            for m, deps in sorted(graph.items()) for d in sorted(deps) if layer(d) > layer(m)]


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


def test_imports_run_one_way_entry_research_core():
    assert upward_imports(package_imports(PACKAGE)) == []


def test_only_the_settings_module_reads_the_environment():
    assert [r for r in env_reads(PACKAGE) if not r.startswith(f"{SETTINGS}:")] == []


def test_every_module_is_in_the_package_map():
    """``danae_lite/__init__.py`` names every module by its full name, under its layer's heading
    (the map a newcomer reads first)."""
    text = (PACKAGE / "__init__.py").read_text(encoding="utf-8")
    sections = {"core": text.index("**Core**"), "research": text.index("**Research engine**"),
                "": text.index("**Entry points**")}
    bounds = sorted(sections.values()) + [len(text)]
    misplaced = []
    for name in modules(PACKAGE):
        if name.split(".")[-1].startswith("_") or name in LAYERS:
            continue
        start = sections[name.split(".")[0] if "." in name else ""]
        part = text[start:bounds[bounds.index(start) + 1]]
        if f"danae_lite.{name}`" not in part:
            misplaced.append(name)
    assert misplaced == []


def test_layers_are_the_folders():
    """Every module sits in a layer folder or is one of the few entry points; the layer folders
    hold nothing else (no deeper folders to hide a module in)."""
    entry = {n for n in modules(PACKAGE) if "." not in n}
    assert entry == {"__init__", "__main__", "book", "cli", "cli_data", "config", *LAYERS}
    assert all(len(n.split(".")) <= 2 for n in modules(PACKAGE))
    assert {n.split(".")[0] for n in modules(PACKAGE) if "." in n} == set(LAYERS)


TORCH_FREE_CHAPTERS = ("01_kalman_filter", "02_sensors_to_estimates")
"""The chapters that run without torch (the Kalman filter and its estimates)."""


def chapter_imports(stem: str) -> list[str]:
    """The import statements of a chapter's code cells (at any depth of a cell), as source lines."""
    import json

    nb = json.loads((PACKAGE.parent / "notebooks" / f"{stem}.ipynb").read_text(encoding="utf-8"))
    lines = []
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            source = "".join(cell["source"])
            tree = ast.parse("\n".join(l for l in source.splitlines() if not l.lstrip().startswith(("%", "!"))))
            lines += [ast.unparse(n) for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]
    return lines


def loaded_after(statements: list[str]) -> set[str]:
    """The top-level names in ``sys.modules`` of a fresh interpreter after running ``statements``."""
    import subprocess
    import sys

    probe = "\n".join([*statements, "import sys", "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))"])
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                         cwd=PACKAGE.parent, env={**__import__("os").environ, "DANAE_CACHE": "off"})
    return set(run.stdout.split())


@pytest.mark.parametrize("stem", TORCH_FREE_CHAPTERS)
def test_the_kf_chapters_and_setup_load_no_torch(stem: str):
    """Everything chapters 1-2 import, and the common ``setup()``, runs without loading torch."""
    statements = [*chapter_imports(stem), "from danae_lite.book import setup", "setup(verbose=False)"]
    assert any("danae_lite.core" in s for s in statements)
    loaded = loaded_after(statements)
    assert "danae_lite" in loaded and "torch" not in loaded


def test_the_torch_probe_sees_torch_when_it_is_loaded():
    """The probe is not vacuous: a chapter that trains loads torch through the same route."""
    assert "torch" in loaded_after(["from danae_lite.core.train import TrainConfig"])


@pytest.fixture
def toy_package(tmp_path: Path) -> Path:
    pkg = tmp_path / "danae_lite"
    for folder in (pkg, pkg / "core", pkg / "research"):
        folder.mkdir()
        (folder / "__init__.py").write_text("")
    (pkg / "core" / "kalman.py").write_text("def f():\n    from ..research.leaderboard import g\n")  # core -> research, late
    (pkg / "research" / "leaderboard.py").write_text("from .. import cli\n")  # research -> entry
    (pkg / "cli.py").write_text("from danae_lite.core.kalman import f\n")
    (pkg / "core" / "windows.py").write_text(
        "import os\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..cli import x\n"
        "a = os.environ.get('DANAE_FAST')\nb = os.environ[DATA_ENV]\nc = os.getenv('HOME')\n")
    (pkg / "core" / "angles.py").write_text("from . import windows\nfrom .windows import a\n")  # same layer
    return pkg


def test_the_checks_find_what_they_look_for(toy_package: Path):
    """The checks are not vacuous: on a toy package they find a circle made by an import inside a
    function, the upward imports (the layer read from the folder), and the two environment reads
    (not HOME, not TYPE_CHECKING); an import within a layer is neither."""
    graph = package_imports(toy_package)
    assert graph["core.windows"] == set()  # the TYPE_CHECKING import does not count
    assert graph["core.angles"] == {"core", "core.windows"}
    assert circles(graph) == [["cli", "core.kalman", "research.leaderboard"]]
    assert upward_imports(graph) == ["core core.kalman -> research research.leaderboard",
                                     "research research.leaderboard -> entry cli"]
    assert env_reads(toy_package) == ["core.windows:5", "core.windows:6"]
