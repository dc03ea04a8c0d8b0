"""stochmod: stochastic error models of inertial sensors.

Process families (``stochmod.GM``, ``stochmod.WN`` ...) come from plugins registered in the
entry-point group ``stochmod``; :func:`process_names` lists them and :func:`get_process`
returns one by name.
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import TYPE_CHECKING, Any

from stochmod.errors import (
    AccuracyWarning,
    DomainError,
    EstimationError,
    InputError,
    SpecError,
    StochmodError,
    UnknownProcessError,
)
from stochmod.registry import (
    combiner_names,
    get_combiner,
    get_process,
    process_names,
    register_plugin,
    unregister_plugin,
)

#: The public names of submodules, imported on first access (PEP 562, Scientific Python's
#: SPEC 1): ``import stochmod`` (and so every ``stochmod`` command and fleet worker) does not
#: pay for scipy.signal, scipy.stats, networkx or numba until a name that needs them is used.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod": ("examples", "units"),
    "stochmod.hookspecs": ("hookimpl", "hookspec"),
    "stochmod.model": ("Model", "augment_axes", "model_from_spec"),
    "stochmod.params": ("Parameter",),
    "stochmod.process": ("PhysicalValue", "Process", "as_generator", "has_theoretical_wv"),
    "stochmod.combination": ("CombinationResult", "combine"),
    "stochmod.signal.arma": ("ArmaFit", "fit_arma", "select_arma"),
    "stochmod.signal.arch_lm": ("ArchLMTest", "arch_lm_test"),
    "stochmod.signal.garch": ("GarchFit", "fit_garch", "select_garch"),
    "stochmod.fit.gmwm": ("GMWMResult", "gmwm"),
    "stochmod.fit.selection": ("SelectionResult", "candidate_lattice", "select"),
    "stochmod.fit.validation": ("OctavePSD", "ValidationBands", "octave_psd", "validate"),
    "stochmod.signal.acf": ("acf", "fit_gm_acf"),
    "stochmod.signal.allan": ("AllanVariance", "avar"),
    "stochmod.signal.allan_reading": ("AllanReading", "allan_reading"),
    "stochmod.signal.ar_fit": ("burg", "fit_ar", "yule_walker"),
    "stochmod.signal.denoise": ("denoise",),
    "stochmod.classical.pipelines": ("ModelComparison", "acf_gm_model", "av_model", "avwd_model",
                                     "compare_models", "denoised_ar_model", "psd_model"),
    "stochmod.signal.psd": ("psd", "psd_reading"),
    "stochmod.signal.wavelet_variance": ("WaveletVariance", "wvar"),
    "stochmod.statespace": ("StateSpaceBlock",),
    "stochmod.units": ("STANDARD_GRAVITY", "convert", "from_si", "to_si"),
}
_LAZY_NAMES = {name: module for module, names in _LAZY.items() for name in names}

if TYPE_CHECKING:  # the same names for type checkers and editors
    from stochmod import examples, units
    from stochmod.classical.pipelines import (ModelComparison, acf_gm_model, av_model,
                                              avwd_model, compare_models, denoised_ar_model,
                                              psd_model)
    from stochmod.combination import CombinationResult, combine
    from stochmod.fit.gmwm import GMWMResult, gmwm
    from stochmod.fit.selection import SelectionResult, candidate_lattice, select
    from stochmod.fit.validation import OctavePSD, ValidationBands, octave_psd, validate
    from stochmod.hookspecs import hookimpl, hookspec
    from stochmod.model import Model, augment_axes, model_from_spec
    from stochmod.params import Parameter
    from stochmod.process import PhysicalValue, Process, as_generator, has_theoretical_wv
    from stochmod.signal.acf import acf, fit_gm_acf
    from stochmod.signal.allan import AllanVariance, avar
    from stochmod.signal.allan_reading import AllanReading, allan_reading
    from stochmod.signal.ar_fit import burg, fit_ar, yule_walker
    from stochmod.signal.arch_lm import ArchLMTest, arch_lm_test
    from stochmod.signal.arma import ArmaFit, fit_arma, select_arma
    from stochmod.signal.denoise import denoise
    from stochmod.signal.garch import GarchFit, fit_garch, select_garch
    from stochmod.signal.psd import psd, psd_reading
    from stochmod.signal.wavelet_variance import WaveletVariance, wvar
    from stochmod.statespace import StateSpaceBlock
    from stochmod.units import STANDARD_GRAVITY, convert, from_si, to_si

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "hookimpl",
    "hookspec",
    "Process",
    "as_generator",
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
    "units",
    "examples",
    "select",
    "validate",
    "ValidationBands",
    "octave_psd",
    "OctavePSD",
    "has_theoretical_wv",
    "SelectionResult",
    "candidate_lattice",
    "to_si",
    "from_si",
    "convert",
    "STANDARD_GRAVITY",
    "wvar",
    "WaveletVariance",
    "gmwm",
    "GMWMResult",
    "avar",
    "AllanVariance",
    "allan_reading",
    "AllanReading",
    "psd",
    "psd_reading",
    "acf",
    "fit_gm_acf",
    "burg",
    "yule_walker",
    "fit_ar",
    "denoise",
    "av_model",
    "avwd_model",
    "denoised_ar_model",
    "psd_model",
    "acf_gm_model",
    "compare_models",
    "ModelComparison",
    "StochmodError",
    "InputError",
    "DomainError",
    "SpecError",
    "UnknownProcessError",
    "EstimationError",
    "AccuracyWarning",
    "combine",
    "CombinationResult",
    "combiner_names",
    "get_combiner",
    "fit_garch",
    "select_garch",
    "GarchFit",
    "fit_arma",
    "select_arma",
    "ArmaFit",
    "arch_lm_test",
    "ArchLMTest",
]


def __getattr__(name: str) -> Any:
    """The public names of submodules, imported on first use (:data:`_LAZY`), the
    submodules themselves (``stochmod.datasheet``; a module's own submodules are imported
    by their importers, as for any package) and the registered process families:
    ``stochmod.GM``."""
    module = _LAZY_NAMES.get(name)
    if module is None and name.islower() and importlib.util.find_spec(f"stochmod.{name}"):
        module = "stochmod"  # a submodule: ``import stochmod`` then ``stochmod.fit.gmwm``
    if module == "stochmod":
        value = importlib.import_module(f"stochmod.{name}")
    elif module is not None:
        value = getattr(importlib.import_module(module), name)
    if module is not None:
        globals()[name] = value  # later look-ups are plain attribute reads
        return value
    if name.isupper() or (name[:1].isupper() and name in process_names()):
        try:
            return get_process(name)
        except UnknownProcessError:
            pass
    raise AttributeError(f"module 'stochmod' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(__all__) | set(process_names()))
