"""The plugin registry: one pluggy manager, entry-point discovery, lookup of families by name.

Plugins installed with an entry point in the ``stochmod`` group are loaded on first use.
Third parties may also register a plugin object at run time with :func:`register_plugin`.
"""

from __future__ import annotations

import importlib
import threading
from typing import TYPE_CHECKING, Any

import pluggy

from stochmod.errors import StochmodError, UnknownProcessError
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
    "readers",
    "reader_names",
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
        readers()
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


def _check_reader(obj: Any) -> str:
    name = getattr(obj, "name", None)
    if not isinstance(name, str) or not name:
        raise StochmodError(f"plugin returned reader {obj!r} without a name")
    suffixes = getattr(obj, "suffixes", ())
    if not isinstance(suffixes, tuple) or not all(isinstance(s, str) for s in suffixes):
        raise StochmodError(f"reader {name!r}: suffixes must be a tuple of str, got {suffixes!r}")
    if not (callable(getattr(obj, "read", None)) and callable(getattr(obj, "sniff", None))):
        raise StochmodError(f"reader {name!r} needs callable read(path, **options) and sniff(path)")
    return name


def readers() -> dict[str, Any]:
    """Return the registered log-format readers keyed by name (hook ``stochmod_readers``).

    Raises
    ------
    StochmodError
        A reader without a name, suffixes or methods, or two readers of one name.
    """
    found: dict[str, Any] = {}
    for batch in reversed(plugin_manager().hook.stochmod_readers()):  # registration order
        for obj in batch:
            name = _check_reader(obj)
            if name in found and found[name] is not obj:
                raise StochmodError(f"two plugins register a reader named {name!r}")
            found[name] = obj
    return found


def reader_names() -> list[str]:
    """Return the names of the registered readers, in registration order."""
    return list(readers())
