"""Tests of stochmod.empirical.allan: the Allan variance family, tau grids, EDF and intervals.

Truth: allantools (oadev, adev, ohdev, hdev, mdev and ci.edf_greenhall) on the same data at
the same averaging factors; a brute-force double sum for the modified Hadamard variance
(allantools has none); the exact EDF ``tr(A)^2 / tr(A^2)`` of the estimator's quadratic form
for white phase noise; seeded white-noise and random-walk simulations (coverage of the
intervals, closed-form AV); Quinchia et al. (2013) eq. 15's worked example.
"""

from __future__ import annotations

import contextlib
import io
import math
import warnings

import allantools
import allantools.ci as aci
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stochmod.core.errors import InputError
from stochmod.empirical.allan import (
    KINDS,
    AllanVariance,
    avar,
    greenhall_edf,
    local_slopes,
    percent_error,
    tau_grid,
)

PEERS = {
    "overlapping": allantools.oadev,
    "non-overlapping": allantools.adev,
    "hadamard": allantools.ohdev,
    "non-overlapping-hadamard": allantools.hdev,
    "modified": allantools.mdev,
}


def _signal(n: int, seed: int = 0) -> np.ndarray:
    """White noise plus a random walk plus an offset: every tau has a distinct variance."""
    rng = np.random.default_rng(seed)
    return 3.0 + rng.standard_normal(n) + 0.02 * np.cumsum(rng.standard_normal(n))


def _peer(kind: str, x: np.ndarray, freq: float, taus: np.ndarray):
    taus_out, dev, _, ns = PEERS[kind](x, rate=freq, data_type="freq", taus=taus)
    return taus_out, dev**2, ns


# ----------------------------------------------------------------------------- vs allantools


@pytest.mark.parametrize("kind", sorted(PEERS))
@pytest.mark.parametrize("taus", ["octave", "decade", "explicit"])
@pytest.mark.parametrize("n", [1000, 1001, 4097])
def test_variances_equal_allantools(kind, taus, n):
    x = _signal(n, seed=n)
    freq = 20.0
    if taus == "explicit":
        grid = np.array([1, 3, 7, 8, 50, 101, 2 * n // 9]) / freq  # mixes powers of two
        res = avar(x, freq, taus=grid, kind=kind)
    else:
        res = avar(x, freq, taus=taus, kind=kind)
    t_peer, v_peer, ns = _peer(kind, x, freq, res.tau)
    np.testing.assert_array_equal(t_peer, res.tau)
    np.testing.assert_array_equal(ns, res.n_terms)
    np.testing.assert_allclose(res.avar, v_peer, rtol=1e-10, atol=0)


@pytest.mark.parametrize("kind", ["overlapping", "hadamard"])
def test_pyramid_across_chunks_equals_allantools(kind):
    # longer than the pyramid's block (2^17 samples): the chunk seams are exercised
    x = _signal(300_001, seed=5)
    res = avar(x, 100.0, taus="octave", kind=kind)
    _, v_peer, ns = _peer(kind, x, 100.0, res.tau)
    np.testing.assert_array_equal(ns, res.n_terms)
    np.testing.assert_allclose(res.avar, v_peer, rtol=1e-10, atol=0)


@pytest.mark.parametrize("kind", sorted(PEERS))
def test_all_taus_equal_allantools(kind):
    x = _signal(301, seed=3)
    res = avar(x, 1.0, taus="all", kind=kind)
    t_peer, v_peer, ns = _peer(kind, x, 1.0, res.tau)
    np.testing.assert_array_equal(t_peer, res.tau)
    assert res.m.tolist() == list(range(1, res.m[-1] + 1))
    np.testing.assert_allclose(res.avar, v_peer, rtol=1e-10, atol=0)


def _mhvar_brute(y: np.ndarray, freq: float, m: int) -> float:
    """Riley & Howe (2008) modified Hadamard variance as a literal double sum over the phase."""
    tau0 = 1.0 / freq
    x = np.concatenate([[0.0], np.cumsum(y - y.mean())]) * tau0
    big_n = x.size
    total = 0.0
    count = big_n - 4 * m + 1
    for j in range(count):
        inner = 0.0
        for i in range(j, j + m):
            inner += x[i + 3 * m] - 3 * x[i + 2 * m] + 3 * x[i + m] - x[i]
        total += inner * inner
    return total / (6.0 * m**4 * tau0**2 * count)


@pytest.mark.parametrize("n", [64, 97])
def test_modified_hadamard_equals_brute_force(n):
    y = _signal(n, seed=n)
    res = avar(y, 4.0, taus="all", kind="modified-hadamard")
    assert res.m[-1] == n // 4  # largest m with two terms: P - 4m + 1 >= 2
    expected = [_mhvar_brute(y, 4.0, int(m)) for m in res.m]
    np.testing.assert_allclose(res.avar, expected, rtol=1e-10)
    assert res.n_terms.tolist() == [n + 2 - 4 * int(m) for m in res.m]


def test_white_noise_allan_variance_closed_form():
    # seeded white noise, sigma^2 per sample: E[AV] = sigma^2 / m; mean of many estimates
    rng = np.random.default_rng(11)
    sigma2, freq = 4.0, 50.0
    fits = [avar(rng.standard_normal(4000) * 2.0, freq) for _ in range(200)]
    res, runs = fits[0], [f.avar for f in fits]
    mean = np.mean(runs, axis=0)
    se = np.std(runs, axis=0, ddof=1) / np.sqrt(len(runs))
    assert np.all(np.abs(mean - sigma2 / res.m) < 4 * se)
    # the IEEE coefficient: AV = N^2 / tau with N^2 = sigma^2 / freq
    np.testing.assert_allclose(mean * res.tau, sigma2 / freq, rtol=0.05)


# ----------------------------------------------------------------------------- tau grids


def test_octave_grid_reaches_largest_valid_m():
    for kind in KINDS:
        for n in (100, 257, 1000):
            m = tau_grid(n, 1.0, "octave", kind)
            assert m.tolist() == [2**k for k in range(m.size)]
            res = avar(_signal(n), 1.0, taus=m, kind=kind)
            assert np.all(res.n_terms >= 2)
            with pytest.raises(InputError, match="outside the valid range"):
                avar(_signal(n), 1.0, taus=[2.0 * m[-1]], kind=kind)


def test_decade_grid_dense_and_deduplicated():
    m = tau_grid(100_000, 100.0, "decade", points_per_decade=20)
    assert np.all(np.diff(m) > 0) and m[0] == 1
    expected = np.unique(np.round(10.0 ** (np.arange(0, 200) / 20)).astype(int))
    np.testing.assert_array_equal(m, expected[expected <= (100_000 - 1) // 2])
    np.testing.assert_array_equal(tau_grid(100_000, 100.0, "log", points_per_decade=20), m)


def test_tau_reduction_keeps_log_uniform_subset():
    full = tau_grid(10_000, 1.0, "all")
    red = tau_grid(10_000, 1.0, "all", tau_reduction=40)
    assert 20 <= red.size <= 40 and set(red) <= set(full)
    assert red[0] == 1 and red[-1] == full[-1]
    gaps = np.diff(np.log10(red[red >= 20]))  # beyond the integer-crowded start
    assert gaps.max() < 2.5 * np.log10(full[-1]) / 39


def test_explicit_taus_sorted_and_equal_to_m_over_freq():
    res = avar(_signal(500), 10.0, taus=[0.8, 0.1, 2.5, 0.1])
    np.testing.assert_array_equal(res.m, [1, 8, 25])
    np.testing.assert_allclose(res.tau, res.m / 10.0)


# ----------------------------------------------------------------------------- EDF


def _quadratic_form_rows(P: int, m: int, d: int, overlapping: bool, modified: bool) -> np.ndarray:
    coef = [(-1) ** (d - k) * math.comb(d, k) for k in range(d + 1)]
    rows = []
    if modified:
        for j in range(P - (d + 1) * m + 1):
            r = np.zeros(P)
            for i in range(j, j + m):
                for k, c in enumerate(coef):
                    r[i + k * m] += c
            rows.append(r)
    else:
        for i in range(0, P - d * m, 1 if overlapping else m):
            r = np.zeros(P)
            for k, c in enumerate(coef):
                r[i + k * m] += c
            rows.append(r)
    return np.array(rows)


@settings(max_examples=60, deadline=None)
@given(
    d=st.sampled_from([2, 3]),
    variant=st.sampled_from([(True, False), (False, False), (True, True)]),
    m=st.integers(1, 12),
    extra=st.integers(0, 60),
)
def test_edf_white_phase_is_exact(d, variant, m, extra):
    # white phase noise (alpha = 2): the phase is iid, the variance a quadratic form x'Ax,
    # whose exact EDF 2 E^2 / Var is tr(A)^2 / tr(A^2).
    overlapping, modified = variant
    P = (d + 1) * m + 1 + extra
    rows = _quadratic_form_rows(P, m, d, overlapping, modified)
    if rows.shape[0] < 2:
        return
    a = rows.T @ rows
    exact = np.trace(a) ** 2 / np.trace(a @ a)
    ours = greenhall_edf(2, d, m, P, overlapping=overlapping, modified=modified)
    assert ours == pytest.approx(exact, rel=1e-9)


def _peer_edf(alpha, d, m, n, overlapping, modified):
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        try:
            return aci.edf_greenhall(alpha=alpha, d=d, m=m, N=n, overlapping=overlapping,
                                     modified=modified)
        except (NotImplementedError, AssertionError):
            # allantools leaves alpha = 2 with K <= d open, and its Table 2 lacks alpha = -4
            return None


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(
    d=st.sampled_from([1, 2, 3]),
    alpha=st.integers(-4, 2),
    overlapping=st.booleans(),
    modified=st.booleans(),
    m=st.integers(1, 5000),
    n_over=st.integers(2, 200_000),
)
def test_edf_equals_allantools(d, alpha, overlapping, modified, m, n_over):
    if alpha + 2 * d <= 1:
        return
    n = (d + 1) * m + n_over  # enough phase points for at least two terms
    ref = _peer_edf(alpha, d, m, n, overlapping, modified)
    if ref is None or not np.isfinite(ref):
        return
    ours = greenhall_edf(alpha, d, m, n, overlapping=overlapping, modified=modified)
    assert ours == pytest.approx(ref, rel=1e-9)


def test_edf_rejects_invalid_noise():
    with pytest.raises(InputError, match="alpha"):
        greenhall_edf(-3, 2, 4, 1000)
    with pytest.raises(InputError, match="d must be"):
        greenhall_edf(0, 4, 4, 1000)


def test_edf_of_avar_matches_greenhall_for_its_noise():
    res = avar(_signal(3000), 1.0, taus="decade", kind="hadamard", noise="RW")
    assert np.all(res.noise == -2)
    expected = greenhall_edf(-2, 3, res.m, 3001, overlapping=True)
    np.testing.assert_allclose(res.edf, expected, rtol=1e-12)


# ----------------------------------------------------------------------------- intervals


def _coverage(kind: str, make, truth, noise, reps: int = 300, n: int = 1000) -> np.ndarray:
    rng = np.random.default_rng(2024)
    hits = 0
    for _ in range(reps):
        res = avar(make(rng, n), 1.0, taus="octave", kind=kind, noise=noise)
        t = truth(res.m.astype(float))
        hits = hits + ((res.ci_low <= t) & (t <= res.ci_high))
    return hits / reps


@pytest.mark.parametrize("kind", ["overlapping", "non-overlapping", "hadamard"])
@pytest.mark.parametrize("noise", ["WN", "auto"])
def test_edf_interval_coverage_on_white_noise(kind, noise):
    cover = _coverage(kind, lambda r, n: r.standard_normal(n), lambda m: 1.0 / m, noise)
    # 300 replications: binomial standard deviation 0.0126 around 0.95
    assert np.all(np.abs(cover - 0.95) < 0.05), cover
    assert abs(cover.mean() - 0.95) < 0.02


def test_edf_interval_coverage_on_random_walk():
    # discrete random walk, unit increments: AV(m) = (2 m^2 + 1) / (6 m) (exact)
    cover = _coverage("overlapping", lambda r, n: np.cumsum(r.standard_normal(n)),
                      lambda m: (2 * m**2 + 1) / (6 * m), "auto")
    assert np.all(np.abs(cover - 0.95) < 0.05), cover


def test_auto_noise_identifies_random_walk_and_white_noise():
    rng = np.random.default_rng(8)
    assert np.all(avar(rng.standard_normal(20_000), 1.0).noise == 0)
    assert np.all(avar(np.cumsum(rng.standard_normal(20_000)), 1.0).noise == -2)


def test_percent_error_seed_example_and_meaning():
    # Quinchia et al. (2013), text after eq. 15: N = 360000, clusters of 60000 -> ~32 %
    assert round(float(percent_error(360_000, 60_000))) == 32
    # eq. 15 is the relative spread of a deviation built from N/m - 1 independent squared
    # differences: sqrt(mean of nu squared standard normals), nu = 39
    rng = np.random.default_rng(3)
    devs = np.sqrt(np.mean(rng.standard_normal((20_000, 39)) ** 2, axis=1))
    assert np.std(devs) / np.mean(devs) == pytest.approx(
        float(percent_error(640, 16)) / 100.0, rel=0.03
    )
    assert np.isinf(percent_error(16, 16))


def test_simple_interval_is_eq15_band():
    x = _signal(2000)
    res = avar(x, 2.0, ci="simple", alpha=0.3173105078629141)  # z = 1
    delta = percent_error(2000, res.m) / 100.0
    np.testing.assert_allclose(np.sqrt(res.ci_high), res.adev * (1 + delta), rtol=1e-9)
    np.testing.assert_allclose(np.sqrt(res.ci_low), res.adev * np.maximum(1 - delta, 0), rtol=1e-9)
    none = avar(x, 2.0, ci="none")
    assert np.all(np.isnan(none.ci_low)) and np.all(np.isnan(none.ci_high))


# ----------------------------------------------------------------------------- slopes, output


@settings(max_examples=50, deadline=None)
@given(slope=st.floats(-2.5, 2.5), c=st.floats(1e-12, 1e6), width=st.floats(0.05, 0.6))
def test_local_slopes_of_a_power_law_are_exact(slope, c, width):
    tau = np.geomspace(0.01, 1000.0, 51)
    got = local_slopes(tau, c * tau**slope, half_width=width)
    np.testing.assert_allclose(got, slope, atol=1e-9)


def test_summary_and_dict_carry_the_numbers():
    res = avar(_signal(1000), 10.0, taus="octave")
    assert isinstance(res, AllanVariance)
    d = res.to_dict()
    np.testing.assert_allclose(d["avar"], res.avar)
    np.testing.assert_allclose(d["adev"], np.sqrt(res.avar))
    assert d["m"] == res.m.tolist() and d["kind"] == "overlapping" and d["n"] == 1000
    text = res.summary()
    assert "overlapping" in text and "N = 1000" in text
    assert f"{res.adev[3]:.6g}" in text


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"x": [1.0, 2.0]}, "at least 3"),
        ({"x": [1.0, np.nan, 2.0, 3.0, 4.0]}, "NaN"),
        ({"x": np.ones((10, 2))}, "one-dimensional"),
        ({"taus": [0.15]}, "multiples of the sample period"),
        ({"taus": [-1.0]}, "positive"),
        ({"taus": [1e6]}, "outside the valid range"),
        ({"taus": "weekly"}, "taus must be one of"),
        ({"kind": "total"}, "kind must be one of"),
        ({"ci": "bootstrap"}, "ci must be one of"),
        ({"alpha": 1.5}, "alpha"),
        ({"noise": "pink"}, "noise"),
        ({"noise": -3}, "not valid for this kind"),
        ({"freq": 0.0}, "freq"),
        ({"taus": "all", "tau_reduction": 1}, "tau_reduction"),
        ({"taus": "decade", "points_per_decade": 0}, "points_per_decade"),
    ],
)
def test_bad_input_raises(kwargs, match):
    args = {"x": _signal(200), "freq": 10.0} | kwargs
    with pytest.raises(InputError, match=match):
        avar(**args)
