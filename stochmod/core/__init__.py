"""The core: errors, input checks, parameters, units, text tables, the process contract,
composite models, state-space blocks and generic wavelet-variance theory. It imports nothing
else from stochmod.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.core.errors import (
        AccuracyWarning,
        DomainError,
        EstimationError,
        InputError,
        SpecError,
        StochmodError,
        UnknownProcessError,
    )
    from stochmod.core.model import Model, as_model, augment_axes
    from stochmod.core.params import Parameter
    from stochmod.core.process import PhysicalValue, Process, as_generator
    from stochmod.core.statespace import ContinuousBlock, StateSpaceBlock, van_loan
    from stochmod.core.units import STANDARD_GRAVITY, convert, from_si, parse_unit, to_si

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.core.errors": (
        "StochmodError",
        "InputError",
        "DomainError",
        "SpecError",
        "UnknownProcessError",
        "EstimationError",
        "AccuracyWarning",
    ),
    "stochmod.core.params": ("Parameter",),
    "stochmod.core.process": ("Process", "PhysicalValue", "as_generator"),
    "stochmod.core.model": ("Model", "as_model", "augment_axes"),
    "stochmod.core.statespace": ("StateSpaceBlock", "ContinuousBlock", "van_loan"),
    "stochmod.core.units": ("convert", "to_si", "from_si", "parse_unit", "STANDARD_GRAVITY"),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
