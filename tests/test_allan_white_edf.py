"""The exact EDF of the Allan variance family for i.i.d. white rate samples
(:func:`stochmod.empirical.allan.white_rate_edf`) and the intervals of ``avar`` built on it.

Truth: ``tr(A)^2 / tr(A^2)`` of the estimator's quadratic form in the rate samples, with A
built as an explicit matrix from the phase definition (``x_k = sum_{i<k} (y_i - mean y)``);
an O(m) integer sum of the filter's autocorrelation for long filters; the closed form
``M^2 / (1.5 M - 0.5)``; and a seeded 4000-run Monte Carlo of the interval coverage
(variances vectorised over the runs, checked against ``avar`` on the first 20).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from stochmod.core.errors import InputError
from stochmod.empirical.allan import KINDS, avar, greenhall_edf, white_rate_edf

_DIFF = {2: (1, -2, 1), 3: (-1, 3, -3, 1)}  # d-th difference of the phase


def _terms(n: int, m: int, kind: str) -> np.ndarray:
    """Rows of the terms as linear forms in the N rate samples, from the phase definition."""
    d, overlapping, modified = KINDS[kind]
    p = n + 1
    center = np.eye(n) - 1.0 / n  # y - mean y
    phase = np.tril(np.ones((p, n)), -1) @ center  # x_k = sum_{i<k} (y_i - mean y)
    diff = []
    for i in range(0, p - d * m, 1 if overlapping else m):
        r = np.zeros(p)
        for k, c in enumerate(_DIFF[d]):
            r[i + k * m] = c
        diff.append(r)
    rows = np.array(diff) @ phase
    if modified:  # sums of m consecutive differences
        rows = np.array([rows[j : j + m].sum(axis=0) for j in range(rows.shape[0] - m + 1)])
    return rows


def _brute_edf(n: int, m: int, kind: str, cov: np.ndarray | None = None) -> float:
    """2 E[v]^2 / Var[v] = tr(A S)^2 / tr((A S)^2) for rates of covariance S (identity)."""
    rows = _terms(n, m, kind)
    a = rows.T @ rows
    if cov is not None:
        a = a @ cov
    return float(np.trace(a) ** 2 / np.trace(a @ a))


def _largest_m(n: int, kind: str) -> int:
    """Largest m with at least one term."""
    d, _, modified = KINDS[kind]
    return n // (d + 1) if modified else n // d


@settings(max_examples=150, deadline=None)
@given(kind=st.sampled_from(sorted(KINDS)), n=st.integers(4, 90), frac=st.floats(0.0, 1.0))
@example(kind="overlapping", n=4, frac=0.0)  # m = 1 on the shortest signals
@example(kind="modified-hadamard", n=4, frac=1.0)  # m = 1, one term: edf = 1
@example(kind="overlapping", n=90, frac=1.0)  # m = 45, one term
@example(kind="non-overlapping-hadamard", n=90, frac=1.0)
@example(kind="modified", n=90, frac=1.0)
@example(kind="hadamard", n=90, frac=0.0)
def test_exact_edf_equals_the_explicit_quadratic_form(kind, n, frac):
    top = _largest_m(n, kind)
    m = 1 + round(frac * (top - 1))
    d, overlapping, modified = KINDS[kind]
    ours = white_rate_edf(d, m, n, overlapping=overlapping, modified=modified)
    assert ours == pytest.approx(_brute_edf(n, m, kind), rel=1e-10)


def _filter(m: int, kind: str) -> np.ndarray:
    """h with ``t_i = sum_k h_k y_{i s + k}``: (d-1)-th lag-m difference of m-sample sums."""
    d, _, modified = KINDS[kind]
    h = np.zeros(d * m, dtype=np.int64)
    for k in range(d):
        h[k * m : (k + 1) * m] = (-1) ** (d - 1 - k) * math.comb(d - 1, k)
    return np.convolve(h, np.ones(m, dtype=np.int64)) if modified else h


def _direct_edf(n: int, m: int, kind: str) -> float:
    """O(m) sum in integers over the filter's autocorrelation (np.correlate), every lag."""
    _, overlapping, _ = KINDS[kind]
    h = _filter(m, kind)
    r = [int(v) for v in np.correlate(h, h, "full")[h.size - 1 :]]
    stride = 1 if overlapping else m
    terms = (n - h.size) // stride + 1
    var = terms * r[0] ** 2 + 2 * sum(
        (terms - k) * r[k * stride] ** 2 for k in range(1, terms) if k * stride < h.size
    )
    return (terms * r[0]) ** 2 / var


@settings(max_examples=60, deadline=None)
@given(kind=st.sampled_from(sorted(KINDS)), m=st.integers(20, 400), extra=st.integers(0, 3000))
@example(kind="modified-hadamard", m=400, extra=0)
@example(kind="overlapping", m=33, extra=35)
def test_long_filters_equal_the_direct_sum(kind, m, extra):
    d, overlapping, modified = KINDS[kind]
    n = ((d + 1) * m if modified else d * m) + extra
    ours = white_rate_edf(d, m, n, overlapping=overlapping, modified=modified)
    assert ours == pytest.approx(_direct_edf(n, m, kind), rel=1e-12)


@pytest.mark.parametrize("n", [4, 1000, 10_000_001])
def test_allan_variance_at_m1_is_the_closed_form(n):
    terms = n - 1
    closed = terms**2 / (1.5 * terms - 0.5)
    for kind in ("overlapping", "non-overlapping", "modified"):
        d, overlapping, modified = KINDS[kind]
        got = white_rate_edf(d, 1, n, overlapping=overlapping, modified=modified)
        assert got == pytest.approx(closed, rel=1e-13)
    if n == 1000:
        assert round(closed, 1) == 666.2
        assert round(greenhall_edf(0, 2, 1, n + 1), 1) == 782.0


def test_non_overlapping_allan_variance_has_the_same_form_at_every_m():
    m = np.array([1, 2, 3, 7, 50, 333])
    terms = 1000 // m - 1
    np.testing.assert_allclose(white_rate_edf(2, m, 1000, overlapping=False),
                               terms**2 / (1.5 * terms - 0.5), rtol=1e-13)


@pytest.mark.parametrize("kind", ["overlapping", "non-overlapping", "hadamard", "modified"])
@pytest.mark.parametrize("m", [1, 2, 4])
def test_greenhall_white_edf_is_exact_for_a_phase_averaged_over_tau0(kind, m):
    # phase averaged over tau0: rate samples with a triangular window, correlation 1/4
    n = 60
    cov = np.eye(n) + 0.25 * (np.eye(n, k=1) + np.eye(n, k=-1))
    d, overlapping, modified = KINDS[kind]
    ref = greenhall_edf(0, d, m, n + 1, overlapping=overlapping, modified=modified)
    assert _brute_edf(n, m, kind, cov) == pytest.approx(ref, rel=1e-9)
    assert white_rate_edf(d, m, n, overlapping=overlapping, modified=modified) == pytest.approx(
        _brute_edf(n, m, kind), rel=1e-10)


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("n", [1000, 100_000])
def test_agrees_with_greenhall_where_it_takes_f_infinite(kind, n):
    d, overlapping, modified = KINDS[kind]
    m = np.unique(np.geomspace(100 // (d + 1) + 1, _largest_m(n, kind) // 2, 40).astype(int))
    ours = white_rate_edf(d, m, n, overlapping=overlapping, modified=modified)
    ref = greenhall_edf(0, d, m, n + 1, overlapping=overlapping, modified=modified)
    np.testing.assert_allclose(ours, ref, rtol=2.5e-3)


def test_avar_uses_the_exact_edf_for_white_noise_only():
    x = np.random.default_rng(5).standard_normal(3000)
    wn = avar(x, 2.0, taus="decade", kind="hadamard", noise="WN")
    np.testing.assert_allclose(wn.edf, white_rate_edf(3, wn.m, 3000), rtol=1e-14)
    auto = avar(x, 2.0, noise="auto")
    assert np.all(auto.noise == 0)
    np.testing.assert_allclose(auto.edf, white_rate_edf(2, auto.m, 3000), rtol=1e-14)
    old = avar(x, 2.0, noise="WN", white_edf="greenhall")
    np.testing.assert_allclose(old.edf, greenhall_edf(0, 2, old.m, 3001), rtol=1e-14)
    rw = avar(x, 2.0, kind="modified", noise="RW")
    np.testing.assert_allclose(rw.edf, greenhall_edf(-2, 2, rw.m, 3001, modified=True),
                               rtol=1e-14)
    with pytest.raises(InputError, match="white_edf"):
        avar(x, 2.0, white_edf="phase")
    with pytest.raises(InputError, match="d must be"):
        white_rate_edf(1, 1, 100)
    with pytest.raises(InputError, match="no term"):
        white_rate_edf(2, 51, 100)


# ----------------------------------------------------------------------------- coverage

_REPS, _N, _M = 4000, 1000, (1, 2, 4)


@pytest.fixture(scope="module")
def white_runs() -> np.ndarray:
    return np.random.default_rng(2026).standard_normal((_REPS, _N))


def _variances(runs: np.ndarray, m: int, kind: str) -> np.ndarray:
    """The variance of every run at m, vectorised over the runs: sum t_i^2 / (c_d m^2 M)."""
    d, overlapping, modified = KINDS[kind]
    h = _filter(m, kind).astype(float)
    t = np.lib.stride_tricks.sliding_window_view(runs, h.size, axis=1) @ h
    t = t if overlapping else t[:, ::m]
    return np.mean(t**2, axis=1) / (math.comb(2 * d - 2, d - 1) * m ** (4 if modified else 2))


def _coverage(runs: np.ndarray, kind: str, white_edf: str) -> np.ndarray:
    """Share of runs whose avar interval holds the true variance ``sum h^2 / (c_d m^2)``."""
    d, _, modified = KINDS[kind]
    taus = np.array(_M, dtype=float)
    first = [avar(y, 1.0, taus=taus, kind=kind, noise="WN", white_edf=white_edf)
             for y in runs[:20]]
    low, high = first[0].ci_low / first[0].avar, first[0].ci_high / first[0].avar
    cover = []
    for j, m in enumerate(_M):
        v = _variances(runs, m, kind)
        for i, res in enumerate(first):  # avar's variance and bounds scale as these
            assert res.avar[j] == pytest.approx(v[i], rel=1e-12)
            assert res.ci_low[j] == pytest.approx(low[j] * v[i], rel=1e-12)
            assert res.ci_high[j] == pytest.approx(high[j] * v[i], rel=1e-12)
        truth = np.sum(_filter(m, kind) ** 2) / (math.comb(2 * d - 2, d - 1)
                                                 * m ** (4 if modified else 2))
        cover.append(np.mean((low[j] * v <= truth) & (truth <= high[j] * v)))
    return np.array(cover)


@pytest.mark.parametrize("kind", ["overlapping", "non-overlapping", "hadamard", "modified"])
def test_white_noise_intervals_cover_at_the_shortest_taus(white_runs, kind):
    # 4000 runs: binomial standard deviation 0.34 % around 95 %
    cover = _coverage(white_runs, kind, "exact")
    assert np.all((cover >= 0.94) & (cover <= 0.96)), cover


def test_greenhall_white_edf_undercovers_rate_samples_at_m1(white_runs):
    cover = _coverage(white_runs, "overlapping", "greenhall")
    assert cover[0] < 0.935, cover
