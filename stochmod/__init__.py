"""stochmod: stochastic error models of inertial sensors.

Process families (``stochmod.GM``, ``stochmod.WN`` ...) come from plugins registered in the
entry-point group ``stochmod``; :func:`process_names` lists them and :func:`get_process`
returns one by name.
"""

from __future__ import annotations

from typing import Any

from stochmod.errors import (
    DomainError,
    EstimationError,
    InputError,
    SpecError,
    StochmodError,
    UnknownProcessError,
)
from stochmod.hookspecs import hookimpl, hookspec
from stochmod.model import Model, augment_axes, model_from_spec
from stochmod.params import Parameter
from stochmod.process import PhysicalValue, Process
from stochmod.registry import get_process, process_names, register_plugin, unregister_plugin
from stochmod.statespace import StateSpaceBlock

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "hookimpl",
    "hookspec",
    "Process",
    "Parameter",
    "PhysicalValue",
    "Model",
    "StateSpaceBlock",
    "model_from_spec",
    "augment_axes",
    "process_names",
    "get_process",
    "register_plugin",
    "unregister_plugin",
    "StochmodError",
    "InputError",
    "DomainError",
    "SpecError",
    "UnknownProcessError",
    "EstimationError",
]


def __getattr__(name: str) -> Any:
    """Registered process families are reachable as attributes: ``stochmod.GM``."""
    if name.isupper() or (name[:1].isupper() and name in process_names()):
        try:
            return get_process(name)
        except UnknownProcessError:
            pass
    raise AttributeError(f"module 'stochmod' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(__all__) | set(process_names()))
