"""The eq. 17 covariance's four-step power spectrum (:mod:`stochmod.empirical.four_step`): its
length rule against a brute-force search, its layout and index map against numpy's
double-precision real transform, and the covariance through it against the direct sum."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import fft
from test_wv_covariance import direct_eq17  # eq. 17 by its definition, O(N^2)

from stochmod.empirical import four_step
from stochmod.empirical.wavelet_variance import wvar
from stochmod.empirical.wv_covariance import wv_covariance


def _is_7_smooth(v: int) -> bool:
    for p in (2, 3, 5, 7):
        while v % p == 0:
            v //= p
    return v == 1


def _brute_force_shape(n: int) -> tuple[int, int]:
    """Every split n1 <= n2 <= 2 n1 of 7-smooth factors, the least product >= n (ties: the
    larger n1), by exhaustive search."""
    best = None
    for n1 in range(1, 2 * math.isqrt(n) + 2):
        if not _is_7_smooth(n1):
            continue
        for n2 in range(max(n1, -(-n // n1)), 2 * n1 + 1):
            if _is_7_smooth(n2):
                key = (n1 * n2, -n1)
                if best is None or key < best[0]:
                    best = (key, (n1, n2))
                break  # the least n2 for this n1
    return best[1]


@settings(max_examples=60, deadline=None)
@given(n=st.integers(four_step.FOUR_STEP_MIN, 1 << 22))
def test_transform_shape_is_the_least_smooth_balanced_split(n):
    assert four_step.transform_shape(n) == _brute_force_shape(n)


def test_transform_shape_of_short_series_and_round_sizes():
    assert four_step.transform_shape(777) == (1, fft.next_fast_len(777))
    assert four_step.transform_shape(2) == (1, 2)
    assert four_step.transform_shape(1 << 20) == (1024, 1024)  # the fleet's files: no padding
    assert four_step.transform_shape(2_000_000) == (1250, 1600)  # the benches' signal
    n1, n2 = four_step.transform_shape((1 << 20) + 1)
    assert n1 * n2 == 1_049_760  # 972 x 1080, 0.11 % padding


def _power_in_layout(x: np.ndarray, n1: int, n2: int) -> np.ndarray:
    """numpy's double-precision |rfft(x)|^2 reordered as the four-step layout:
    out[k1 n2 + k2] = P[k1 + n1 k2], out[H] = P[H] (Nyquist)."""
    exact = np.abs(np.fft.rfft(x.astype(np.float64))) ** 2
    k = (np.arange(n1)[:, None] + n1 * np.arange(n2)[None, :]).ravel()
    return np.append(exact[k], exact[-1])


@settings(max_examples=60, deadline=None)
@given(n1=st.integers(1, 24), n2=st.integers(1, 3 * four_step.BLOCK + 5),
       seed=st.integers(0, 2**32 - 1), exponent=st.integers(-30, 30))
def test_layout_power_equals_the_real_transform(n1, n2, seed, exponent):
    """Every (n1, n2), odd and even, tiny, and with n2 not a multiple of the block of columns:
    the four-step powers equal numpy's double-precision ones at the mapped frequencies, within
    float32 rounding, in any unit."""
    x = (np.random.default_rng(seed).standard_normal(2 * n1 * n2) * 2.0**exponent).astype(
        np.float32)
    exact = _power_in_layout(x, n1, n2)
    out = np.full(n1 * n2 + 1, np.nan, dtype=np.float32)
    four_step.power_spectrum(x.copy(), four_step.plan(n1, n2), out)
    assert np.max(np.abs(out - exact)) <= 1e-5 * np.max(exact)


@pytest.mark.parametrize("shape", [(1, 1), (2, 1), (1, 2), (2, 2), (3, 3), (5, 7), (4, 65),
                                   (9, 130), (16, 64)])
def test_layout_power_of_a_single_tone(shape):
    """A cosine at frequency f has all its power at f and N - f: the layout puts it at
    position k1 n2 + k2 of f = k1 + n1 k2 (closed form: (N/2)^2 A^2 with amplitude A)."""
    n1, n2 = shape
    h = n1 * n2
    for f in {1, h // 2, h - 1} - {0, h}:
        x = (3.0 * np.cos(np.pi * f * np.arange(2 * h) / h)).astype(np.float32)
        out = np.empty(h + 1, dtype=np.float32)
        four_step.power_spectrum(x, four_step.plan(n1, n2), out)
        where = (f % n1) * n2 + f // n1
        assert out[where] == pytest.approx((h * 3.0) ** 2, rel=1e-5)
        others = np.delete(out, where)
        assert np.max(others) <= 1e-5 * out[where]


@pytest.fixture
def short_four_step(monkeypatch):
    """The four-step layout from 24 points on and blocks of 8 columns, so that short signals
    (fast to check against the direct sum) take the long signals' path, with a last block
    that is not full."""
    monkeypatch.setattr(four_step, "FOUR_STEP_MIN", 24)
    monkeypatch.setattr(four_step, "BLOCK", 8)
    four_step.transform_shape.cache_clear()
    four_step.plan.cache_clear()
    yield
    four_step.transform_shape.cache_clear()
    four_step.plan.cache_clear()


@pytest.mark.parametrize("n", [777, 913, 1000])
def test_covariance_through_the_layout_equals_the_direct_sum(short_four_step, n):
    """Odd and even lengths and n1, H = n1 n2 padded or not, n2 over several blocks of 8
    columns, the last one partial or full (see the next test), serial and threaded: the
    direct eq. 17 sum, and the same digits for every thread count."""
    n1, n2 = four_step.transform_shape(n)
    assert n1 > 1 and n1 * n2 >= n
    x = np.random.default_rng(n).standard_t(4, size=n)
    V = wv_covariance(x, 6, workers=1)
    assert V == pytest.approx(direct_eq17(x, 6), rel=2e-5)
    assert np.array_equal(wv_covariance(x, 6, workers=2), V)


def test_short_layouts_pad_and_split_over_blocks(short_four_step):
    """The fixture's claims about the shapes used above."""
    assert four_step.transform_shape(777) == (28, 28)  # last block 4 of 8 columns
    assert four_step.transform_shape(913) == (27, 35)  # odd n1, last block 3 columns
    assert four_step.transform_shape(1000) == (25, 40)  # no padding, full blocks


@pytest.mark.parametrize("shape", [(6, 20), (7, 9), (12, 40)])
def test_threaded_transform_gives_the_serial_digits(monkeypatch, shape):
    """The first pass's blocks in runs on a pool and the second pass on scipy's threads: the
    same complex layout, bit for bit, as one thread (blocks of 8 columns: several runs, the
    last one partial)."""
    import concurrent.futures

    monkeypatch.setattr(four_step, "BLOCK", 8)
    tables = four_step.plan(*shape)
    x = np.random.default_rng(sum(shape)).standard_normal(2 * shape[0] * shape[1])
    serial = four_step.transform(x.astype(np.float32), tables).copy()
    for workers in (2, 3):
        with concurrent.futures.ThreadPoolExecutor(workers) as pool:
            threaded = four_step.transform(x.astype(np.float32), tables, pool, workers)
        assert np.array_equal(threaded, serial)


def _bfloat16_budget(n: int, group: int) -> int:
    """SPECTRA_BYTES that makes wv_covariance hold `group` bfloat16 level spectra of an
    n-sample signal (two rows of the slots are the landing rows of a float32 spectrum)."""
    n1, n2 = four_step.transform_shape(n)
    width = n1 * n2 + 1
    return 2 * (width + width % 2) * (group + 2)


@pytest.mark.parametrize("group", [1, 2, 5, 6])
def test_bfloat16_spectra_are_within_their_bound_of_the_direct_sum(short_four_step, monkeypatch,
                                                                     group):
    """The long records' path, bfloat16 level spectra held `group` at a time (several passes,
    one pass with the last level alone, one pass with all): within 2^-7 (two bfloat16
    roundings of non-negative terms) of the direct double-precision eq. 17, clipped or not,
    the same digits for every thread count, and the same to float rounding for every group."""
    import importlib

    module = importlib.import_module("stochmod.empirical.wv_covariance")
    n, J = 913, 6
    x = np.random.default_rng(group).standard_t(4, size=n)
    exact = direct_eq17(x, J)
    reference = wv_covariance(x, J, workers=1)  # float32 spectra
    bounds = 2.0 * np.sqrt(wvar(x, 1.0, levels=J).wv)
    clipped_reference = wv_covariance(x, J, clip=bounds, workers=1)
    seen = []
    original = module._bfloat16_gram

    def spy(*args, **kwargs):
        seen.append(args[4])
        return original(*args, **kwargs)

    monkeypatch.setattr(module, "_bfloat16_gram", spy)
    monkeypatch.setattr(module, "SPECTRA_BYTES", _bfloat16_budget(n, group))
    V = wv_covariance(x, J, workers=1)
    assert seen == [group]
    assert np.max(np.abs(V / exact - 1.0)) <= 2.0**-7 + 2e-5
    assert np.max(np.abs(V / reference - 1.0)) <= 2.0**-7 + 2e-5
    assert not np.array_equal(V, reference)  # the path taken is not the float32 one
    assert np.array_equal(V, V.T)
    for workers in (2, 3):
        assert np.array_equal(wv_covariance(x, J, workers=workers), V)
    monkeypatch.setattr(module, "SPECTRA_BYTES", _bfloat16_budget(n, 1))
    np.testing.assert_allclose(wv_covariance(x, J, workers=1), V, rtol=1e-12)
    monkeypatch.setattr(module, "SPECTRA_BYTES", _bfloat16_budget(n, group))
    clipped = wv_covariance(x, J, clip=bounds, workers=2)
    assert np.array_equal(clipped, wv_covariance(x, J, clip=bounds, workers=1))
    assert np.max(np.abs(clipped / clipped_reference - 1.0)) <= 2.0**-7 + 2e-5
