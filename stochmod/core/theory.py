"""Generic theoretical wavelet variances: from an autocovariance, from a PSD, or by simulation.

These are the fallbacks of :class:`stochmod.core.process.Process` for families that do not declare
an analytic wavelet variance. Levels follow the project convention: at level ``j`` the Haar
filter has width ``2^j`` and averages ``m = 2^(j-1)`` samples per half.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np
from scipy import sparse

from stochmod.core.filters import filter_width, squared_gain

__all__ = [
    "haar_kernel",
    "wv_from_autocovariance",
    "wv_from_psd",
    "wv_covariance_from_psd",
]


def haar_kernel(m: int) -> np.ndarray:
    """Autocorrelation ``a(t) = sum_l h_l h_{l+t}`` of the Haar MODWT filter of half-width `m`, t = 0..2m-1.

    ``a(t) = (2m - 3t) / (4 m^2)`` for ``0 <= t <= m`` and ``-(2m - t) / (4 m^2)`` for
    ``m <= t < 2m``; the wavelet variance is ``a(0) g(0) + 2 sum_{t>0} a(t) g(t)``.
    """
    t = np.arange(2 * m, dtype=np.float64)
    a = np.where(t <= m, 2 * m - 3 * t, -(2 * m - t))
    return a / (4.0 * m * m)


def wv_from_autocovariance(acvf: Callable[[np.ndarray], np.ndarray], levels: int) -> np.ndarray:
    """Haar wavelet variance at levels 1..`levels` by the exact finite sum over the autocovariance.

    Parameters
    ----------
    acvf : callable
        ``acvf(lags) -> autocovariance`` at integer lags (in samples), unit^2.
    levels : int
        Number of levels J.

    Notes
    -----
    Exact, but the sum cancels when the autocovariance decays slowly compared with ``2^j``
    (the kernel sums to zero); families with slow dynamics should provide a closed form.
    """
    out = np.empty(levels)
    for j in range(1, levels + 1):
        m = 2 ** (j - 1)
        a = haar_kernel(m)
        g = np.asarray(acvf(np.arange(2 * m)), dtype=np.float64)
        out[j - 1] = a[0] * g[0] + 2.0 * np.dot(a[1:], g[1:])
    return out


_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(12)


def wv_from_psd(
    psd: Callable[[np.ndarray], np.ndarray],
    levels: int,
    freq: float,
    *,
    wavelet: str = "haar",
    breakpoints: Sequence[float] = (),
) -> np.ndarray:
    """Wavelet variance ``int |H_j(f)|^2 S(f) df`` (eq. 8 of Stebler et al.) by quadrature.

    Parameters
    ----------
    psd : callable
        Two-sided PSD of the sampled process, ``psd(f_hz) -> unit^2/Hz`` for f in (0, freq/2].
    levels : int
        Number of levels J.
    freq : float
        Sampling frequency, Hz.
    wavelet : str
        ``"haar"`` or any orthogonal pywt wavelet name.
    breakpoints : sequence of float
        Frequencies (Hz) where the PSD is not smooth (band edges); panels split there.

    Notes
    -----
    Composite 12-point Gauss-Legendre panels between the zeros ``k / 2^(j-1)`` of the filter
    gain, refined geometrically towards f = 0 so that PSDs singular at the origin
    (``1/f``, ``1/f^2``) are integrated accurately. Panels on which the PSD is not resolved
    (its Legendre coefficients at the 12 nodes have not decayed, e.g. the sharp peak of an
    AR(2) near the unit circle) are bisected until they are; relative accuracy about 1e-10.
    The cost is O(2^j) per level.
    """
    out = np.empty(levels)
    for j in range(1, levels + 1):
        edges = _panel_edges(j, wavelet, freq, breakpoints)
        out[j - 1] = 2.0 * _integrate_panels(psd, j, wavelet, freq, edges[:-1], edges[1:])
    return out


def wv_covariance_from_psd(
    psd: Callable[[np.ndarray], np.ndarray],
    n_coef: Sequence[int],
    freq: float,
    *,
    wavelet: str = "haar",
    breakpoints: Sequence[float] = (),
) -> np.ndarray:
    """Large-sample covariance of the unbiased empirical WVs of a Gaussian process with PSD `psd`.

    ``cov(v_j, v_k) = 2 / max(M_j, M_k) * int_{-1/2}^{1/2} |H_j(f)|^2 |H_k(f)|^2 S(f)^2 df``
    (f in cycles/sample, S per cycle/sample): the covariance of the sample means of the
    squared coefficients of two jointly stationary Gaussian series, whose cross-spectrum is
    ``H_j conj(H_k) S``, with the shorter series (M coefficients) nested in the longer one
    (Percival & Walden, 2000, Section 8.3, eq. 307 for j = k). Non-Gaussian components
    (quantization noise) add a fourth-cumulant term this formula leaves out.

    Haar: Gauss-Legendre panels on the lobes of the gains up to 16 lobes of each, and beyond
    them the gains' oscillating factors ``sin^4(pi m f)`` replaced by their averages over a
    lobe (3/8 for one; for the product of two, 35/128 at equal m, 7/64 at a ratio 2, 9/64
    beyond), where ``S^2 / sin^2(pi f)`` is smooth on the lobe's scale: relative accuracy
    about 1e-3, cost O(J^2) PSD evaluations of a few hundred points. Other wavelets: the
    adaptive quadrature of :func:`wv_from_psd` on every lobe, O(J 2^J).

    Parameters
    ----------
    psd : callable
        Two-sided PSD, ``psd(f_hz) -> unit^2/Hz`` for f in (0, freq/2]; may be singular at 0
        as ``1/f^2`` (random walk): the gains vanish as ``f^2`` each.
    n_coef : sequence of int
        Number of coefficients ``M_j`` of the estimator at levels 1..J.
    freq : float
        Sampling frequency, Hz.
    wavelet, breakpoints
        As for :func:`wv_from_psd`.

    Returns
    -------
    ndarray (J, J)
        Symmetric covariance, unit^4.
    """
    M = np.asarray(n_coef, dtype=np.float64)
    J = M.size
    out = np.empty((J, J))
    if wavelet == "haar":
        extra = tuple(b / freq for b in breakpoints if 0 < b / freq < 0.5)
        nodes, weights = _haar_covariance_plan(J, extra)
        s = np.asarray(psd(nodes * freq), dtype=np.float64) * freq  # per cycle/sample
        integrals = 2.0 * (weights @ (s * s))
        row = 0
        for k in range(1, J + 1):
            for j in range(1, k + 1):
                out[j - 1, k - 1] = out[k - 1, j - 1] = 2.0 * integrals[row] / max(M[j - 1], M[k - 1])
                row += 1
        return out
    for k in range(1, J + 1):
        edges = _panel_edges(k, wavelet, freq, breakpoints)  # the deeper level's lobes

        def weighted(f_hz: np.ndarray, k: int = k) -> np.ndarray:
            s = np.asarray(psd(f_hz), dtype=np.float64) * freq  # per cycle/sample
            return squared_gain(f_hz / freq, k, wavelet) * s * s / freq

        for j in range(1, k + 1):
            integral = 2.0 * _integrate_panels(weighted, j, wavelet, freq, edges[:-1], edges[1:])
            out[j - 1, k - 1] = out[k - 1, j - 1] = 2.0 * integral / max(M[j - 1], M[k - 1])
    return out


#: Lobes of a Haar gain integrated exactly before its oscillating factor is averaged.
_EXACT_LOBES = 16


def _gl_rule(edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of 12-point Gauss-Legendre on each panel between the sorted, distinct
    `edges` (cycles/sample): ``int fun ~ sum(weights * fun(nodes))``."""
    edges = np.unique(edges)
    a, b = edges[:-1], edges[1:]
    half = 0.5 * (b - a)
    x = (a + half)[:, None] + half[:, None] * _GL_NODES[None, :]
    return x.ravel(), (half[:, None] * _GL_WEIGHTS[None, :]).ravel()


def _haar_product_rule(mj: int, mk: int, breakpoints: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of ``int_0^{1/2} |H_j|^2 |H_k|^2 S^2 df ~ sum(weights * S^2(nodes))``
    for Haar half-widths ``mj <= mk`` (see :func:`wv_covariance_from_psd`): the gains, and
    their lobe averages beyond the exactly integrated lobes, are folded into the weights."""
    def sin2(x: np.ndarray) -> np.ndarray:
        return np.sin(np.pi * x) ** 2

    def gain(x: np.ndarray, m: int) -> np.ndarray:
        return squared_gain(x, m.bit_length(), "haar")

    ratio = mk // mj
    both = 35.0 / 128.0 if ratio == 1 else 7.0 / 64.0 if ratio == 2 else 9.0 / 64.0

    def octaves(lo: float, hi: float) -> np.ndarray:  # 4 panels per octave, then the breakpoints
        edges = lo * 2.0 ** (np.arange(0, 4 * np.log2(hi / lo) + 1) / 4.0)
        inside = [b for b in breakpoints if lo < b < hi]
        return np.concatenate([[lo], edges[edges < hi], inside, [hi]])

    f_k = min(_EXACT_LOBES / mk, 0.5)
    f_j = min(_EXACT_LOBES / mj, 0.5)
    near_zero = (0.5 / mk) * 2.0 ** -np.arange(0, 60)
    lobes_k = np.arange(0, _EXACT_LOBES + 1) / mk
    x, w = _gl_rule(np.concatenate([near_zero, lobes_k[lobes_k < f_k], [f_k],
                                    [b for b in breakpoints if b < f_k]]))
    nodes, weights = [x], [w * gain(x, mj) * gain(x, mk)]
    if f_k < f_j:  # k's gain by its lobe average 3/8 / (mk^2 sin^2)
        lobes_j = np.arange(0, _EXACT_LOBES + 1) / mj
        x, w = _gl_rule(np.concatenate([octaves(f_k, min(1.0 / mj, f_j)),
                                        lobes_j[(lobes_j > f_k) & (lobes_j < f_j)], [f_j]]))
        nodes.append(x)
        weights.append(w * gain(x, mj) * 0.375 / (mk * mk * sin2(x)))
    if f_j < 0.5:  # both gains by the average of their product
        x, w = _gl_rule(octaves(f_j, 0.5))
        nodes.append(x)
        weights.append(w * both / (mj * mj * mk * mk * sin2(x) ** 2))
    return np.concatenate(nodes), np.concatenate(weights)


@functools.lru_cache(maxsize=16)
def _haar_covariance_plan(levels: int, breakpoints: tuple[float, ...]) -> tuple[np.ndarray, sparse.csr_array]:
    """The quadrature of every Haar pair ``j <= k`` of levels 1..`levels` at once.

    Returns the distinct nodes (cycles/sample, shape (n,)) and a sparse (P, n) weight matrix,
    one row per pair in the order ``k = 1..J, j = 1..k``, so that the P integrals
    ``int_0^{1/2} |H_j|^2 |H_k|^2 S^2 df`` are ``weights @ S^2(nodes)``. Neither depends on
    the PSD: a model covariance evaluates its PSD once, at the n nodes, whatever its
    parameters (the plan is cached per number of levels and breakpoints, in cycles/sample).
    """
    rules = [_haar_product_rule(2 ** (j - 1), 2 ** (k - 1), breakpoints)
             for k in range(1, levels + 1) for j in range(1, k + 1)]
    nodes, column = np.unique(np.concatenate([x for x, _ in rules]), return_inverse=True)
    row = np.repeat(np.arange(len(rules)), [x.size for x, _ in rules])
    weights = sparse.csr_array((np.concatenate([w for _, w in rules]), (row, column.ravel())),
                               shape=(len(rules), nodes.size))
    nodes.flags.writeable = False
    return nodes, weights


def _panel_edges(level: int, wavelet: str, freq: float, breakpoints: Sequence[float]) -> np.ndarray:
    """Quadrature panel edges on [0, 1/2] (cycles/sample) for the level-`level` gain: no wider
    than one lobe of the gain (1/m for Haar, 1/(m L1/2) for longer filters), refined
    geometrically towards 0, split at the `breakpoints` (Hz)."""
    m = 2 ** (level - 1)
    per = m * max(1, filter_width(1, wavelet) // 2)
    edges = np.arange(0, per // 2 + 1) / per if per > 1 else np.array([0.0])
    near_zero = (1.0 / (2 * m)) * 2.0 ** -np.arange(0, 60)
    extra = np.asarray([b / freq for b in breakpoints if 0 < b / freq < 0.5])
    return np.unique(np.concatenate([edges, near_zero, extra, [0.5]]))


# PSD values at the 12 nodes -> coefficients of its Legendre series on the panel
_TO_LEGENDRE = np.linalg.inv(np.polynomial.legendre.legvander(_GL_NODES, _GL_NODES.size - 1))
_MAX_BISECTIONS = 40


def _integrate_panels(psd: Callable[[np.ndarray], np.ndarray], level: int, wavelet: str,
                      freq: float, a: np.ndarray, b: np.ndarray) -> float:
    """``int |H_j(f)|^2 S(f) freq df`` over the panels [a, b] (f in cycles/sample), bisecting
    the panels whose PSD is not resolved by the 12-point rule."""
    total = 0.0
    for _ in range(_MAX_BISECTIONS):
        half = 0.5 * (b - a)
        x = (a + half)[:, None] + half[:, None] * _GL_NODES[None, :]
        gain = squared_gain(x, level, wavelet)
        s = np.asarray(psd(x * freq), dtype=np.float64).reshape(x.shape)
        parts = half * ((gain * s * freq) @ _GL_WEIGHTS)
        # error bound of a panel: the size of the PSD's last Legendre terms times its weight
        tail = np.abs(s @ _TO_LEGENDRE[-2:].T).sum(axis=1)
        err = tail * 2.0 * half * freq * gain.max(axis=1)
        bad = (err > 1e-12 * abs(total + parts.sum())) & (b - a > 1e-12)
        total += float(parts[~bad].sum())
        if not bad.any():
            return total
        mid = a[bad] + half[bad]
        a, b = np.concatenate([a[bad], mid]), np.concatenate([mid, b[bad]])
    return total + float(parts[bad].sum())
