"""The overlapping Allan and Hadamard sums' compiled loop (:mod:`stochmod.empirical.allan_jit`)
against an exact integer computation of ``sum_i (Delta^d_m c_i)^2``, and against its own
plain-Python function."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stochmod.core import jit
from stochmod.empirical import allan_jit

needs_numba = pytest.mark.skipif(not jit.AVAILABLE, reason="STOCHMOD_DISABLE_JIT is set")

#: Phase values up to 2^16 in magnitude: every difference (< 2^19) and square (< 2^38) is
#: exact in float64, and a sum of up to 2^17 of them fits int64.
_BOUND = 1 << 16


def _exact(c: np.ndarray, m: int, d: int) -> int:
    """sum_i (sum_k (-1)^(d-k) C(d, k) c_{i+k m})^2 in int64 (binomial form of the d-th lag-m
    difference, not the nested differences of the implementations)."""
    n_t = c.size - d * m
    diff = sum((-1) ** (d - k) * math.comb(d, k) * c[k * m : k * m + n_t] for k in range(d + 1))
    return int(np.sum(diff * diff))


@settings(max_examples=60, deadline=None)
@given(d=st.sampled_from([2, 3]), m=st.integers(1, 300), extra=st.integers(0, 400),
       seed=st.integers(0, 2**32 - 1))
def test_sum_equals_the_exact_integer_sum(d, m, extra, seed):
    """Every lag, both orders, from one term (``P = d m + 1``, the shortest phase) up."""
    c = np.random.default_rng(seed).integers(-_BOUND, _BOUND, d * m + 1 + extra)
    exact = _exact(c, m, d)
    got = allan_jit.difference_sumsq(c.astype(np.float64), m, d)
    assert got == pytest.approx(exact, rel=1e-13, abs=0)


@pytest.mark.parametrize("d, m", [(2, 1), (2, 70_001), (3, 3), (3, 40_000)])
def test_long_sum_equals_the_exact_integer_sum(d, m):
    """Phases of more than 2^17 samples, long and short lags."""
    c = np.random.default_rng(m).integers(-_BOUND, _BOUND, (1 << 17) + d * m + 5)
    got = allan_jit.difference_sumsq(c.astype(np.float64), m, d)
    assert got == pytest.approx(_exact(c, m, d), rel=1e-12, abs=0)


@needs_numba
@settings(max_examples=40, deadline=None)
@given(d=st.sampled_from([2, 3]), m=st.integers(1, 50), extra=st.integers(0, 2000),
       seed=st.integers(0, 2**32 - 1))
def test_compiled_sum_equals_its_plain_function(d, m, extra, seed):
    c = np.random.default_rng(seed).standard_normal(d * m + 1 + extra).cumsum()
    assert allan_jit.difference_sumsq(c, m, d) == pytest.approx(
        allan_jit.difference_sumsq.py_func(c, m, d), rel=1e-12, abs=0)
