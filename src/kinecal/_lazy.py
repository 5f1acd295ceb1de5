"""Lazy package exports: a package names its public entry points without importing them.

A package ``__init__`` that imported its modules eagerly would load the whole package (and
its dependencies) whenever any one module of it is imported, slowing the command line and
tying modules together. `lazy_exports` gives the package a module-level ``__getattr__``
(PEP 562) that imports the defining module on first use.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(package: str, names: dict[str, str]
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for `package` exporting ``{name: defining module}``.

    Parameters
    ----------
    package : str
        The package's ``__name__`` (for the error message).
    names : dict
        Public name -> dotted name of the module that defines it.
    """

    def __getattr__(name: str) -> Any:
        if name in names:
            return getattr(importlib.import_module(names[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(names)

    return __getattr__, __dir__
