"""Standard errors, t- and p-values and their table, shared by the ARMA and GARCH fit results."""

from __future__ import annotations

import numpy as np
from scipy import stats

from stochmod.core.tables import format_table

__all__ = ["EstimatesMixin"]


class EstimatesMixin:
    """For frozen result classes with ``params``, ``param_names``, ``cov_params`` and ``n``."""

    __slots__ = ()
    params: np.ndarray
    param_names: tuple[str, ...]
    cov_params: np.ndarray
    n: int

    @property
    def std_errors(self) -> np.ndarray:
        """Standard errors: square roots of the diagonal of the inverse information matrix."""
        return np.sqrt(np.maximum(np.diag(self.cov_params), 0.0))

    @property
    def tvalues(self) -> np.ndarray:
        """``estimate / standard error`` (the seed's Tables 1-2)."""
        return self.params / self.std_errors

    @property
    def pvalues(self) -> np.ndarray:
        """Two-sided p-values of the t-tests (Student, ``n - k`` degrees of freedom)."""
        return 2.0 * stats.t.sf(np.abs(self.tvalues), df=max(self.n - self.params.size, 1))

    def estimates_table(self, title: str) -> str:
        """Estimate, standard error, t-value and p-value per parameter."""
        rows = [[nm, v, se, t, pv] for nm, v, se, t, pv in
                zip(self.param_names, self.params, self.std_errors, self.tvalues, self.pvalues)]
        return format_table(["parameter", "estimate", "std error", "t-value", "p-value"], rows,
                            title=title, digits=4)
