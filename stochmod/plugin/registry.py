"""The plugin registry: one pluggy manager, entry-point discovery, lookup of families by name.

Plugins installed with an entry point in the ``stochmod`` group are loaded on first use.
Third parties may also register a plugin object at run time with :func:`register_plugin`.
"""

from __future__ import annotations

import importlib
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import pluggy

from stochmod.core.errors import InputError, StochmodError, UnknownProcessError
from stochmod.plugin.hookspecs import PROJECT_NAME, StochmodSpec

if TYPE_CHECKING:
    from stochmod.core.process import Process

__all__ = [
    "plugin_manager",
    "register_plugin",
    "unregister_plugin",
    "process_names",
    "get_process",
    "processes",
    "criteria",
    "weightings",
    "readers",
    "reader_names",
    "combiners",
    "combiner_names",
    "get_combiner",
]

_lock = threading.RLock()
_manager: pluggy.PluginManager | None = None
#: The core's own hook implementations (the WVIC criterion, the GMWM weightings), registered
#: with the entry points.
_BUILTIN_PLUGINS = ("stochmod.fit.criteria", "stochmod.fit.weighting_plugins")


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
        weightings()
        readers()
        combiners()
    except StochmodError:
        pm.unregister(plugin)
        raise


def unregister_plugin(plugin: object) -> None:
    """Remove a plugin registered with :func:`register_plugin`."""
    plugin_manager().unregister(plugin)


def processes() -> dict[str, type[Process]]:
    """Return every registered process family, keyed by its ``family`` name."""
    from stochmod.core.process import Process

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


def _named_objects(batches: list[list[Any]], kind: str, requirement: str,
                   conforms: Callable[[Any], bool]) -> dict[str, Any]:
    """Key the objects of one hook's results by their ``name``, refusing malformed or doubled ones.

    Parameters
    ----------
    batches : list of list
        What the hook returned, one list per plugin, in pluggy's call order.
    kind : str
        What the objects are ("weighting", "reader", "combiner"), for messages.
    requirement : str
        What `conforms` asks of an object, for messages.
    conforms : callable
        True when an object (its ``name`` already checked) has what the contract requires.
    """
    found: dict[str, Any] = {}
    for batch in batches:
        for obj in batch:
            name = getattr(obj, "name", None)
            if not (isinstance(name, str) and name):
                raise StochmodError(f"plugin returned {obj!r}, which is not a {kind}: it is "
                                    f"without a name (a non-empty str); a {kind} needs {requirement}")
            if not conforms(obj):
                raise StochmodError(f"plugin returned {obj!r}, which is not a {kind} (it needs "
                                    f"{requirement})")
            if name in found and found[name] is not obj:
                raise StochmodError(f"two plugins register a {kind} named {name!r}: "
                                    f"{type(found[name]).__module__} and {type(obj).__module__}")
            found[name] = obj
    return found


def weightings() -> dict[str, Any]:
    """Return the registered GMWM weightings keyed by name, sorted (``stochmod_weightings``).

    Raises
    ------
    StochmodError
        A weighting without a ``name`` or ``matrix``, or two plugins with one name.
    """
    found = _named_objects(plugin_manager().hook.stochmod_weightings(), "weighting",
                           "a name and matrix(data)",
                           lambda w: callable(getattr(w, "matrix", None)))
    return dict(sorted(found.items()))


def _is_reader(obj: Any) -> bool:
    suffixes = getattr(obj, "suffixes", ())
    return (isinstance(suffixes, tuple) and all(isinstance(s, str) for s in suffixes)
            and callable(getattr(obj, "read", None)) and callable(getattr(obj, "sniff", None)))


def readers() -> dict[str, Any]:
    """Return the registered log-format readers keyed by name, in registration order
    (hook ``stochmod_readers``; the order in which :func:`stochmod.io.recording.read_recording` sniffs).

    Raises
    ------
    StochmodError
        A reader without a name, suffixes or methods, or two readers of one name.
    """
    return _named_objects(list(reversed(plugin_manager().hook.stochmod_readers())), "reader",
                          "a tuple of str suffixes and callable read(path, **options) and "
                          "sniff(path)", _is_reader)


def reader_names() -> list[str]:
    """Return the names of the registered readers, in registration order."""
    return list(readers())


def combiners() -> dict[str, Any]:
    """Return every registered redundant-sensor combiner, keyed by its ``name``, sorted.

    Raises
    ------
    StochmodError
        A plugin returned an object without ``name``, ``assumes`` and a callable ``combine``, or
        two plugins register the same name.
    """
    found = _named_objects(
        plugin_manager().hook.stochmod_combiners(), "combiner",
        "a str `name`, a str `assumes` and a `combine(x, **options)` method",
        lambda c: isinstance(getattr(c, "assumes", None), str) and callable(getattr(c, "combine", None)),
    )
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
