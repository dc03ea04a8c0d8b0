"""The plugin SDK: everything a stochmod plugin imports, in one public module.

A plugin (first-party or third-party) imports ``stochmod.sdk`` and nothing else from
stochmod. What it finds here, by plugin point (docs/plugin_contract.md):

- every plugin: :data:`hookimpl`, the errors, the input checks and :func:`format_table`;
- process families (``stochmod_processes``): :class:`Process` and its declarations
  (:class:`Parameter`, :class:`PhysicalValue`, :class:`StateSpaceBlock`,
  :class:`ContinuousBlock`), the optional vectorised-WV protocol :class:`VectorisedWV`, the
  base :class:`ScaledFamily` of families whose Haar WV is a scale times a factor,
  :func:`as_generator`, the unit conversions, the closed forms of geometric Haar wavelet
  variances, the wavelet filters and the optional compiler (:func:`compiled`,
  :data:`JIT_AVAILABLE`);
- readers (``stochmod_readers``): :class:`Reader`, :class:`Recording`, :func:`import_optional`,
  :func:`sensor_kind`;
- weightings (``stochmod_weightings``): :class:`Weighting`, :class:`WeightingInput`,
  :class:`WeightingMatrix`;
- combiners (``stochmod_combiners``): :class:`CombinationResult`, :func:`as_sensor_array`,
  :func:`residuals_from_mean`, and the estimators a combiner may build on (:func:`wvar`,
  :func:`fit_arma`, :func:`select_arma`, :func:`fit_garch`, :func:`select_garch`,
  :func:`prepare_garch`).

Names whose modules import scipy.signal or scipy.stats are imported on first access, so that
loading a plugin stays cheap.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from stochmod.core.checks import (
    as_signal,
    check_freq,
    check_positive,
    check_positive_int,
    checked_values,
    scalar_or_array,
)
from stochmod.core.coefficients import check_coefficients
from stochmod.core.errors import (
    AccuracyWarning,
    DomainError,
    EstimationError,
    InputError,
    SpecError,
    StochmodError,
)
from stochmod.core.filters import modwt_filters
from stochmod.core.geometric import (
    AV_PEAK_VALUE,
    POSITIVE_ROWS_KERNEL_MAX_U,
    WV_PEAK_X,
    haar_wv_geometric,
    haar_wv_geometric_dlog,
    haar_wv_geometric_parts,
    haar_wv_positive,
    haar_wv_positive_rows,
    log1p_complex,
    positive_rows_kernel,
)
from stochmod.core.jit import AVAILABLE as JIT_AVAILABLE
from stochmod.core.jit import compiled
from stochmod.core.model import Model
from stochmod.core.params import Parameter, get_domain
from stochmod.core.process import PhysicalValue, Process, as_generator
from stochmod.core.statespace import ContinuousBlock, StateSpaceBlock
from stochmod.core.tables import format_table
from stochmod.core.units import (
    BI_FACTOR,
    bi_floor,
    bi_from_floor,
    parse_unit,
    rw_density,
    rw_variance,
    to_si,
    wn_density,
)
from stochmod.io.recording import Reader, Recording, import_optional
from stochmod.io.sensors import sensor_kind
from stochmod.plugin.hookspecs import hookimpl
from stochmod.plugin.registry import get_process
from stochmod.plugin.spec import model_from_spec

#: Module of each name imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.core.vectorised_wv": ("VectorisedWV",),
    "stochmod.core.scaled_family": ("ScaledFamily",),
    "stochmod.fit.weighting_plugins": ("Weighting", "WeightingInput", "WeightingMatrix"),
    "stochmod.redundant.combination": ("CombinationResult", "as_sensor_array",
                                       "residuals_from_mean"),
    "stochmod.empirical.wavelet_variance": ("wvar",),
    "stochmod.fit.arma": ("ArmaFit", "fit_arma", "select_arma"),
    "stochmod.fit.garch": ("GarchFit", "fit_garch", "select_garch"),
}
_LAZY_NAMES = {name: module for module, names in _LAZY.items() for name in names}

if TYPE_CHECKING:
    from stochmod.core.scaled_family import ScaledFamily
    from stochmod.core.vectorised_wv import VectorisedWV
    from stochmod.empirical.wavelet_variance import wvar
    from stochmod.fit.arma import ArmaFit, fit_arma, select_arma
    from stochmod.fit.garch import GarchFit, fit_garch, select_garch
    from stochmod.fit.weighting_plugins import Weighting, WeightingInput, WeightingMatrix
    from stochmod.redundant.combination import (CombinationResult, as_sensor_array,
                                                residuals_from_mean)

__all__ = [
    # every plugin
    "hookimpl",
    "StochmodError",
    "InputError",
    "DomainError",
    "SpecError",
    "EstimationError",
    "AccuracyWarning",
    "as_signal",
    "check_freq",
    "check_positive",
    "check_positive_int",
    "checked_values",
    "scalar_or_array",
    "format_table",
    "get_process",
    "model_from_spec",
    # process families
    "Process",
    "VectorisedWV",
    "ScaledFamily",
    "Model",
    "Parameter",
    "get_domain",
    "PhysicalValue",
    "StateSpaceBlock",
    "ContinuousBlock",
    "as_generator",
    "check_coefficients",
    "compiled",
    "JIT_AVAILABLE",
    "modwt_filters",
    "BI_FACTOR",
    "bi_floor",
    "bi_from_floor",
    "parse_unit",
    "rw_density",
    "rw_variance",
    "to_si",
    "wn_density",
    "AV_PEAK_VALUE",
    "POSITIVE_ROWS_KERNEL_MAX_U",
    "WV_PEAK_X",
    "haar_wv_geometric",
    "haar_wv_geometric_dlog",
    "haar_wv_geometric_parts",
    "haar_wv_positive",
    "haar_wv_positive_rows",
    "log1p_complex",
    "positive_rows_kernel",
    # readers
    "Reader",
    "Recording",
    "import_optional",
    "sensor_kind",
    # weightings
    "Weighting",
    "WeightingInput",
    "WeightingMatrix",
    # combiners
    "CombinationResult",
    "as_sensor_array",
    "residuals_from_mean",
    "wvar",
    "ArmaFit",
    "fit_arma",
    "select_arma",
    "GarchFit",
    "fit_garch",
    "select_garch",
    "prepare_garch",
]


def prepare_garch() -> None:
    """Load the compiled GARCH likelihood pass in this process now, so that worker processes
    forked afterwards inherit it (:func:`stochmod.fit.garch_jit.prepare`)."""
    importlib.import_module("stochmod.fit.garch_jit").prepare()


def __getattr__(name: str) -> Any:
    """A name of :data:`_LAZY`, imported on first use."""
    module = _LAZY_NAMES.get(name)
    if module is None:
        raise AttributeError(f"module 'stochmod.sdk' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return list(__all__)
