"""The Haar wavelet variance's two implementations (issues 13 and 14): the pure-numpy path and
the optional compiled loops (numba, :mod:`stochmod.empirical.haar_jit`) give the same numbers,
and the robust estimator's one-pass Haar levels equal the M-scale of the coefficients."""

from __future__ import annotations

import numpy as np
import pytest

from stochmod.core import filters
from stochmod.core import jit
from stochmod.empirical import haar_jit, modwt
from stochmod.empirical.robust_wv import m_scale, scale_rho
from stochmod.empirical.wavelet_variance import wvar

PATHS = ["numpy", pytest.param("jit", marks=pytest.mark.skipif(
    not jit.AVAILABLE, reason="numba (the 'fast' extra) is not installed"))]


@pytest.fixture(params=PATHS)
def path(request, monkeypatch):
    monkeypatch.setattr(haar_jit, "AVAILABLE", request.param == "jit")
    return request.param


def _signal(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n) + 0.05 * np.cumsum(rng.standard_normal(n)) + 1e3


@pytest.mark.parametrize("chunk, halo, n", [(64, 4, 5003), (256, 16, 2**13 + 7)])
def test_classical_sweeps_match_convolution(path, monkeypatch, chunk, halo, n):
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
def test_level_coefficients_match_convolution(path, n):
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


@pytest.mark.skipif(not jit.AVAILABLE, reason="numba is not installed")
def test_compiled_and_numpy_classical_agree_to_rounding(monkeypatch):
    x = _signal(300_001, 3)
    jit = wvar(x, 10.0).wv
    monkeypatch.setattr(haar_jit, "AVAILABLE", False)
    np.testing.assert_allclose(jit, wvar(x, 10.0).wv, rtol=1e-13, atol=0)


def _contaminated(n: int, seed: int, share: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n) + np.cumsum(1e-2 * rng.standard_normal(n))
    x[rng.choice(n, size=int(share * n), replace=False)] += 30.0
    return x


@pytest.mark.parametrize("share", [0.001, 0.25])
def test_robust_one_pass_levels_equal_m_scale_of_the_coefficients(path, share):
    """wvar(robust) runs the M-scale inside the pyramid on unscaled differences; it must equal
    m_scale on the level's coefficients (numpy path: the same float32 sums bit for bit;
    compiled: float64 sums, within the single-precision bound of test_robust_wv). A quarter
    of spikes puts more coefficients outside the core than the compiled loop records, which
    makes it compute the level again."""
    x = _contaminated(1 << 18, 4, share)
    chi = scale_rho(0.6)
    res = wvar(x, 1.0, levels=9, robust=True)
    for j in range(1, 10):
        est = m_scale(modwt.modwt_coefficients(x, j), chi)
        if path == "numpy":
            assert res.wv[j - 1] == est.variance
        else:
            assert res.wv[j - 1] == pytest.approx(est.variance, rel=1e-6)
        assert res.contamination.share[j - 1] == pytest.approx(est.n_rejected / est_size(x, j),
                                                               abs=2.0 / est_size(x, j))


def est_size(x: np.ndarray, j: int) -> int:
    return x.size - 2**j + 1


@pytest.mark.parametrize("unit", [1e-7, 1e6])
def test_robust_wv_scales_with_the_unit(path, unit):
    """The estimate is a variance: x in another unit gives unit^2 times it. Before the power
    sums were normalised (power of two), u^5 left float32's range: at 1e-7 the estimate was
    ~10 % off and at 1e5 the scale equation 'had no root'."""
    x = _contaminated(1 << 18, 5, 0.001)
    ref = wvar(x, 1.0, robust=True)
    scaled = wvar(x * unit, 1.0, robust=True)
    np.testing.assert_allclose(scaled.wv / unit**2, ref.wv, rtol=1e-6)
    assert np.array_equal(scaled.contamination.share, ref.contamination.share)
    assert m_scale(modwt.modwt_coefficients(x * unit, 1), scale_rho(0.6)).variance == \
        pytest.approx(ref.wv[0] * unit**2, rel=1e-6)


@pytest.mark.parametrize("robust", [False, True])
def test_a_column_view_gives_the_digits_of_its_contiguous_copy(path, robust):
    """A column of a 2-D array (a strided view) and the same data contiguous give the same WV
    bit for bit: the compiled sums' order must not follow the memory layout (a selection's
    column result must not depend on the other columns)."""
    table = np.random.default_rng(12).standard_normal((50_000, 3))
    table[::997, 1] += 40.0  # spikes: the robust pass's rare-coefficient branch runs too
    options = {"robust": True} if robust else {}
    view = wvar(table[:, 1], 100.0, **options)
    copy = wvar(np.ascontiguousarray(table[:, 1]), 100.0, **options)
    np.testing.assert_array_equal(view.wv, copy.wv)
