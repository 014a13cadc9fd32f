"""A subpackage's public names, each imported from its module on first use (PEP 562).

A subpackage's `__init__` names its surface without importing its modules, so that importing
one module of it (`objects.mesh`) does not load the others and their dependencies:

    __all__, __getattr__, __dir__ = lazy_exports(__name__, {"dataset": ("load_manifest",)})

No name may be that of a module of the subpackage: importing the module would replace it
(the command `collect` is `experiments.collect.collect`, and `drake_continuum.collect`).
"""

from __future__ import annotations

import importlib
import sys

__all__ = ["lazy_exports"]


def lazy_exports(package: str, modules: dict[str, tuple[str, ...]]):
    """(__all__, __getattr__, __dir__) of `package` re-exporting each module's names
    ({module relative to the package: names})."""
    where = {name: module for module, names in modules.items() for name in names}

    def __getattr__(name: str):
        module = where.get(name)
        if module is None:  # an AttributeError lets `from package import module` import it
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{module}", package), name)
        setattr(sys.modules[package], name, value)  # found directly from now on
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(where))

    return list(where), __getattr__, __dir__
