"""Estimation: the GMWM estimator, its inference, and model selection."""
