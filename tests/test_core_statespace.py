"""Tests of stochmod.core.statespace: Van Loan discretisation against closed forms and against
direct quadrature, composition of steps against repeated multiplication, block assembly,
and the composer's per-axis augmentation (stochmod.core.model.augment_axes).

Closed forms: first-order Gauss-Markov dx = -beta x dt + dW, Qc = 2 beta sigma2:
Phi = exp(-beta dt), Q = sigma2 (1 - exp(-2 beta dt)) (evaluated with mpmath); double
integrator with white acceleration of density q: Phi = [[1, dt], [0, 1]],
Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]].
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad_vec
from scipy.linalg import expm

import stochmod
from stochmod import sdk
from stochmod.core.errors import InputError
from stochmod.core.model import augment_axes
from stochmod.core.statespace import ContinuousBlock, StateSpaceBlock, compose_steps, stack_blocks, van_loan

mp.mp.dps = 40
LOG = st.floats(-6, 3)  # log10 of a scale


@settings(max_examples=150, deadline=None)
@given(lbeta=LOG, ldt=LOG, sigma2=st.floats(1e-6, 1e6))
def test_van_loan_scalar_gauss_markov(lbeta: float, ldt: float, sigma2: float) -> None:
    beta, dt = 10.0**lbeta, 10.0**ldt
    Phi, Q = van_loan(ContinuousBlock([[-beta]], [[1.0]], [[2 * beta * sigma2]]), dt)
    x = mp.mpf(beta) * mp.mpf(dt)
    assert Phi[0, 0] == pytest.approx(float(mp.exp(-x)), rel=1e-12, abs=1e-300)
    assert Q[0, 0] == pytest.approx(float(sigma2 * -mp.expm1(-2 * x)), rel=1e-9, abs=1e-300)


@settings(max_examples=150, deadline=None)
@given(ldt=LOG, q=st.floats(1e-10, 1e4))
def test_van_loan_double_integrator(ldt: float, q: float) -> None:
    dt = 10.0**ldt
    Phi, Q = van_loan(ContinuousBlock([[0, 1], [0, 0]], [[0], [1]], [[q]]), dt)
    np.testing.assert_allclose(Phi, [[1, dt], [0, 1]], rtol=1e-13, atol=0)
    exact = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    np.testing.assert_allclose(Q, exact, rtol=1e-9)
    assert np.array_equal(Q, Q.T)


@pytest.mark.parametrize("seed", range(5))
def test_van_loan_against_direct_quadrature(seed: int) -> None:
    """Q = int_0^dt expm(F s) G Qc G' expm(F' s) ds by adaptive quadrature, for random stable F."""
    rng = np.random.default_rng(seed)
    k, r = 3, 2
    A = rng.normal(size=(k, k))
    F = A - (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(k)
    G = rng.normal(size=(k, r))
    L = rng.normal(size=(r, r))
    Qc = L @ L.T
    dt = 0.37
    Phi, Q = van_loan(ContinuousBlock(F, G, Qc), dt)
    integrand = lambda s: expm(F * s) @ G @ Qc @ G.T @ expm(F.T * s)  # noqa: E731
    exact, _ = quad_vec(integrand, 0.0, dt, epsabs=0, epsrel=1e-13)
    np.testing.assert_allclose(Phi, expm(F * dt), rtol=1e-12)
    np.testing.assert_allclose(Q, exact, rtol=1e-10, atol=1e-14 * np.abs(exact).max())


def test_compose_steps_against_repeated_multiplication() -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 4))
    Phi = 0.9 * A / np.max(np.abs(np.linalg.eigvals(A)))  # spectral radius 0.9
    B = rng.normal(size=(4, 4))
    Q = B @ B.T
    P, S = np.eye(4), np.zeros((4, 4))
    for k in range(1, 51):
        P, S = Phi @ P, Phi @ S @ Phi.T + Q  # x_k = Phi x_{k-1} + w_k
        Pk, Sk = compose_steps(Phi, Q, k)
        np.testing.assert_allclose(Pk, P, rtol=1e-11, atol=1e-14)
        np.testing.assert_allclose(Sk, S, rtol=1e-11, atol=1e-14)


def test_compose_steps_of_the_continuous_form() -> None:
    """k steps of van_loan(dt) equal van_loan(k dt) (semigroup property of the exact form)."""
    cont = ContinuousBlock([[0, 1], [0, -0.3]], [[0], [1]], [[2.0]])
    Phi1, Q1 = van_loan(cont, 0.01)
    for k in (2, 3, 7, 50):
        Pk, Qk = van_loan(cont, 0.01 * k)
        Pc, Qcmp = compose_steps(Phi1, Q1, k)
        np.testing.assert_allclose(Pc, Pk, rtol=1e-12)
        np.testing.assert_allclose(Qcmp, Qk, rtol=1e-10)


def test_compose_steps_rejects_zero_steps() -> None:
    with pytest.raises(InputError, match="number of steps must be >= 1, got 0"):
        compose_steps(np.eye(1), np.eye(1), 0)


def _block(names: tuple[str, ...], scale: float, white: float = 0.0, continuous: bool = True) -> StateSpaceBlock:
    k = len(names)
    cont = ContinuousBlock(-scale * np.eye(k), np.eye(k), np.eye(k)) if continuous and k else None
    return StateSpaceBlock(names, scale * np.eye(k), 2 * scale * np.eye(k), np.arange(1, k + 1),
                           3 * scale * np.eye(k), white, 0.1, cont)


def test_stack_blocks_structure() -> None:
    a, b, w = _block(("a1", "a2"), 1.0, 0.5), _block(("b",), 7.0), _block((), 1.0, 0.25)
    s = stack_blocks([a, w, b], 0.1)
    assert s.state_names == ("a1", "a2", "b")
    np.testing.assert_array_equal(s.Phi, np.diag([1.0, 1.0, 7.0]))
    np.testing.assert_array_equal(s.Q, np.diag([2.0, 2.0, 14.0]))
    np.testing.assert_array_equal(s.P0, np.diag([3.0, 3.0, 21.0]))
    np.testing.assert_array_equal(s.H, [1, 2, 1])
    assert s.white_var == 0.75 and s.dt == 0.1
    np.testing.assert_array_equal(s.F, -np.diag([1.0, 1.0, 7.0]))
    # without a continuous form in every stateful block there is none in the stack
    assert stack_blocks([a, _block(("c",), 1.0, continuous=False)], 0.1).continuous is None


def test_stack_blocks_errors() -> None:
    with pytest.raises(InputError, match="no blocks"):
        stack_blocks([], 0.1)
    with pytest.raises(InputError, match="duplicate state names"):
        stack_blocks([_block(("a",), 1.0), _block(("a",), 2.0)], 0.1)


def test_state_space_block_validation() -> None:
    with pytest.raises(InputError, match=r"Phi has shape \(1, 1\), expected \(2, 2\)"):
        StateSpaceBlock(("a", "b"), [[1.0]], np.eye(2), [1, 0], np.eye(2))
    with pytest.raises(InputError, match=r"H has shape \(1,\), expected \(2,\)"):
        StateSpaceBlock(("a", "b"), np.eye(2), np.eye(2), [1], np.eye(2))
    empty = StateSpaceBlock((), [], [], [], [], 2.0)
    assert empty.Phi.shape == (0, 0) and empty.n_states == 0 and empty.F is None
    assert _block(("x",), 1.0).renamed("GM1").state_names == ("GM1.x",)


def test_augment_axes_six_axes() -> None:
    RW, WN, RR = stochmod.get_process("RW"), stochmod.get_process("WN"), stochmod.get_process("RR")
    freq, dt = 100.0, 0.05
    axes = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
    models = {}
    for i, axis in enumerate(axes):
        m = RW(sigma2=1e-6 * (i + 1)) + WN(sigma2=1e-3 * (i + 1))
        if i % 2:
            m = m + RR(omega=1e-7)
        models[axis] = m.bind(freq)
    aug = augment_axes(models, dt)
    singles = [models[a].augment(dt) for a in axes]
    sizes = [b.n_states for b in singles]
    assert aug.n_states == sum(sizes) == 6 * 1 + 3 * 2
    assert aug.axes == tuple(axes)
    assert aug.state_names[:2] == ("gyro_x.RW.value", "gyro_y.RW.value")
    assert aug.state_names[2:4] == ("gyro_y.RR.ramp", "gyro_y.RR.slope")
    assert len(set(aug.state_names)) == aug.n_states
    np.testing.assert_allclose(aug.white_var, [1e-3 * (i + 1) for i in range(6)], rtol=1e-15)
    start = 0
    for i, b in enumerate(singles):
        sl = slice(start, start + b.n_states)
        np.testing.assert_array_equal(aug.Phi[sl, sl], b.Phi)
        np.testing.assert_array_equal(aug.Q[sl, sl], b.Q)
        np.testing.assert_array_equal(aug.H[i, sl], b.H)
        assert np.count_nonzero(aug.H[i]) == np.count_nonzero(b.H)  # row i reads only axis i
        off = np.ones(aug.n_states, bool)
        off[sl] = False
        assert not aug.Phi[sl][:, off].any() and not aug.Q[sl][:, off].any()
        start += b.n_states
    # RW over dt: Phi = 1, Q = sigma2 * freq * dt (per-sample increment variance times steps)
    assert aug.Q[0, 0] == pytest.approx(1e-6 * freq * dt, rel=1e-12)


def test_augment_axes_errors() -> None:
    WN = stochmod.get_process("WN")
    with pytest.raises(InputError, match="at least one axis"):
        augment_axes({}, 0.01)
    with pytest.raises(sdk.SpecError, match="must be a Model"):
        augment_axes({"gyro_x": WN(sigma2=1.0)}, 0.01)
