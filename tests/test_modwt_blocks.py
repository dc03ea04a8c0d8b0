"""The Haar pyramid's multi-level sweeps (several levels per pass over memory) across block
boundaries: the wavelet variances equal the mean square of the direct convolution."""

import numpy as np
import pytest

from stochmod.core import filters
from stochmod.empirical import modwt
from stochmod.empirical.wavelet_variance import wvar


@pytest.mark.parametrize("chunk, halo", [(64, 4), (256, 16), (1 << 16, 16)])
@pytest.mark.parametrize("n", [2, 3, 129, 1000, 5003])
def test_haar_sweeps_match_convolution_across_blocks(monkeypatch, chunk, halo, n):
    monkeypatch.setattr(modwt, "_CHUNK", chunk)
    monkeypatch.setattr(modwt, "_HALO", halo)
    rng = np.random.default_rng(n)
    x = rng.standard_normal(n) + 0.1 * np.cumsum(rng.standard_normal(n)) + 1e3
    levels = filters.max_level(n)
    res = wvar(x, 1.0, levels=levels)
    for j in range(1, levels + 1):
        direct = np.convolve(x, filters.modwt_filter(j), mode="valid")
        assert res.n_coef[j - 1] == direct.size
        assert res.wv[j - 1] == pytest.approx(np.mean(direct**2), rel=1e-10)


def test_sweeps_and_level_by_level_pyramid_agree_to_rounding(monkeypatch):
    """With and without a coefficient buffer (level by level): same sums, up to summation order."""
    monkeypatch.setattr(modwt, "_CHUNK", 128)
    x = np.random.default_rng(5).standard_normal(20_000).cumsum()
    swept = list(modwt.pyramid(x, 13, "haar"))
    stepped = list(modwt.pyramid(x, 13, "haar", np.empty(x.size)))
    assert [(j, m) for j, _, m in swept] == [(j, m) for j, _, m in stepped]
    np.testing.assert_allclose([s for _, s, _ in swept], [s for _, s, _ in stepped], rtol=1e-12)


def test_constant_and_tiny_signals():
    from stochmod.core.errors import InputError

    with pytest.raises(InputError, match="constant"):
        wvar(np.full(100, 3.0), 1.0)
    tiny = np.random.default_rng(1).standard_normal(100) * 1e-170  # squares underflow to 0
    assert wvar(tiny, 1.0).wv[0] == 0.0
