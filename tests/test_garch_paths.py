"""GARCH(p, q)'s two implementations: the compiled one-pass kernel (numba, the ``fast`` extra,
:mod:`stochmod.fit.garch_jit`) and the numpy/lfilter fallback give the same likelihood,
score and information matrices, and the same maxima.

Truth: the numpy path, itself checked against a plain loop and finite differences in
tests/test_garch.py, and the simulation's known parameters.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from stochmod.core import jit
from stochmod.fit import garch
from stochmod.fit import garch_jit
from test_garch import simulate_garch  # eq. 7 by a plain loop

needs_numba = pytest.mark.skipif(not jit.AVAILABLE, reason="numba (the 'fast' extra) is "
                                 "not installed, or STOCHMOD_DISABLE_JIT is set")


def _both(monkeypatch, make):
    """``make()`` on the compiled path, then on the numpy path."""
    monkeypatch.setattr(garch_jit, "AVAILABLE", True)
    compiled = make()
    monkeypatch.setattr(garch_jit, "AVAILABLE", False)
    return compiled, make()


@needs_numba
@pytest.mark.parametrize("p, q, theta", [
    (1, 1, [0.1, 0.1, 0.8]), (2, 1, [0.08, 0.12, 0.04, 0.72]), (1, 2, [0.08, 0.12, 0.4, 0.3]),
    (2, 2, [0.05, 0.08, 0.03, 0.5, 0.35]), (2, 0, [0.5, 0.2, 0.1]),
    (3, 3, [0.04, 0.05, 0.03, 0.02, 0.3, 0.25, 0.3])])
def test_compiled_terms_equal_the_numpy_ones(monkeypatch, p, q, theta) -> None:
    """5003 samples: ten blocks of the compiled pass and a partial one."""
    x = simulate_garch(5003, 0.05, [0.1, 0.05], [0.7], seed=4)
    y = x / np.sqrt(np.mean(x * x))
    theta = np.array(theta)
    jit, ref = _both(monkeypatch, lambda: garch._Likelihood(y, p, q).terms(theta, hessian=True))
    assert jit[0] == pytest.approx(ref[0], rel=1e-13)
    np.testing.assert_allclose(jit[3], ref[3], rtol=1e-14)  # sigma^2
    for got, want in zip((jit[1], jit[2], jit[4]), (ref[1], ref[2], ref[4])):
        np.testing.assert_allclose(got, want, rtol=1e-11, atol=1e-12 * np.abs(want).max())
    value, _ = _both(monkeypatch, lambda: garch._Likelihood(y, p, q).value(theta))
    assert value == jit[0]


@needs_numba
def test_compiled_pass_refuses_a_non_positive_variance(monkeypatch) -> None:
    x = simulate_garch(2000, 0.05, [0.1], [0.8], seed=1)
    bad = np.array([-0.1, 0.1, 0.8])
    jit, ref = _both(monkeypatch, lambda: garch._Likelihood(x, 1, 1).value(bad))
    assert jit == ref == -np.inf
    s2, s2_ref = _both(monkeypatch, lambda: garch.garch_variance(x, 1e300, [0.1], [0.8]))
    np.testing.assert_array_equal(s2, s2_ref)  # inf from overflow: the numpy recursion's array


@needs_numba
@pytest.mark.parametrize("p, q, truth", [(1, 1, (0.05, [0.08], [0.9])),
                                         (2, 2, (0.05, [0.06, 0.04], [0.5, 0.35]))])
def test_both_paths_reach_the_same_maximum(monkeypatch, p, q, truth) -> None:
    """Through the prefix path too (shortened here), where collapsed shares are raised."""
    monkeypatch.setattr(garch, "_PREFIX_SAMPLES", 15_000)
    x = 1e-4 * simulate_garch(60_001, *truth, seed=21)
    jit, ref = _both(monkeypatch, lambda: garch.fit_garch(x, p, q))
    assert jit.converged and ref.converged
    assert abs(jit.loglikelihood - ref.loglikelihood) < 1e-8 * abs(ref.loglikelihood)
    np.testing.assert_array_less(np.abs(jit.params - ref.params), 1e-3 * ref.std_errors)
    np.testing.assert_allclose(jit.std_errors, ref.std_errors, rtol=1e-4)
    est = np.concatenate([[truth[0] * 1e-8], truth[1], truth[2]])
    assert np.all(np.abs(jit.params - est) < 4 * jit.std_errors), (jit.params, jit.std_errors)


def test_raised_shares_keep_the_sum_and_the_floor() -> None:
    theta = np.array([0.3, 0.02, 1e-23, 0.5, 0.47])
    raised = garch._raise_shares(theta)
    assert raised[0] == theta[0] and raised[2] == garch._SHARE_FLOOR
    assert raised[1:].sum() == pytest.approx(theta[1:].sum(), abs=1e-15)
    assert raised[3] == pytest.approx(0.5 - garch._SHARE_FLOOR, abs=1e-15)


def test_disable_jit_environment_variable_forces_numpy() -> None:
    env = dict(os.environ, STOCHMOD_DISABLE_JIT="1")
    out = subprocess.run([sys.executable, "-c", "from stochmod.fit import garch_jit; "
                          "print(garch_jit.AVAILABLE)"], env=env, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


@needs_numba
def test_prepare_leaves_the_pass_compiled_for_forked_workers() -> None:
    garch_jit.prepare()
    assert garch_jit.garch_pass.signatures  # machine code in this process, inherited by a fork
