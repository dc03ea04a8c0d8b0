"""ScaledFamily (stochmod.core.scaled_family): the WV, Jacobian, vectorised rows and kernel it
gives a family from its declared Haar factor.

The truths: the base class's generic WV (the exact Haar sum over the autocovariance for WN and
QN, the quadrature of the generalised PSD for RW: other computations than ``scale * factor``)
over the whole parameter domain; the closed forms the families wrote by hand before, bit for
bit; and the rows and kernel against ``wv``/``wv_jacobian``, bit for bit.
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import stochmod
from stochmod.core.process import Process
from stochmod.core.scaled_family import ScaledFamily
from stochmod.core.vectorised_wv import declares_wv_rows, wv_kernel, wv_rows_domains
from stochmod.sdk import Parameter
from stochmod.testing import check_wv_rows, strategy_for

FREQ = 100.0
FAMILIES = ("WN", "RW", "QN")


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def _family(name: str) -> type[ScaledFamily]:
    return stochmod.get_process(name)


def _former_wv(p: ScaledFamily, levels: int) -> np.ndarray:
    """The Haar WV as each family computed it by hand before it used the base."""
    j = np.arange(1, levels + 1)
    m = 2.0 ** np.arange(levels)
    if p.family == "WN":
        return p.sigma2 / 2.0**j
    if p.family == "RW":
        return p.sigma2 * (m / 6.0 + 1.0 / (12.0 * m))
    return p.Q2 * (1.5 * 4.0 ** -np.arange(levels, dtype=np.float64))


@pytest.mark.parametrize("name", FAMILIES)
def test_wn_rw_qn_are_scaled_families_with_rows_and_kernel_in_force(name: str) -> None:
    cls = _family(name)
    assert issubclass(cls, ScaledFamily) and declares_wv_rows(cls)
    assert wv_rows_domains(cls) is not None
    assert wv_kernel(cls) is cls.haar_wv_kernel  # None without numba, else the compiled one
    for wrote in ("wv", "wv_jacobian", "haar_wv_rows"):  # none hand-written any more
        assert wrote not in vars(cls)


@pytest.mark.parametrize("name", FAMILIES)
def test_wv_is_the_generic_fallback_over_the_domain(name: str) -> None:
    """``scale * factor`` against Process.wv, the base class's own computation: the exact Haar
    sum over the autocovariance (WN, QN) or the quadrature of the PSD (RW)."""
    cls = _family(name)

    @settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(p=strategy_for(cls, decades=30.0), levels=st.integers(1, 14))
    def run(p: ScaledFamily, levels: int) -> None:
        got = p.wv(levels, FREQ)
        ref = Process.wv(p, levels, FREQ)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=0)

    run()


@pytest.mark.parametrize("name", FAMILIES)
@settings(max_examples=60, deadline=None)
@given(scale=st.floats(min_value=5e-324, max_value=1e280), levels=st.integers(1, 40))
def test_wv_and_jacobian_are_the_former_closed_forms_bit_for_bit(name: str, scale: float,
                                                                 levels: int) -> None:
    """Tiny scales included: WN's product with 2^-j rounds like its former division by 2^j
    into the subnormal range."""
    cls = _family(name)
    p = cls(**{cls.parameter_specs[0].name: scale})
    assert np.array_equal(_bits(p.wv(levels, FREQ)), _bits(_former_wv(p, levels)))
    unit = cls(**{cls.parameter_specs[0].name: 1.0})
    assert np.array_equal(_bits(p.wv_jacobian(levels, FREQ)[:, 0]), _bits(_former_wv(unit, levels)))


@pytest.mark.parametrize("name", FAMILIES)
@settings(max_examples=30, deadline=None)
@given(scales=st.lists(st.floats(min_value=1e-300, max_value=1e300), min_size=1, max_size=9),
       levels=st.integers(1, 30))
def test_rows_and_kernel_are_wv_and_jacobian_bit_for_bit(name: str, scales: list[float],
                                                         levels: int) -> None:
    cls = _family(name)
    proto = cls.example(FREQ)
    values = np.array(scales)[:, None]
    wv, jac = proto.haar_wv_rows(values, levels, FREQ)
    assert wv.shape == (len(scales), levels) and jac.shape == (len(scales), levels, 1)
    kernel = wv_kernel(cls)
    m = 2.0 ** np.arange(levels)
    for k, scale in enumerate(scales):
        p = proto.from_vector([scale])
        assert np.array_equal(_bits(wv[k]), _bits(p.wv(levels, FREQ)))
        assert np.array_equal(_bits(jac[k]), _bits(p.wv_jacobian(levels, FREQ)))
        if kernel is not None:
            start = np.linspace(1.0, 2.0, levels)
            got_wv, got_jac = start.copy(), np.full((levels, 3), np.nan)
            assert kernel(values[k], m, FREQ, got_wv, got_jac[:, 1:2])
            assert np.array_equal(_bits(got_wv), _bits(start + wv[k]))
            assert np.array_equal(_bits(got_jac[:, 1:2]), _bits(jac[k]))
            assert np.isnan(got_jac[:, [0, 2]]).all()  # a strided view: only its column


def test_wn_factor_holds_for_every_wavelet_and_the_others_fall_back() -> None:
    wn, rw = _family("WN")(sigma2=3.0), _family("RW")(sigma2=1e-4)
    assert np.array_equal(wn.wv(6, FREQ, "db4"), wn.wv(6, FREQ))
    np.testing.assert_allclose(rw.wv(6, FREQ, "db4"), Process.wv(rw, 6, FREQ, "db4"), rtol=0)


# --------------------------------------------------------------------- a family of its own
@attrs.frozen
class Flicker8(ScaledFamily):
    """A test family: Haar WV ``c2 / j`` (a made-up factor), nothing else of substance."""

    c2: float | None = None

    family: ClassVar[str] = "Flicker8"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("c2", "positive", "u^2", "scale", role="variance"),)

    @classmethod
    def haar_factor(cls, levels, freq):
        return 1.0 / np.arange(1, levels + 1) + 0.0 * freq

    def psd(self, f, freq):
        return np.full(np.shape(f), self.c2 / freq)

    def white_variance(self, freq):
        return float(self.c2)

    def start(self, wv, freq, *, index=0, count=1, rng=None):
        return self.with_values(c2=float(wv[0]))

    @classmethod
    def example(cls, freq):
        return cls(c2=2.0)


def test_a_new_scaled_family_gets_wv_jacobian_rows_and_kernel_from_its_factor() -> None:
    p = Flicker8(c2=2.0)
    assert np.array_equal(p.wv(5, FREQ), 2.0 * (1.0 / np.arange(1, 6)))
    assert np.array_equal(p.wv_jacobian(5, FREQ), (1.0 / np.arange(1, 6))[:, None])
    p.wv_jacobian(5, FREQ)[0, 0] = 7.0  # a fresh array: the cached factor is not touched
    assert p.wv_jacobian(5, FREQ)[0, 0] == 1.0
    figures = check_wv_rows(Flicker8, FREQ, rng=3)
    assert figures["binding"] and figures["kernel_rows"] == (16 if wv_kernel(Flicker8) else 0)


def test_a_subclass_that_changes_the_factor_keeps_the_rows_in_force_and_consistent() -> None:
    class Doubled(Flicker8):
        @classmethod
        def haar_factor(cls, levels, freq):
            return 2.0 * super().haar_factor(levels, freq)

    assert declares_wv_rows(Doubled) and wv_rows_domains(Doubled) is not None
    p = Doubled(c2=3.0)
    assert np.array_equal(p.wv(4, FREQ), 3.0 * (2.0 / np.arange(1, 5)))
    wv, jac = p.haar_wv_rows(np.array([[3.0]]), 4, FREQ)
    assert np.array_equal(wv[0], p.wv(4, FREQ)) and np.array_equal(jac[0], p.wv_jacobian(4, FREQ))
    check_wv_rows(Doubled, FREQ, rng=1)  # rows and kernel follow the subclass's factor


def test_a_subclass_that_changes_wv_loses_the_rows_and_kernel() -> None:
    class Changed(Flicker8):
        def wv(self, levels, freq, wavelet="haar"):
            return 1.5 * super().wv(levels, freq, wavelet)

    assert not declares_wv_rows(Changed)
    assert wv_rows_domains(Changed) is None and wv_kernel(Changed) is None


def test_the_base_refuses_more_than_one_parameter_and_a_misshapen_factor() -> None:
    with pytest.raises(TypeError, match="one scalar parameter"):
        @attrs.frozen
        class Two(Flicker8):
            b: float | None = None
            parameter_specs: ClassVar[tuple[Parameter, ...]] = (
                Parameter("c2", "positive", "u^2", role="variance"),
                Parameter("b", "positive", "1/s", role="rate"))

    class Short(Flicker8):
        @classmethod
        def haar_factor(cls, levels, freq):
            return np.ones(levels - 1)

    with pytest.raises(TypeError, match=r"shape \(3,\), expected \(4,\)"):
        Short(c2=1.0).wv(4, FREQ)
