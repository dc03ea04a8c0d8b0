"""Redundant sensors: the combination of time-aligned recordings into one synthetic signal."""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.redundant.combination import CombinationResult, combine

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.redundant.combination": ("CombinationResult", "combine"),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
