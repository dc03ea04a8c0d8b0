"""Workflows over many results: fleets of units on a dask cluster or serially."""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.workflows.fleet import UnitSteps, calibrate_files, run_fleet

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.workflows.fleet": ("calibrate_files", "run_fleet", "UnitSteps"),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
