"""Bundled example recordings (simulated, with known truth)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.data.examples import xsens_mtig, xsens_mtig_models
    from stochmod.data.redundant import redundant_gyros

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.data.examples": ("xsens_mtig", "xsens_mtig_models"),
    "stochmod.data.redundant": ("redundant_gyros",),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
