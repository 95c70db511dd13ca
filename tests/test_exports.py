"""A package's exported names never shadow, nor are shadowed by, its own submodules."""

from __future__ import annotations

import importlib
import pkgutil

import pytest

from masspush._exports import lazy

PACKAGES = ["masspush.sim", "masspush.data", "masspush.learn", "masspush.bayes",
            "masspush.real", "masspush.reports"]  # fmt: skip


@pytest.mark.parametrize("name", PACKAGES)
def test_no_exported_name_is_also_a_submodule(name: str):
    # After `import pkg.x`, Python binds the module on the package as `x`; an exported
    # function `x` would then be unreachable as `from pkg import x` (it gives the module).
    package = importlib.import_module(name)
    submodules = {info.name for info in pkgutil.iter_modules(package.__path__)}
    assert not submodules & set(package.__all__)


@pytest.mark.parametrize("name", PACKAGES)
def test_every_exported_name_resolves_to_its_object_after_its_module_is_imported(name: str):
    package = importlib.import_module(name)
    for module, exported in package.EXPORTS.items():
        loaded = importlib.import_module(f"{name}.{module}")
        for export in exported:
            assert getattr(package, export) is getattr(loaded, export), f"{name}.{export}"


def test_an_unknown_name_is_an_attribute_error_naming_it():
    getattr_ = lazy("masspush.sim", {"chain": ("ChainParams",)})
    assert getattr_("ChainParams").__name__ == "ChainParams"
    with pytest.raises(AttributeError, match=r"'masspush\.sim' has no attribute 'nope'"):
        getattr_("nope")
