"""The plugin registry: one pluggy manager, entry-point discovery, lookup of families by name.

Plugins installed with an entry point in the ``stochmod`` group are loaded on first use.
Third parties may also register a plugin object at run time with :func:`register_plugin`.
"""

from __future__ import annotations

import importlib
import threading
from typing import TYPE_CHECKING, Any

import pluggy

from stochmod.errors import InputError, StochmodError, UnknownProcessError
from stochmod.hookspecs import PROJECT_NAME, StochmodSpec

if TYPE_CHECKING:
    from stochmod.process import Process

__all__ = [
    "plugin_manager",
    "register_plugin",
    "unregister_plugin",
    "process_names",
    "get_process",
    "processes",
    "criteria",
    "combiners",
    "combiner_names",
    "get_combiner",
]

_lock = threading.RLock()
_manager: pluggy.PluginManager | None = None
#: The core's own hook implementations (the WVIC criterion), registered with the entry points.
_BUILTIN_PLUGINS = ("stochmod.fit.criteria",)


def plugin_manager() -> pluggy.PluginManager:
    """Return the process-wide plugin manager, loading entry-point plugins the first time.

    Loading happens at first use, never while a module is being imported, so that a plugin
    module imported before stochmod (``import stochmod_ar`` first) is registered complete.
    """
    global _manager
    with _lock:
        if _manager is None:
            pm = pluggy.PluginManager(PROJECT_NAME)
            pm.add_hookspecs(StochmodSpec)
            pm.load_setuptools_entrypoints(PROJECT_NAME)
            for name in _BUILTIN_PLUGINS:
                pm.register(importlib.import_module(name), name=name)
            _manager = pm
        return _manager


def register_plugin(plugin: object, name: str | None = None) -> None:
    """Register a plugin object (module or instance with hook implementations) at run time."""
    pm = plugin_manager()
    pm.register(plugin, name=name)
    try:
        processes()  # validate names now, not at first use
    except StochmodError:
        pm.unregister(plugin)
        raise


def unregister_plugin(plugin: object) -> None:
    """Remove a plugin registered with :func:`register_plugin`."""
    plugin_manager().unregister(plugin)


def processes() -> dict[str, type[Process]]:
    """Return every registered process family, keyed by its ``family`` name."""
    from stochmod.process import Process

    found: dict[str, type[Process]] = {}
    for batch in plugin_manager().hook.stochmod_processes():
        for cls in batch:
            if not (isinstance(cls, type) and issubclass(cls, Process)):
                raise StochmodError(f"plugin returned {cls!r}, which is not a Process subclass")
            name = cls.family
            if name in found and found[name] is not cls:
                raise StochmodError(
                    f"two plugins register a process family named {name!r}: "
                    f"{found[name].__module__} and {cls.__module__}"
                )
            found[name] = cls
    return dict(sorted(found.items()))


def process_names() -> list[str]:
    """Return the names of the registered process families, sorted."""
    return list(processes())


def get_process(name: str) -> type[Process]:
    """Return the process family registered under `name` (case-sensitive, e.g. ``"GM"``)."""
    table = processes()
    try:
        return table[name]
    except KeyError:
        raise UnknownProcessError(
            f"unknown process family {name!r}; registered families: {', '.join(table) or 'none'}"
        ) from None


def criteria() -> dict[str, Any]:
    """Return the registered model-selection criteria keyed by name."""
    return {c.name: c for batch in plugin_manager().hook.stochmod_criteria() for c in batch}


def combiners() -> dict[str, Any]:
    """Return every registered redundant-sensor combiner, keyed by its ``name``, sorted.

    Raises
    ------
    StochmodError
        A plugin returned an object without ``name``, ``assumes`` and a callable ``combine``, or
        two plugins register the same name.
    """
    found: dict[str, Any] = {}
    for batch in plugin_manager().hook.stochmod_combiners():
        for comb in batch:
            name = getattr(comb, "name", None)
            if not (isinstance(name, str) and name and isinstance(getattr(comb, "assumes", None), str)
                    and callable(getattr(comb, "combine", None))):
                raise StochmodError(
                    f"plugin returned {comb!r}, which is not a combiner (it needs a str `name`, "
                    "a str `assumes` and a `combine(x, **options)` method)"
                )
            if name in found and found[name] is not comb:
                raise StochmodError(
                    f"two plugins register a combiner named {name!r}: "
                    f"{type(found[name]).__module__} and {type(comb).__module__}"
                )
            found[name] = comb
    return dict(sorted(found.items()))


def combiner_names() -> list[str]:
    """Return the names of the registered combiners, sorted."""
    return list(combiners())


def get_combiner(name: str) -> Any:
    """Return the combiner registered under `name` (e.g. ``"garch"``)."""
    table = combiners()
    try:
        return table[name]
    except KeyError:
        raise InputError(
            f"unknown combiner {name!r}; registered combiners: {', '.join(table) or 'none'}"
        ) from None
