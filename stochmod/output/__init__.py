"""What a calibration hands on: datasheets, exports to navigation stacks, the HTML report and
figures.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.output.datasheet import Datasheet, datasheet
    from stochmod.output.exports import EXPORT_FORMATS, write_exports
    from stochmod.output.html_report import write_report
    from stochmod.output.plots import plot_fit, save_fit_figure

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.output.datasheet": ("Datasheet", "datasheet"),
    "stochmod.output.exports": ("EXPORT_FORMATS", "write_exports"),
    "stochmod.output.html_report": ("write_report",),
    "stochmod.output.plots": ("plot_fit", "save_fit_figure"),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
