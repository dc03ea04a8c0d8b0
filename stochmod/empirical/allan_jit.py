"""Compiled pass of the overlapping Allan and Hadamard variances at any tau: the sum of the
squared lag-m phase differences from one cumulative sum.

For the phase ``c`` (``N + 1`` points) and the averaging factor ``m``,
:func:`difference_sumsq` returns ``sum_i (Delta^d_m c_i)^2`` over ``i = 0 .. N - d m``, the
numerator of the overlapping Allan (``d = 2``) or Hadamard (``d = 3``) variance (NIST SP 1065
eqs. 7 and 14; :mod:`stochmod.empirical.allan`). One loop reads the three or four shifted
views of the phase once and keeps the sum in registers; it indexes contiguous views of ``c``,
not ``c[i + m]``, so that LLVM vectorises it. The squares are summed in several partial sums
(``reassoc``). Compiled by :func:`stochmod.core.jit.compiled`; with
``STOCHMOD_DISABLE_JIT=1`` the same function runs as plain Python.
"""

from __future__ import annotations

import numpy as np

from stochmod.core.jit import compiled

__all__ = ["difference_sumsq"]


@compiled
def difference_sumsq(c: np.ndarray, m: int, d: int) -> float:  # pragma: no cover
    """Sum of the squared d-th lag-m differences of the phase `c` (float64, 1-D).

    Parameters
    ----------
    c : ndarray, shape (P,)
        The phase (a cumulative sum of the rate), any unit.
    m : int
        Lag, samples (``P - d m >= 1``).
    d : {2, 3}
        Order of the difference: 2 for the Allan variance, 3 for the Hadamard variance.

    Returns
    -------
    float
        ``sum_{i=0}^{P-d m-1} (Delta^d_m c_i)^2``, unit^2.
    """
    n_t = c.size - d * m
    c0 = c[:n_t]
    c1 = c[m : m + n_t]
    c2 = c[2 * m : 2 * m + n_t]
    total = 0.0
    if d == 2:
        for i in range(n_t):
            t = (c2[i] - c1[i]) - (c1[i] - c0[i])
            total += t * t
    else:
        c3 = c[3 * m : 3 * m + n_t]
        for i in range(n_t):
            u = (c2[i] - c1[i]) - (c1[i] - c0[i])  # second difference at i
            t = (((c3[i] - c2[i]) - c2[i]) + c1[i]) - u  # the one at i + m, minus u
            total += t * t
    return total
