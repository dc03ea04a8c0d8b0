"""Time stamps of a recording: the sampling rate, dropped samples, gaps and jitter.

A logger writes one time stamp per sample. :func:`analyse_timing` estimates the sampling
period from them and finds where samples are missing, so that a recording with holes is never
modelled as if it were evenly sampled (DESIGN.md: gaps are refused or split, never dropped
silently).

The estimate works in three steps:

1. the *nominal* period ``p0`` is the median interval between consecutive stamps;
2. an interval longer than ``gap_factor * p0`` is a *gap*; it holds
   ``round(interval / p0) - 1`` missing samples (one missing sample is a *dropped sample*);
3. every stamp gets its sample number ``k_i`` (counting the missing ones), and the period is
   the least-squares slope of the stamps on ``k_i``: the rate uses the whole record, gaps
   included, and is exact for exactly periodic stamps.

Jitter is the deviation of each gap-free interval from the estimated period.
"""

from __future__ import annotations

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.errors import InputError
from stochmod.core.tables import format_number, format_table

__all__ = ["Gap", "TimingReport", "analyse_timing", "DEFAULT_GAP_FACTOR"]

#: An interval longer than this many nominal periods is a gap (a missing sample at least).
DEFAULT_GAP_FACTOR = 1.5


@attrs.frozen
class Gap:
    """A hole in the time stamps.

    Attributes
    ----------
    index : int
        0-based index of the last sample before the gap (the next sample is ``index + 1``).
    time : float
        Time stamp of that sample, s.
    duration : float
        Interval between the two samples around the gap, s.
    missing : int
        Samples missing in the gap (``round(duration / period) - 1``; at least 1).
    """

    index: int
    time: float
    duration: float
    missing: int

    def describe(self) -> str:
        """One line: where the gap is and how long it is."""
        return (
            f"after sample {self.index} (t = {format_number(self.time)} s): "
            f"{format_number(self.duration)} s, {self.missing} sample(s) missing"
        )


@attrs.frozen
class TimingReport:
    """What the time stamps of a recording say about its sampling.

    Attributes
    ----------
    n : int
        Number of time stamps (samples).
    start, stop : float
        First and last time stamp, s.
    period : float
        Estimated sampling period, s (least squares over the whole record, gaps counted).
    gaps : tuple of Gap
        Every interval longer than ``gap_factor`` periods, in time order.
    jitter_rms : float
        Root-mean-square deviation of the gap-free intervals from ``period``, s.
    jitter_max : float
        Largest absolute deviation of a gap-free interval from ``period``, s.
    jitter_max_index : int
        Index of the sample that starts the interval with the largest deviation.
    gap_factor : float
        The threshold used, in periods.
    """

    n: int
    start: float
    stop: float
    period: float
    gaps: tuple[Gap, ...]
    jitter_rms: float
    jitter_max: float
    jitter_max_index: int
    gap_factor: float = DEFAULT_GAP_FACTOR

    @property
    def rate(self) -> float:
        """Estimated sampling frequency, Hz."""
        return 1.0 / self.period

    @property
    def duration(self) -> float:
        """Time from the first to the last stamp, s."""
        return self.stop - self.start

    @property
    def dropped(self) -> int:
        """Total number of missing samples over all gaps."""
        return sum(g.missing for g in self.gaps)

    @property
    def has_gaps(self) -> bool:
        """Whether any sample is missing."""
        return bool(self.gaps)

    def segment_bounds(self) -> list[tuple[int, int]]:
        """Half-open sample ranges ``[start, stop)`` of the gap-free segments, in order."""
        cuts = [g.index + 1 for g in self.gaps]
        return list(zip([0, *cuts], [*cuts, self.n]))

    def describe_gaps(self, limit: int = 5) -> str:
        """The first `limit` gaps, one per clause, and how many more there are."""
        text = "; ".join(g.describe() for g in self.gaps[:limit])
        more = len(self.gaps) - limit
        return text + (f"; and {more} more" if more > 0 else "")

    def summary(self) -> str:
        """Rate, duration, dropped samples, jitter and a table of the gaps."""
        head = format_table(
            [
                "samples",
                "duration s",
                "rate Hz",
                "period s",
                "gaps",
                "dropped",
                "jitter rms s",
                "jitter max s",
                "at sample",
            ],
            [
                [
                    self.n,
                    self.duration,
                    self.rate,
                    self.period,
                    len(self.gaps),
                    self.dropped,
                    self.jitter_rms,
                    self.jitter_max,
                    self.jitter_max_index,
                ]
            ],
            title="time stamps",
        )
        if not self.gaps:
            return head + "\nno gaps"
        rows = [[g.index, g.time, g.duration, g.missing] for g in self.gaps]
        return (
            head
            + "\n\n"
            + format_table(
                ["after sample", "t s", "interval s", "missing"],
                rows,
                title=f"gaps (intervals longer than {format_number(self.gap_factor)} periods)",
            )
        )


def analyse_timing(
    time: ArrayLike, *, gap_factor: float = DEFAULT_GAP_FACTOR, name: str = "time stamps"
) -> TimingReport:
    """Estimate the sampling rate and find gaps and jitter in a series of time stamps.

    Parameters
    ----------
    time : array_like, shape (n,)
        Time stamps in seconds, strictly increasing, n >= 2.
    gap_factor : float
        An interval longer than ``gap_factor`` times the median interval is a gap (> 1).
    name : str
        How error messages call the stamps (e.g. the file name).

    Returns
    -------
    TimingReport

    Raises
    ------
    InputError
        Fewer than two stamps, non-finite stamps, or a stamp not later than its predecessor
        (the message gives the first such position).
    """
    t = np.asarray(time, dtype=np.float64)
    if t.ndim != 1 or t.size < 2:
        raise InputError(
            f"{name}: need a 1-D series of at least 2 time stamps, got shape {t.shape}"
        )
    if not np.all(np.isfinite(t)):
        raise InputError(
            f"{name}: non-finite time stamp at sample {int(np.flatnonzero(~np.isfinite(t))[0])}"
        )
    if not gap_factor > 1.0:
        raise InputError(f"gap_factor must be greater than 1, got {gap_factor!r}")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0])
        raise InputError(
            f"{name}: time stamps must increase; sample {i + 1} (t = {format_number(t[i + 1])} s) "
            f"is not later than sample {i} (t = {format_number(t[i])} s); {bad.size} such place(s)"
        )
    p0 = float(np.median(dt))
    steps = np.maximum(np.rint(dt / p0), 1.0)
    is_gap = dt > gap_factor * p0
    k = np.concatenate([[0.0], np.cumsum(steps)])
    kc = k - k.mean()
    period = float(np.dot(kc, t - t.mean()) / np.dot(kc, kc))
    gaps = tuple(
        Gap(
            index=int(i), time=float(t[i]), duration=float(dt[i]), missing=max(int(steps[i]) - 1, 1)
        )
        for i in np.flatnonzero(is_gap)
    )
    dev = np.where(is_gap, 0.0, dt - period)
    regular = ~is_gap
    jitter_rms = float(np.sqrt(np.mean(dev[regular] ** 2))) if regular.any() else 0.0
    worst = int(np.argmax(np.abs(dev)))
    return TimingReport(
        n=int(t.size),
        start=float(t[0]),
        stop=float(t[-1]),
        period=period,
        gaps=gaps,
        jitter_rms=jitter_rms,
        jitter_max=float(abs(dev[worst])),
        jitter_max_index=worst,
        gap_factor=float(gap_factor),
    )
