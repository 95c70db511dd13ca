"""Lazy re-exports: a package names its public API in `__all__` and imports each name's
module only when the name is first used, so that importing one module of a package does not
import all of them (and their heavy dependencies)."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy(package: str, exports: Mapping[str, tuple[str, ...]]) -> Callable[[str], Any]:
    """A module `__getattr__` for `package`: {module (relative to it): names it exports}."""
    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str) -> Any:
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{where[name]}"), name)

    return __getattr__


def names(exports: Mapping[str, tuple[str, ...]]) -> list[str]:
    return sorted(name for group in exports.values() for name in group)
