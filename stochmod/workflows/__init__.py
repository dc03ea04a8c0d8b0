"""Workflows: the main job (a recording in, its calibration out) and fleets of units on a dask
cluster or serially."""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.workflows.calibrate import (CalibrationRun, assemble, calibrate,
                                              calibration_run, prepare, select_column,
                                              select_columns)
    from stochmod.workflows.fleet import UnitSteps, calibrate_files, run_fleet

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.workflows.calibrate": ("calibrate", "calibration_run", "CalibrationRun", "prepare",
                                     "select_column", "select_columns", "assemble"),
    "stochmod.workflows.fleet": ("calibrate_files", "run_fleet", "UnitSteps"),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
