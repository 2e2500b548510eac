"""Packages whose public names are imported on first use (PEP 562), as ``gevsim`` itself does.

A package's ``__init__`` that imported every submodule made ``gevsim scenes`` import numba, h5py and
colour-science to read a few TOML files (issue 37, item 5). A package built with :func:`attach`
imports a submodule when one of its names is first read; ``from package import name`` and
``package.submodule`` work as before. The package keeps the eager imports under ``if TYPE_CHECKING:``
for mypy and editors (``tests/test_startup.py`` checks that they and the names given here agree).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable
from typing import Any


def attach(package: str, names: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package``: ``names`` maps each public name to the submodule that
    defines it (``"basis"``), or to ``"submodule:attribute"`` where the name differs there."""

    def __getattr__(name: str) -> Any:
        where = names.get(name)
        if where is None:
            if not name.startswith("__") and importlib.util.find_spec(f"{package}.{name}") is not None:
                return importlib.import_module(f"{package}.{name}")  # a submodule nobody imported yet
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, attribute = where.partition(":")
        value = getattr(importlib.import_module(f"{package}.{module}"), attribute or name)
        setattr(sys.modules[package], name, value)  # from now on an ordinary attribute
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__
