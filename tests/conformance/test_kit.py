"""The conformance kit itself: it passes a correct toy family and FAILS, precisely on the
check concerned, on deliberately broken ones (so every check is shown able to fail).

The toy family OU is a first-order Gauss-Markov process written here from its textbook closed
forms (AR(1) with phi = exp(-beta/freq): autocovariance sigma2 phi^|k|, sampled PSD
sigma2 (1 - phi^2) / (freq |1 - phi e^{-i 2 pi f / freq}|^2), SDE dx = -beta x dt + dW with
Qc = 2 beta sigma2), independent of the first-party GM plugin.
"""

from __future__ import annotations

import math
from typing import ClassVar

import attrs
import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, find, given, settings
from scipy.signal import lfilter

import stochmod
from stochmod.core.errors import InputError
from stochmod.core.params import DOMAINS, Parameter, get_domain
from stochmod.core.process import Process, as_generator
from stochmod.core.statespace import ContinuousBlock, StateSpaceBlock
from stochmod.testing import (
    CHECKS,
    ConformanceReport,
    check_family,
    check_wv_monte_carlo,
    strategy_for,
)

WN = stochmod.get_process("WN")


@attrs.frozen
class OU(Process):
    """Toy first-order Gauss-Markov process (see the module docstring)."""

    beta: float | None = None
    sigma2: float | None = None

    family: ClassVar[str] = "OUtoy"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("beta", "positive", "1/s", role="rate"),
        Parameter("sigma2", "positive", "u^2", role="variance"),
    )
    ieee952: ClassVar[tuple[tuple[str, ...], ...]] = (("rate", "variance"),)

    @classmethod
    def from_ieee952(cls, coefficients, freq):
        return cls(beta=coefficients["rate"], sigma2=coefficients["variance"])

    def to_ieee952(self, freq, names):
        return {"rate": self.beta, "variance": self.sigma2}

    def start(self, wv, freq, *, index=0, count=1, rng=None):
        return self.with_values(beta=freq / 20.0, sigma2=2.0 * float(wv[0]))

    def _phi(self, freq: float) -> float:
        return math.exp(-self.beta / freq)

    def autocovariance(self, lags, freq):
        return self.sigma2 * self._phi(freq) ** np.abs(np.asarray(lags, dtype=float))

    def psd(self, f, freq):
        phi = self._phi(freq)
        w = 2 * np.pi * np.asarray(f, dtype=float) / freq
        return self.sigma2 * (1 - phi**2) / (freq * (1 - 2 * phi * np.cos(w) + phi**2))

    @property
    def state_names(self):
        return ("x",)

    def continuous_block(self, freq):
        return ContinuousBlock([[-self.beta]], [[1.0]], [[2 * self.beta * self.sigma2]])

    def initial_covariance(self, freq):
        return np.array([[self.sigma2]])

    def simulate(self, n, freq, rng):
        g = as_generator(rng)
        phi = self._phi(freq)
        e = g.standard_normal(n) * math.sqrt(self.sigma2 * (1 - phi**2))
        e[0] = g.standard_normal() * math.sqrt(self.sigma2)
        return lfilter([1.0], [1.0, -phi], e)

    @classmethod
    def example(cls, freq):
        return cls(beta=freq / 20.0, sigma2=1.0)


# --------------------------------------------------------------------- broken families
@attrs.frozen
class WNWrongWV(WN):
    """WV 10% too high (and hence its analytic Jacobian disagrees with it)."""

    family: ClassVar[str] = "WNwrongwv"

    def wv(self, levels, freq, wavelet="haar"):
        return 1.1 * super().wv(levels, freq, wavelet)


@attrs.frozen
class WNWrongPSD(WN):
    """PSD integrates to 1.2 sigma2."""

    family: ClassVar[str] = "WNwrongpsd"

    def psd(self, f, freq):
        return 1.2 * super().psd(f, freq)


@attrs.frozen
class WNNegativeWV(WN):
    """WV negative for sigma2 < 1e-6 (correct at the example)."""

    family: ClassVar[str] = "WNnegwv"

    def wv(self, levels, freq, wavelet="haar"):
        wv = super().wv(levels, freq, wavelet)
        return -wv if self.sigma2 < 1e-6 else wv


@attrs.frozen
class WNNoValidation(WN):
    """Accepts any value."""

    family: ClassVar[str] = "WNnoval"

    def __attrs_post_init__(self):
        pass


@attrs.frozen
class WNLossySpec(WN):
    """to_spec forgets the values."""

    family: ClassVar[str] = "WNlossy"

    def to_spec(self):
        return {"family": self.family, "params": {}}


@attrs.frozen
class WNWrongSimulation(WN):
    """Simulates with variance 1.1 sigma2."""

    family: ClassVar[str] = "WNwrongsim"

    def simulate(self, n, freq, rng):
        return math.sqrt(1.1) * super().simulate(n, freq, rng)


_unseeded = np.random.default_rng()


@attrs.frozen
class WNUnseeded(WN):
    """Ignores the seed."""

    family: ClassVar[str] = "WNunseeded"

    def simulate(self, n, freq, rng):
        return math.sqrt(self.sigma2) * _unseeded.standard_normal(int(n))


@attrs.frozen
class WNNoExample(WN):
    """Does not provide an example instance."""

    family: ClassVar[str] = "WNnoex"
    example = classmethod(Process.example.__func__)


@attrs.frozen
class WNWrongRole(WN):
    """Declares its variance as an amplitude (selection would shrink it by the wrong power)."""

    family: ClassVar[str] = "WNwrongrole"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("sigma2", "positive", "u^2", role="amplitude"),)


@attrs.frozen
class WNNoRole(WN):
    """Declares no role."""

    family: ClassVar[str] = "WNnorole"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (Parameter("sigma2", "positive", "u^2"),)


@attrs.frozen
class WNWrongIEEE(WN):
    """Builds itself from N forgetting the sampling frequency: sigma2 = N^2."""

    family: ClassVar[str] = "WNwrongieee"

    @classmethod
    def from_ieee952(cls, coefficients, freq):
        return cls(sigma2=coefficients["N"] ** 2)


@attrs.frozen
class OUWrongBlock(OU):
    """Continuous block with twice the driving noise."""

    family: ClassVar[str] = "OUwrongblock"

    def continuous_block(self, freq):
        return ContinuousBlock([[-self.beta]], [[1.0]], [[4 * self.beta * self.sigma2]])


@attrs.frozen
class OUEulerNative(OU):
    """Native block by Euler discretisation, inconsistent with the exact block(dt)."""

    family: ClassVar[str] = "OUeuler"

    def discrete_block(self, freq):
        dt = 1 / freq
        return StateSpaceBlock(("x",), [[1 - self.beta * dt]], [[2 * self.beta * self.sigma2 * dt]],
                               [1.0], [[self.sigma2]], 0.0, dt)


@attrs.frozen
class OUWrongJacobian(OU):
    """Analytic Jacobian 1% off."""

    family: ClassVar[str] = "OUwrongjac"

    def wv_jacobian(self, levels, freq):
        return 1.01 * super().wv_jacobian(levels, freq)


# --------------------------------------------------------------------- tests
def test_the_kit_passes_a_correct_family(register) -> None:
    report = check_family(register(OU), freq=100.0, rng=5)
    report.raise_if_failed()
    # every check applies to a stateful stationary family, but wv_rows: OU does not declare
    # the vectorised-WV protocol
    assert report.passed == tuple(c for c in CHECKS if c != "wv_rows")
    assert "VectorisedWV" in report.skipped["wv_rows"]
    # figures are measurements: the PSD integral equals sigma2 = 1 of the example
    assert report.figures["psd_integral"]["integral"] == pytest.approx(1.0, rel=1e-9)
    assert report.figures["rediscretisation"]["n_states"] == 1


@pytest.mark.parametrize(
    ("cls", "expected"),
    [
        # (wv_rows is skipped: the rows inherited from WN are not in force below a changed wv)
        (WNWrongWV, {"wv_monte_carlo", "wv_fallbacks", "wv_jacobian", "ieee952"}),
        (WNWrongPSD, {"psd_integral", "wv_fallbacks"}),
        (WNNegativeWV, {"wv_domain"}),
        (WNNoValidation, {"bad_values"}),
        (WNLossySpec, {"round_trips"}),
        (WNWrongSimulation, {"wv_monte_carlo"}),
        (WNUnseeded, {"simulate"}),
        (OUWrongBlock, {"state_space"}),
        (OUEulerNative, {"rediscretisation"}),
        (OUWrongJacobian, {"wv_jacobian"}),
        (WNWrongRole, {"declarations"}),
        (WNNoRole, {"declarations"}),
        (WNWrongIEEE, {"ieee952"}),
    ],
    ids=lambda v: v.__name__ if isinstance(v, type) else None,
)
def test_the_kit_fails_on_a_broken_family(register, cls, expected) -> None:
    report = check_family(register(cls), freq=100.0, rng=7)
    assert set(report.failed) == expected, report.summary()
    with pytest.raises(AssertionError, match=cls.family):
        report.raise_if_failed()


def test_failure_messages_are_precise(register) -> None:
    report = check_family(register(WNWrongWV), freq=100.0, rng=7, checks=["wv_monte_carlo", "wv_fallbacks"])
    # the level, the theory and the Monte Carlo mean are named
    assert "j=1: theory 0.55" in report.failed["wv_monte_carlo"]
    assert "exact Haar sum over the autocovariance" in report.failed["wv_fallbacks"]
    bad = check_family(register(WNNoValidation), freq=100.0, checks=["bad_values"]).failed["bad_values"]
    assert "sigma2 = -1.0" in bad and "DomainError" in bad


def test_missing_example_is_a_failure_not_a_skip(register) -> None:
    report = check_family(register(WNNoExample), freq=100.0)
    assert set(report.failed) == set(CHECKS) and not report.skipped
    assert "no example" in report.failed["example"]
    # example is abstract: a family without one has no instance at all
    assert WNNoExample.__abstractmethods__ == frozenset({"example"})
    with pytest.raises(TypeError, match="abstract"):
        WNNoExample(sigma2=2.0)


def test_skips_carry_reasons() -> None:
    report = check_family(WN, freq=100.0, checks=["rediscretisation"])
    assert report.skipped == {"rediscretisation": "WN is feed-through only (no states to re-discretise)"}
    assert report.ok


def test_report_is_reproducible_and_readable(register) -> None:
    a = check_family(register(OU), freq=50.0, rng=3, checks=["wv_monte_carlo", "state_space"])
    b = check_family(OU, freq=50.0, rng=3, checks=["wv_monte_carlo", "state_space"])
    assert a == b
    assert isinstance(a, ConformanceReport)
    text = a.summary()
    assert "Conformance of OUtoy at 50 Hz" in text and "wv_monte_carlo" in text and "passed" in text


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(InputError, match="unknown check"):
        check_family(WN, checks=["nonsense"])
    with pytest.raises(InputError, match="free parameter"):
        check_family(WN())
    with pytest.raises(InputError, match="Process"):
        check_family(int)
    with pytest.raises(InputError, match="no level"):
        check_wv_monte_carlo(WN(sigma2=1.0), n=8)


def test_monte_carlo_check_detects_a_small_bias_when_asked_for_power() -> None:
    """A 0.5 % error in the theory passes the cheap default (4.5 SE is about 1.5 % at level 1)
    but not a stronger run (about 0.35 %)."""

    @attrs.frozen
    class Slightly(WN):
        def wv(self, levels, freq, wavelet="haar"):
            return 1.005 * super().wv(levels, freq, wavelet)

    check_wv_monte_carlo(Slightly(sigma2=1.0), 100.0, rng=0)
    with pytest.raises(AssertionError, match="j=1"):
        check_wv_monte_carlo(Slightly(sigma2=1.0), 100.0, rng=0, n_mc=100, n=2**16)


# --------------------------------------------------------------------- strategy_for
@attrs.frozen
class AllDomains(Process):
    """A family with one parameter in each built-in domain (for strategy_for)."""

    a: float | None = None
    b: float | None = None
    c: float | None = None
    d: float | None = None
    phi: tuple | None = None

    family: ClassVar[str] = "AllDomains"

    def white_variance(self, freq):
        return 1.0

    def psd(self, f, freq):
        return np.full(np.shape(f), 1.0 / freq)

    def start(self, wv, freq, *, index=0, count=1, rng=None):
        return self

    @classmethod
    def example(cls, freq):
        return cls(a=1.0, b=0.0, c=0.0, d=0.5, phi=(0.0, 0.0, 0.0))

    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("a", "positive", "u^2"),
        Parameter("b", "real", "u"),
        Parameter("c", "correlation", "1"),
        Parameter("d", "unit_interval", "1"),
        Parameter("phi", "stationary_ar", "1", size=3),
    )


def _largest_root(phi) -> float:
    """Largest modulus of the roots of z^p - phi_1 z^(p-1) - ... - phi_p (< 1: stationary)."""
    return float(np.max(np.abs(np.roots(np.r_[1.0, -np.asarray(phi)]))))


def test_builtin_domains_all_have_a_strategy() -> None:
    assert {s.domain for s in AllDomains.parameter_specs} == set(DOMAINS)


@settings(max_examples=200, suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(strategy_for(AllDomains))
def test_strategy_draws_inside_every_domain(p: AllDomains) -> None:
    for spec in p.parameters():
        value = np.asarray(getattr(p, spec.name), dtype=float)
        assert get_domain(spec.domain).contains(value)


@pytest.mark.parametrize(
    ("name", "condition"),
    [
        ("small positive", lambda p: p.a < 1e-6),
        ("large positive", lambda p: p.a > 1e6),
        ("negative real", lambda p: p.b < -1e3),
        ("zero real", lambda p: p.b == 0.0),
        ("correlation near -1", lambda p: p.c < -0.999),
        ("unit interval near 1", lambda p: p.d > 0.999),
        ("AR near a unit root", lambda p: _largest_root(p.phi) > 0.99),
    ],
)
def test_strategy_reaches_the_edges_of_the_domain(name, condition) -> None:
    settings_ = settings(max_examples=2000, database=None, phases=[Phase.generate],
                         suppress_health_check=list(HealthCheck))
    found = find(strategy_for(AllDomains), condition, settings=settings_)
    assert condition(found)


def test_strategy_keeps_an_instance_structure() -> None:
    p = find(strategy_for(WN(sigma2=3.0)), lambda p: True)
    assert isinstance(p, WN) and not p.is_free


def test_wv_rows_check_catches_a_row_one_ulp_off():
    """check_wv_rows compares a family's vectorised rows with its wv/wv_jacobian bit for bit:
    one entry moved by one ulp fails it; the family's own rows pass."""
    from stochmod_gm import GM

    from stochmod.testing import NotApplicable, check_wv_rows

    class OffByOneUlp(GM):
        def haar_wv_rows(self, values, levels, freq):
            wv, jac = super().haar_wv_rows(values, levels, freq)
            wv = wv.copy()
            wv[-1, 3] = np.nextafter(wv[-1, 3], np.inf)
            return wv, jac

    assert check_wv_rows(GM, 100.0, rng=2)["rows"] == 16
    with pytest.raises(AssertionError, match="row 15 .* differs from its wv"):
        check_wv_rows(OffByOneUlp, 100.0, rng=2)
    with pytest.raises(NotApplicable, match="does not declare the vectorised-WV protocol"):
        check_wv_rows(stochmod.get_process("AR"), 100.0)
    with pytest.raises(NotApplicable, match="not in force"):  # inherited rows below a changed wv
        check_wv_rows(WNWrongWV, 100.0)


def test_wv_rows_check_holds_a_kernel_to_the_rows_bit_for_bit():
    """check_wv_rows also runs a family's haar_wv_kernel (VectorisedWV.haar_wv_kernel) on each
    row: GM's and WN's kernels give their rows' digits; a kernel one ulp off, or one that
    overwrites the WV instead of adding to it, fails."""
    from stochmod_gm import GM
    from stochmod_wn import WN

    from stochmod.core.vectorised_wv import wv_kernel
    from stochmod.testing import check_wv_rows

    if wv_kernel(GM) is None or wv_kernel(WN) is None:
        pytest.skip("the kernels run uncompiled (STOCHMOD_DISABLE_JIT is set)")
    assert check_wv_rows(GM, 100.0, rng=2)["kernel_rows"] > 0
    assert check_wv_rows(WN, 100.0, rng=2)["kernel_rows"] == 16

    def one_ulp_off(values, m, freq, wv, jac):
        done = GM.haar_wv_kernel(values, m, freq, wv, jac)
        jac[2, 0] = np.nextafter(jac[2, 0], np.inf)
        return done

    def overwrites(values, m, freq, wv, jac):
        wv[:] = 0.0
        return WN.haar_wv_kernel(values, m, freq, wv, jac)

    class OffKernel(GM):
        haar_wv_kernel = staticmethod(one_ulp_off)

    class Overwriting(WN):
        haar_wv_kernel = staticmethod(overwrites)

    with pytest.raises(AssertionError, match="haar_wv_kernel at row 0 .* Jacobian"):
        check_wv_rows(OffKernel, 100.0, rng=2)
    with pytest.raises(AssertionError, match="WV added to the start"):
        check_wv_rows(Overwriting, 100.0, rng=2)
