"""GARCH maxima on the boundary (a coefficient at 0) and the warm starts of the order growth.

Truth: seeded simulations of eq. 7 with known orders (a plain loop, tests/test_garch.py) and the
nesting of the models: a GARCH(2, 1) with ``alpha_2 = 0`` is the GARCH(1, 1), so its maximised
log-likelihood is the smaller model's; the warm-started fits of :func:`select_garch` reach the
maxima of independent cold fits.
"""

from __future__ import annotations

import numpy as np
import pytest

from stochmod.fit import garch
from test_garch import simulate_garch  # eq. 7 by a plain loop


@pytest.fixture(scope="module")
def garch11() -> np.ndarray:
    return 1e-4 * simulate_garch(40_000, 0.05, [0.08], [0.9], seed=32)  # alpha_2 hat = 0


def test_a_coefficient_with_its_maximum_at_zero_is_held_there(garch11) -> None:
    small = garch.fit_garch(garch11, 1, 1)
    big = garch.fit_garch(garch11, 2, 1)
    assert big.converged
    assert big.alpha[1] < 1e-200  # held on the boundary, not crept towards it
    assert big.loglikelihood == pytest.approx(small.loglikelihood, abs=1e-6)
    gap = np.abs(big.params[[0, 1, 3]] - small.params)
    np.testing.assert_array_less(gap, 1e-3 * small.std_errors)
    # Kuhn-Tucker at the boundary: moving mass into alpha_2 from the others lowers the likelihood
    nudged = np.concatenate([[big.omega], big.alpha + [0.0, 1e-4], big.beta - 1e-4])
    nudged_ll = garch.garch_loglikelihood(garch11, nudged[0], nudged[1:3], nudged[3:])
    assert nudged_ll < big.loglikelihood


@pytest.mark.parametrize("data, nested, order, warm", [
    ("garch11", (1, 1), (2, 1), True), ("garch11", (1, 1), (1, 2), False),
    ("garch21", (1, 1), (2, 1), False), ("garch21", (2, 1), (2, 2), False)])
def test_warm_starts_reach_the_cold_maxima(garch11, data, nested, order, warm) -> None:
    """From the smaller model's estimate where the added coefficient stays at 0 (alpha_2 on the
    GARCH(1, 1) data), from the grid where it rises (beta_2 there; alpha_2 = 0.12 of the
    GARCH(2, 1) data; its beta_2)."""
    x = (garch11 if data == "garch11"
         else simulate_garch(40_000, 0.05, [0.03, 0.12], [0.75], seed=34))
    small = garch.fit_garch(x, *nested)
    scale = float(np.sqrt(np.mean(x * x)))
    start = garch._warm_start(garch._Likelihood(x / scale, *order), small, scale)
    assert (start is not None) == warm
    grown = garch._fit_garch(x, *order, 10, 200, 1e-8, None, small)
    cold = garch.fit_garch(x, *order)
    assert grown.converged
    assert grown.loglikelihood >= cold.loglikelihood - 1e-8 * abs(cold.loglikelihood)
    assert grown.loglikelihood >= small.loglikelihood - 1e-6


def test_select_garch_grows_to_a_needed_coefficient() -> None:
    """GARCH(2, 1) data with a large alpha_2: (1, 1) leaves ARCH effects, the growth finds the
    truth's order and parameters."""
    truth = (0.05, [0.03, 0.2], [0.6])
    x = simulate_garch(40_000, *truth, seed=33)
    fit = garch.select_garch(x)
    assert fit.order == (2, 1)
    assert garch.fit_garch(x, 1, 1).lm_test.pvalue < 0.05
    est = np.concatenate([[truth[0]], truth[1], truth[2]])
    assert np.all(np.abs(fit.params - est) < 4 * fit.std_errors), (fit.params, fit.std_errors)


def test_underflowed_omega_and_shares_map_to_finite_coordinates() -> None:
    """A maximum approached with omega -> 0 (a near-integrated process on a prefix) can leave
    omega at 0.0 in float64; the next stage must start from it, not fail on log(0)."""
    z = garch._from_theta(np.array([0.0, 0.0, 0.9]))
    assert np.all(np.isfinite(z)) and z[0] < -700 and z[1] < -700
    back = garch._to_theta(z)
    assert back[0] < 1e-300 and back[2] == pytest.approx(0.9, rel=1e-12)
