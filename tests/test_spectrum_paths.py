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


def _nearest_bfloat16(values: np.ndarray) -> np.ndarray:
    """The bfloat16 (uint16 upper half) nearest to each float32 value, ties to the even one:
    the two candidates (the value truncated to 16 bits, and the next one away from zero)
    compared by their exact distance in double precision."""
    bits = values.view(np.uint32).astype(np.uint64)
    down = bits & 0xFFFF0000
    up = down + 0x10000
    exact = values.astype(np.float64)
    below = down.astype(np.uint32).view(np.float32).astype(np.float64)
    above = up.astype(np.uint32).view(np.float32).astype(np.float64)
    d_down, d_up = np.abs(exact - below), np.abs(above - exact)
    pick_up = (d_up < d_down) | ((d_up == d_down) & ((down >> 16) % 2 == 1))
    return (np.where(pick_up, up, down) >> 16).astype(np.uint16)


_BELOW_ROUNDING_TO_INF = float(np.float32(3.38e38))
_FLOAT32 = st.floats(min_value=-_BELOW_ROUNDING_TO_INF, max_value=_BELOW_ROUNDING_TO_INF, width=32,
                     allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(values=st.lists(_FLOAT32, min_size=1, max_size=50),
       ties=st.lists(st.integers(0, 0x7F7E), max_size=10))
def test_bfloat16_rounding_is_to_nearest_even(values, ties):
    """In place, every finite float32 from subnormals to 3.38e38 and either sign, and values
    exactly halfway between two bfloat16 (odd and even upper halves): the nearest, ties to
    even, written in the first half of the buffer."""
    halfway = (np.array(ties, dtype=np.uint32) << 16) | 0x8000
    data = np.concatenate([np.array(values, dtype=np.float32), halfway.view(np.float32)])
    want = _nearest_bfloat16(data)
    spectrum_jit.to_bfloat16(data)
    assert np.array_equal(data.view(np.uint16)[: want.size], want)


@settings(max_examples=30, deadline=None)
@given(m=st.integers(0, 300), extra=st.integers(0, 40), seed=st.integers(0, 2**32 - 1),
       exponent=st.integers(-60, 60))
def test_float64_coefficients_become_their_float32_products_in_place(m, extra, seed, exponent):
    """The buffer's first 8 m bytes as float64 become ``float32(c * factor)`` rounded once,
    the rest zeros: as numpy's multiply into a separate float32 array."""
    rng = np.random.default_rng(seed)
    c = rng.standard_normal(m) * 2.0**exponent
    factor = float(rng.uniform(0.1, 10.0)) * 2.0**-exponent
    buf = np.full(2 * (m + extra), np.nan, dtype=np.float32)  # 2 H float32, as the FFT buffer
    buf.view(np.float64)[:m] = c
    want = np.zeros(buf.size, dtype=np.float32)
    np.multiply(c, factor, out=want[:m])
    spectrum_jit.scale_to_float32(buf, m, factor)
    assert np.array_equal(buf, want)


@settings(max_examples=30, deadline=None)
@given(J=st.integers(1, 9), K=st.integers(1, 400), width=st.integers(1, 70),
       seed=st.integers(0, 2**32 - 1), data=st.data())
def test_bfloat16_gram_equals_the_double_precision_product(J, K, width, seed, data):
    """The lower triangle of the rows from `first` on, over columns [start, stop), against
    numpy's float64 product of the decoded rows (zeros elsewhere)."""
    first = data.draw(st.integers(0, J - 1))
    start = data.draw(st.integers(0, K))
    stop = data.draw(st.integers(start, K))
    powers = (np.random.default_rng(seed).random((J, K)) * 1e3).astype(np.float32)
    spectrum_jit.to_bfloat16(powers.reshape(-1))
    rows = powers.reshape(-1).view(np.uint16)[: J * K].reshape(J, K).copy()
    decoded = (rows.astype(np.uint32) << 16).view(np.float32).astype(np.float64)
    part = decoded[:, start:stop]
    want = np.tril(part @ part.T)
    want[:first] = 0.0
    got = spectrum_jit.bfloat16_gram(rows, first, start, stop, width)
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=0)


@settings(max_examples=30, deadline=None)
@given(n1=st.integers(1, 14), n2=st.integers(1, 30), seed=st.integers(0, 2**32 - 1),
       data=st.data())
def test_split_power_in_row_ranges_equals_one_call(n1, n2, seed, data):
    """Disjoint ranges of row pairs, covering 0 .. n1 // 2, give the full call's powers."""
    rng = np.random.default_rng(seed)
    tables = four_step.plan(n1, n2)
    c = (rng.standard_normal((n1, n2)) + 1j * rng.standard_normal((n1, n2))).astype(np.complex64)
    whole = np.empty(n1 * n2 + 1, dtype=np.float32)
    spectrum_jit.split_power(c, tables.rows, tables.cols, whole)
    pairs = n1 // 2 + 1
    cuts = sorted(data.draw(st.lists(st.integers(0, pairs), max_size=4)))
    edges = [0, *cuts, pairs]
    parts = np.full(n1 * n2 + 1, np.nan, dtype=np.float32)
    for lo, hi in zip(edges[:-1], edges[1:]):
        spectrum_jit.split_power(c, tables.rows, tables.cols, parts, lo, hi)
    assert np.array_equal(parts, whole)


@needs_numba
@settings(max_examples=20, deadline=None)
@given(J=st.integers(1, 6), K=st.integers(1, 200), width=st.integers(1, 40),
       seed=st.integers(0, 2**32 - 1))
def test_compiled_bfloat16_loops_equal_their_plain_functions(J, K, width, seed):
    """to_bfloat16 and scale_to_float32 bit for bit; the bfloat16 Gram to double rounding."""
    rng = np.random.default_rng(seed)
    values = (rng.random(J * K) * 10.0).astype(np.float32)
    a, b = values.copy(), values.copy()
    spectrum_jit.to_bfloat16(a)
    spectrum_jit.to_bfloat16.py_func(b)
    assert np.array_equal(a, b)
    rows = a.view(np.uint16)[: J * K].reshape(J, K).copy()
    np.testing.assert_allclose(spectrum_jit.bfloat16_gram(rows, 0, 0, K, width),
                               spectrum_jit.bfloat16_gram.py_func(rows, 0, 0, K, width),
                               rtol=1e-13, atol=0)
    buf = np.zeros(2 * K + 4, dtype=np.float32)
    buf.view(np.float64)[:K] = rng.standard_normal(K)
    other = buf.copy()
    spectrum_jit.scale_to_float32(buf, K, 0.37)
    spectrum_jit.scale_to_float32.py_func(other, K, 0.37)
    assert np.array_equal(buf, other)
