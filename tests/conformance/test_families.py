"""Every registered process family passes the conformance kit (stochmod.testing).

The truth behind each check is stated in stochmod/testing.py: closed-form identities (PSD
integral = variance, composed steps = re-discretisation, round trips), the base class's
independent generic computations, and seeded Monte Carlo means within their standard error.
"""

from __future__ import annotations

import pytest

import stochmod
from stochmod.testing import CHECKS, check_family


def test_every_family_passes_the_kit(family_name: str) -> None:
    report = check_family(stochmod.get_process(family_name), freq=100.0, rng=20240611)
    assert report.ran == tuple(CHECKS)
    report.raise_if_failed()
    # `example` is part of the contract: it can fail but never be skipped
    assert "example" in report.passed


@pytest.mark.parametrize("freq", [1.0, 400.0])
def test_deterministic_checks_at_other_rates(family_name: str, freq: float) -> None:
    """Identities that must hold at any sampling frequency (no Monte Carlo)."""
    checks = ("example", "round_trips", "bad_values", "psd_integral", "wv_fallbacks",
              "rediscretisation", "wv_jacobian")
    check_family(stochmod.get_process(family_name), freq=freq, rng=1, checks=checks).raise_if_failed()

