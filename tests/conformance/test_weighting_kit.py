"""The conformance kit's weighting check: every registered weighting passes it, and weightings
that break the contract fail it with a message naming the broken property.

Truth: each broken weighting below is wrong by construction (asymmetric, indefinite, of the
wrong shape, random without the seed, dependent on the signal's unit, needing the signal
while saying it does not).
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np
import pytest

from stochmod.fit.weighting_plugins import DIAGONAL, Weighting, WeightingInput, WeightingMatrix, get_weighting
from stochmod.plugin.registry import weightings
from stochmod.testing import check_weighting

FREQ = 100.0
TRUTH = "GM(beta=2.0, sigma2=1.0) + WN(sigma2=0.5)"


@pytest.mark.parametrize("name", sorted(weightings()))
def test_every_registered_weighting_conforms(name: str) -> None:
    figures = check_weighting(get_weighting(name), TRUTH, FREQ, rng=7)
    assert figures["registered"] and figures["levels"] == 12  # the default levels of 2^13 samples
    assert figures["scale_rel_error"] <= 1e-5 and np.isfinite(figures["objective"])
    assert figures["covariance"] == (name in {"optimal", "bootstrap"})


@attrs.frozen
class Base(Weighting):
    name: ClassVar[str] = "broken"
    description: ClassVar[str] = "a broken weighting"

    def matrix(self, data: WeightingInput) -> WeightingMatrix:
        return DIAGONAL.matrix(data)


class Asymmetric(Base):
    def matrix(self, data):
        om = DIAGONAL.matrix(data).omega
        return WeightingMatrix(om + np.triu(np.full(om.shape, np.max(om)), 1))


class Indefinite(Base):
    def matrix(self, data):
        om = DIAGONAL.matrix(data).omega.copy()
        om[0, 1] = om[1, 0] = 2 * np.sqrt(om[0, 0] * om[1, 1])
        return WeightingMatrix(om)


class WrongShape(Base):
    def matrix(self, data):
        return WeightingMatrix(np.eye(data.levels - 1))


class Unseeded(Base):
    def matrix(self, data):
        return WeightingMatrix(np.diag(np.random.default_rng().uniform(1, 2, data.levels)))


class Ridge(Base):
    """diag(1/var) + I: the identity does not change with the unit, the rest does."""

    def matrix(self, data):
        return WeightingMatrix(DIAGONAL.matrix(data).omega + np.eye(data.levels))


class SecretlyNeedsSignal(Base):
    def matrix(self, data):
        return WeightingMatrix(np.eye(data.levels) / np.var(data.signal))


class BadCovariance(Base):
    def matrix(self, data):
        return WeightingMatrix(np.eye(data.levels), -np.eye(data.levels))


class NoFlags(Base):
    needs_fit = "no"  # type: ignore[assignment]


class UnknownInference(Base):
    inference = "posterior"


@pytest.mark.parametrize("broken, match", [
    (Asymmetric(), "not symmetric"),
    (Indefinite(), "not positive definite"),
    (WrongShape(), "must have shape"),
    (Unseeded(), "same input gives another matrix"),
    (Ridge(), "would depend on the signal's unit"),
    (SecretlyNeedsSignal(), "failed on the wavelet variance alone"),
    (BadCovariance(), "positive variances"),
    (NoFlags(), "needs_fit must be a bool"),
    (UnknownInference(), "inference must be 'data' or 'model'"),
])
def test_broken_weightings_fail_on_the_property_they_break(broken: Base, match: str) -> None:
    with pytest.raises(AssertionError, match=match):
        check_weighting(broken, TRUTH, FREQ, rng=7)


def test_a_correct_unregistered_weighting_passes_without_the_gmwm_round_trip() -> None:
    figures = check_weighting(Base(), TRUTH, FREQ, rng=7)
    assert figures["registered"] is False and figures["objective"] is None
    assert figures["scale_rel_error"] < 1e-12  # the diagonal weighting scales exactly by scale^-4
