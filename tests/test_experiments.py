"""experiments/ imports only masspush's public API, and every experiment imports: a refactor
of the package cannot break one silently."""

from __future__ import annotations

import ast
import importlib
import importlib.util
from pathlib import Path

import pytest

EXPERIMENTS = sorted((Path(__file__).parents[1] / "experiments").rglob("*.py"))
PUBLIC_MODULES = {"masspush", "masspush.config", "masspush.settings", "masspush.metrics",
                  "masspush.env", "masspush.evaluate", "masspush.models"}  # fmt: skip
PUBLIC_PACKAGES = {"masspush.sim", "masspush.data", "masspush.learn", "masspush.bayes",
                   "masspush.real", "masspush.reports"}  # fmt: skip


def test_there_are_experiments():
    assert len(EXPERIMENTS) >= 10


@pytest.mark.parametrize("path", EXPERIMENTS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_an_experiment_imports_only_the_public_api(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("masspush"):
            module = node.module
            if module in PUBLIC_PACKAGES:
                public = set(importlib.import_module(module).__all__)
                private = [a.name for a in node.names if a.name not in public]
                assert not private, f"{path.name}: {module} does not export {private}"
            else:
                assert module in PUBLIC_MODULES, f"{path.name} reaches into {module}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("masspush"):
                    assert alias.name in PUBLIC_MODULES | PUBLIC_PACKAGES, alias.name


@pytest.mark.parametrize("path", EXPERIMENTS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_an_experiment_imports(path: Path):
    spec = importlib.util.spec_from_file_location(f"experiment_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # each runs only under __main__
    assert callable(getattr(module, "main", None)), f"{path.name} has no main()"
