"""One model from several recordings of the same sensor model (replicates).

:func:`stochmod.gmwm` and :func:`stochmod.select` hand a list of 1-D signals here: the pooled
wavelet variance (:mod:`stochmod.signal.pooled`: replicates' WVs weighted by their lengths, the
covariance propagated from each replicate's eq. 17 covariance with the deep levels decoupled)
is matched once, and the fit's inference uses the pooled covariance, so its intervals are about
``sqrt(K)`` narrower than one replicate's. The homogeneity test of the replicates is kept on the
result (``result.pooled.test``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from stochmod._validation import as_signal, check_freq, check_positive_int
from stochmod.errors import InputError
from stochmod.fit.weighting import chi2_variance, data_covariance, weighting_from_covariance
from stochmod.signal.modwt import default_levels
from stochmod.signal.pooled import PooledWaveletVariance, pool_wv
from stochmod.signal.wavelet_variance import wvar

__all__ = ["is_replicates", "pooled_wv", "gmwm_replicates", "select_replicates"]


def is_replicates(data: Any) -> bool:
    """True for a list or tuple of one-dimensional signals (replicates), False otherwise."""
    return (isinstance(data, (list, tuple)) and len(data) > 0
            and all(isinstance(d, np.ndarray) and d.ndim == 1 for d in data))


def pooled_wv(signals: Sequence[np.ndarray], freq: float, levels: int | None = None,
              wavelet: str = "haar") -> PooledWaveletVariance:
    """Pooled WV of the replicates with decoupled eq. 17 covariances (the fit layer's V)."""
    if len(signals) < 2:
        raise InputError("a list of replicates needs at least two signals")
    freq = check_freq(freq)
    xs = [as_signal(s, name=f"replicate {k}", min_length=8) for k, s in enumerate(signals)]
    for k, x in enumerate(xs):
        if np.ptp(x) == 0:
            raise InputError(f"replicate {k} is constant: it has no noise to model")
    J = min(default_levels(x.size, wavelet) for x in xs)
    if levels is not None:
        levels = check_positive_int(levels, name="levels")
        if levels > J:
            raise InputError(f"levels = {levels} but the shortest replicate allows {J}")
        J = levels
    wvs = [wvar(x, freq, wavelet=wavelet, levels=J) for x in xs]
    return pool_wv(wvs, [data_covariance(x, emp, J) for x, emp in zip(xs, wvs)])


def gmwm_replicates(signals: Sequence[np.ndarray], model: Any, freq: float | None, *,
                    weighting: Any = "diagonal", levels: int | None = None, wavelet: str = "haar",
                    **options: Any) -> Any:
    """:func:`stochmod.gmwm` on the pooled WV of replicates; ``result.pooled`` holds the pooling.

    ``weighting="optimal"`` uses the inverse pooled covariance; ``"diagonal"`` the chi-square
    variances of the pooled WV (its summed degrees of freedom); others as in :func:`gmwm`.
    """
    from stochmod.fit.gmwm import gmwm

    if freq is None:
        raise InputError("freq (Hz) is required when data is a list of signals")
    pooled = pooled_wv(signals, freq, levels, wavelet)
    omega = weighting_from_covariance(pooled.covariance) if weighting == "optimal" else weighting
    result = gmwm(pooled.wv, model, freq, weighting=omega, wavelet=wavelet, **options)
    result = result.with_data_covariance(pooled.covariance)
    if isinstance(weighting, str):
        result.weighting = weighting
    result.pooled = pooled
    return result


def select_replicates(signals: Sequence[np.ndarray], freq: float | None, *, candidates: Any,
                      families: Sequence[str], max_counts: Any, criterion: str, weighting: str,
                      executor: Any, progress: bool | None, rng: Any, levels: int | None,
                      names: Sequence[str] | None) -> Any:
    """:func:`stochmod.select` on the pooled WV of replicates (one selection, one column)."""
    from stochmod.fit import selection as sel

    if freq is None:
        raise InputError("freq (Hz) is required when x is a list of signals")
    pooled = pooled_wv(signals, freq, levels)
    emp, V = pooled.wv, pooled.covariance
    if weighting == "diagonal":
        omega = np.diag(1.0 / chi2_variance(emp.wv, emp.n_coef, emp.levels))
    elif weighting == "identity":
        omega = np.eye(emp.wv.size)
    else:
        omega = weighting_from_covariance(V)
    shared = [sel._Column(emp, omega, V)]
    crit = sel._criteria.get_criterion(criterion)
    if max_counts is None and candidates is None:
        max_counts = {"GM": 3} if "GM" in families else {}
    graph = sel.nested_graph(sel._as_candidates(candidates, families, max_counts))
    for name, node in graph.nodes.items():
        free = int(node["model"].free_mask().sum())
        if free == 0 or free > emp.wv.size:
            raise InputError(f"candidate {name} has {free} free parameters for {emp.wv.size} levels")
    with sel._executor(executor) as pool, sel._progress(graph.number_of_nodes(), progress, "select") as bar:
        fits = sel._run_fits(pool, graph, shared, emp.freq, weighting, sel._base_seed(rng), bar)[0]
    column = "pooled" if names is None else str(list(names)[0])
    result = sel._result(column, fits, graph, crit, criterion, weighting, shared[0])
    return result
