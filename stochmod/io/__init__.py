"""Recordings (columns with their sensor kind and unit, read through the readers plugin point,
and their time stamps) and the calibration file.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.io.calibration import AxisCalibration, Calibration
    from stochmod.io.recording import Reader, Recording, read_recording
    from stochmod.io.timing import TimingReport, analyse_timing

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.io.calibration": ("Calibration", "AxisCalibration"),
    "stochmod.io.recording": ("Recording", "Reader", "read_recording"),
    "stochmod.io.timing": ("TimingReport", "analyse_timing"),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
