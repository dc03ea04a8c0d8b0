"""The plugin layer: pluggy hook specifications, the registry, the spec language that names
registered families, and the SDK module plugins import.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.plugin.hookspecs import hookimpl, hookspec
    from stochmod.plugin.registry import (
        combiner_names,
        get_combiner,
        get_process,
        process_names,
        reader_names,
        register_plugin,
        unregister_plugin,
    )
    from stochmod.plugin.spec import model_from_spec

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.plugin.hookspecs": ("hookimpl", "hookspec"),
    "stochmod.plugin.spec": ("model_from_spec",),
    "stochmod.plugin.registry": (
        "get_process",
        "process_names",
        "register_plugin",
        "unregister_plugin",
        "get_combiner",
        "combiner_names",
        "reader_names",
    ),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
