"""Tests of stochmod.io.timing.analyse_timing: rate, gaps and jitter against the stamps' truth.

Truth: stamps built from a known rate with known samples removed (the gaps are the runs of
removed indices, computed here from the kept indices), and the jitter as the rms residual of
numpy's own least-squares line through the stamps (np.polyfit).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stochmod.core.errors import InputError
from stochmod.io.timing import analyse_timing


def _gaps_from_kept(kept: np.ndarray) -> list[tuple[int, int]]:
    """(position in the kept series, samples missing) of every hole in `kept`."""
    step = np.diff(kept)
    return [(int(i), int(step[i] - 1)) for i in np.flatnonzero(step > 1)]


@settings(max_examples=40, deadline=None)
@given(
    rate=st.floats(1.0, 2000.0),
    n=st.integers(8, 400),
    t0=st.floats(0.0, 1e5),
    seed=st.integers(0, 2**32 - 1),
)
def test_rate_and_gaps_exact_for_periodic_stamps(rate: float, n: int, t0: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    # drop up to n/8 samples, never the first or last, runs of any length
    drop = rng.choice(np.arange(1, n - 1), size=rng.integers(0, n // 8 + 1), replace=False)
    kept = np.setdiff1d(np.arange(n), drop)
    report = analyse_timing(t0 + kept / rate)
    # the stamps themselves are rounded to float64: a few ulps of t over the record's duration
    t_last = t0 + kept[-1] / rate
    assert report.rate == pytest.approx(rate, rel=1e-12 + 4 * np.spacing(t_last) * rate / kept[-1])
    assert [(g.index, g.missing) for g in report.gaps] == _gaps_from_kept(kept)
    assert report.dropped == drop.size
    assert report.n == kept.size
    bounds = report.segment_bounds()
    assert sum(b - a for a, b in bounds) == kept.size
    for a, b in bounds:  # each segment is evenly sampled
        assert np.all(np.diff(kept[a:b]) == 1)


def test_jitter_is_the_residual_of_the_least_squares_line() -> None:
    rng = np.random.default_rng(5)
    n, rate = 5000, 200.0
    t = np.arange(n) / rate + rng.uniform(-1e-4, 1e-4, n)  # 0.1 ms jitter on a 5 ms period
    report = analyse_timing(t)
    slope = np.polyfit(np.arange(n), t, 1)[0]
    dev = np.diff(t) - slope
    assert report.period == pytest.approx(slope, rel=1e-12)
    assert report.jitter_rms == pytest.approx(np.sqrt(np.mean(dev**2)), rel=1e-9)
    assert report.jitter_max == pytest.approx(np.max(np.abs(dev)), rel=1e-9)
    assert report.jitter_max_index == int(np.argmax(np.abs(dev)))
    assert not report.has_gaps
    # uniform(-a, a) on both ends of an interval: var = 2 a^2 / 3
    assert report.jitter_rms == pytest.approx(np.sqrt(2 / 3) * 1e-4, rel=0.03)


def test_summary_names_the_gaps() -> None:
    t = np.delete(np.arange(100) * 0.01, [10, 11, 12, 50])
    report = analyse_timing(t)
    text = report.summary()
    assert [(g.index, g.missing, g.time) for g in report.gaps] == [(9, 3, 0.09), (46, 1, 0.49)]
    assert report.gaps[0].duration == pytest.approx(0.04)
    assert "after sample" in text and "  9" in text and "0.49" in text
    assert report.describe_gaps(limit=1).endswith("and 1 more")


@pytest.mark.parametrize(
    ("t", "match"),
    [
        ([0.0, 0.01, 0.01, 0.03], r"sample 2 \(t = 0.01 s\) is not later than sample 1"),
        ([0.0, 0.02, 0.01], r"sample 2 .* is not later"),
        ([0.0], "at least 2"),
        ([0.0, np.nan, 0.2], "non-finite time stamp at sample 1"),
    ],
)
def test_bad_stamps_raise(t: list[float], match: str) -> None:
    with pytest.raises(InputError, match=match):
        analyse_timing(t)


def test_gap_factor_must_exceed_one() -> None:
    with pytest.raises(InputError, match="gap_factor"):
        analyse_timing([0.0, 1.0, 2.0], gap_factor=1.0)
