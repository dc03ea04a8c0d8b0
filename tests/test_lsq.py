"""The lean Levenberg-Marquardt solver (stochmod.fit.lsq).

Truth: the normal-equations solution of a linear least-squares problem; the known minimum
(1, 1) of Rosenbrock's function; the projection of an unconstrained minimum onto a box; scipy's
trf (the peer) on the same exponential-fit problems, same tolerances, same run; the norm of
the damped step in 50-digit arithmetic (mpmath).
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares

from stochmod.fit.lsq import _damping, levenberg_marquardt

TOL = {"ftol": 1e-12, "xtol": 1e-12, "gtol": 1e-12, "max_nfev": 500}


def test_linear_problem_gives_the_normal_equations_solution() -> None:
    rng = np.random.default_rng(0)
    A = rng.normal(size=(20, 5)) * [1.0, 1e3, 1e-3, 1.0, 10.0]  # badly scaled columns
    b = rng.normal(size=20)
    res = levenberg_marquardt(lambda x: A @ x - b, lambda x: A, np.zeros(5), (-1e9, 1e9), **TOL)
    truth = np.linalg.solve(A.T @ A, A.T @ b)
    assert res.success and res.status in (1, 2, 3, 4)
    # ftol bounds the cost's relative decrease at the end: the cost to ~ftol, the point to
    # about its square root (scaled by the conditioning)
    assert res.cost == pytest.approx(0.5 * np.sum((A @ truth - b) ** 2), rel=1e-12)
    np.testing.assert_allclose(res.x, truth, rtol=1e-6)


def test_rosenbrock_reaches_its_minimum() -> None:
    def fun(x):
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])

    def jac(x):
        return np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]])

    res = levenberg_marquardt(fun, jac, np.array([-1.2, 1.0]), (-10.0, 10.0), **TOL)
    np.testing.assert_allclose(res.x, [1.0, 1.0], rtol=1e-8)
    assert res.nfev < 100


def test_box_bounds_give_the_projected_minimum() -> None:
    # separable: the minimum over the box is the clipped unconstrained one
    target = np.array([5.0, -0.5, -7.0])
    res = levenberg_marquardt(lambda x: x - target, lambda x: np.eye(3), np.zeros(3), (-2.0, 2.0), **TOL)
    np.testing.assert_allclose(res.x, [2.0, -0.5, -2.0], rtol=1e-9)
    assert np.all(np.abs(res.x) <= 2.0)


def _exponential_problem(seed: int):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 4.0, 20)
    y = 2.0 * np.exp(-1.3 * t) + 0.5 * np.exp(-0.2 * t) + 0.01 * rng.normal(size=t.size)

    def fun(p):
        return p[0] * np.exp(-p[1] * t) + p[2] * np.exp(-p[3] * t) - y

    def jac(p):
        e1, e2 = np.exp(-p[1] * t), np.exp(-p[3] * t)
        return np.column_stack([e1, -p[0] * t * e1, e2, -p[2] * t * e2])

    return fun, jac, np.array([1.0, 1.0, 1.0, 0.1])


@pytest.mark.parametrize("seed", range(4))
def test_same_minimum_as_scipy_trf(seed: int) -> None:
    fun, jac, x0 = _exponential_problem(seed)
    ours = levenberg_marquardt(fun, jac, x0, (-50.0, 50.0), **TOL)
    peer = least_squares(fun, x0, jac=jac, bounds=(-50.0, 50.0), method="trf", x_scale="jac",
                         ftol=1e-12, xtol=1e-12, gtol=1e-12)
    assert ours.cost <= peer.cost * (1 + 1e-9)
    np.testing.assert_allclose(np.sort(ours.x.reshape(2, 2), axis=0),
                               np.sort(peer.x.reshape(2, 2), axis=0), rtol=1e-5)


def test_a_failing_trial_point_is_a_rejected_step() -> None:
    """Residuals that raise (a model outside its reach) or are not finite beyond x = 1 only
    shorten the steps: the search ends at the constrained minimum x = 1 from the inside."""
    def fun(x):
        if x[0] > 1.0:
            raise ValueError("outside the model's reach")
        return np.array([x[0] - 3.0, np.log(2.0 - x[0])])

    def jac(x):
        return np.array([[1.0], [-1.0 / (2.0 - x[0])]])

    res = levenberg_marquardt(fun, jac, np.array([0.0]), (-10.0, 10.0), **TOL)
    assert res.x[0] <= 1.0
    assert res.x[0] == pytest.approx(1.0, abs=1e-6)
    with pytest.raises(ValueError, match="not finite at the start"):
        levenberg_marquardt(lambda x: np.array([np.nan]), jac, np.array([0.0]), (-1.0, 1.0), **TOL)
    with pytest.raises(ValueError, match="start is not finite"):
        levenberg_marquardt(fun, jac, np.array([np.nan]), (-10.0, 10.0), **TOL)


def test_callback_stops_the_search_and_the_budget_is_kept() -> None:
    fun, jac, x0 = _exponential_problem(0)
    seen: list[float] = []

    def stop(intermediate_result) -> None:
        seen.append(intermediate_result.cost)
        if len(seen) == 3:
            raise StopIteration

    res = levenberg_marquardt(fun, jac, x0, (-50.0, 50.0), **TOL, callback=stop)
    assert res.status == -2 and res.success and res.cost == seen[-1]
    assert seen == sorted(seen, reverse=True)  # every accepted step lowers the cost
    capped = levenberg_marquardt(fun, jac, x0, (-50.0, 50.0), **{**TOL, "max_nfev": 4})
    assert capped.status == 0 and not capped.success and capped.nfev == 4


def _exact_norm(sur: np.ndarray, s2: np.ndarray, mu: float) -> float:
    """||sur / (s2 + mu)|| in 50-digit arithmetic (no underflow)."""
    with mpmath.workdps(50):
        return float(mpmath.sqrt(mpmath.fsum((mpmath.mpf(float(a)) / (mpmath.mpf(float(b)) + mu)) ** 2
                                             for a, b in zip(sur, s2))))


# A region shrunk by rejected steps on the ADIS16405 accelerometer: p * p / d underflowed to
# zero and the Newton iteration divided by it.
ADIS_REGION = (np.array([2.0141424454304535, 1.7326056597407193, 0.98600425753618137,
                         0.26724734564399139, 2.9164865367466670e-07]),
               np.array([0.08564300739534325, -0.6165084115986947, -0.0108975582617495,
                         0.6186606693671222, 0.072921083104373]),
               4.285770979357966e-109)


@settings(max_examples=400, deadline=None)
@given(st.integers(1, 6), st.floats(-300.0, 2.0), st.floats(-12.0, 3.0), st.integers(0, 2**32 - 1))
@example(1, -157.0, 0.0, 0)  # low * high overflowed
def test_the_damping_fills_the_region_at_every_scale(n, log_radius, log_scale, seed) -> None:
    """mu gives a step of norm within 10 % of the region's radius (checked in 50 digits), down
    to regions of 1e-300, where the squares of the step underflow."""
    rng = np.random.default_rng(seed)
    s2 = 10.0 ** rng.uniform(-8.0, 1.0, n)
    sur = rng.normal(0.0, 1.0, n) * 10.0**log_scale
    radius = 10.0**log_radius
    assume(np.linalg.norm(sur / s2) > radius)  # the Gauss-Newton step is longer
    g_norm = float(np.linalg.norm(sur))
    mu = _damping(s2, sur, radius, g_norm)
    assert 0.0 < mu <= g_norm / radius
    assert _exact_norm(sur, s2, mu) == pytest.approx(radius, rel=0.1)


def test_the_damping_of_a_region_shrunk_by_rejected_steps() -> None:
    s2, sur, radius = ADIS_REGION
    mu = _damping(s2, sur, radius, float(np.linalg.norm(sur)))
    assert _exact_norm(sur, s2, mu) == pytest.approx(radius, rel=0.1)
