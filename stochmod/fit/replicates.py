"""One model from several recordings of the same sensor model (replicates).

:func:`stochmod.gmwm` and :func:`stochmod.select` hand a list of 1-D signals here: the pooled
wavelet variance (:mod:`stochmod.empirical.pooled`: replicates' WVs weighted by their lengths, the
covariance propagated from each replicate's eq. 17 covariance with the deep levels decoupled)
is matched once, and the fit's inference uses the pooled covariance, so its intervals are about
``sqrt(K)`` narrower than one replicate's. The homogeneity test of the replicates is kept on the
result (``result.pooled.test``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from stochmod.core.checks import as_signal, check_freq
from stochmod.core.errors import InputError
from stochmod.fit.weighting import data_covariance
from stochmod.empirical.pooled import PooledWaveletVariance, pool_wv, replicate_levels
from stochmod.empirical.wavelet_variance import wvar

__all__ = ["is_replicates", "pooled_wv"]


def is_replicates(data: Any) -> bool:
    """True for a list or tuple of one-dimensional signals (replicates), False otherwise."""
    return (isinstance(data, (list, tuple)) and len(data) > 0
            and all(isinstance(d, np.ndarray) and d.ndim == 1 for d in data))


def pooled_wv(signals: Sequence[np.ndarray], freq: float, levels: int | None = None,
              wavelet: str = "haar") -> PooledWaveletVariance:
    """Pooled WV of the replicates with decoupled eq. 17 covariances (the fit layer's V); each
    replicate contributes the levels its length supports (:func:`replicate_levels`)."""
    if len(signals) < 2:
        raise InputError("a list of replicates needs at least two signals")
    freq = check_freq(freq)
    xs = [as_signal(s, name=f"replicate {k}", min_length=8) for k, s in enumerate(signals)]
    for k, x in enumerate(xs):
        if np.ptp(x) == 0:
            raise InputError(f"replicate {k} is constant: it has no noise to model")
    depths = replicate_levels([x.size for x in xs], levels, wavelet)
    wvs = [wvar(x, freq, wavelet=wavelet, levels=J) for x, J in zip(xs, depths)]
    return pool_wv(wvs, [data_covariance(x, emp, J) for x, emp, J in zip(xs, wvs, depths)])
