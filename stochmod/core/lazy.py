"""Lazy public names of a package (PEP 562; Scientific Python's SPEC 1).

A package lists its public names once, by module, and imports a module only when one of its
names is first used: ``import stochmod`` and ``import stochmod.empirical`` stay cheap (no
scipy.signal, scipy.stats, networkx or numba until a name that needs them is used).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_names"]


def lazy_names(package: str, table: Mapping[str, tuple[str, ...]]
               ) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """``__all__``, ``__getattr__`` and ``__dir__`` of `package` from `table`.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    table : mapping of str to tuple of str
        Module (absolute name) -> the public names it defines, in the order of ``__all__``.

    Returns
    -------
    names : list of str
        The public names, in the table's order.
    getattr_ : callable
        The package's ``__getattr__``: imports the module of a public name on first access
        and caches the value in the package's namespace.
    dir_ : callable
        The package's ``__dir__``.
    """
    where = {name: module for module, names in table.items() for name in names}
    names = list(where)
    namespace = importlib.import_module(package).__dict__

    def getattr_(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value  # later look-ups are plain attribute reads
        return value

    def dir_() -> list[str]:
        return sorted(set(names) | {k for k in namespace if not k.startswith("_")})

    return names, getattr_, dir_
