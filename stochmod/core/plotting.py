"""Matplotlib helpers shared by every figure stochmod draws (the fit, output and CLI layers).

Nothing here imports matplotlib at module level: the helpers take the axes the caller made.
"""

from __future__ import annotations

from typing import Any

__all__ = ["log_grid"]


def log_grid(ax: Any) -> None:
    """A grid on log-log axes `ax`: every decade, and minor lines at 2 and 5 times it (a
    minor tick at each of 2..9 is most of the time of drawing a log-log figure)."""
    from matplotlib.ticker import LogLocator

    for axis in (ax.xaxis, ax.yaxis):
        axis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
    ax.grid(True, which="both", alpha=0.3)
