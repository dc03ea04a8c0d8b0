"""GARCH(p, q)'s compiled pass (:mod:`stochmod.fit.garch_jit`) against its own plain-Python
functions; the refusal of a variance that is not positive and finite; compilation before forks.

Truth for the pass itself: a plain loop and finite differences in tests/test_garch.py.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stochmod.core import jit
from stochmod.fit import garch
from stochmod.fit import garch_jit
from test_garch import loop_variance, simulate_garch  # eq. 7 by a plain loop

needs_numba = pytest.mark.skipif(not jit.AVAILABLE, reason="STOCHMOD_DISABLE_JIT is set")


def _pass(kernel, x2, bc, theta, p, level):
    k = theta.size
    s2, score, info, observed = np.zeros(x2.size), np.zeros(k), np.zeros((k, k)), np.zeros((k, k))
    ll = kernel(x2, bc, theta[0], theta[1 : 1 + p].copy(), theta[1 + p :].copy(), level, s2,
                score, info, observed)
    return ll, s2, score, info, observed


@needs_numba
@settings(max_examples=30, deadline=None)
@given(p=st.integers(1, 3), q=st.integers(0, 3), n=st.integers(1, 1500), level=st.integers(0, 2),
       seed=st.integers(0, 2**32 - 1))
def test_compiled_pass_equals_its_plain_function(p, q, n, level, seed):
    """Up to three blocks of 512 samples, every level of output."""
    rng = np.random.default_rng(seed)
    shares = rng.dirichlet(np.ones(p + q + 1)) * 0.99
    theta = np.concatenate([[0.1], shares[: p + q]])
    x2 = np.square(rng.standard_normal(n))
    bc = garch.backcast(x2)
    got = _pass(garch_jit.garch_pass, x2, bc, theta, p, level)
    want = _pass(garch_jit.garch_pass.py_func, x2, bc, theta, p, level)
    assert got[0] == pytest.approx(want[0], rel=1e-12)
    np.testing.assert_allclose(got[1], want[1], rtol=1e-13, atol=0)  # sigma^2
    for a, b in zip(got[2:], want[2:]):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * max(np.abs(b).max(), 1.0))
    s2 = np.zeros(n)
    garch_jit.variance_recursion(x2, bc, theta[0], theta[1 : 1 + p].copy(), theta[1 + p :].copy(),
                                 s2)
    s2_plain = np.zeros(n)
    garch_jit.variance_recursion.py_func(x2, bc, theta[0], theta[1 : 1 + p].copy(),
                                         theta[1 + p :].copy(), s2_plain)
    np.testing.assert_allclose(s2, s2_plain, rtol=1e-13, atol=0)


@pytest.mark.filterwarnings("ignore:overflow encountered")
def test_pass_refuses_a_non_positive_variance() -> None:
    x = simulate_garch(2000, 0.05, [0.1], [0.8], seed=1)
    assert garch._Likelihood(x, 1, 1).value(np.array([-0.1, 0.1, 0.8])) == -np.inf
    assert garch.garch_loglikelihood(x, 1e308, [0.1], [0.8]) == -np.inf
    s2 = garch.garch_variance(x, 1e308, [0.1], [0.8])  # overflows: every variance, as it is
    assert np.isinf(s2).any()
    np.testing.assert_allclose(s2, loop_variance(x, 1e308, [0.1], [0.8]), rtol=1e-12)


def test_raised_shares_keep_the_sum_and_the_floor() -> None:
    theta = np.array([0.3, 0.02, 1e-23, 0.5, 0.47])
    raised = garch._raise_shares(theta)
    assert raised[0] == theta[0] and raised[2] == garch._SHARE_FLOOR
    assert raised[1:].sum() == pytest.approx(theta[1:].sum(), abs=1e-15)
    assert raised[3] == pytest.approx(0.5 - garch._SHARE_FLOOR, abs=1e-15)


def test_disable_jit_environment_variable_gives_the_plain_functions() -> None:
    env = dict(os.environ, STOCHMOD_DISABLE_JIT="1")
    code = ("from stochmod.fit import garch_jit; import sys; "
            "print(hasattr(garch_jit.garch_pass, 'py_func'), 'numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False False"


@needs_numba
def test_prepare_leaves_the_pass_compiled_for_forked_workers() -> None:
    garch_jit.prepare()
    assert garch_jit.garch_pass.signatures  # machine code in this process, inherited by a fork
