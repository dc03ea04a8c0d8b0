"""Estimation: the GMWM estimator, its inference, and model selection.

Modules, bottom first: ``weighting`` (covariances of the empirical WV), ``engine`` (the
least-squares problem of eq. 20, the multi-start search, canonical order, sandwich
covariance), ``results`` (``GMWMResult``), ``weightings`` (the weighting plugin point),
``indirect`` (eq. 29), ``bootstrap`` (parametric bootstrap intervals and J-test, the
identification diagnostic), ``criteria``, ``gmwm``, ``validation``, ``selection``; see
docs/architecture.md."""

from __future__ import annotations

from typing import TYPE_CHECKING

from stochmod.core.lazy import lazy_names

if TYPE_CHECKING:
    from stochmod.fit.arch_lm import ArchLMTest, arch_lm_test
    from stochmod.fit.arma import ArmaFit, fit_arma, select_arma
    from stochmod.fit.bootstrap import Bootstrap, Identification, bootstrap, identification
    from stochmod.fit.garch import GarchFit, fit_garch, select_garch
    from stochmod.fit.gmwm import GMWMResult, gmwm
    from stochmod.fit.selection import SelectionResult, candidate_lattice, select
    from stochmod.fit.triad import TriadChoice, triad_select
    from stochmod.fit.validation import ValidationBands, validate

#: Module of each public name, imported on first access.
_LAZY: dict[str, tuple[str, ...]] = {
    "stochmod.fit.gmwm": ("GMWMResult", "gmwm"),
    "stochmod.fit.bootstrap": ("Bootstrap", "Identification", "bootstrap", "identification"),
    "stochmod.fit.selection": ("SelectionResult", "select", "candidate_lattice"),
    "stochmod.fit.validation": ("ValidationBands", "validate"),
    "stochmod.fit.triad": ("TriadChoice", "triad_select"),
    "stochmod.fit.arma": ("ArmaFit", "fit_arma", "select_arma"),
    "stochmod.fit.garch": ("GarchFit", "fit_garch", "select_garch"),
    "stochmod.fit.arch_lm": ("ArchLMTest", "arch_lm_test"),
}

__all__, __getattr__, __dir__ = lazy_names(__name__, _LAZY)
