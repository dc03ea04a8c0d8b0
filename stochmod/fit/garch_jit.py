"""Compiled GARCH(p, q) pass: variance, likelihood, score and information at once (eqs. 7-9).

The recursion of eq. 7 is sequential, so one pass runs it block by block (``_BLOCK`` samples,
held in cache) and, per block, the derivative recursions and every sum: one read of ``x^2``
per evaluation, nothing written unless ``sigma^2`` is asked for. Compiled by
:func:`stochmod.core.jit.compiled`; with ``STOCHMOD_DISABLE_JIT=1`` the same functions run as
plain Python.

Recursions, with ``F = 1 / (1 - sum_j beta_j B^j)`` the causal filter of eq. 7 (pre-sample
``x^2`` and ``sigma^2`` equal to the backcast, pre-sample derivatives 0):

    D[a] = F drive[a],  drive_t = (1, x^2_{t-i}, sigma^2_{t-j})      (d sigma_t^2 / d theta_a)
    d^2 sigma_t^2 / d theta_a d beta_j = E_{t-j}[a] + sum_l [a = beta_l] E_{t-l}[beta_j]

with ``E[a] = F D[a]`` (the second derivatives obey the recursion driven by ``D_{t-j}`` in the
``beta_j`` column, and F commutes with the lag), so the observed information needs ``k`` more
filtered rows and the lagged sums ``sum_t u_t E_{t-j}[a]``, ``u_t = (1 - r_t) / sigma_t^2``.
"""

from __future__ import annotations

import math

import numpy as np

from stochmod.core import jit
from stochmod.core.jit import compiled

__all__ = ["garch_pass", "prepare", "variance_recursion"]

_BLOCK = 512  # samples per block: sigma^2, D and E rows of a block stay in L1/L2

#: ``contract`` also fuses multiply-adds; no flag that assumes finite values, so the check of
#: each variance stays exact.
_compile = compiled(fastmath=frozenset({"reassoc", "contract"}))


@_compile
def garch_pass(x2: np.ndarray, bc: float, omega: float, alpha: np.ndarray, beta: np.ndarray,
               level: int, s2_out: np.ndarray, score: np.ndarray, info: np.ndarray,
               observed: np.ndarray) -> float:  # pragma: no cover
    """One pass of eq. 7 over `x2`: the Gaussian log-likelihood (nats, returned) and, by
    `level`, its score and information matrices (into the arrays given).

    Parameters
    ----------
    x2 : ndarray, shape (T,)
        Squared data ``x_t^2`` (C-contiguous float64).
    bc : float
        Pre-sample value of ``x^2`` and ``sigma^2`` (the backcast).
    omega : float
        Constant of eq. 7.
    alpha, beta : ndarray, shapes (p,) and (q,)
        Coefficients on ``x^2_{t-i}`` and on ``sigma^2_{t-j}``.
    level : int
        0: the log-likelihood only; 1: also the score ``-1/2 sum u_t D_t`` into `score` (k,)
        and the expected information ``1/2 sum D_t D_t^T / sigma_t^4`` into `info` (k, k),
        ``k = 1 + p + q``; 2: also the observed information ``-d^2 loglik / d theta^2`` into
        `observed` (k, k).
    s2_out : ndarray, shape (T,) or (0,)
        Receives ``sigma_t^2`` unless empty.

    Returns ``-inf`` (the outputs then incomplete) as soon as a variance is not positive and
    finite.
    """
    n = x2.size
    p = alpha.size
    q = beta.size
    k = 1 + p + q
    lead = max(q, 1)  # columns before a block's first sample: the last q of the block before
    size = lead + _BLOCK
    write = s2_out.size > 0
    s2 = np.empty(size)
    s2[:lead] = bc
    d = np.zeros((k if level >= 1 else 1, size))
    e = np.zeros((k if level >= 2 and q > 0 else 1, size))
    u = np.empty(_BLOCK)
    w = np.empty(_BLOCK)
    c2 = np.empty(_BLOCK)
    sc = np.zeros(k)
    sum_inf = np.zeros((k, k))
    sum_obs = np.zeros((k, k))
    lagged = np.zeros((k, lead))  # sum_t u_t E_{t-1-j}[a]
    sum_log = 0.0
    sum_r = 0.0
    for start in range(0, n, _BLOCK):
        m = min(_BLOCK, n - start)
        for t in range(m):  # eq. 7, sequential
            v = omega
            for i in range(1, p + 1):
                v += alpha[i - 1] * (x2[start + t - i] if start + t >= i else bc)
            for j in range(q):
                v += beta[j] * s2[lead + t - 1 - j]
            if not (v > 0.0 and v < math.inf):
                return -math.inf
            s2[lead + t] = v
        t = 0
        while t + 8 <= m:  # one log per 8 variances (their product rounds by ~8 ulp)
            prod = 1.0
            for i in range(8):
                prod *= s2[lead + t + i]
            if 1e-300 < prod < 1e300:
                sum_log += math.log(prod)
            else:
                for i in range(8):
                    sum_log += math.log(s2[lead + t + i])
            t += 8
        for i in range(t, m):
            sum_log += math.log(s2[lead + i])
        for t in range(m):  # (at level 0 too: the sum then rounds as at the levels above)
            inv = 1.0 / s2[lead + t]
            r = x2[start + t] * inv
            sum_r += r
            u[t] = (1.0 - r) * inv
            w[t] = inv * inv
            c2[t] = 2.0 * r - 1.0
        if write:
            for t in range(m):
                s2_out[start + t] = s2[lead + t]
        if level >= 1:
            for t in range(m):  # D = F drive, the k rows interleaved (independent chains)
                tt = lead + t
                val = 1.0
                for j in range(q):
                    val += beta[j] * d[0, tt - 1 - j]
                d[0, tt] = val
                for a in range(1, p + 1):
                    val = x2[start + t - a] if start + t >= a else bc
                    for j in range(q):
                        val += beta[j] * d[a, tt - 1 - j]
                    d[a, tt] = val
                for a in range(p + 1, k):
                    val = s2[tt - (a - p)]
                    for j in range(q):
                        val += beta[j] * d[a, tt - 1 - j]
                    d[a, tt] = val
            for a in range(k):
                acc = 0.0
                for t in range(m):
                    acc += u[t] * d[a, lead + t]
                sc[a] += acc
                for b in range(a + 1):
                    acc_inf = 0.0
                    acc_obs = 0.0
                    for t in range(m):
                        prod = w[t] * d[a, lead + t] * d[b, lead + t]
                        acc_inf += prod
                        acc_obs += c2[t] * prod
                    sum_inf[a, b] += acc_inf
                    sum_obs[a, b] += acc_obs
        if level >= 2 and q > 0:
            for t in range(m):  # E = F D
                tt = lead + t
                for a in range(k):
                    val = d[a, tt]
                    for j in range(q):
                        val += beta[j] * e[a, tt - 1 - j]
                    e[a, tt] = val
            for a in range(k):
                for j in range(q):
                    acc = 0.0
                    for t in range(m):
                        acc += u[t] * e[a, lead + t - 1 - j]
                    lagged[a, j] += acc
        for j in range(lead):  # the block's last columns lead the next block
            s2[j] = s2[m + j]
            for a in range(d.shape[0]):
                d[a, j] = d[a, m + j]
            for a in range(e.shape[0]):
                e[a, j] = e[a, m + j]
    if level >= 1:
        for a in range(k):
            score[a] = -0.5 * sc[a]
            for b in range(a + 1):
                info[a, b] = info[b, a] = 0.5 * sum_inf[a, b]
                if level >= 2:
                    observed[a, b] = observed[b, a] = 0.5 * sum_obs[a, b]
    if level >= 2:
        for j in range(q):  # 1/2 sum_t u_t d^2 sigma_t^2 in the beta_j row and column
            col = 1 + p + j
            for a in range(col):
                h = lagged[a, j]
                if a > p:  # a = beta_l: + sum_t u_t E_{t-l}[beta_j]
                    h += lagged[col, a - 1 - p]
                observed[a, col] += 0.5 * h
                observed[col, a] += 0.5 * h
            observed[col, col] += lagged[col, j]
    return -0.5 * (n * math.log(2.0 * math.pi) + sum_log + sum_r)


@_compile
def variance_recursion(x2: np.ndarray, bc: float, omega: float, alpha: np.ndarray,
                       beta: np.ndarray, s2: np.ndarray) -> None:  # pragma: no cover
    """``s2[t] = sigma_t^2`` of eq. 7 for every t, whatever the values (a variance that
    overflows or is not positive stays in `s2`, and so do those after it); `x2`, `bc`,
    `omega`, `alpha` and `beta` as in :func:`garch_pass`, `s2` of the shape of `x2`."""
    p = alpha.size
    q = beta.size
    for t in range(x2.size):
        v = omega
        for i in range(1, p + 1):
            v += alpha[i - 1] * (x2[t - i] if t >= i else bc)
        for j in range(1, q + 1):
            v += beta[j - 1] * (s2[t - j] if t >= j else bc)
        s2[t] = v


def prepare() -> None:
    """Compile :func:`garch_pass` (or load it from numba's cache) in this process now, so that
    processes forked afterwards inherit the machine code instead of each loading it again;
    nothing when ``STOCHMOD_DISABLE_JIT`` is set."""
    if jit.AVAILABLE:
        k = 3
        garch_pass(np.ones(16), 1.0, 0.1, np.full(1, 0.1), np.full(1, 0.8), 2, np.empty(0),
                   np.zeros(k), np.zeros((k, k)), np.zeros((k, k)))
