"""stochmod.core.checks: the finiteness check of every signal, against numpy's isfinite."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stochmod.core.checks import as_signal, check_freq
from stochmod.core.errors import InputError

# every float64, the extremes, infinities and NaN included: sums that overflow, cancel or
# propagate NaN all occur
FLOATS = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=300, deadline=None)
@given(hnp.arrays(np.float64, st.integers(2, 40), elements=FLOATS))
def test_a_signal_passes_exactly_when_every_value_is_finite(x):
    if np.all(np.isfinite(x)):
        assert np.array_equal(as_signal(x), x)
    else:
        first = int(np.flatnonzero(~np.isfinite(x))[0])
        kind = "NaN" if np.isnan(x[first]) else "inf"
        with pytest.raises(InputError, match=f"{kind} at flat index {first}"):
            as_signal(x)


def test_finite_values_whose_sum_overflows_pass_without_a_warning():
    x = np.full(8, np.finfo(np.float64).max)
    with np.errstate(over="ignore"):
        assert not np.isfinite(x.sum())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(as_signal(x), x)
    with pytest.raises(InputError, match="inf at flat index 3"):
        as_signal(np.r_[x[:3], np.inf, -x[:4]])


@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                 st.floats(allow_nan=False).map(np.float64), st.integers(-5, 10**6),
                 st.booleans()))
def test_check_freq_accepts_exactly_the_positive_finite_numbers(freq):
    """A sampling frequency passes exactly when it is a real number (not a bool) that is
    positive and finite, and comes back as that value in a plain float (the plain-float fast
    path gives the general path's verdict and value)."""
    ok = (not isinstance(freq, bool)) and 0 < float(freq) and float(freq) != float("inf")
    if ok:
        out = check_freq(freq)
        assert out.__class__ is float and out == float(freq)
    else:
        with pytest.raises(InputError, match="freq"):
            check_freq(freq)
