"""stochmod.core.geometric: Haar WV of a geometric autocovariance, against mpmath.

References, written independently of the code under test:
- the exact finite sum ``sum_{|t| < 2m} a_m(|t|) z^|t|`` at 50 digits for m up to 2^12, with
  the Haar kernel's piecewise-linear formula, itself checked against the autocorrelation of
  the filter taps ``(1, ..., 1, -1, ..., -1) / (2m)`` built here by brute force;
- the textbook closed form in z at 80 digits for deeper levels (it is validated against the
  finite sum below, and at 80 digits its cancellation, at most ~3 * 8 + 3 * 9 digits here,
  leaves > 25 digits).
"""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from stochmod.core.errors import InputError
from stochmod.core.geometric import (
    haar_kernel_value,
    haar_wv_geometric,
    haar_wv_geometric_dlog,
    haar_wv_geometric_parts,
    haar_wv_positive_rows,
    log1p_complex,
)

TOL = 1e-12  # the module promises a few ulps; the hard requirement is 1e-9


def mp_kernel(m: int) -> list:
    """a_m(t) = sum_l h_l h_{l+t}, t = 0..2m-1, from the Haar taps (brute force)."""
    h = [mp.mpf(1) / (2 * m)] * m + [-mp.mpf(1) / (2 * m)] * m
    return [mp.fsum(h[l] * h[l + t] for l in range(2 * m - t)) for t in range(2 * m)]


_KERNELS: dict[int, list] = {}


def mp_sum(z, m: int):
    """sum_{|t| < 2m} a_m(|t|) z^|t| at the current precision."""
    if m not in _KERNELS:  # the piecewise-linear formula, checked against mp_kernel below
        with mp.workdps(50):
            _KERNELS[m] = [mp.mpf(2 * m - 3 * t if t <= m else -(2 * m - t)) / (4 * m * m)
                           for t in range(2 * m)]
    a = _KERNELS[m]
    out, zt = a[0], mp.mpf(1)
    for t in range(1, 2 * m):
        zt *= z
        out += 2 * a[t] * zt
    return out


def mp_closed(z, m: int):
    zm = z**m
    return (m * (1 - z * z) - z * (1 - zm) * (3 - zm)) / (2 * m * m * (1 - z) ** 2)


def z_of(log_z: complex | float, sign: int = 1):
    return sign * mp.exp(mp.mpc(log_z) if isinstance(log_z, complex) else mp.mpf(log_z))


def reference(log_z, m: int, sign: int = 1):
    if m <= 2**12:
        with mp.workdps(50):
            return mp_sum(z_of(log_z, sign), m)
    with mp.workdps(80):
        return mp_closed(z_of(log_z, sign), m)


def rel_err(got, ref) -> float:
    return float(abs(mp.mpc(complex(got)) - ref) / abs(ref))


# ----------------------------------------------------------------- the reference itself
@pytest.mark.parametrize("m", [1, 2, 8, 64])
def test_mp_kernel_matches_the_stated_formula(m):
    # (2m - 3t)/(4 m^2) for t <= m, -(2m - t)/(4 m^2) beyond: the closed form in the docs
    a = mp_kernel(m)
    for t in range(2 * m):
        expect = mp.mpf(2 * m - 3 * t if t <= m else -(2 * m - t)) / (4 * m * m)
        assert abs(a[t] - expect) < mp.mpf(10) ** -40
    np.testing.assert_allclose(haar_kernel_value(np.arange(2 * m + 3), m),
                               [float(x) for x in a] + [0.0, 0.0, 0.0], rtol=0, atol=1e-17)


@pytest.mark.parametrize("log_z", [-1e-3, -0.7, -0.2 + 1.1j, -3e-4 - 2.9j])
@pytest.mark.parametrize("m", [1, 4, 256])
def test_closed_form_reference_equals_finite_sum(log_z, m):
    with mp.workdps(50):
        z = z_of(log_z)
        assert abs(mp_closed(z, m) - mp_sum(z, m)) < mp.mpf(10) ** -35 * abs(mp_sum(z, m))


# ----------------------------------------------------------------- W_m over the domain
@settings(max_examples=60, deadline=None)
@given(log_u=st.floats(-9.0, 1.7), j=st.integers(1, 31), sign=st.sampled_from([1, -1]))
@example(log_u=-8.0, j=1, sign=1)  # beta/freq = 1e-8: days of correlation time at 1 kHz
@example(log_u=-8.0, j=31, sign=1)
@example(log_u=math.log10(-math.log(0.99927)), j=1, sign=1)  # R gmwm off by 7e-7 here
@example(log_u=math.log10(-math.log(0.9999972)), j=2, sign=1)  # ... and by 10x here
@example(log_u=math.log10(-math.log(0.9999)), j=3, sign=-1)  # phi = -0.9999
@example(log_u=math.log10(-math.log(0.9999972)), j=30, sign=-1)
@example(log_u=1.7, j=1, sign=1)  # |z| = e^-50: the polynomial branch
def test_real_z_matches_mpmath(log_u, j, sign):
    u = 10.0**log_u
    m = 2 ** (j - 1)
    got = haar_wv_geometric(-u, m, sign=sign)
    assert np.isrealobj(got)
    assert rel_err(got, reference(-u, m, sign)) <= TOL


@settings(max_examples=60, deadline=None)
@given(log_eps=st.floats(-9.0, 0.5), theta=st.floats(-math.pi, math.pi), j=st.integers(1, 31))
@example(log_eps=-9.0, theta=1e-6, j=20)  # slow, slightly oscillating
@example(log_eps=-6.0, theta=2.5, j=31)
@example(log_eps=-5.0, theta=math.pi, j=2)  # on the negative real axis by convention
@example(log_eps=-9.0, theta=math.nextafter(math.pi, 0.0), j=3)  # W cancels to 1e-10
def test_complex_z_matches_mpmath(log_eps, theta, j):
    log_z = complex(-(10.0**log_eps), theta)
    m = 2 ** (j - 1)
    got = haar_wv_geometric(log_z, m)
    # relative to |W|, except near the zeros that W_m, a polynomial, has off the real axis
    # the documented convention: an imaginary part of exactly +-math.pi means the negative real axis
    on_axis = abs(theta) == math.pi
    ref = reference(-(10.0**log_eps), m, -1) if on_axis else reference(log_z, m)
    # and, where W itself cancels (near z = +-1 with |z| -> 1), a few ulps of the terms: their
    # absolute sum sum_t |a_m(t)| |z|^t is at most W_m(|z|) + |z|^ceil(2m/3) (a_m(t) < 0 only
    # from t = ceil(2m/3) on, where 4 sum |a_m(t)| <= 1); no double-precision evaluation does
    # better than rounding them (hypothesis found theta one ulp below pi, m = 2: 1e-17 absolute)
    eps = 10.0**log_eps
    with mp.workdps(50):
        w_abs = abs(reference(-eps, m))
        terms = w_abs + math.exp(-eps * math.ceil(2 * m / 3))
        scale = max(abs(ref), w_abs * 1e-3, terms * 1e-4)
    assert float(abs(mp.mpc(complex(got)) - ref) / scale) <= 1e-11


def test_negative_real_axis_is_exact():
    # log of a negative number: imaginary part exactly pi means z = -|z| (sign path, no cos(m pi))
    for m in (2, 2**20, 2**29):
        got = haar_wv_geometric(complex(math.log(0.9999), math.pi), m)
        assert np.isrealobj(got)
        assert rel_err(got, reference(math.log(0.9999), m, -1)) <= TOL


def test_zero_z_and_vectorisation():
    m = 2.0 ** np.arange(8)
    np.testing.assert_allclose(haar_wv_geometric(-np.inf, m), 1.0 / (2 * m), rtol=1e-15)
    grid = haar_wv_geometric(np.array([[-1e-3], [-2.0]]), m[None, :])
    assert grid.shape == (2, 8)
    for i, lz in enumerate((-1e-3, -2.0)):
        for k in range(8):
            assert rel_err(grid[i, k], reference(lz, int(m[k]))) <= TOL


# ----------------------------------------------------------------- derivative and parts
@settings(max_examples=40, deadline=None)
@given(log_u=st.floats(-8.0, 1.5), j=st.integers(1, 31), sign=st.sampled_from([1, -1]))
@example(log_u=-8.0, j=1, sign=1)
@example(log_u=-8.0, j=31, sign=1)
def test_dlog_matches_mpmath_derivative(log_u, j, sign):
    u = 10.0**log_u
    m = 2 ** (j - 1)
    got = float(haar_wv_geometric_dlog(-u, m, sign=sign))
    with mp.workdps(80):
        ref = mp.diff(lambda lz: mp_closed(sign * mp.exp(lz), m), mp.mpf(-u))
        # the derivative crosses zero at the maximum of W over u: compare on the scale W / u
        scale = abs(mp_closed(sign * mp.exp(mp.mpf(-u)), m)) / u
        assert float(abs(got - ref) / max(abs(ref), scale * 1e-3)) <= 1e-10


@settings(max_examples=40, deadline=None)
@given(log_u=st.floats(-9.0, 1.5), theta=st.sampled_from([0.0, 1e-4, 1.0, 3.0]),
       j=st.integers(1, 31), sign=st.sampled_from([1, -1]))
def test_parts_match_mpmath_and_sum_to_w(log_u, theta, j, sign):
    log_z = complex(-(10.0**log_u), theta) if theta else -(10.0**log_u)
    m = 2 ** (j - 1)
    lead, rest = haar_wv_geometric_parts(log_z, m, sign=sign)
    with mp.workdps(80):
        z = z_of(log_z, sign)
        ref_lead = (1 + z) / (2 * m * (1 - z))
        ref_rest = -z * (1 - z**m) * (3 - z**m) / (2 * m * m * (1 - z) ** 2)
        assert rel_err(lead, ref_lead) <= TOL
        assert rel_err(rest, ref_rest) <= 1e-11


def test_log1p_complex_keeps_the_real_part():
    for w in (1e-9 + 1e-7j, -1e-12 + 3e-6j, -5e-9 + 1e-4j, 0.3 - 0.2j):
        with mp.workdps(40):
            ref = mp.log1p(mp.mpc(w))
        got = log1p_complex(w)
        assert abs(got.real - float(ref.real)) <= 1e-15 * abs(float(ref.real))
        assert abs(got.imag - float(ref.imag)) <= 1e-15 * abs(float(ref.imag))


# ----------------------------------------------------------------- bad input
@pytest.mark.parametrize("log_z, m", [(0.1, 1), (0.0, 1), (-1.0, 0), (-1.0, 1.5), (float("nan"), 1),
                                      (-1.0, -2)])
def test_bad_input_raises(log_z, m):
    with pytest.raises(InputError):
        haar_wv_geometric(log_z, m)


def test_bad_sign_raises():
    with pytest.raises(InputError, match="sign"):
        haar_wv_geometric(-1.0, 1, sign=2)


# ----------------------------------------------------------------- the Gauss-Markov fast path
@settings(max_examples=40, deadline=None)
@given(log_u=st.floats(-10.0, 0.8), j=st.integers(1, 31))
@example(log_u=-10.0, j=31)  # the recursion's longest sum of the doubling terms
@example(log_u=-0.3, j=1)  # g(u) and sinh(u) - u from the direct forms
def test_positive_rows_match_mpmath_and_their_derivative(log_u, j):
    """The doubling recursion of g (haar_wv_positive_rows) keeps a few ulps at every level,
    and dW/du matches mpmath's derivative of the closed form."""
    u = 10.0**log_u
    w, dw = haar_wv_positive_rows(np.array([u]), 2.0 ** np.arange(j))
    m = 2 ** (j - 1)
    assert rel_err(w[0, -1], reference(-u, m)) <= 1e-15
    with mp.workdps(80):
        ref = -mp.diff(lambda lz: mp_closed(mp.exp(lz), m), mp.mpf(-u))
        scale = abs(mp_closed(mp.exp(mp.mpf(-u)), m)) / u
        assert float(abs(dw[0, -1] - ref) / max(abs(ref), scale * 1e-3)) <= 1e-10


def test_positive_rows_take_any_half_widths() -> None:
    """Some of 1, 2, 4, ... come from the full ladder; other integers from haar_wv_geometric."""
    u = np.array([3e-4, 0.2, 7.5])  # the last one: z < 1e-3, the polynomial
    w, dw = haar_wv_positive_rows(u, 2.0 ** np.arange(12))
    ws, dws = haar_wv_positive_rows(u, np.array([8.0, 2048.0, 1.0]))
    np.testing.assert_array_equal(ws, w[:, [3, 11, 0]])
    np.testing.assert_array_equal(dws, dw[:, [3, 11, 0]])
    wo, _ = haar_wv_positive_rows(u, np.array([3.0, 5.0]))
    for i in range(u.size):
        for k, m in enumerate((3, 5)):
            assert rel_err(wo[i, k], reference(-u[i], m)) <= TOL
    with pytest.raises(InputError, match="m must be positive"):
        haar_wv_positive_rows(u, np.array([0.0, 1.0]))
