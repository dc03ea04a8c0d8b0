"""Where the robust wavelet variance found outliers: the diagnostic a robust
:class:`~stochmod.empirical.wv_classical.WaveletVariance` carries
(:mod:`stochmod.empirical.robust_wv`)."""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np

from stochmod.core.fields import array_field
from stochmod.core.tables import format_number, format_table

__all__ = ["Contamination"]


def _arrays_equal(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


@attrs.frozen
class Contamination:
    """Where the robust wavelet variance found outliers.

    Attributes
    ----------
    levels : ndarray of int, shape (J,)
    tau : ndarray, shape (J,)
        Averaging times, s.
    share : ndarray, shape (J,)
        Fraction of the level's coefficients beyond ``c`` robust standard deviations (no
        weight for the biweight, clipped for Huber).
    expected_share : float
        The same fraction for Gaussian coefficients, ``P(|Z| > c)``.
    worst_time : tuple of ndarray
        Per level, the centre times (s from the first sample) of the filter windows of the
        largest coefficients beyond ``c / sqrt(2)``, largest first (at most 5).
    worst_score : tuple of ndarray
        Their size in robust standard deviations.
    classical_levels : tuple of int
        Levels where the scale equation had no root (too few effectively independent
        coefficients, typically the deepest of a random walk): the classical mean of squares
        stands there, with the classical variance (``kappa_j = 1``).
    replaced_time : ndarray
        Times (s from the first sample) of the samples replaced as isolated outliers before
        the decomposition (:func:`~stochmod.empirical.robust_wv.robust_wvar`'s screening).
        When there are some, level 1's share and worst positions are those of the record as
        given (the level-1 Haar coefficients, where they were found); the other levels
        describe the screened record.
    """

    levels: np.ndarray = array_field()
    tau: np.ndarray = array_field()
    share: np.ndarray = array_field()
    expected_share: float
    worst_time: tuple[np.ndarray, ...] = attrs.field(eq=attrs.cmp_using(eq=_arrays_equal))
    worst_score: tuple[np.ndarray, ...] = attrs.field(eq=attrs.cmp_using(eq=_arrays_equal))
    classical_levels: tuple[int, ...] = ()
    replaced_time: np.ndarray = attrs.field(factory=lambda: np.empty(0),
                                            eq=attrs.cmp_using(eq=np.array_equal))

    def summary(self) -> str:
        """Table of the share rejected per level against the Gaussian share, and the worst times."""
        rows = []
        for j, t, s, times, scores in zip(self.levels, self.tau, self.share, self.worst_time,
                                          self.worst_score):
            worst = ", ".join(f"{format_number(a, 5)} s ({b:.0f} sd)" for a, b in
                              zip(times[:3], scores[:3])) or "-"
            if int(j) in self.classical_levels:
                worst = "no root: classical estimate"
            rows.append((int(j), t, 100.0 * s, worst))
        title = (f"Contamination: share of coefficients beyond c (Gaussian: "
                 f"{format_number(100 * self.expected_share, 3)}%) and worst positions")
        table = format_table(["level", "tau [s]", "rejected %", "worst (time, size)"], rows,
                             title=title, digits=4)
        if self.replaced_time.size == 0:
            return table
        first = ", ".join(f"{format_number(t, 5)} s" for t in self.replaced_time[:5])
        more = ", ..." if self.replaced_time.size > 5 else ""
        return (f"{table}\nIsolated outliers replaced before the decomposition: "
                f"{self.replaced_time.size} samples ({first}{more})")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of every field."""
        return {
            "levels": [int(j) for j in self.levels],
            "tau": [float(t) for t in self.tau],
            "share": [float(s) for s in self.share],
            "expected_share": float(self.expected_share),
            "worst_time": [[float(t) for t in a] for a in self.worst_time],
            "worst_score": [[float(t) for t in a] for a in self.worst_score],
            "classical_levels": [int(j) for j in self.classical_levels],
            "replaced_time": [float(t) for t in self.replaced_time],
        }
