"""The Haar wavelet variance's compiled loops (:mod:`stochmod.empirical.haar_jit`): each agrees
with its own plain-Python function, the wavelet variances equal the direct convolution's, and
the robust estimator's one-pass Haar levels equal the M-scale of the coefficients."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stochmod.core import filters, jit
from stochmod.empirical import haar_jit, modwt
from stochmod.empirical.robust_wv import m_scale, robust_wvar, scale_rho
from stochmod.empirical.wavelet_variance import wvar

needs_numba = pytest.mark.skipif(not jit.AVAILABLE, reason="STOCHMOD_DISABLE_JIT is set")


def _signal(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n) + 0.05 * np.cumsum(rng.standard_normal(n)) + 1e3


@pytest.mark.parametrize("chunk, halo, n", [(64, 4, 5003), (256, 16, 2**13 + 7)])
def test_classical_sweeps_match_convolution(monkeypatch, chunk, halo, n):
    """Small blocks, so that sweeps, halos and tails are all exercised."""
    monkeypatch.setattr(modwt, "_CHUNK", chunk)
    monkeypatch.setattr(modwt, "_HALO", halo)
    x = _signal(n, n)
    levels = filters.max_level(n)
    res = wvar(x, 1.0, levels=levels)
    for j in range(1, levels + 1):
        direct = np.convolve(x, filters.modwt_filter(j), mode="valid")
        assert res.wv[j - 1] == pytest.approx(np.mean(direct**2), rel=1e-11)


@pytest.mark.parametrize("n", [2, 4097, 10_007])
def test_level_coefficients_match_convolution(n):
    """The pyramid with coefficients (eq. 17, the classical WV with intervals): every level's
    interior coefficients and their sum of squares equal the direct convolution's (the
    compiled level runs in place through blocks of 4096 samples: one, two and three here)."""
    x = _signal(n, n)
    buf = np.full(n, np.nan)
    levels = filters.max_level(n)
    seen = 0
    for j, sumsq, m in modwt.pyramid(x, levels, "haar", buf):
        direct = np.convolve(x, filters.modwt_filter(j), mode="valid")
        assert m == direct.size
        np.testing.assert_allclose(buf[:m], direct, rtol=1e-9, atol=1e-9)
        assert sumsq == pytest.approx(np.sum(direct**2), rel=1e-11)
        seen += 1
    assert seen == levels


def _contaminated(n: int, seed: int, share: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n) + np.cumsum(1e-2 * rng.standard_normal(n))
    x[rng.choice(n, size=int(share * n), replace=False)] += 30.0
    return x


@pytest.mark.parametrize("share", [0.001, 0.25])
def test_robust_one_pass_levels_equal_m_scale_of_the_coefficients(share):
    """wvar(robust) runs the M-scale inside the pyramid on unscaled differences; it must equal
    m_scale on the level's coefficients (float64 sums against m_scale's float32 ones, within
    the single-precision bound of test_robust_wv). A quarter
    of spikes puts more coefficients outside the core than the compiled loop records, which
    makes it compute the level again."""
    x = _contaminated(1 << 18, 4, share)
    chi = scale_rho(0.6)
    # the per-level estimator (the screening of isolated outliers would change the coefficients)
    res = robust_wvar(x, 1.0, levels=9, screen=False)
    for j in range(1, 10):
        est = m_scale(modwt.modwt_coefficients(x, j), chi)
        assert res.wv[j - 1] == pytest.approx(est.variance, rel=1e-6)
        assert res.contamination.share[j - 1] == pytest.approx(est.n_rejected / est_size(x, j),
                                                               abs=2.0 / est_size(x, j))


def est_size(x: np.ndarray, j: int) -> int:
    return x.size - 2**j + 1


@pytest.mark.parametrize("unit", [1e-7, 1e6])
def test_robust_wv_scales_with_the_unit(unit):
    """The estimate is a variance: x in another unit gives unit^2 times it. Before the power
    sums were normalised (power of two), u^5 left float32's range: at 1e-7 the estimate was
    ~10 % off and at 1e5 the scale equation 'had no root'."""
    x = _contaminated(1 << 18, 5, 0.001)
    ref = wvar(x, 1.0, robust=True)
    scaled = wvar(x * unit, 1.0, robust=True)
    np.testing.assert_allclose(scaled.wv / unit**2, ref.wv, rtol=1e-6)
    assert np.array_equal(scaled.contamination.share, ref.contamination.share)
    assert m_scale(modwt.modwt_coefficients(x * unit, 1), scale_rho(0.6)).variance == \
        pytest.approx(robust_wvar(x, 1.0, screen=False).wv[0] * unit**2, rel=1e-6)


@pytest.mark.parametrize("robust", [False, True])
def test_a_column_view_gives_the_digits_of_its_contiguous_copy(robust):
    """A column of a 2-D array (a strided view) and the same data contiguous give the same WV
    bit for bit, wherever the arrays and the kernels' buffers sit: the compiled sums' order
    must not follow the memory layout (a selection's column result must not depend on the
    other columns, nor on what the process allocated before)."""
    options = {"robust": True} if robust else {}
    first = None
    for _ in range(150):  # fresh arrays each time: the buffers land elsewhere on the heap
        table = np.random.default_rng(12).standard_normal((50_000, 3))
        table[::997, 1] += 40.0  # spikes: the robust pass's rare-coefficient branch runs too
        view = wvar(table[:, 1], 100.0, **options)
        copy = wvar(np.ascontiguousarray(table[:, 1]), 100.0, **options)
        first = view.wv if first is None else first
        np.testing.assert_array_equal(view.wv, first)
        np.testing.assert_array_equal(copy.wv, first)


def _rng_signal(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n) + 10.0


_PYRAMID_LOOPS = ("_level", "_sum_sq_diff", "_last_level", "_level_in_place", "_sweep_block")


def _pyramid_case(n: int, levels: int, k: int, fused: bool, chunk: int, seed: int):
    src = _rng_signal(seed, n)
    levels = min(levels, filters.max_level(n))
    parted = min(k + fused, levels)  # the sweep that fixes the digits: k or k + 1 levels
    k = min(k, parted)
    bufs = np.zeros((2, min(chunk + 2**parted - 1, n)))
    return src, levels, k, parted, bufs


_CASES = {"n": st.integers(2, 600), "levels": st.integers(1, 9), "k": st.integers(1, 4),
          "fused": st.booleans(), "chunk": st.integers(1, 40), "seed": st.integers(0, 2**32 - 1)}


@needs_numba
@settings(max_examples=40, deadline=None)
@given(**_CASES)
def test_compiled_pyramid_equals_its_plain_function(n, levels, k, fused, chunk, seed):
    """haar_pyramid_sums and the level loops it calls, compiled against plain Python: the same
    V values bit for bit, the sums of squares to rounding (reassociated partial sums)."""
    src, levels, k, parted, bufs = _pyramid_case(n, levels, k, fused, chunk, seed)
    v, totals = np.zeros(n), np.zeros(levels)
    haar_jit.haar_pyramid_sums(src, v, levels, k, parted, bufs, chunk, totals)
    with pytest.MonkeyPatch.context() as patch:  # the plain pyramid through the plain loops
        for name in _PYRAMID_LOOPS:
            patch.setattr(haar_jit, name, getattr(haar_jit, name).py_func)
        v_plain, totals_plain = np.zeros(n), np.zeros(levels)
        haar_jit.haar_pyramid_sums.py_func(src, v_plain, levels, k, parted, bufs.copy(), chunk,
                                           totals_plain)
    np.testing.assert_array_equal(v, v_plain)
    np.testing.assert_allclose(totals, totals_plain, rtol=1e-12, atol=0)


@settings(max_examples=40, deadline=None)
@given(**_CASES)
def test_pyramid_schedule_leaves_the_digits(n, levels, k, fused, chunk, seed):
    """The digits follow the pieces of a sweep of `parted` levels, not the schedule: a sweep
    of ``parted - 1`` levels, whose deeper levels follow each other through memory a few blocks
    apart, gives the totals and V values of a sweep of `parted` levels run level by level over
    the whole signal (every block of the sweep, then each deeper level from start to end),
    bit for bit."""
    src, levels, k, parted, bufs = _pyramid_case(n, levels, k, fused, chunk, seed)
    v, totals = np.zeros(n), np.zeros(levels)
    haar_jit.haar_pyramid_sums(src, v, levels, k, parted, bufs, chunk, totals)
    v_ref, ref = np.zeros(n), np.zeros(levels)
    end = n - (2**parted - 1)
    tail = (end - 1) // chunk * chunk
    for s in range(0, tail + 1, chunk):
        haar_jit._sweep_block(src, v_ref, n, parted, False, levels == parted, bufs, s,
                              end if s == tail else s + chunk, s == tail, ref)
    size = end
    for j in range(parted + 1, levels + 1):
        step = 2 ** (j - 1)
        size -= step
        for s in range(0, size, chunk):
            ref[j - 1] += haar_jit._level_in_place(v_ref[s:], min(chunk, size - s), step,
                                                   j < levels)
    np.testing.assert_array_equal(totals, ref)
    if levels > parted:  # V_{J-1}, the last one written (none when the sweep is the last)
        m = n - 2 ** (levels - 1) + 1
        np.testing.assert_array_equal(v[:m], v_ref[:m])


@needs_numba
@settings(max_examples=30, deadline=None)
@given(n=st.integers(2, 9000), step=st.integers(1, 64), update=st.booleans(),
       seed=st.integers(0, 2**32 - 1))
def test_compiled_level_coefficients_equal_their_plain_function(n, step, update, seed):
    """Across the loop's inner blocks of 4096 samples."""
    n_valid = n + step
    x = _rng_signal(seed, n_valid)
    out = []
    for kernel in (haar_jit.haar_level_coefficients, haar_jit.haar_level_coefficients.py_func):
        v, w = x.copy(), np.zeros(n_valid)
        total = kernel(v, n_valid, step, -0.25, update, w)
        out.append((v, w, total))
    np.testing.assert_array_equal(out[0][0], out[1][0])
    np.testing.assert_array_equal(out[0][1], out[1][1])
    assert out[0][2] == pytest.approx(out[1][2], rel=1e-12)


@needs_numba
@settings(max_examples=30, deadline=None)
@given(n=st.integers(2, 9000), step=st.integers(1, 64), cap=st.integers(0, 50),
       stride=st.integers(1, 300), core=st.floats(0.05, 20.0), in_place=st.booleans(),
       seed=st.integers(0, 2**32 - 1))
def test_compiled_power_sums_equal_their_plain_function(n, step, cap, stride, core, in_place,
                                                        seed):
    """The sums, the coefficients outside the core (more than `cap` of them too) and the next
    level's subsample; in place or into another array."""
    n_valid = n + step
    x = _rng_signal(seed, n_valid)
    m_next = max(n - 2 * step, 0)
    out = []
    for kernel in (haar_jit.haar_level_power_sums, haar_jit.haar_level_power_sums.py_func):
        src = x.copy()
        dst = src if in_place else np.zeros(n)
        sums, idx, big = np.zeros(6), np.zeros(cap, dtype=np.int64), np.zeros(cap)
        left, right = np.zeros((2, -(-m_next // stride)))
        nb = kernel(src, dst, n_valid, step, 0.5, core, sums, idx, big, stride, left, right)
        out.append((nb, dst[:n].copy(), idx, big, left, right, sums))
    (nb, *arrays, sums), (nb_plain, *plain, sums_plain) = out
    assert nb == nb_plain
    for got, want in zip(arrays, plain):
        np.testing.assert_array_equal(got, want)
    np.testing.assert_allclose(sums, sums_plain, rtol=1e-11, atol=0)
