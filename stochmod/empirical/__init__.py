"""Empirical quantities of a signal: wavelet variance (classical, robust, pooled, with its
covariance), Allan variance and its reading, PSD, autocorrelation, AR coefficients and
wavelet de-noising. Returns numbers and coefficients, never models.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.empirical.acf import acf, fit_gm_acf
    from stochmod.empirical.allan import AllanVariance, avar
    from stochmod.empirical.allan_reading import AllanReading, allan_reading
    from stochmod.empirical.ar_fit import ARFit, burg, fit_ar, yule_walker
    from stochmod.empirical.denoise import denoise
    from stochmod.empirical.pooled import PooledWaveletVariance, pooled_wvar
    from stochmod.empirical.psd import PSDReading, PowerSpectrum, psd, psd_reading
    from stochmod.empirical.wavelet_variance import WaveletVariance, wvar
    from stochmod.empirical.wv_covariance import wv_covariance

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.empirical.wavelet_variance": ("WaveletVariance", "wvar"),
    "stochmod.empirical.pooled": ("PooledWaveletVariance", "pooled_wvar"),
    "stochmod.empirical.wv_covariance": ("wv_covariance",),
    "stochmod.empirical.allan": ("AllanVariance", "avar"),
    "stochmod.empirical.allan_reading": ("AllanReading", "allan_reading"),
    "stochmod.empirical.psd": ("PowerSpectrum", "psd", "PSDReading", "psd_reading"),
    "stochmod.empirical.acf": ("acf", "fit_gm_acf"),
    "stochmod.empirical.ar_fit": ("ARFit", "burg", "yule_walker", "fit_ar"),
    "stochmod.empirical.denoise": ("denoise",),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
