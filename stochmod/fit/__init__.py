"""Estimation: the GMWM estimator, its inference, and model selection.

Modules, bottom first: ``weighting`` (covariances of the empirical WV), ``engine`` (the
least-squares problem of eq. 20, the multi-start search, canonical order, sandwich
covariance), ``results`` (``GMWMResult``), ``weightings`` (the weighting plugin point),
``indirect`` (eq. 29), ``criteria``, ``gmwm``, ``validation``, ``selection``; see
docs/architecture.md.
"""
