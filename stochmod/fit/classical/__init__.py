"""The classical pipelines: readings of the Allan variance, PSD, autocorrelation and AR fits
turned into models through the registry, and their comparison with GMWM fits.

This package sits above :mod:`stochmod.empirical` (which returns coefficients) and
:mod:`stochmod.fit` (whose weighting :func:`compare_models` uses); see docs/architecture.md.
"""

from stochmod.fit.classical import build, pipelines
from stochmod.fit.classical.build import (
    BIAS_OPTIONS,
    acf_model,
    allan_model,
    ar_model,
    family_for,
    model_from_coefficients,
    psd_reading_model,
    reading_model,
)
from stochmod.fit.classical.pipelines import (
    ACFGMModel,
    AVModel,
    AVWDModel,
    DenoisedARModel,
    ModelComparison,
    ModelScore,
    PSDModel,
    acf_gm_model,
    av_model,
    avwd_model,
    compare_models,
    denoised_ar_model,
    psd_model,
)

__all__ = [*build.__all__, *pipelines.__all__]
