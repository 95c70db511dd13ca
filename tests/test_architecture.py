"""The package's layering: no import cycles (function-level imports included), and no
layer reaching up into one above it (docs/architecture.md)."""

from __future__ import annotations

import ast
import importlib
import pkgutil
from pathlib import Path

import pytest

import masspush

SRC = Path(masspush.__file__).parent
REPO = SRC.parents[1]

# The layers, lowest first (docs/architecture.md): a module may import its own layer's and
# lower layers' modules, never a higher layer's; `learn` and `bayes` share a layer but not
# each other's code.
LAYERS = [
    ("masspush.config", "masspush.metrics", "masspush._exports", "masspush._compat"),
    ("masspush.cluster",),
    ("masspush.sim",),
    ("masspush.settings", "masspush.env"),
    ("masspush.data",),
    ("masspush.evaluate",),
    ("masspush.learn", "masspush.bayes"),
    ("masspush.models",),
    ("masspush.real",),
    ("masspush.reports",),
    ("masspush.cli",),
]
APART = [("masspush.learn", "masspush.bayes")]
NO_TORCH = ("masspush.config", "masspush.metrics", "masspush.sim", "masspush.settings",
            "masspush.env", "masspush.data", "masspush.evaluate", "masspush.bayes")  # fmt: skip


def layer_of(module: str) -> tuple[int, str] | None:
    for i, names in enumerate(LAYERS):
        for name in names:
            if module == name or module.startswith(name + "."):
                return i, name
    return None


def module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path) -> set[str]:
    """Every module that `path` imports, at any depth of its code."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(
                    package.split(".")[: len(package.split(".")) - node.level + 1]
                    + ([base] if base else [])
                )
            found.add(base)
            # `from masspush.sim import chain` imports the module masspush.sim.chain.
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return found


MODULES = {module_name(p): p for p in SRC.rglob("*.py")}
GRAPH = {m: {i for i in imports_of(p) if i in MODULES and i != m} for m, p in MODULES.items()}


def test_no_import_cycles():
    # Tarjan's strongly connected components; any component of two or more is a cycle.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in GRAPH[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(GRAPH):
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_a_package_does_not_import_itself_through_its_init():
    # A module importing its own package's __init__ (which imports the module back) is a
    # cycle the graph above sees as an edge to the package; it is caught there. Here: every
    # subpackage has an __init__, so the layout is importable without namespace packages.
    for path in SRC.rglob("*.py"):
        assert (path.parent / "__init__.py").exists(), path


@pytest.mark.parametrize("layer", [name for names in LAYERS for name in names])
def test_lower_layers_never_reach_up(layer: str):
    own, own_name = layer_of(layer)
    broken = []
    for name, path in MODULES.items():
        if layer_of(name) != (own, own_name):
            continue
        for imported in imports_of(path):
            root = imported.split(".")[0]
            if root in ("torch", "stable_baselines3", "sb3_contrib") and layer in NO_TORCH:
                broken.append(f"{name} imports {imported}")
            where = layer_of(imported) if root == "masspush" else None
            if where is None:
                continue
            if where[0] > own or (own_name, where[1]) in APART or (where[1], own_name) in APART:
                broken.append(f"{name} imports {imported}")
    assert not broken, "\n".join(broken)


def test_every_module_imports():
    for info in pkgutil.walk_packages(masspush.__path__, "masspush."):
        if not info.name.endswith("__main__"):  # that one runs the CLI
            importlib.import_module(info.name)
