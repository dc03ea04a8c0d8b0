"""Empirical quantities of a signal: wavelet variance (classical, robust, pooled, with its covariance), Allan variance and its reading, PSD, autocorrelation, AR coefficients and wavelet de-noising. Returns numbers and coefficients, never models."""

__all__: list[str] = []
