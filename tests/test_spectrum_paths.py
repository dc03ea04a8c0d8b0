"""The eq. 17 covariance's two power-spectrum paths: scipy's real transform (pure numpy/scipy)
and the complex transform of sample pairs with the compiled split
(:mod:`stochmod.empirical.spectrum_jit`, through :mod:`stochmod.empirical.four_step`), each against
an independent double-precision computation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stochmod.core import jit
from stochmod.empirical import four_step, haar_jit, spectrum_jit

needs_numba = pytest.mark.skipif(not jit.AVAILABLE,
                                 reason="numba (the 'fast' extra) is not installed")


@needs_numba
@settings(max_examples=40, deadline=None)
@given(half=st.integers(1, 600), seed=st.integers(0, 2**32 - 1),
       exponent=st.integers(-30, 30))
def test_split_power_equals_the_real_transform(half, seed, exponent):
    """|X_k|^2 from the half-length complex transform, k = 0 .. N/2, for every even N from 2 and
    any unit (powers of two from 1e-9 to 1e9): within float32 rounding of numpy's
    double-precision real transform."""
    n = 2 * half
    x = (np.random.default_rng(seed).standard_normal(n) * 2.0**exponent).astype(np.float32)
    out = np.empty(half + 1, dtype=np.float32)
    exact = np.abs(np.fft.rfft(x.astype(np.float64))) ** 2
    four_step.power_spectrum(x, four_step.plan(1, half), out)  # the natural order (n1 = 1)
    assert np.max(np.abs(out - exact)) <= 1e-5 * np.max(exact)


def test_twiddles_are_the_unit_circle():
    table = four_step.plan(1, 6).cols  # (cos, sin) of 2 pi k / N for N = 12 real samples
    k = np.arange(6)
    np.testing.assert_allclose(table[:, 0] + 1j * table[:, 1], np.exp(2j * np.pi * k / 12),
                               atol=1e-7)


@needs_numba
@pytest.mark.parametrize("J, K, width", [(1, 5, 128), (3, 300, 128), (4, 128, 128),
                                         (7, 1000, 64), (19, 777, 128)])
def test_power_gram_equals_the_double_precision_product(J, K, width):
    """The compiled Gram (rows in groups of four, the rest one by one; a last partial block)
    against numpy's float64 product of the same float32 rows."""
    powers = np.random.default_rng(J * K).random((J, K)).astype(np.float32) * 1e3
    exact = powers.astype(np.float64) @ powers.T.astype(np.float64)
    gram = spectrum_jit.power_gram(powers, width)
    np.testing.assert_allclose(gram, exact, rtol=1e-13)
    assert np.array_equal(gram, gram.T)
