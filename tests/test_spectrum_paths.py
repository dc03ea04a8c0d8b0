"""The eq. 17 covariance's compiled spectrum loops (:mod:`stochmod.empirical.spectrum_jit`, through
:mod:`stochmod.empirical.four_step`): each against an independent double-precision computation,
and each compiled loop against its own plain-Python function."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stochmod.core import jit
from stochmod.empirical import four_step, spectrum_jit

needs_numba = pytest.mark.skipif(not jit.AVAILABLE, reason="STOCHMOD_DISABLE_JIT is set")


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


@needs_numba
@settings(max_examples=30, deadline=None)
@given(n1=st.integers(1, 12), n2=st.integers(1, 40), seed=st.integers(0, 2**32 - 1))
def test_compiled_split_and_twiddles_equal_their_plain_functions(n1, n2, seed):
    """split_power (through the pair's power) and twiddle_block on a random layout: compiled
    and plain Python agree to float32 rounding."""
    rng = np.random.default_rng(seed)
    tables = four_step.plan(n1, n2)
    c = (rng.standard_normal((n1, n2)) + 1j * rng.standard_normal((n1, n2))).astype(np.complex64)
    width = min(n2, tables.low.shape[1])
    runs = []
    for split, twiddle, pair in ((spectrum_jit.split_power, spectrum_jit.twiddle_block, None),
                                 (spectrum_jit.split_power.py_func,
                                  spectrum_jit.twiddle_block.py_func,
                                  spectrum_jit._pair.py_func)):
        out, block = np.empty(n1 * n2 + 1, dtype=np.float32), c[:, :width].copy()
        saved = spectrum_jit._pair
        if pair is not None:
            spectrum_jit._pair = pair
        try:
            split(c, tables.rows, tables.cols, out)
        finally:
            spectrum_jit._pair = saved
        twiddle(block, 0, tables.low, tables.high)
        runs.append((out, block))
    for got, want in zip(*runs):
        np.testing.assert_allclose(got, want, rtol=2e-7, atol=0)


@needs_numba
@settings(max_examples=30, deadline=None)
@given(J=st.integers(1, 9), K=st.integers(1, 300), width=st.integers(1, 70),
       seed=st.integers(0, 2**32 - 1))
def test_compiled_gram_equals_its_plain_function(J, K, width, seed):
    powers = np.random.default_rng(seed).random((J, K)).astype(np.float32)
    np.testing.assert_allclose(spectrum_jit.power_gram(powers, width),
                               spectrum_jit.power_gram.py_func(powers, width), rtol=1e-13)
