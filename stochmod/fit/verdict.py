"""A verdict on a selected model: does it describe the data, and where does it not?

Two checks of a GMWM fit against its own data (Stebler et al. 2014, Sections III-B and V-D):

- the **J-test** (eq. 27): the model is rejected at level ``alpha`` when the test's p-value
  is below it;
- the **band**: at each level j the empirical WV should lie in the 95 % band of the WV
  estimator under the fitted model. The band is the chi-square interval of the model's WV
  ``nu_j(theta)`` with the equivalent degrees of freedom ``eta_j = 2 nu_j^2 / V_jj`` of the
  large-sample covariance V of the empirical WV under the model
  (:attr:`~stochmod.fit.results.GMWMResult.null_wv_covariance`, the J-test's V), so a
  model that holds keeps about 95 % of the levels inside; the levels outside are where it
  misfits.

On long real records every candidate of a lattice is often rejected (the J-test's power
grows with the record); the verdict then says that the model is the best of the lattice,
not a correct one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np
from scipy import special

from stochmod.core.checks import check_alpha
from stochmod.fit.results import GMWMResult

__all__ = ["Verdict", "verdict", "BAND_LEVEL"]

#: Coverage of the band each level's empirical WV is compared with.
BAND_LEVEL = 0.95


@attrs.frozen
class Verdict:
    """Accepted or rejected, and where the model misfits.

    Attributes
    ----------
    accepted : bool
        The J-test does not reject the model at :attr:`alpha` (False when it was not run).
    pvalue : float or None
        The J-test's p-value (None where it could not be computed: no degrees of freedom).
    alpha : float
        Level of the test.
    inside : float
        Share of the levels whose empirical WV lies in the model's 95 % band, in [0, 1].
    misfit_levels : tuple of int
        The levels j outside the band.
    misfit_tau : tuple of float
        Their averaging times, s.
    every_candidate_rejected : bool or None
        Whether the J-test rejected every candidate of the selection's lattice (None for a
        single fit): the model is then the best of the lattice, not a correct one.
    """

    accepted: bool
    pvalue: float | None
    alpha: float
    inside: float
    misfit_levels: tuple[int, ...]
    misfit_tau: tuple[float, ...]
    every_candidate_rejected: bool | None = None

    def summary(self) -> str:
        """One line: the verdict, the share of levels in the band, the levels that misfit."""
        if self.pvalue is None:
            head = "not tested (no degrees of freedom for the J-test)"
        else:
            word = "accepted" if self.accepted else "rejected"
            head = f"{word} by the J-test at {100 * self.alpha:g} % (p = {self.pvalue:.3g})"
        band = f"{100 * self.inside:.0f} % of the levels inside the model's 95 % band"
        misfit = ("" if not self.misfit_tau else
                  "; misfit at tau = " + ", ".join(f"{t:.3g}" for t in self.misfit_tau) + " s")
        tail = ("; every candidate was rejected: this is the best model of the lattice, not a "
                "correct one" if self.every_candidate_rejected else "")
        return f"{head}; {band}{misfit}{tail}"

    def to_dict(self) -> dict[str, Any]:
        return {"accepted": self.accepted, "jtest_pvalue": self.pvalue, "alpha": self.alpha,
                "inside_band": self.inside, "misfit_levels": list(self.misfit_levels),
                "misfit_tau": list(self.misfit_tau),
                "every_candidate_rejected": self.every_candidate_rejected}


def model_band(fit: GMWMResult, level: float = BAND_LEVEL) -> tuple[np.ndarray, np.ndarray]:
    """The `level` band of the empirical WV under the fitted model, levels 1..J (unit^2):
    ``nu_j eta_j / chi2_{eta_j}(1 - a/2)`` to ``nu_j eta_j / chi2_{eta_j}(a/2)`` with
    ``eta_j = 2 nu_j^2 / V_jj``."""
    a = 1.0 - level
    nu = fit.model.wv(fit.levels)
    var = np.diag(fit.null_wv_covariance)[: fit.levels]
    eta = 2.0 * nu * nu / var
    return (nu * eta / special.chdtri(eta, a / 2.0),
            nu * eta / special.chdtri(eta, 1.0 - a / 2.0))


def verdict(fit: GMWMResult, alpha: float = 0.05,
            candidates: Sequence[Any] | None = None) -> Verdict:
    """The verdict on `fit` (a GMWM fit with its empirical WV).

    Parameters
    ----------
    fit : GMWMResult
    alpha : float
        Level of the J-test, in (0, 1).
    candidates : sequence of RankingRow, optional
        The selection's ranking (:attr:`~stochmod.fit.selection.SelectionResult.ranking`), to
        say whether every candidate was rejected.

    Returns
    -------
    Verdict
    """
    alpha = check_alpha(alpha)
    jt = fit.jtest
    pvalue = None if jt is None else float(jt.pvalue)
    low, high = model_band(fit)
    wv = fit.empirical.wv[: fit.levels]
    outside = np.flatnonzero((wv < low) | (wv > high))
    rejected = None
    if candidates is not None:
        ps = [row.jtest_pvalue for row in candidates]
        rejected = bool(ps) and all(p is not None and p < alpha for p in ps)
    return Verdict(accepted=pvalue is not None and pvalue >= alpha, pvalue=pvalue, alpha=alpha,
                   inside=1.0 - outside.size / wv.size,
                   misfit_levels=tuple(int(j) for j in fit.empirical.levels[outside]),
                   misfit_tau=tuple(float(t) for t in fit.empirical.tau[outside]),
                   every_candidate_rejected=rejected)
