"""The public names of a package, imported from their modules on first use (PEP 562).

Every package of robot_ctrl exports its public names this way, so that importing one module (the
command line, a child process) does not import its siblings, MuJoCo or Pinocchio with them::

    __all__, __getattr__, __dir__ = lazy_exports(__name__, {"adapter": ["HardwareAdapter"], ...})
"""

from __future__ import annotations

import importlib
import sys
from typing import Callable


def lazy_exports(package: str, modules: dict[str, list[str]]) -> tuple[list[str], Callable, Callable]:
    """``(__all__, __getattr__, __dir__)`` of ``package``, each of whose public names is defined in
    the module ``modules`` lists it under (a module path relative to the package)."""
    where = {name: f"{package}.{module}" for module, names in modules.items() for name in names}

    def __getattr__(name: str):
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(where[name]), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(where))

    return sorted(where), __getattr__, __dir__
