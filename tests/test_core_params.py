"""Tests of stochmod.core.params: domains, their bijections with an unconstrained space, the
PACF <-> AR map and its stationarity, Jacobians and DomainError messages.

Truth: mpmath at 40 digits for the elementwise maps and their derivatives; numpy polynomial
roots for AR stationarity (an AR(p) is stationary iff every root of
1 - phi_1 z - ... - phi_p z^p lies outside the unit circle); the closed forms of the
Durbin-Levinson map for p = 1, 2 (phi_1 = r_1 (1 - r_2), phi_2 = r_2; Monahan 1984).
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from stochmod.core.errors import DomainError
from stochmod.core.params import DOMAINS, Parameter, ar_to_pacf, get_domain, pacf_to_ar

mp.mp.dps = 40

# domain -> (value strategy inside it, exact inverse map theta -> value with mpmath)
ELEMENTWISE = {
    "positive": (st.floats(-300, 300).map(lambda e: 10.0**e), mp.exp),
    "real": (st.floats(-1e12, 1e12), lambda t: t),
    "correlation": (st.floats(-0.999999, 0.999999), mp.tanh),
    "unit_interval": (st.floats(1e-9, 1 - 1e-9), lambda t: 1 / (1 + mp.exp(-t))),
}
PACF = st.floats(-0.99, 0.99)


def _reciprocal_roots(phi: np.ndarray) -> np.ndarray:
    """Moduli of the roots of z^p - phi_1 z^(p-1) - ... - phi_p, the reciprocals of the roots
    of 1 - phi_1 z - ... - phi_p z^p (monic, so numpy's companion matrix stays finite)."""
    return np.abs(np.roots(np.r_[1.0, -np.asarray(phi, dtype=float)]))


def _stationary_by_roots(phi: np.ndarray) -> bool:
    return bool(np.all(_reciprocal_roots(phi) < 1.0))


def _step_down_atol(r: list[float]) -> float:
    """The inverse (step-down) recursion divides by 1 - r_k^2 at each lag, so rounding of phi
    is amplified by about prod_k 1 / (1 - r_k^2) (intrinsic conditioning near the boundary),
    with p steps of rounding on top."""
    return 5e-14 * len(r) * float(np.prod(1.0 / (1.0 - np.square(r))))


def test_every_domain_is_tested() -> None:
    assert set(ELEMENTWISE) | {"stationary_ar"} == set(DOMAINS)


@pytest.mark.parametrize("name", sorted(ELEMENTWISE))
@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_elementwise_round_trip_and_inverse_map(name: str, data: st.DataObject) -> None:
    dom = get_domain(name)
    strategy, exact_inverse = ELEMENTWISE[name]
    value = data.draw(strategy)
    assert dom.contains(np.array(value))
    theta = float(dom.to_unconstrained(np.array(value)))
    assert np.isfinite(theta)
    back = float(dom.from_unconstrained(np.array(theta)))
    assert back == pytest.approx(value, rel=1e-12, abs=1e-300)
    # the inverse map is the stated function, evaluated exactly
    assert back == pytest.approx(float(exact_inverse(mp.mpf(theta))), rel=1e-13, abs=1e-300)


@pytest.mark.parametrize("name", sorted(ELEMENTWISE))
@settings(max_examples=100, deadline=None)
@given(theta=st.floats(-15, 15))
def test_elementwise_jacobian_is_the_exact_derivative(name: str, theta: float) -> None:
    dom = get_domain(name)
    exact = float(mp.diff(ELEMENTWISE[name][1], mp.mpf(theta)))
    J = dom.jacobian(np.array([theta]))
    assert J.shape == (1, 1)
    assert J[0, 0] == pytest.approx(exact, rel=1e-12, abs=1e-300)


@settings(max_examples=200, deadline=None)
@given(r=st.lists(PACF, min_size=1, max_size=8))
def test_pacf_to_ar_is_stationary_and_invertible(r: list[float]) -> None:
    phi = pacf_to_ar(np.array(r))
    assert phi.shape == (len(r),)
    assert _stationary_by_roots(phi)
    np.testing.assert_allclose(ar_to_pacf(phi), r, rtol=1e-9, atol=_step_down_atol(r))


@settings(max_examples=100, deadline=None)
@given(r1=PACF, r2=PACF)
def test_pacf_to_ar_closed_forms(r1: float, r2: float) -> None:
    np.testing.assert_allclose(pacf_to_ar(np.array([r1])), [r1], rtol=0)
    np.testing.assert_allclose(pacf_to_ar(np.array([r1, r2])), [r1 * (1 - r2), r2], rtol=1e-14, atol=1e-300)


@settings(max_examples=300, deadline=None)
@given(phi=st.lists(st.floats(-2.5, 2.5), min_size=1, max_size=5))
def test_stationary_ar_domain_agrees_with_polynomial_roots(phi: list[float]) -> None:
    assume(np.all(np.abs(_reciprocal_roots(np.array(phi)) - 1.0) > 1e-6))  # the boundary itself is not resolvable
    assert get_domain("stationary_ar").contains(np.array(phi)) == _stationary_by_roots(np.array(phi))


@settings(max_examples=100, deadline=None)
@given(r=st.lists(PACF, min_size=1, max_size=5))
def test_stationary_ar_transform_round_trip(r: list[float]) -> None:
    dom = get_domain("stationary_ar")
    phi = pacf_to_ar(np.array(r))
    theta = dom.to_unconstrained(phi)
    np.testing.assert_allclose(np.tanh(theta), r, rtol=1e-9, atol=_step_down_atol(r))
    np.testing.assert_allclose(dom.from_unconstrained(theta), phi, rtol=1e-10, atol=1e-13)


@settings(max_examples=50, deadline=None)
@given(theta=st.lists(st.floats(-3, 3), min_size=1, max_size=4))
def test_stationary_ar_jacobian_against_richardson_differences(theta: list[float]) -> None:
    dom = get_domain("stationary_ar")
    t = np.array(theta)
    h = 1e-3

    def diff(step: float) -> np.ndarray:
        cols = []
        for i in range(t.size):
            e = np.zeros_like(t)
            e[i] = step
            cols.append((dom.from_unconstrained(t + e) - dom.from_unconstrained(t - e)) / (2 * step))
        return np.column_stack(cols)

    reference = (4 * diff(h / 2) - diff(h)) / 3  # error O(h^4)
    np.testing.assert_allclose(dom.jacobian(t), reference, rtol=1e-6, atol=1e-9)


def test_non_stationary_ar_message() -> None:
    with pytest.raises(DomainError, match=r"not stationary .* at lag 2"):
        ar_to_pacf(np.array([0.5, 1.2]))
    with pytest.raises(DomainError, match="at lag 1"):
        ar_to_pacf(np.array([1.0]))


# ------------------------------------------------------------------ Parameter.check
@pytest.mark.parametrize(
    ("param", "value", "message"),
    [
        (Parameter("sigma2", "positive", "u^2"), -1.0, r"FAM\.sigma2 = -1\.0 is outside its domain \(x > 0\)"),
        (Parameter("sigma2", "positive", "u^2"), 0.0, r"FAM\.sigma2 = 0\.0 is outside"),
        (Parameter("sigma2", "positive", "u^2"), float("nan"), r"FAM\.sigma2 = nan is outside"),
        (Parameter("sigma2", "positive", "u^2"), float("inf"), r"FAM\.sigma2 = inf is outside"),
        (Parameter("rho", "correlation", "1"), 1.0, r"FAM\.rho = 1\.0 is outside its domain \(-1 < x < 1\)"),
        (Parameter("p", "unit_interval", "1"), 0.0, r"FAM\.p = 0\.0 is outside its domain \(0 < x < 1\)"),
        (Parameter("b", "real", "u"), float("nan"), r"FAM\.b = nan is outside"),
        (Parameter("sigma2", "positive", "u^2"), "1.0", r"FAM\.sigma2 must be numeric"),
        (Parameter("sigma2", "positive", "u^2"), [1.0, 2.0], r"FAM\.sigma2 must be a scalar"),
        (Parameter("phi", "stationary_ar", "1", size=2), [0.1], r"FAM\.phi must have 2 value\(s\), got 1"),
        (Parameter("phi", "stationary_ar", "1", size=2), [0.5, 1.2], r"FAM\.phi .* outside its domain"),
    ],
)
def test_parameter_check_messages(param: Parameter, value: object, message: str) -> None:
    with pytest.raises(DomainError, match=message):
        param.check(value, "FAM")


def test_parameter_check_accepts_and_converts() -> None:
    positive = Parameter("sigma2", "positive", "u^2")
    assert positive.check(2, "F") == 2.0 and isinstance(positive.check(2, "F"), float)
    assert positive.check(np.array([3.0]), "F") == 3.0  # a one-element array is a scalar
    phi = Parameter("phi", "stationary_ar", "1", size=2).check((0.5, -0.2), "F")
    np.testing.assert_array_equal(phi, [0.5, -0.2])


def test_unknown_domains() -> None:
    with pytest.raises(DomainError, match="unknown parameter domain 'negative'"):
        get_domain("negative")
    with pytest.raises(ValueError, match="domain"):
        Parameter("x", "negative", "u")


def test_stationary_domain_accepts_a_scalar_coefficient_and_saturated_pacf_stays_stationary():
    dom = get_domain("stationary_ar")
    assert dom.contains(np.array(0.5)) and not dom.contains(np.array(1.0))
    phi = dom.from_unconstrained(np.array([40.0, -40.0]))
    assert np.all(np.abs(np.roots(np.r_[1.0, -phi])) < 1.0)


@pytest.mark.parametrize("name", ["positive", "real", "correlation", "unit_interval"])
def test_scalar_contains_gives_the_verdict_of_contains(name: str) -> None:
    from stochmod.core.params import scalar_contains

    contains = scalar_contains(name)
    values = [0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 1 - 2**-53, -1 + 2**-53, 5e-324, -5e-324, 1e308,
              -1e308, np.inf, -np.inf, np.nan]
    for v in values:
        assert contains(v) == DOMAINS[name].contains(np.asarray(v)), (name, v)


def test_scalar_contains_declines_vector_and_unknown_domains() -> None:
    from stochmod.core.params import scalar_contains

    assert scalar_contains("stationary_ar") is None and scalar_contains("nope") is None


def test_fast_from_unconstrained_is_the_general_rebuild_bit_for_bit() -> None:
    """Process.from_unconstrained's direct path (scalar built-in domains) gives the values,
    types, equality and errors of the rebuild through from_vector and the domain checks."""
    import warnings

    from stochmod import model_from_spec
    from stochmod.core.process import Process, _scalar_layout

    model = model_from_spec("GM(beta=2.0, sigma2=1e-6) + WN(sigma2=1e-4) + BI(B=1e-3, fc=0.1) "
                            "+ AR(phi=[0.5], sigma2=1.0)", 100.0)
    assert _scalar_layout(type(model.processes[-1])) is None  # AR checks more: full rebuild
    rng = np.random.default_rng(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for p in model.processes[:3]:
            for scale in (1.0, 30.0, 800.0):  # 800: exp overflows and underflows
                for _ in range(200):
                    theta = rng.normal(0.0, scale, p.n_params)
                    slow = fast = None
                    try:
                        values = [np.atleast_1d(get_domain(s.domain).from_unconstrained(theta[i:i + 1]))
                                  for i, s in enumerate(p.parameters())]
                        slow = Process.from_vector(p, np.concatenate(values))
                    except DomainError as e:
                        with pytest.raises(DomainError, match=str(e).split("=")[0]):
                            p.from_unconstrained(theta)
                        continue
                    fast = p.from_unconstrained(theta)
                    assert fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
                    for s in p.parameters():
                        assert type(getattr(fast, s.name)) is float


def test_a_family_that_validates_its_fields_is_rebuilt_in_full() -> None:
    """A third-party family whose parameter field has an attrs validator does not take the
    direct path of from_unconstrained: its validator runs on every rebuilt value."""
    import attrs

    from stochmod import model_from_spec
    from stochmod.core.process import _scalar_layout

    wn = type(model_from_spec("WN(sigma2=1.0)", 100.0).processes[0])
    calls = []

    @attrs.frozen
    class CheckedWN(wn):
        family = "CHECKED_WN"
        sigma2: float | None = attrs.field(default=None,
                                           validator=lambda inst, att, v: calls.append(v))

    assert _scalar_layout(wn) is not None and _scalar_layout(CheckedWN) is None
    rebuilt = CheckedWN(sigma2=1.0).from_unconstrained(np.array([0.5]))
    assert calls[-1] == rebuilt.sigma2 > 0


@pytest.mark.parametrize("domain", ["positive", "real", "correlation", "unit_interval"])
def test_a_plain_float_gets_the_array_paths_verdict_and_value(domain: str) -> None:
    """Parameter.check's plain-float path against its general path (an np.float64 takes it):
    the same value back, or the same DomainError, at the domains' edges and beyond."""
    spec = Parameter("p", domain, "u")
    values = [0.0, -0.0, 5e-324, 1e-300, 0.5, 1.0 - 2**-53, 1.0, -1.0, -0.5, 2.0, -3.0, 1e308,
              np.inf, -np.inf, np.nan]
    for v in values:
        try:
            expected = spec.check(np.float64(v), "F")
        except DomainError as err:
            with pytest.raises(DomainError, match="outside its domain"):
                spec.check(float(v), "F")
            assert "outside its domain" in str(err)
            continue
        got = spec.check(float(v), "F")
        assert type(got) is float and got == expected
