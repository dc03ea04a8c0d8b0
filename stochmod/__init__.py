"""stochmod: stochastic error models of inertial sensors.

The names below are the public API; everything else is reached through its subpackage
(``stochmod.empirical``, ``stochmod.fit``, ``stochmod.nav`` ...), and plugins import
:mod:`stochmod.sdk`. Process families come from plugins registered in the entry-point
group ``stochmod``: :func:`process_names` lists them, :func:`get_process` returns one, and
``stochmod.GM`` is ``get_process("GM")`` for every registered family.

The names are imported on first access (PEP 562, Scientific Python's SPEC 1), so that
``import stochmod`` (and so every ``stochmod`` command and fleet worker) does not pay for
scipy.signal, scipy.stats, networkx or numba until a name that needs them is used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from stochmod.core.errors import InputError, StochmodError, UnknownProcessError
from stochmod.plugin.registry import (
    combiner_names,
    get_process,
    process_names,
    register_plugin,
    unregister_plugin,
)

#: Module of each lazily imported public name.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.core.model": ("Model", "augment_axes"),
    "stochmod.core.process": ("Process",),
    "stochmod.plugin.spec": ("model_from_spec",),
    "stochmod.empirical.wavelet_variance": ("wvar",),
    "stochmod.empirical.allan": ("avar",),
    "stochmod.empirical.allan_reading": ("allan_reading",),
    "stochmod.empirical.psd": ("psd",),
    "stochmod.empirical.ar_fit": ("burg",),
    "stochmod.empirical.denoise": ("denoise",),
    "stochmod.fit.gmwm": ("gmwm",),
    "stochmod.fit.selection": ("select",),
    "stochmod.fit.validation": ("validate",),
    "stochmod.fit.garch": ("fit_garch",),
    "stochmod.redundant.combination": ("combine",),
    "stochmod.io.calibration": ("Calibration",),
    "stochmod.workflows.calibrate": ("calibrate",),
}
_LAZY_NAMES = {name: module for module, names in _LAZY.items() for name in names}

if TYPE_CHECKING:  # the same names for type checkers and editors
    from stochmod.core.model import Model, augment_axes
    from stochmod.core.process import Process
    from stochmod.empirical.allan import avar
    from stochmod.empirical.allan_reading import allan_reading
    from stochmod.empirical.ar_fit import burg
    from stochmod.empirical.denoise import denoise
    from stochmod.empirical.psd import psd
    from stochmod.empirical.wavelet_variance import wvar
    from stochmod.fit.garch import fit_garch
    from stochmod.fit.gmwm import gmwm
    from stochmod.fit.selection import select
    from stochmod.fit.validation import validate
    from stochmod.plugin.spec import model_from_spec
    from stochmod.io.calibration import Calibration
    from stochmod.redundant.combination import combine
    from stochmod.workflows.calibrate import calibrate

__version__ = "0.1.0"

__all__ = [
    "__version__",
    # models and families
    "Model",
    "Process",
    "model_from_spec",
    "augment_axes",
    "get_process",
    "process_names",
    "register_plugin",
    "unregister_plugin",
    # empirical quantities
    "wvar",
    "avar",
    "allan_reading",
    "psd",
    "burg",
    "denoise",
    # estimation
    "gmwm",
    "select",
    "validate",
    "fit_garch",
    # the main job
    "calibrate",
    "Calibration",
    # redundant sensors
    "combine",
    "combiner_names",
    # errors
    "StochmodError",
    "InputError",
]


def __getattr__(name: str) -> Any:
    """A public name of :data:`_LAZY`, imported on first use, or a registered process family
    (``stochmod.GM``)."""
    module = _LAZY_NAMES.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module), name)
        globals()[name] = value  # later look-ups are plain attribute reads
        return value
    if name[:1].isupper() and name in process_names():
        try:
            return get_process(name)
        except UnknownProcessError:
            pass
    raise AttributeError(f"module 'stochmod' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(__all__) | set(process_names()))
